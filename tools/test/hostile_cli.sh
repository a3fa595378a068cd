#!/bin/sh
# Command-line cases a hostile user runs, each a ctest entry:
#   hostile_cli.sh CASE TINYLINE WORKDIR
# Exit 0: passed; 1: failed (the reason on stderr); 77: skipped (not possible here).
set -u
case_name=$1
tl=$2
work=$3/$case_name
rm -rf "$work"
mkdir -p "$work"

fail() {
  echo "FAIL ($case_name): $*" >&2
  [ -f "$work/out.txt" ] && sed -n 1,40p "$work/out.txt" >&2
  exit 1
}
skip() {
  echo "SKIP ($case_name): $*" >&2
  exit 77
}
now() { date +%s.%N; }
# elapsed START: seconds since START (a shell float via awk)
elapsed() { awk -v a="$1" -v b="$(now)" 'BEGIN { printf "%.1f", b - a }'; }
longer_than() { awk -v e="$1" -v l="$2" 'BEGIN { exit !(e > l) }'; }

# A 100 kHz source recorded with a tiny queue on four threads: no crash, and
# --duration ends the run (it used to crash, or run on for tens of seconds).
recorder_load() {
  cat > "$work/load.launch.yaml" <<EOF
launch:
- arg: {name: depth, default: "1"}
- node: {pkg: tinyline, exec: pulse, name: source, param: [{name: rate_hz, value: 100000.0}], remap: [{from: output, to: /fast}]}
- node: {pkg: bag, exec: recorder, name: rec, param: [{name: path, value: "$work/load.mcap"}, {name: queue_depth, value: "\$(var depth)"}]}
EOF
  for depth in 1 2 5 10; do
    rm -f "$work/load.mcap" "$work/load.mcap.part"
    t0=$(now)
    "$tl" launch "$work/load.launch.yaml" depth:=$depth --duration 1 --threads 4 --no-table > "$work/out.txt" 2>&1
    rc=$?
    e=$(elapsed "$t0")
    [ $rc -lt 128 ] || fail "depth $depth: killed by signal $((rc - 128))"
    [ $rc -eq 0 ] || fail "depth $depth: exit code $rc"
    longer_than "$e" 15 && fail "depth $depth: --duration 1 took $e s"
    "$tl" bag info "$work/load.mcap" > "$work/info.txt" 2>&1 || fail "depth $depth: the bag does not read back"
    grep -q "dropped=" "$work/info.txt" || fail "depth $depth: the bag does not say what was dropped"
  done
}

# Ctrl-C on the same load ends the launch promptly (it used to take up to a
# minute, depending on where the workers were: several tries).
ctrl_c() {
  cat > "$work/load.launch.yaml" <<EOF
launch:
- arg: {name: depth, default: "5"}
- node: {pkg: tinyline, exec: pulse, name: source, param: [{name: rate_hz, value: 100000.0}], remap: [{from: output, to: /fast}]}
- node: {pkg: bag, exec: recorder, name: rec, param: [{name: path, value: "$work/load.mcap"}, {name: queue_depth, value: "\$(var depth)"}]}
EOF
  for depth in 2 5 10 5; do
    "$tl" launch "$work/load.launch.yaml" depth:=$depth --threads 4 --no-table > "$work/out.txt" 2>&1 &
    pid=$!
    sleep 1.5
    t0=$(now)
    kill -INT $pid
    wait $pid
    rc=$?
    e=$(elapsed "$t0")
    [ $rc -lt 128 ] || fail "depth $depth: killed by signal $((rc - 128))"
    longer_than "$e" 10 && fail "depth $depth: Ctrl-C took $e s to end the launch"
    [ -f "$work/load.mcap" ] || fail "depth $depth: no bag after Ctrl-C"
  done
}

# A full disk inside a launch: a non-zero exit naming the error, and the
# file that was there before is still there (a private tmpfs of 64 KiB).
full_disk() {
  command -v unshare > /dev/null || skip "no unshare"
  mkdir -p "$work/mnt"
  # 1000-byte messages into a 16 KiB disk: full after a few dozen messages,
  # which even a loaded machine publishes well within the run.
  text=$(printf '%01000d' 0)
  cat > "$work/full.launch.yaml" <<EOF
launch:
- node: {pkg: tinyline, exec: pulse, name: source, param: [{name: rate_hz, value: 2000.0}, {name: text, value: "$text"}], remap: [{from: output, to: /big}]}
- node: {pkg: bag, exec: recorder, name: rec, param: [{name: path, value: "$work/mnt/rec.mcap"}, {name: compression, value: none}, {name: chunk_size_kb, value: 4}]}
EOF
  unshare -m sh -c "mount -t tmpfs -o size=16k tmpfs '$work/mnt' || exit 77
    echo previous > '$work/mnt/rec.mcap'
    '$tl' launch '$work/full.launch.yaml' --duration 2 --no-table > '$work/out.txt' 2>&1
    rc=\$?
    cat '$work/mnt/rec.mcap' > '$work/after.txt'
    exit \$rc"
  rc=$?
  [ $rc -eq 77 ] && skip "cannot mount a tmpfs in a private mount namespace (not root?)"
  [ $rc -ne 0 ] || fail "exit code 0 on a full disk"
  [ $rc -lt 128 ] || fail "killed by signal $((rc - 128))"
  grep -q "No space left on device" "$work/out.txt" || fail "the error is not shown"
  [ "$(cat "$work/after.txt")" = previous ] || fail "the existing file was replaced"
}

# A FIFO or /dev/zero where a file is expected: refused at once, naming it
# (a FIFO used to block forever, /dev/zero to be read until memory ran out).
odd_inputs() {
  mkfifo "$work/pipe.yaml" "$work/pipe.csv" || skip "no mkfifo"
  printf 'launch:\n- include: {file: pipe.yaml}\n' > "$work/inc.launch.yaml"
  printf 'launch:\n- include: {file: /dev/zero}\n' > "$work/zero.launch.yaml"
  for args in "launch $work/pipe.yaml" "launch $work/inc.launch.yaml" "launch /dev/zero" \
              "launch $work/zero.launch.yaml" "bag info $work/pipe.yaml" "bag play $work/pipe.yaml" \
              "bag recover $work/pipe.yaml $work/out.mcap" "calib fit $work/pipe.csv -o $work/x.yaml" \
              "calib fit /dev/zero -o $work/x.yaml" "calib eval $work/pipe.csv --calib /dev/zero" \
              "calib measured --data $work/pipe.yaml" "sim serve $work/pipe.yaml" "sim serve /dev/zero"; do
    timeout 20 "$tl" $args > "$work/out.txt" 2>&1
    rc=$?
    [ $rc -eq 124 ] && fail "$args: still waiting after 20 s"
    [ $rc -eq 1 ] || fail "$args: exit code $rc, not 1"
    grep -q "is a FIFO, not a regular file\|is a character device, not a regular file" "$work/out.txt" ||
      fail "$args: the message does not say what is wrong"
  done
}

case "$case_name" in
  recorder_load | ctrl_c | full_disk | odd_inputs) "$case_name" ;;
  *) echo "unknown case $case_name" >&2; exit 2 ;;
esac
echo "ok: $case_name"
