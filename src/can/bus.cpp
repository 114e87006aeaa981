// open_bus: picks the backend from the URL's scheme and validates the rest.
#include "mrroc/can/bus.hpp"

#include <net/if.h>

#include <cstdio>
#include <cstdlib>
#include <string>

#include <fmt/format.h>

#include "mrroc/core/error.hpp"
#include "socketcan.hpp"
#include "virtual_bus.hpp"

namespace mrroc::can {

namespace {

constexpr const char* kKnownSchemes = "known: socketcan:<interface>, virtual:<name>";

[[noreturn]] void bad_url(std::string_view url, const std::string& why) {
  throw ConfigError("CAN bus URL '" + std::string(url) + "': " + why);
}

/// 'c', or \xNN for a character that would not show.
std::string quoted(char c) {
  if (c > ' ' && c <= '~') return std::string("'") + c + "'";
  if (c == ' ') return "' '";
  char hex[8];
  std::snprintf(hex, sizeof hex, "\\x%02x", static_cast<unsigned>(static_cast<unsigned char>(c)));
  return hex;
}

bool is_name_character(char c) {
  return (c >= 'A' && c <= 'Z') || (c >= 'a' && c <= 'z') || (c >= '0' && c <= '9') || c == '_' ||
         c == '-';
}

void check_virtual_name(std::string_view url, std::string_view name) {
  if (name.empty()) bad_url(url, "empty bus name (expected virtual:<name>, e.g. virtual:cell1)");
  if (name.size() > detail::kVirtualBusNameMax)
    bad_url(url, "bus name is " + std::to_string(name.size()) + " characters long, the limit is " +
                     std::to_string(detail::kVirtualBusNameMax));
  for (const char c : name)
    if (!is_name_character(c))
      bad_url(url, "bus name has the character " + quoted(c) +
                       "; names use only A-Z, a-z, 0-9, '_' and '-'");
}

/// MRROC_CAN_NAMESPACE, when set, follows the rules of bus names.
void check_virtual_namespace(std::string_view url) {
  const char* space = std::getenv(detail::kVirtualBusNamespaceVariable);
  if (space == nullptr || *space == '\0') return;
  const std::string_view value(space);
  // fmt, not operator+ of std::string: GCC 12 at -O2 warns wrongly (array-bounds) about the latter.
  const std::string what = fmt::format("{}='{}'", detail::kVirtualBusNamespaceVariable, value);
  if (value.size() > detail::kVirtualBusNameMax)
    bad_url(url, what + " is " + std::to_string(value.size()) + " characters long, the limit is " +
                     std::to_string(detail::kVirtualBusNameMax));
  for (const char c : value)
    if (!is_name_character(c))
      bad_url(url, what + " has the character " + quoted(c) +
                       "; names use only A-Z, a-z, 0-9, '_' and '-'");
}

void check_interface_name(std::string_view url, std::string_view interface) {
  if (interface.empty())
    bad_url(url, "empty interface name (expected socketcan:<interface>, e.g. socketcan:can0)");
  if (interface.size() >= IFNAMSIZ)
    bad_url(url, "interface name is " + std::to_string(interface.size()) +
                     " characters long, the limit is " + std::to_string(IFNAMSIZ - 1) +
                     " (IFNAMSIZ - 1)");
  for (const char c : interface)
    if (c == '/' || c == ':' || c <= ' ' || c > '~')
      bad_url(url, "interface name has the character " + quoted(c));
}

}  // namespace

namespace {

struct BusUrl {
  std::string_view scheme;
  std::string_view rest;
};

/// The URL's scheme and the rest, both validated. @throws ConfigError (bad_url).
BusUrl parse_bus_url(std::string_view url) {
  const std::size_t colon = url.find(':');
  if (url.empty()) bad_url(url, std::string("empty URL (") + kKnownSchemes + ")");
  if (colon == std::string_view::npos)
    bad_url(url, std::string("no scheme (") + kKnownSchemes + ")");
  const std::string_view scheme = url.substr(0, colon);
  const std::string_view rest = url.substr(colon + 1);
  if (rest.starts_with("//"))
    bad_url(url, "no '//' after the scheme (write " + std::string(scheme) + ":" +
                     std::string(rest.substr(2)) + ")");
  if (scheme == "socketcan") {
    check_interface_name(url, rest);
  } else if (scheme == "virtual") {
    check_virtual_name(url, rest);
  } else {
    bad_url(url, "unknown scheme '" + std::string(scheme) + "' (" + kKnownSchemes + ")");
  }
  return {scheme, rest};
}

}  // namespace

void check_bus_url(std::string_view url) { (void)parse_bus_url(url); }

std::unique_ptr<Bus> open_bus(std::string_view url) {
  const BusUrl parsed = parse_bus_url(url);
  if (parsed.scheme == "socketcan") return detail::open_socketcan_bus(url, parsed.rest);
  check_virtual_namespace(url);
  return detail::open_virtual_bus(url, parsed.rest);
}

}  // namespace mrroc::can
