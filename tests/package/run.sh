#!/bin/sh
# Installs the build tree into a temporary prefix, builds tests/package against it with
# find_package(mrroc), runs the consumer program on the installed IRb-6 model, and runs a process
# set from the installed binaries whose ECP task comes from the out-of-tree plugin library; every
# installed header is compiled alone in a translation unit of its own.
set -eu
BUILD=$1
SOURCE=$(cd "$(dirname "$0")" && pwd)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
cmake --install "$BUILD" --prefix "$WORK/prefix" >/dev/null
cmake -S "$SOURCE" -B "$WORK/build" -DCMAKE_PREFIX_PATH="$WORK/prefix" | grep "headers compiled"
cmake --build "$WORK/build" -j2 >/dev/null
echo "every installed header compiled alone; the extension points without LCM and TOML"
"$WORK/build/consumer" "$WORK/prefix/share/mrroc/robots/irb6"
cat > "$WORK/wave.toml" <<TOML
[system]
name = "wave"
[mp]
task = "start_and_wait"
[[robot]]
name = "irb6"
model = "$WORK/prefix/share/mrroc/robots/irb6"
[robot.edp]
plugin = "mujoco"
[robot.ecp]
task = "wave"
library = "$WORK/build/libwave_task.so"
[robot.ecp.args]
waves = 1
amplitude = 0.2
TOML
"$WORK/prefix/bin/mrroc-launch" "$WORK/wave.toml"
