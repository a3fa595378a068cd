#!/usr/bin/env bash
# usage: run_downstream.sh BUILD_DIR WORK_DIR DOWNSTREAM_SRC
set -euo pipefail
build=$1 work=$2 src=$3
rm -rf "$work"
cmake --install "$build" --prefix "$work/prefix" > "$work.install.log" 2>&1 || { cat "$work.install.log"; exit 1; }
cmake -S "$src" -B "$work/build" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release
cmake --build "$work/build" -j2
"$work/build/downstream" "$work/prefix"
