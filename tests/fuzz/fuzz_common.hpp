#pragma once
/// @file
/// Shared checks of the fuzz targets (tests/fuzz/fuzz_*.cpp, docs/fuzzing.md).
///
/// A target that finds a broken property calls `fuzz::fail`, which prints what was expected and
/// aborts; libFuzzer then reports a crash and keeps the input. Exceptions are sorted with
/// `fuzz::guarded`: the ones a parser documents are the caller's business, anything else (another
/// mrroc::Error, a std::exception, anything at all) aborts naming its type and text.

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <string>
#include <string_view>
#include <typeinfo>

#include <fmt/format.h>

#include "mrroc/core/error.hpp"

namespace fuzz {

/// Prints "fuzz: property violated: <what>" and aborts (libFuzzer keeps the input as a crash).
[[noreturn]] inline void fail(const std::string& what) {
  std::fprintf(stderr, "\nfuzz: property violated: %s\n", what.c_str());
  std::fflush(stderr);
  std::abort();
}

inline void expect(bool condition, const std::string& what) {
  if (!condition) fail(what);
}

/// Runs `body`; exceptions of type `Allowed` go to `on_allowed`; any other exception aborts naming
/// its dynamic type, its text and `where`. Returns true when `body` returned normally.
template <class Allowed, class Body, class OnAllowed>
bool guarded(const char* where, Body&& body, OnAllowed&& on_allowed) {
  try {
    body();
    return true;
  } catch (const Allowed& e) {
    on_allowed(e);
  } catch (const mrroc::Error& e) {
    fail(fmt::format("{}: unexpected mrroc error {}: {}", where, typeid(e).name(), e.what()));
  } catch (const std::exception& e) {
    fail(fmt::format("{}: unexpected exception {}: {}", where, typeid(e).name(), e.what()));
  } catch (...) {
    fail(fmt::format("{}: unexpected exception of unknown type", where));
  }
  return false;
}

/// Runs `body`, which must not throw at all.
template <class Body>
void no_throw(const char* where, Body&& body) {
  try {
    body();
  } catch (const mrroc::Error& e) {
    fail(fmt::format("{}: must not throw, threw mrroc error {}: {}", where, typeid(e).name(),
                     e.what()));
  } catch (const std::exception& e) {
    fail(fmt::format("{}: must not throw, threw {}: {}", where, typeid(e).name(), e.what()));
  } catch (...) {
    fail(fmt::format("{}: must not throw, threw an exception of unknown type", where));
  }
}

/// True when `text` starts with "<file>:<line>: error: " and line >= 1; `line` receives it.
inline bool has_location_prefix(std::string_view text, std::string_view file,
                                long* line = nullptr) {
  if (!text.starts_with(file)) return false;
  text.remove_prefix(file.size());
  if (!text.starts_with(':')) return false;
  text.remove_prefix(1);
  long value = 0;
  std::size_t digits = 0;
  while (digits < text.size() && digits < 10 && text[digits] >= '0' && text[digits] <= '9')
    value = value * 10 + (text[digits++] - '0');
  if (digits == 0 || value < 1) return false;
  text.remove_prefix(digits);
  if (line != nullptr) *line = value;
  return text.starts_with(": error: ");
}

/// A value as text for comparisons and messages: doubles by their bits, so that NaN payloads and
/// the sign of zero count, and strings with their bytes escaped.
inline std::string bits(double v) {
  std::uint64_t b = 0;
  std::memcpy(&b, &v, sizeof b);
  return fmt::format("{:016x}", b);
}
inline std::string escaped(std::string_view s) {
  std::string out = "\"";
  for (const char c : s) {
    const auto u = static_cast<unsigned char>(c);
    if (u >= 0x20 && u < 0x7f && c != '"' && c != '\\')
      out += c;
    else
      out += fmt::format("\\x{:02x}", u);
  }
  return out + "\"";
}

/// LCM writes a string with strlen(): a string field loses everything from its first NUL on the
/// wire (docs/fuzzing.md). Round-trip comparisons apply the same cut to the expected value.
inline std::string wire_string(const std::string& s) { return std::string(s.c_str()); }

}  // namespace fuzz
