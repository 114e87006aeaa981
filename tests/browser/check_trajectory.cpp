// Reads a trajectory file with the library's parser (ecp::TrajectoryFile::load, what a task's
// TeachInPlaybackGenerator replays) and prints its header and poses; exit 1 with the parser's
// error when it does not parse. Used by the browser test on the files "Record pose" writes.
#include <cstdio>
#include <exception>

#include "mrroc/ecp/generators/trajectory_file.hpp"

int main(int argc, char** argv) {
  if (argc != 2 || std::string(argv[1]) == "--help") {
    std::fprintf(stderr, "usage: %s TRAJECTORY_FILE\n", argv[0]);
    return 2;
  }
  try {
    const auto t = mrroc::ecp::TrajectoryFile::load(argv[1]);
    std::printf("representation=%s axes=%zu robot=%s poses=%zu\n",
                mrroc::edp::to_string(t.representation), t.axes, t.robot.c_str(), t.points.size());
    for (const auto& p : t.points) {
      for (double v : p.values) std::printf(" %.6f", v);
      std::printf("\n");
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "%s\n", e.what());
    return 1;
  }
}
