// The teach-in trajectory file parser (mrroc::ecp::TrajectoryFile::parse, which load() runs on a
// file's content) and its writer (to_text).
//
// Properties (docs/fuzzing.md):
// - the only exception is ConfigError reading "<name>:<line>: error: " with 1 <= line <= the
//   number of lines of the text;
// - an accepted file is consistent: axes in 1..64, every point with values_per_point() finite
//   values, a duration > 0 or a velocity scale in (0, 1], not both; a FRAME point is a frame;
// - to_text() does not throw, parses back to the same trajectory, and is a fixed point
//   (to_text(parse(to_text(t))) == to_text(t)).
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>

#include "fuzz_common.hpp"
#include "mrroc/ecp/generators/trajectory_file.hpp"

namespace {

const std::string kName = "fuzz.traj";

void check_file(const mrroc::ecp::TrajectoryFile& t) {
  fuzz::expect(t.axes >= 1 && t.axes <= 64, fmt::format("axes {} accepted", t.axes));
  std::size_t expected = 0;
  fuzz::no_throw("values_per_point", [&] { expected = t.values_per_point(); });
  for (std::size_t i = 0; i < t.points.size(); ++i) {
    const mrroc::ecp::TrajectoryPoint& p = t.points[i];
    fuzz::expect(p.values.size() == expected, fmt::format("point {} has {} values, expected {}",
                                                          i + 1, p.values.size(), expected));
    for (const double v : p.values)
      fuzz::expect(std::isfinite(v), fmt::format("point {} holds {}", i + 1, v));
    fuzz::expect(!(p.duration_s && p.velocity_scale), "a point with duration and velocity scale");
    if (p.duration_s)
      fuzz::expect(std::isfinite(*p.duration_s) && *p.duration_s > 0.0,
                   fmt::format("duration {} accepted", *p.duration_s));
    if (p.velocity_scale)
      fuzz::expect(*p.velocity_scale > 0.0 && *p.velocity_scale <= 1.0,
                   fmt::format("velocity_scale {} accepted", *p.velocity_scale));
  }
}

std::optional<mrroc::ecp::TrajectoryFile> parse(std::string_view text, const char* what,
                                                bool must_parse) {
  std::optional<mrroc::ecp::TrajectoryFile> out;
  fuzz::guarded<mrroc::ConfigError>(
      what, [&] { out = mrroc::ecp::TrajectoryFile::parse(text, kName); },
      [&](const mrroc::ConfigError& e) {
        if (must_parse)
          fuzz::fail(fmt::format("{}: the writer's own text does not parse: {}\n{}", what, e.what(),
                                 text));
        long line = 0;
        fuzz::expect(fuzz::has_location_prefix(e.what(), kName, &line),
                     fmt::format("ConfigError without '{}:<line>: error: ': {}", kName,
                                 fuzz::escaped(e.what())));
        const auto lines = static_cast<long>(std::count(text.begin(), text.end(), '\n')) + 1;
        fuzz::expect(line <= lines, fmt::format("error at line {} of a text of {} lines: {}", line,
                                                lines, e.what()));
      });
  return out;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  const std::optional<mrroc::ecp::TrajectoryFile> file =
      parse(text, "TrajectoryFile::parse", false);
  if (!file) return 0;
  check_file(*file);
  std::string written;
  fuzz::no_throw("to_text of a parsed file", [&] { written = file->to_text(); });
  const std::optional<mrroc::ecp::TrajectoryFile> again =
      parse(written, "TrajectoryFile::parse of to_text()", true);
  fuzz::expect(*again == *file, fmt::format("parse(to_text(t)) != t; to_text(t):\n{}", written));
  std::string rewritten;
  fuzz::no_throw("to_text of a re-parsed file", [&] { rewritten = again->to_text(); });
  fuzz::expect(rewritten == written,
               fmt::format("to_text is not a fixed point:\n{}\n---\n{}", written, rewritten));
  return 0;
}
