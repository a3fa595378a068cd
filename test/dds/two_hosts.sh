#!/bin/bash
# Two "hosts": network namespaces joined by a veth pair (10.77.0.1 <-> 10.77.0.2),
# each running one process group of a launch file, configured one of the two
# ways docs/dds.md gives for a real network: a Cyclone configuration (named
# interface, unicast peers, no multicast; MODE uri, the default) or ROS 2's
# ROS_STATIC_PEERS naming the other host (MODE static_peers). Exits 77 (skip)
# where the machine refuses namespaces.
#
#   two_hosts.sh TINYLINE LAUNCH_FILE WORKDIR [MODE]
set -u
TL=$1
LAUNCH=$2
WORK=$3
MODE=${4:-uri}

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
dds_env() {  # interface, peer address: the one variable of one host's environment
  if [ "$MODE" = static_peers ]; then
    echo "ROS_STATIC_PEERS=$2"
  else
    echo "CYCLONEDDS_URI=<CycloneDDS><Domain Id=\"any\"><General><Interfaces><NetworkInterface name=\"$1\"/></Interfaces><AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex><Peers><Peer address=\"$2\"/></Peers></Discovery></Domain></CycloneDDS>"
  fi
}
mkfifo "$WORK/pid" "$WORK/go"
ip link set lo up

# Host B: a namespace of its own; it tells us its pid, then waits until its
# end of the cable is up before starting (Cyclone picks interfaces at start).
unshare --net bash -c "
  echo \$\$ > '$WORK/pid'
  read _ < '$WORK/go'
  ip link set lo up
  exec env '$(dds_env vb 10.77.0.1)' '$TL' launch '$LAUNCH' --process host_b --no-table 2>&1 | sed -u 's/^/[host_b] /'
" &
read -r BPID < "$WORK/pid"

ip link add va type veth peer name vb netns "$BPID"
ip addr add 10.77.0.1/24 dev va
ip link set va up
nsenter -t "$BPID" -n ip addr add 10.77.0.2/24 dev vb
nsenter -t "$BPID" -n ip link set vb up
echo "veth up: host_a 10.77.0.1 (va) <-> host_b 10.77.0.2 (vb)"
echo go > "$WORK/go"

env "$(dds_env va 10.77.0.2)" "$TL" launch "$LAUNCH" --process host_a --no-table 2>&1 | sed -u 's/^/[host_a] /' &
wait
