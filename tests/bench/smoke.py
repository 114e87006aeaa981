#!/usr/bin/env python3
"""Every benchmark program runs to its RESULT line, in a short smoke mode (seconds each).

  tests/bench/smoke.py BIN_DIR      (inside scripts/netns-run; ctest's bench_smoke)

The benchmarks are run for their figures by scripts/bench, which takes minutes and a quiet
machine, so nothing ran them between two regenerations of docs/benchmarks.md and they broke
unseen (a crash at start, a first macro-step the EDP refuses). This runs each one with a few
samples and fails when one crashes, exits with an error, refuses a macro-step or prints no
RESULT line of its benchmark. No figure is judged here.
"""
import os
import re
import subprocess
import sys
import time

# (program, arguments, RESULT tags it must print, exit codes it may end with)
RUNS = [
    ("bench_ik", ["200"], ["B3"], {0}),
    ("bench_servo", ["2"], ["B2", "B7"], {0}),
    ("bench_chain", ["100"], ["B1", "B4"], {0}),
    ("bench_launch", ["1"], ["B8"], {0}),
    ("bench_can", ["100"], ["B6"], {0}),
    # Exit 1 means a reply was lost or late in this short soak on a busy machine, and a late
    # successor's stopping ramp can make the soak's next macro-step too abrupt (refused): figures,
    # judged by scripts/soak, not here. A crash still fails.
    ("bench_soak", ["4", "2"], ["B5"], {0, 1}),
    ("bench_continuity", ["--smoke"], ["B9"], {0}),
    ("bench_collision", ["200"], ["B10"], {0}),
]

# Lines that mean the program broke, whatever its exit code: a crash, or a refusal of the
# macro-steps a benchmark plans (they must keep within the limits).
CRASHED = re.compile(r"terminate called|Segmentation fault|Aborted|AddressSanitizer")
BROKEN = re.compile(CRASHED.pattern + r"|SET refused|refused:")


def main():
    if len(sys.argv) != 2 or sys.argv[1] in ("-h", "--help"):
        print(__doc__.strip())
        return 0 if len(sys.argv) == 2 else 2
    bin_dir = sys.argv[1]
    if os.environ.get("MRROC_IN_NETNS") != "1":
        print("smoke: run me inside scripts/netns-run (the benchmarks use LCM)")
        return 2
    failures = []
    for program, args, tags, codes in RUNS:
        path = os.path.join(bin_dir, program)
        started = time.monotonic()
        try:
            done = subprocess.run([path] + args, capture_output=True, text=True, timeout=120)
            code, out = done.returncode, done.stdout + done.stderr
        except subprocess.TimeoutExpired as e:
            code = None
            out = (e.stdout or b"").decode(errors="replace") if isinstance(e.stdout, bytes) \
                else (e.stdout or "")
        seconds = time.monotonic() - started
        found = set(re.findall(r"^RESULT (B\d+)", out, flags=re.M))
        missing = [t for t in tags if t not in found]
        # bench_collision's note quotes a refusal of its guard on purpose (a random path into
        # the table or the floor): only a crash counts there.
        pattern = CRASHED if program in ("bench_soak", "bench_collision") else BROKEN
        broken = [line for line in out.splitlines() if pattern.search(line)][:3]
        problems = []
        if code is None:
            problems.append("did not end within 120 s")
        elif code not in codes:
            problems.append(f"exit code {code} (expected {sorted(codes)})")
        if missing:
            problems.append("no RESULT line for " + ", ".join(missing))
        if broken:
            problems.append("printed: " + " | ".join(broken))
        verdict = "FAIL" if problems else "ok  "
        print(f"{verdict} {program} {' '.join(args)}: {seconds:.1f} s, exit {code}, RESULT "
              f"{' '.join(sorted(found)) or 'none'}" + ("; " + "; ".join(problems) if problems
                                                        else ""), flush=True)
        if problems:
            failures.append(program)
            print("  its last lines:\n    " + "\n    ".join(out.splitlines()[-15:]), flush=True)
    if failures:
        print(f"smoke: {len(failures)} of {len(RUNS)} benchmarks broke: {', '.join(failures)}")
        return 1
    print(f"smoke: all {len(RUNS)} benchmarks ran to their RESULT lines")
    return 0


if __name__ == "__main__":
    sys.exit(main())
