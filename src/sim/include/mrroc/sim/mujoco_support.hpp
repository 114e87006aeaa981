#pragma once
/// @file
/// Small helpers around the MuJoCo 2.2 C API shared by the `mujoco` EDP plugin and the axis
/// emulator's cell world: owning pointers, model loading with a readable error text, names in
/// messages, and the state checks that detect an unstable simulation.
///
/// Units are MuJoCo's (SI: m, rad, kg, s). The check functions do not allocate (they run in
/// servo loops).

#include <filesystem>
#include <memory>
#include <string>

#include <mujoco/mujoco.h>

namespace mrroc::sim {

struct ModelDeleter {
  void operator()(mjModel* m) const noexcept { mj_deleteModel(m); }
};
struct DataDeleter {
  void operator()(mjData* d) const noexcept { mj_deleteData(d); }
};
using ModelPtr = std::unique_ptr<mjModel, ModelDeleter>;
using DataPtr = std::unique_ptr<mjData, DataDeleter>;

/// Loads an MJCF file (from `vfs` when it holds `file`, else from disk). On failure returns
/// nullptr and sets `error` to MuJoCo's message on one line ("unknown MuJoCo error" when empty).
ModelPtr load_mjcf(const std::string& file, const mjVFS* vfs, std::string& error);
/// Loads MJCF text through a MuJoCo virtual file system (no temporary file); as load_mjcf.
ModelPtr load_mjcf_text(const std::string& text, std::string& error);

/// A number in a message, with enough digits to tell 0.0025 from 0.002 ("%.9g").
std::string format_number(double value);
/// A path in single quotes, for messages.
std::string quoted(const std::filesystem::path& path);
/// The model's name of a joint, or "#<id>" when it has none.
std::string joint_name(const mjModel* m, int joint);

/// Text of a MuJoCo warning (`mjtWarning`), e.g. "bad number in qacc (simulation reset)".
const char* warning_text(int warning) noexcept;
/// Number of warnings raised since the data was last reset (all kinds).
int warning_total(const mjData* d) noexcept;

/// The first joint with a non-finite position, velocity or acceleration, or -1 when the whole
/// state is finite.
int non_finite_joint(const mjModel* m, const mjData* d) noexcept;

/// Largest |violation| [m or rad] of the equality constraints with ids first .. first+count-1 as
/// of the last constraint computation (`mj_fwdPosition`); count < 0: all from `first`. 0 when
/// there are none.
double equality_violation(const mjData* d, int first = 0, int count = -1) noexcept;

}  // namespace mrroc::sim
