#pragma once
/// @file
/// Command-line handling shared by the benchmark programs: `--help`, and whole-number arguments
/// checked against their range (a bad one is named with its limits and exits 2, instead of being
/// read as 0 the way atoi would).
#include <cerrno>
#include <cstdio>
#include <cstdlib>
#include <cstring>

namespace mrroc::bench {

/// Prints `usage` to stdout and returns true when the first argument is --help or -h.
inline bool help_requested(int argc, char** argv, const char* usage) {
  if (argc < 2 || (std::strcmp(argv[1], "--help") != 0 && std::strcmp(argv[1], "-h") != 0))
    return false;
  std::fputs(usage, stdout);
  return true;
}

/// `text` as a whole number in lo..hi; otherwise prints why (naming the argument, its unit and
/// limits) and exits with 2.
inline long whole_number(const char* program, const char* name, const char* text, long lo, long hi,
                         const char* unit) {
  errno = 0;
  char* end = nullptr;
  const long value = std::strtol(text, &end, 10);
  if (errno != 0 || end == text || *end != '\0' || value < lo || value > hi) {
    std::fprintf(stderr, "%s: %s '%s' is not a whole number of %s in %ld..%ld (see --help)\n",
                 program, name, text, unit, lo, hi);
    std::exit(2);
  }
  return value;
}

}  // namespace mrroc::bench
