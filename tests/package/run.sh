#!/bin/sh
# Installs the build tree into a temporary prefix, builds tests/package against it with
# find_package(mrroc), and runs the result on the installed IRb-6 model.
set -eu
BUILD=$1
SOURCE=$(cd "$(dirname "$0")" && pwd)
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT
cmake --install "$BUILD" --prefix "$WORK/prefix" >/dev/null
cmake -S "$SOURCE" -B "$WORK/build" -DCMAKE_PREFIX_PATH="$WORK/prefix" >/dev/null
cmake --build "$WORK/build" >/dev/null
"$WORK/build/consumer" "$WORK/prefix/share/mrroc/robots/irb6"
