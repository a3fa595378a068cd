#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# `tinyline launch` with shared memory, each case a ctest entry run inside a
# private mount namespace (bench/dds/with_roudi.sh), so it meets no other RouDi:
#   shm_launch.sh CASE TINYLINE LAUNCH_FILE WORKDIR
# starts_roudi:       no RouDi runs; the launch starts one, two viewer processes
#                     get every cloud intact through shared memory, and RouDi
#                     is gone when the launch ends.
# uses_running_roudi: a RouDi runs (with_roudi.sh); the launch uses it and
#                     leaves it running.
# crashed_viewer:     a viewer is killed with SIGKILL while it holds chunks; the
#                     other gets every cloud intact, also the hundreds after the
#                     kill (more than the 1 MiB pool has chunks: none stay lost).
# Exit 0: passed; 1: failed (the reason on stderr).
set -u
case_name=$1
tl=$2
file=$3
work=$4/$case_name
rm -rf "$work"
mkdir -p "$work"
out=$work/out.txt

fail() {
  echo "FAIL ($case_name): $*" >&2
  [ -f "$out" ] && tail -n 60 "$out" >&2
  exit 1
}
# Whether a RouDi answers on its socket (what the bridge asks too).
roudi_answers() {
  python3 -c 'import socket,sys
s=socket.socket(socket.AF_UNIX,socket.SOCK_DGRAM)
try: s.connect("/tmp/roudi")
except OSError: sys.exit(1)'
}
expect_line() {  # PATTERN COUNT WHAT
  local n
  n=$(grep -cE "$1" "$out")
  [ "$n" -ge "$2" ] || fail "$3 (expected $2 line(s) matching '$1', found $n)"
}
intact_viewers() {  # CLOUDS VIEWERS...
  local clouds=$1
  shift
  for v in "$@"; do
    expect_line "^\[$v\].*clouds: $clouds received, $clouds intact, 0 corrupt, 0 missing" 1 \
      "viewer $v did not get all $clouds clouds intact"
  done
}

starts_roudi() {
  roudi_answers && fail "a RouDi already runs in this namespace"
  "$tl" launch "$file" --duration 10 --no-table >"$out" 2>&1 || fail "the launch failed"
  expect_line '^\[launch\] shared memory: RouDi \(pid [0-9]+\) runs for this launch' 1 "no RouDi was started"
  expect_line 'shared memory on \(iceoryx\)' 3 "not every process is on shared memory"
  intact_viewers 300 viewer_a viewer_b
  local pid
  pid=$(sed -nE 's/^\[launch\] shared memory: RouDi \(pid ([0-9]+)\).*/\1/p' "$out")
  kill -0 "$pid" 2>/dev/null && fail "RouDi (pid $pid) still runs after the launch"
  roudi_answers && fail "a RouDi still answers after the launch"
  return 0
}

uses_running_roudi() {
  roudi_answers || fail "no RouDi runs (run this under bench/dds/with_roudi.sh)"
  "$tl" launch "$file" --duration 10 --no-table >"$out" 2>&1 || fail "the launch failed"
  expect_line '^\[launch\] shared memory: using the RouDi already running' 1 "the running RouDi was not used"
  expect_line 'shared memory on \(iceoryx\)' 3 "not every process is on shared memory"
  intact_viewers 300 viewer_a viewer_b
  roudi_answers || fail "the launch stopped a RouDi it had not started"
}

crashed_viewer() {
  "$tl" launch "$file" count:=1000 report_every:=100 --duration 20 --no-table >"$out" 2>&1 &
  local launch=$! pid=""
  # The first hundred clouds reached viewer_b: it holds chunks now.
  for _ in $(seq 300); do
    grep -qE '^\[viewer_b\].*100 clouds so far' "$out" && break
    kill -0 $launch 2>/dev/null || break
    sleep 0.1
  done
  grep -qE '^\[viewer_b\].*100 clouds so far' "$out" || fail "viewer_b got no clouds"
  pid=$(sed -nE "s/^\[launch\] started process 'viewer_b' \(pid ([0-9]+)\).*/\1/p" "$out")
  [ -n "$pid" ] || fail "no pid for viewer_b"
  kill -KILL "$pid"
  wait $launch
  expect_line "process 'viewer_b' .*was killed by signal 9" 1 "viewer_b was not killed"
  intact_viewers 1000 viewer_a
  grep -qE 'not sent to the processes on this machine' "$out" && fail "the camera ran out of chunks"
  return 0
}

"$case_name" || exit 1
echo "PASS ($case_name)"
