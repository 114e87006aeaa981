#!/bin/sh
# Runs inside the qemu VM of tests/hil/run-qemu.sh (Debian's kernel, chrooted into the host's root
# shared read-only, so build-tree paths are the host's): CAN modules loaded, vcan0 up, vcan1 down,
# lo up with the multicast route. Environment: MRROC_SOURCE_DIR, MRROC_BUILD_DIR, MRROC_BIN_DIR,
# MRROC_CAN_IFACE=vcan0, MRROC_CAN_DOWN_IFACE=vcan1; the working directory is MRROC_BUILD_DIR
# (read-only: write to /tmp). Any command that fails fails the test.
#
# Add further checks at the end (e.g. an EDP <-> axis emulator exchange over vcan0). LCM works
# here too (udpm on lo); there is no other network device.
set -eu
echo "vm-tests: kernel $(uname -r); $(ip -br link show "$MRROC_CAN_IFACE")"

# The SocketCAN tests of the unit test; they must run here, not skip.
out=/tmp/test_can_bus.log
"$MRROC_BIN_DIR/test_can_bus" --gtest_filter='SocketCan.*' --gtest_color=no 2>&1 | tee "$out"
grep -q '^\[  PASSED  \] 7 tests' "$out" || { echo "vm-tests: not all 7 SocketCan tests ran and passed"; exit 1; }
if grep -q '^\[  SKIPPED \]' "$out"; then echo "vm-tests: a SocketCan test was skipped"; exit 1; fi
