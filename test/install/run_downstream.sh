#!/usr/bin/env bash
# usage: run_downstream.sh BUILD_DIR WORK_DIR DOWNSTREAM_SRC CLUSTERING_ONLY_SRC MAX_MB
# Installs the build stripped, checks its size, then builds two consumers:
# one of node libraries (and runs it) and one of laser_clustering_core alone,
# which must not look for or link PCL, OpenCV or Cyclone DDS.
set -euo pipefail
build=$1 work=$2 src=$3 lean_src=$4 max_mb=$5
rm -rf "$work"
mkdir -p "$work"
cmake --install "$build" --prefix "$work/prefix" --strip > "$work/install.log" 2>&1 || { cat "$work/install.log"; exit 1; }
mb=$(du -sm "$work/prefix" | cut -f1)
echo "install: ${mb} MB (at most ${max_mb})"
if ((mb > max_mb)); then
  du -sm "$work/prefix"/lib/* "$work/prefix"/bin/* | sort -rn | head
  exit 1
fi
if file "$work/prefix/bin/tinyline" | grep -q "not stripped"; then
  echo "install: bin/tinyline is not stripped"
  exit 1
fi

cmake -S "$src" -B "$work/build" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release
cmake --build "$work/build" -j2
"$work/build/downstream" "$work/prefix"

lean=$work/clustering_only
cmake -S "$lean_src" -B "$lean" -G Ninja -DCMAKE_PREFIX_PATH="$work/prefix" -DCMAKE_BUILD_TYPE=Release \
  > "$lean.configure.log" 2>&1 || { cat "$lean.configure.log"; exit 1; }
cmake --build "$lean" -j2 > "$lean.build.log" 2>&1 || { cat "$lean.build.log"; exit 1; }
"$lean/clustering_only"
# What a consumer pulls shows in its cache (each found package's _DIR), its
# configure output (PCL's MPI warning) and its link line.
pulled=$(grep -iE '^(PCL|OpenCV|CycloneDDS|VTK|Boost|MPI)[A-Za-z_]*_DIR:' "$lean/CMakeCache.txt" || true)
pulled+=$(grep -E 'MPI|PCL|OpenCV|Cyclone' "$lean.configure.log" || true)
pulled+=$(grep -oiE 'lib(pcl|opencv|ddsc|vtk|boost)[A-Za-z0-9_.-]*' "$lean/build.ninja" | sort -u || true)
if [[ -n "$pulled" ]]; then
  echo "clustering_only pulled what it does not use:"
  echo "$pulled"
  exit 1
fi
echo "install and consumers: ok"
