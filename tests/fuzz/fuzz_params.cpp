// Parameters from TOML text (mrroc::params_from_toml, which parses the arguments of every
// NEXT_STATE command the ECP receives from the MP) and the typed getters of mrroc::Params that
// plugins and tasks read them with.
//
// Properties (docs/fuzzing.md):
// - the only exception is ConfigError reading "<origin>:<line>: error: " with line >= 1;
// - every key is located at "<origin>:<line>" with line >= 1;
// - each getter either returns or throws ConfigError with the key's location; exactly the getters
//   of the value's type succeed (a number also reads as a double); the optional getters agree
//   with the required ones; after reading every key, no key is unread and reject_unread accepts.
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <variant>
#include <vector>

#include "fuzz_common.hpp"
#include "mrroc/config/params.hpp"
#include "mrroc/config/process_set.hpp"

namespace {

const std::string kOrigin = "NEXT_STATE 'fuzz' arguments";

/// Calls `get`; true when it returned, false when it threw ConfigError located at `at`.
template <class Get>
bool reads(const char* getter, const std::string& key, const mrroc::SourceLocation& at, Get&& get) {
  bool ok = false;
  fuzz::guarded<mrroc::ConfigError>(
      getter,
      [&] {
        get();
        ok = true;
      },
      [&](const mrroc::ConfigError& e) {
        fuzz::expect(std::string_view(e.what()).starts_with(at.str() + ": error: '" + key + "'"),
                     fmt::format("{} of {}: ConfigError not at {}: {}", getter, fuzz::escaped(key),
                                 at.str(), fuzz::escaped(e.what())));
      });
  return ok;
}

void check_key(const mrroc::Params& p, const std::string& key, const mrroc::ParamValue& value) {
  const mrroc::SourceLocation at = p.location_of(key);
  fuzz::expect(at.file == kOrigin && at.line >= 1,
               fmt::format("key {} located at {}", fuzz::escaped(key), at.str()));
  fuzz::expect(p.has(key), "has() denies a key of values()");
  const bool is_int = std::holds_alternative<std::int64_t>(value);
  const bool is_double = std::holds_alternative<double>(value);
  auto expect_reads = [&](const char* getter, bool expected, bool got) {
    fuzz::expect(got == expected,
                 fmt::format("{} of {} (value index {}) {}", getter, fuzz::escaped(key),
                             value.index(), got ? "succeeded" : "failed"));
  };
  double d = 0;
  expect_reads("get_double", is_int || is_double,
               reads("get_double", key, at, [&] { d = p.get_double(key); }));
  if (is_double)
    fuzz::expect(fuzz::bits(d) == fuzz::bits(std::get<double>(value)),
                 "get_double changed the value");
  expect_reads("get_double(fallback)", is_int || is_double,
               reads("get_double(fallback)", key, at, [&] { (void)p.get_double(key, 0.5); }));
  expect_reads("get_int", is_int, reads("get_int", key, at, [&] { (void)p.get_int(key); }));
  expect_reads("get_int(fallback)", is_int,
               reads("get_int(fallback)", key, at, [&] { (void)p.get_int(key, 1); }));
  expect_reads("get_bool", std::holds_alternative<bool>(value),
               reads("get_bool", key, at, [&] { (void)p.get_bool(key); }));
  expect_reads("get_bool(fallback)", std::holds_alternative<bool>(value),
               reads("get_bool(fallback)", key, at, [&] { (void)p.get_bool(key, true); }));
  expect_reads("get_string", std::holds_alternative<std::string>(value),
               reads("get_string", key, at, [&] { (void)p.get_string(key); }));
  expect_reads("get_string(fallback)", std::holds_alternative<std::string>(value),
               reads("get_string(fallback)", key, at, [&] { (void)p.get_string(key, "x"); }));
  expect_reads("get_doubles", std::holds_alternative<std::vector<double>>(value),
               reads("get_doubles", key, at, [&] { (void)p.get_doubles(key); }));
  expect_reads("get_doubles(fallback)", std::holds_alternative<std::vector<double>>(value),
               reads("get_doubles(fallback)", key, at, [&] { (void)p.get_doubles(key, {1.0}); }));
  expect_reads("get_double_rows", std::holds_alternative<std::vector<std::vector<double>>>(value),
               reads("get_double_rows", key, at, [&] { (void)p.get_double_rows(key); }));
  expect_reads("get_strings", std::holds_alternative<std::vector<std::string>>(value),
               reads("get_strings", key, at, [&] { (void)p.get_strings(key); }));
}

void check_missing(const mrroc::Params& p) {
  const std::string key = "\x01no such key";
  if (p.has(key)) return;
  const mrroc::SourceLocation at = p.location();
  bool refused = false;
  fuzz::guarded<mrroc::ConfigError>(
      "get_double of a missing key", [&] { (void)p.get_double(key); },
      [&](const mrroc::ConfigError& e) {
        refused = true;
        fuzz::expect(std::string_view(e.what()).starts_with(at.str() + ": error: missing"),
                     fmt::format("missing-key error not at {}: {}", at.str(), e.what()));
      });
  fuzz::expect(refused, "get_double of a missing key returned");
  fuzz::no_throw("get_double(fallback) of a missing key",
                 [&] { fuzz::expect(p.get_double(key, 0.25) == 0.25, "fallback not returned"); });
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string text(reinterpret_cast<const char*>(data), size);
  std::optional<mrroc::Params> params;
  fuzz::guarded<mrroc::ConfigError>(
      "params_from_toml", [&] { params = mrroc::params_from_toml(text, kOrigin); },
      [&](const mrroc::ConfigError& e) {
        fuzz::expect(fuzz::has_location_prefix(e.what(), kOrigin),
                     fmt::format("ConfigError without '{}:<line>: error: ': {}", kOrigin,
                                 fuzz::escaped(e.what())));
      });
  if (!params) return 0;
  const mrroc::Params& p = *params;
  fuzz::expect(p.location().file == kOrigin, "Params not located in its origin");
  check_missing(p);
  for (const auto& [key, value] : p.values()) check_key(p, key, value);
  fuzz::expect(p.unread_keys().empty(), "keys unread after reading every key");
  fuzz::no_throw("reject_unread after reading every key", [&] { p.reject_unread("args"); });
  return 0;
}
