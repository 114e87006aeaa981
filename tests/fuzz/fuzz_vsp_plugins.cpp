// The stock VSP sensor plugins (vsp/plugins/stock_sensors.cpp), configured as the example sets
// configure them, fed raw samples as the VSP shell hands them over.
//
// Input: [vsp][source][rest]. `vsp` (mod the number of [[vsp]] tables in
// configs/sensing-touch.toml, configs/sensing-follow.toml and configs/conveyor-pick.toml) picks the
// plugin and its parameters, `source` (mod its sources) the source, and the rest is one
// raw_sensor_t as received. A fresh plugin per input, so that inputs replay alike.
//
// Properties (docs/fuzzing.md):
// - what does not decode, or does not validate (comm::decode), never reaches a plugin (the shell
//   counts it as malformed);
// - on_sample and make_reading throw nothing but std::exception (the shell catches those:
//   malformed sample, sensor fault);
// - a reading said to be valid has as many names and units as values, and only finite values.
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include <lcm/lcm-cpp.hpp>

#include "fuzz_common.hpp"
#include "mrroc/comm/codec.hpp"
#include "mrroc/comm/request_reply.hpp"
#include "mrroc/config/process_set.hpp"
#include "mrroc/vsp/sensor.hpp"
#include "mrroc_lcm/raw_sensor_t.hpp"

namespace {

std::vector<mrroc::VspConfig>& vsps() {
  static std::vector<mrroc::VspConfig> all;
  return all;
}

/// Calls `body`; std::exception is what the shell catches, anything else is a finding.
template <class Body>
bool shell_catches(const char* where, Body&& body) {
  try {
    body();
    return true;
  } catch (const std::exception&) {
    return false;
  } catch (...) {
    fuzz::fail(fmt::format("{}: threw something that is not a std::exception", where));
  }
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  const std::filesystem::path configs = std::filesystem::path(MRROC_SOURCE_DIR) / "configs";
  for (const char* file : {"sensing-touch.toml", "sensing-follow.toml", "conveyor-pick.toml"}) {
    const mrroc::ProcessSetConfig set = mrroc::load_process_set(configs / file);
    for (const mrroc::VspConfig& v : set.vsps) vsps().push_back(v);
  }
  fuzz::expect(!vsps().empty(), "no [[vsp]] table in the example sets");
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 2) return 0;
  const mrroc::VspConfig& v = vsps()[data[0] % vsps().size()];
  const std::size_t source = data[1] % v.sources.size();
  lcm::ReceiveBuffer buffer{};
  buffer.data = const_cast<std::uint8_t*>(data + 2);
  buffer.data_size = static_cast<std::uint32_t>(size - 2);
  mrroc_lcm::raw_sensor_t m;
  bool decodes = false;
  fuzz::no_throw("comm::detail::decode_received",
                 [&] { decodes = mrroc::comm::detail::decode_received(&buffer, m); });
  if (!decodes) return 0;
  std::optional<mrroc::vsp::RawSample> sample;
  fuzz::guarded<mrroc::comm::DecodeError>(
      "comm::decode", [&] { sample = mrroc::comm::decode(m); },
      [](const mrroc::comm::DecodeError&) {});
  if (!sample) return 0;

  std::unique_ptr<mrroc::vsp::SensorPlugin> plugin = mrroc::vsp::make_sensor(v.plugin);
  mrroc::vsp::SensorSetup setup;
  setup.name = v.name;
  setup.sources = v.sources;
  setup.params = v.params;
  plugin->configure(setup);  // the example sets' own parameters: must be accepted
  const bool taken = shell_catches("on_sample", [&] { plugin->on_sample(source, *sample); });
  mrroc::vsp::Reading reading;
  const bool read = shell_catches("make_reading", [&] { reading = plugin->make_reading({}); });
  if (!read || !reading.valid) return 0;
  fuzz::expect(reading.names.size() == reading.values.size() &&
                   reading.units.size() == reading.values.size(),
               fmt::format("plugin '{}' (VSP '{}'): a valid reading of {} values with {} names "
                           "and {} units",
                           v.plugin, v.name, reading.values.size(), reading.names.size(),
                           reading.units.size()));
  for (std::size_t i = 0; i < reading.values.size(); ++i)
    fuzz::expect(
        std::isfinite(reading.values[i]),
        fmt::format("plugin '{}' (VSP '{}'): a valid reading with {} = {} (sample {} "
                    "{})",
                    v.plugin, v.name,
                    i < reading.names.size() ? reading.names[i] : std::to_string(i),
                    reading.values[i], taken ? "taken" : "refused", sample->values.size()));
  return 0;
}
