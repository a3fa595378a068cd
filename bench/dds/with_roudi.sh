#!/usr/bin/env bash
# SPDX-License-Identifier: Apache-2.0
# Runs a command beside a RouDi (iox-roudi, Debian package iceoryx) of its own:
# in a private mount namespace whose /tmp (RouDi's sockets and locks) and
# /dev/shm (its memory) are fresh, so it meets no other RouDi on the machine
# and leaves nothing behind. With --no-roudi the namespace is all it gives
# (for a command that starts its own, as `tinyline launch` does). Needs root
# (unshare). Usage:
#   bench/dds/with_roudi.sh [--config roudi.toml] [--no-roudi] COMMAND...
set -euo pipefail
config="$(dirname "$(readlink -f "$0")")/../../config/roudi.toml"
if [[ "${1:-}" == "--config" ]]; then config="$(readlink -f "$2")"; shift 2; fi
roudi_too=1
if [[ "${1:-}" == "--no-roudi" ]]; then roudi_too=; shift; fi
if [[ -z "${WITH_ROUDI_INSIDE:-}" ]]; then
  flags=(--config "$config")
  [[ -n "$roudi_too" ]] || flags+=(--no-roudi)
  exec env WITH_ROUDI_INSIDE=1 unshare --mount --propagation private "$0" "${flags[@]}" "$@"
fi
# A tree, build or config under /tmp (a clone in /tmp) stays visible: the
# first folder under /tmp of each is bound back into the fresh /tmp.
keep=()
for p in "$PWD" "$config" "$(command -v "$1" || echo "$1")"; do
  p="$(readlink -f "$p")"
  if [[ "$p" == /tmp/?* ]]; then keep+=("/tmp/$(cut -d/ -f3 <<<"$p")"); fi
done
old_tmp="$(mktemp -d /run/with_roudi.XXXXXX)"
mount --bind /tmp "$old_tmp"
trap 'umount -l "$old_tmp" 2>/dev/null; rmdir "$old_tmp" 2>/dev/null || true' EXIT
mount -t tmpfs tmpfs /tmp
for top in "${keep[@]}"; do
  [[ -d "$top" ]] && continue
  mkdir -p "$top" && mount --bind "$old_tmp/${top#/tmp/}" "$top"
done
mount -t tmpfs tmpfs /dev/shm
if [[ -z "$roudi_too" ]]; then "$@"; exit; fi
iox-roudi -c "$config" -l warning >/tmp/roudi.log 2>&1 &
roudi=$!
trap 'kill -INT $roudi 2>/dev/null; wait $roudi 2>/dev/null || true; umount -l "$old_tmp" 2>/dev/null; rmdir "$old_tmp" 2>/dev/null || true' EXIT
for _ in $(seq 100); do [[ -S /tmp/roudi ]] && break; sleep 0.1; done
[[ -S /tmp/roudi ]] || { cat /tmp/roudi.log >&2; echo "RouDi did not start" >&2; exit 1; }
"$@"
