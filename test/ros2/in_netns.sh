#!/bin/bash
# Runs "$@" (a test) in a machine of its own: a new network namespace with its
# loopback and a "network card" nic0 (10.78.0.1/24, one end of a veth pair
# whose other end, nic0peer, stays in the same namespace), a default route
# through it, and a private /dev/shm. A default ROS 2 node in there behaves as
# on a robot (Fast DDS announces the card's address and multicasts on it),
# but everything it sends stays in the namespace; Fast DDS's shared memory
# cannot reach the nodes of tests running side by side.
#
# The test sees TINYLINE_NETNS=1 and an environment without any DDS or ROS 2
# discovery setting (both sides run with their defaults). Where the machine
# refuses namespaces, the test runs as it is, without TINYLINE_NETNS, and
# skips what needs one.
set -u

clean_env=(-u ROS_DOMAIN_ID -u ROS_AUTOMATIC_DISCOVERY_RANGE -u ROS_STATIC_PEERS -u ROS_LOCALHOST_ONLY
           -u CYCLONEDDS_URI -u RMW_IMPLEMENTATION -u FASTRTPS_DEFAULT_PROFILES_FILE
           -u FASTDDS_DEFAULT_PROFILES_FILE -u ROS_DISCOVERY_SERVER -u ROS_SUPER_CLIENT
           -u TINYLINE_NETNS -u TINYLINE_NETNS_REASON)

if [ "${TINYLINE_NETNS_INNER:-}" != 1 ]; then
  why=""
  if ! command -v ip >/dev/null; then
    why="no 'ip' command (iproute2)"
  elif unshare --net --mount true 2>/dev/null; then
    exec env "${clean_env[@]}" TINYLINE_NETNS_INNER=1 unshare --net --mount --kill-child bash "$0" "$@"
  elif unshare --user --map-root-user --net --mount true 2>/dev/null; then
    exec env "${clean_env[@]}" TINYLINE_NETNS_INNER=1 \
      unshare --user --map-root-user --net --mount --kill-child bash "$0" "$@"
  else
    why="this machine refuses new network namespaces (unshare --net failed)"
  fi
  exec env "${clean_env[@]}" TINYLINE_NETNS_REASON="$why" "$@"
fi

set -e
ip link set lo up
ip link add nic0 type veth peer name nic0peer
# No IPv6 on the cable: the kernel's own neighbour discovery would count as
# traffic on the card.
for dev in nic0 nic0peer; do
  echo 1 > "/proc/sys/net/ipv6/conf/$dev/disable_ipv6" 2>/dev/null || true
done
ip addr add 10.78.0.1/24 dev nic0
ip link set nic0 up
ip link set nic0peer up
ip route add default via 10.78.0.2 dev nic0 onlink
mount -t tmpfs -o size=512m,mode=1777 tmpfs /dev/shm
unset TINYLINE_NETNS_INNER
export TINYLINE_NETNS=1
exec "$@"
