#!/bin/bash
# Two "hosts": network namespaces joined by a veth pair (10.77.0.1 <-> 10.77.0.2),
# each running one process group of a launch file, configured the way
# docs/dds.md says for a real network (named interface, unicast peers, no
# multicast). Exits 77 (skip) where the machine refuses namespaces.
#
#   two_hosts.sh TINYLINE LAUNCH_FILE WORKDIR
set -u
TL=$1
LAUNCH=$2
WORK=$3

if [ "${TWO_HOSTS_INNER:-}" != 1 ]; then
  if ! unshare --user --map-root-user --net true 2>/dev/null; then
    echo "SKIP: this machine refuses new user/network namespaces (unshare --user --net failed)"
    exit 77
  fi
  if ! command -v ip >/dev/null; then
    echo "SKIP: no 'ip' command (iproute2) to set up the veth pair"
    exit 77
  fi
  # Host A is this new namespace; --kill-child takes everything down with it.
  exec env TWO_HOSTS_INNER=1 unshare --user --map-root-user --net --kill-child bash "$0" "$@"
fi

set -e
config() {  # interface, peer address
  echo "<CycloneDDS><Domain Id=\"any\"><General><Interfaces><NetworkInterface name=\"$1\"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex><Peers><Peer address=\"$2\"/></Peers></Discovery></Domain></CycloneDDS>"
}
mkfifo "$WORK/pid" "$WORK/go"
ip link set lo up

# Host B: a namespace of its own; it tells us its pid, then waits until its
# end of the cable is up before starting (Cyclone picks interfaces at start).
unshare --net bash -c "
  echo \$\$ > '$WORK/pid'
  read _ < '$WORK/go'
  ip link set lo up
  exec env CYCLONEDDS_URI='$(config vb 10.77.0.1)' '$TL' launch '$LAUNCH' --process host_b --no-table 2>&1 | sed -u 's/^/[host_b] /'
" &
read -r BPID < "$WORK/pid"

ip link add va type veth peer name vb netns "$BPID"
ip addr add 10.77.0.1/24 dev va
ip link set va up
nsenter -t "$BPID" -n ip addr add 10.77.0.2/24 dev vb
nsenter -t "$BPID" -n ip link set vb up
echo "veth up: host_a 10.77.0.1 (va) <-> host_b 10.77.0.2 (vb)"
echo go > "$WORK/go"

CYCLONEDDS_URI="$(config va 10.77.0.2)" "$TL" launch "$LAUNCH" --process host_a --no-table 2>&1 | sed -u 's/^/[host_a] /' &
wait
