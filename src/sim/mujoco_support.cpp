#include "mrroc/sim/mujoco_support.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>

namespace mrroc::sim {

ModelPtr load_mjcf(const std::string& file, const mjVFS* vfs, std::string& error) {
  std::array<char, 1024> buffer{};
  ModelPtr model(mj_loadXML(file.c_str(), vfs, buffer.data(), static_cast<int>(buffer.size())));
  error.clear();
  if (!model) {
    error = buffer[0] != '\0' ? std::string(buffer.data()) : "unknown MuJoCo error";
    std::replace(error.begin(), error.end(), '\n', ' ');
    while (!error.empty() && error.back() == ' ') error.pop_back();
  }
  return model;
}

ModelPtr load_mjcf_text(const std::string& text, std::string& error) {
  const char* const file = "model.xml";
  auto vfs = std::make_unique<mjVFS>();  // large (file name table): not on the stack
  mj_defaultVFS(vfs.get());
  if (mj_makeEmptyFileVFS(vfs.get(), file, static_cast<int>(text.size())) != 0) {
    error = "cannot make the virtual file";
    return nullptr;
  }
  const int slot = mj_findFileVFS(vfs.get(), file);
  std::memcpy(vfs->filedata[slot], text.data(), text.size());
  ModelPtr model = load_mjcf(file, vfs.get(), error);
  mj_deleteVFS(vfs.get());
  return model;
}

std::string format_number(double value) {
  std::array<char, 32> buffer{};
  std::snprintf(buffer.data(), buffer.size(), "%.9g", value);
  return buffer.data();
}

// Strings appended piece by piece here and below: GCC 12's -O3 warns (-Wstringop-overflow)
// about `"literal" + std::string`, a false positive that fails a Release build with -Werror.
std::string quoted(const std::filesystem::path& path) {
  std::string text(1, '\'');
  text += path.string();
  text += '\'';
  return text;
}

std::string joint_name(const mjModel* m, int joint) {
  const char* name = mj_id2name(m, mjOBJ_JOINT, joint);
  if (name != nullptr) return name;
  std::string text(1, '#');
  text += std::to_string(joint);
  return text;
}

const char* warning_text(int warning) noexcept {
  switch (warning) {
    case mjWARN_INERTIA: return "(near) singular inertia matrix";
    case mjWARN_CONTACTFULL: return "contact list full";
    case mjWARN_CNSTRFULL: return "constraint buffer full";
    case mjWARN_VGEOMFULL: return "visual geom buffer full";
    case mjWARN_BADQPOS: return "bad number in qpos (simulation reset)";
    case mjWARN_BADQVEL: return "bad number in qvel (simulation reset)";
    case mjWARN_BADQACC: return "bad number in qacc (simulation reset)";
    case mjWARN_BADCTRL: return "bad number in ctrl";
    default: return "unknown";
  }
}

int warning_total(const mjData* d) noexcept {
  int total = 0;
  for (const mjWarningStat& w : d->warning) total += w.number;
  return total;
}

int non_finite_joint(const mjModel* m, const mjData* d) noexcept {
  for (int j = 0; j < m->njnt; ++j) {
    const int qpos_end = j + 1 < m->njnt ? m->jnt_qposadr[j + 1] : m->nq;
    for (int i = m->jnt_qposadr[j]; i < qpos_end; ++i)
      if (!std::isfinite(d->qpos[i])) return j;
  }
  for (int v = 0; v < m->nv; ++v)
    if (!std::isfinite(d->qvel[v]) || !std::isfinite(d->qacc[v])) return m->dof_jntid[v];
  return -1;
}

double equality_violation(const mjData* d, int first, int count) noexcept {
  double worst = 0.0;
  for (int r = 0; r < d->nefc; ++r) {
    if (d->efc_type[r] != mjCNSTR_EQUALITY) continue;
    const int id = d->efc_id[r];
    if (id < first || (count >= 0 && id >= first + count)) continue;
    worst = std::max(worst, std::abs(d->efc_pos[r]));
  }
  return worst;
}

}  // namespace mrroc::sim
