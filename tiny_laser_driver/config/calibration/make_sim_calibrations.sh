#!/usr/bin/env bash
# Makes the calibrations the driver ships for the simulated sensors: the
# thesis's procedure on the simulated calibration rail (3.3.3): measure the
# leakage (laser off, dark) and the sensitivity ratio (laser off, even ambient
# light), sweep a white target over 0.15-2.0 m twice in shuffled order while the
# sensor warms up, fit the declared model, and check it on a held-out sweep
# (another seed, distances between the training ones).
#   tiny_laser_driver/config/calibration/make_sim_calibrations.sh [BUILD_DIR]
# Needs a build with sim, tiny_laser_driver and tools.
set -euo pipefail
here=$(cd "$(dirname "$0")" && pwd)
root=$(cd "$here/../../.." && pwd)
build=${1:-$root/build}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
for sensor in tiny_tof_8mm tiny_tof_3p6mm; do
  cfg="$root/sim/config/sensors/$sensor.yaml"
  constants=$("$build/sim/sim_rail_csv" --sensor "$cfg" --constants)
  echo "== $sensor: measured constants $constants"
  "$build/sim/sim_rail_csv" --sensor "$cfg" -o "$tmp/rail.csv" --from 0.15
  # shellcheck disable=SC2086
  "$build/tools/tinyline" calib fit "$tmp/rail.csv" -o "$here/sim_$sensor.yaml" $constants
  "$build/sim/sim_rail_csv" --sensor "$cfg" -o "$tmp/heldout.csv" --from 0.175 --visits 1 --seed 99
  echo "held-out: $("$build/tools/tinyline" calib eval "$tmp/heldout.csv" --calib "$here/sim_$sensor.yaml")"
done
