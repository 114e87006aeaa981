#!/bin/sh
# Runs inside the qemu VM of tests/hil/run-qemu.sh (Debian's kernel; chrooted into the host's root
# shared read-only, so build-tree paths are the host's): CAN modules loaded, vcan0 up, vcan1 down,
# lo up with the multicast route LCM needs, no other network device. Environment:
# MRROC_SOURCE_DIR, MRROC_BUILD_DIR, MRROC_BIN_DIR, MRROC_CAN_IFACE=vcan0,
# MRROC_CAN_DOWN_IFACE=vcan1, TMPDIR (writable; the trees are read-only); the working directory
# is MRROC_BUILD_DIR. Exit non-zero to fail the ctest hil_qemu_vcan.
#
# Add further checks at the end.
set -eu
tmp=${TMPDIR:-/tmp}
echo "vm-tests: kernel $(uname -r); $(ip -br link show "$MRROC_CAN_IFACE")"

# 1. The SocketCAN tests of the unit test against the real kernel: they must run here, not skip.
log=$tmp/test_can_bus.log
rc=0
"$MRROC_BIN_DIR/test_can_bus" --gtest_filter='SocketCan.*' --gtest_color=no >"$log" 2>&1 || rc=$?
cat "$log"
passed=$(sed -n 's/^\[  PASSED  \] \([0-9]*\) tests\{0,1\}\.$/\1/p' "$log")
if [ "$rc" != 0 ]; then echo "vm-tests: test_can_bus SocketCan.* failed (exit code $rc)"; exit 1; fi
if grep -q '^\[  SKIPPED \]' "$log"; then echo "vm-tests: a SocketCan test was skipped"; exit 1; fi
if [ "${passed:-0}" -lt 7 ]; then echo "vm-tests: only ${passed:-0} SocketCan tests passed, expected 7 or more"; exit 1; fi
echo "vm-tests: $passed SocketCan tests passed on $MRROC_CAN_IFACE"

# 2. The EDP's `can` plugin against the cell emulator (mrroc-axis-emu, lock-step) over vcan0:
#    bring-up, cyclic positions out and back, quick stop, an injected drive fault.
log=$tmp/test_can_plugin.log
rc=0
"$MRROC_BIN_DIR/test_can_plugin" --gtest_color=no >"$log" 2>&1 || rc=$?
cat "$log"
if [ "$rc" != 0 ]; then echo "vm-tests: test_can_plugin failed over $MRROC_CAN_IFACE (exit code $rc)"; exit 1; fi
if ! grep -q "socketcan:$MRROC_CAN_IFACE" "$log"; then echo "vm-tests: test_can_plugin did not use $MRROC_CAN_IFACE"; exit 1; fi
echo "vm-tests: EDP can plugin <-> mrroc-axis-emu exchange passed on $MRROC_CAN_IFACE"
