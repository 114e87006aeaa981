// The robot parameters file (robots/<name>/parameters.toml) as mrroc::load_robot_model reads it.
// load_robot_model takes a folder, so the input is written as parameters.toml into a private
// folder that also links the real robots' URDF and MJCF files.
//
// Properties (docs/fuzzing.md):
// - the only exception is ConfigError, reading "<folder>/parameters.toml:<line>: error: " with
//   line >= 1, or "<a file in the folder>: error: " for the URDF checks;
// - an accepted model is consistent: every per-axis list (limits from the URDF, velocities,
//   accelerations, synchronisation positions) has one value per joint name; every kinematic
//   model file exists.
#include <signal.h>
#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <string_view>

#include <console_bridge/console.h>

#include "fuzz_common.hpp"
#include "mrroc/robot/robot_model.hpp"

namespace {

namespace fs = std::filesystem;

fs::path g_folder;

void remove_folder() {
  std::error_code ec;
  fs::remove_all(g_folder, ec);
}

void check_error(const mrroc::ConfigError& e) {
  const std::string file = (g_folder / "parameters.toml").string();
  const std::string_view text = e.what();
  if (fuzz::has_location_prefix(text, file)) return;
  fuzz::expect(
      text.starts_with(g_folder.string() + "/") && text.find(": error: ") != std::string_view::npos,
      fmt::format("ConfigError names neither '{}:<line>' nor a file of the folder: {}", file,
                  fuzz::escaped(text)));
}

void check_model(const mrroc::RobotModel& m) {
  const std::size_t axes = m.axes();
  auto per_axis = [&](const std::vector<double>& v, const char* what) {
    fuzz::expect(v.size() == axes,
                 fmt::format("{} has {} values for {} joints", what, v.size(), axes));
  };
  per_axis(m.lower_limits, "lower_limits");
  per_axis(m.upper_limits, "upper_limits");
  per_axis(m.max_velocity, "max_velocity");
  per_axis(m.max_acceleration, "max_acceleration");
  per_axis(m.synchro_joint_positions, "synchro_joint_positions");
  for (const fs::path& p : m.kinematic_models)
    fuzz::expect(fs::exists(p), fmt::format("kinematic model {} accepted but missing", p.string()));
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  // urdfdom reports every URDF it cannot parse on the console; the target checks the result.
  console_bridge::setLogLevel(console_bridge::CONSOLE_BRIDGE_LOG_NONE);
  // A run that crashed could not remove its folder: remove those of processes that are gone.
  const std::string prefix = "mrroc-fuzz-robot-";
  for (const auto& old : fs::directory_iterator(fs::temp_directory_path())) {
    const std::string name = old.path().filename().string();
    if (!name.starts_with(prefix)) continue;
    const long pid = std::strtol(name.c_str() + prefix.size(), nullptr, 10);
    if (pid > 0 && ::kill(static_cast<pid_t>(pid), 0) != 0 && errno == ESRCH) {
      std::error_code ec;
      fs::remove_all(old.path(), ec);
    }
  }
  g_folder = fs::temp_directory_path() / (prefix + std::to_string(::getpid()));
  fs::remove_all(g_folder);
  fs::create_directories(g_folder);
  for (const auto& robot : fs::directory_iterator(fs::path(MRROC_SOURCE_DIR) / "robots")) {
    if (!robot.is_directory()) continue;
    for (const auto& f : fs::directory_iterator(robot.path())) {
      const std::string ext = f.path().extension().string();
      if (ext == ".urdf" || ext == ".xml")
        fs::create_symlink(f.path(), g_folder / f.path().filename());
    }
  }
  std::atexit(remove_folder);
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  // The file names the URDF to read: a device such as /dev/zero or /dev/stdin would hang the run
  // (the parameters file is trusted, not hostile input).
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  for (const std::string_view device : {"/dev", "/proc", "/sys"})
    if (text.find(device) != std::string_view::npos) return -1;
  {
    std::ofstream out(g_folder / "parameters.toml", std::ios::binary | std::ios::trunc);
    out.write(reinterpret_cast<const char*>(data), static_cast<std::streamsize>(size));
    if (!out) fuzz::fail("cannot write " + (g_folder / "parameters.toml").string());
  }
  std::optional<mrroc::RobotModel> model;
  fuzz::guarded<mrroc::ConfigError>(
      "load_robot_model", [&] { model = mrroc::load_robot_model(g_folder); }, check_error);
  if (model) check_model(*model);
  return 0;
}
