// SPDX-License-Identifier: Apache-2.0
#include <tinyline/dds/settings.hpp>

#include <ifaddrs.h>
#include <net/if.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/un.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstdlib>

#include <fmt/format.h>

namespace tinyline::dds {

namespace {

std::string env(const char* name) {
  const char* v = std::getenv(name);
  return v == nullptr ? std::string() : std::string(v);
}

std::string xml_escape(const std::string& s) {
  std::string out;
  for (char c : s) {
    switch (c) {
      case '&': out += "&amp;"; break;
      case '<': out += "&lt;"; break;
      case '>': out += "&gt;"; break;
      case '"': out += "&quot;"; break;
      default: out += c;
    }
  }
  return out;
}

std::string peer_elements(const std::vector<std::string>& peers) {
  std::string out;
  for (const auto& p : peers) out += "<Peer address=\"" + xml_escape(p) + "\"/>";
  return out;
}

int read_domain_id() {
  const std::string d = env("ROS_DOMAIN_ID");
  if (d.empty()) return 0;
  char* end = nullptr;
  errno = 0;
  const long long v = std::strtoll(d.c_str(), &end, 10);
  if (errno != 0 || end == d.c_str() || *end != '\0') {
    throw DdsError(fmt::format("ROS_DOMAIN_ID='{}' is not a number (expected 0..232)", d));
  }
  return check_domain_id(v, "ROS_DOMAIN_ID");
}

/// ROS_AUTOMATIC_DISCOVERY_RANGE as rcl reads it; unset stays unset (ours
/// means this machine, rcl's the subnet).
std::optional<DiscoveryRange> read_range(std::vector<std::string>& notes) {
  const std::string v = env("ROS_AUTOMATIC_DISCOVERY_RANGE");
  if (v.empty()) return std::nullopt;
  if (v == "OFF") return DiscoveryRange::Off;
  if (v == "LOCALHOST") return DiscoveryRange::Localhost;
  if (v == "SUBNET") return DiscoveryRange::Subnet;
  if (v == "SYSTEM_DEFAULT") return DiscoveryRange::SystemDefault;
  notes.push_back(
      fmt::format("Invalid value '{}' specified for 'ROS_AUTOMATIC_DISCOVERY_RANGE', assuming localhost only", v));
  return DiscoveryRange::Localhost;
}

/// ROS_STATIC_PEERS: ';'-separated, empty items skipped, each under 256
/// characters (rcl's limit).
std::vector<std::string> read_static_peers(std::vector<std::string>& notes) {
  std::vector<std::string> peers;
  const std::string v = env("ROS_STATIC_PEERS");
  std::size_t start = 0;
  while (start <= v.size()) {
    const std::size_t end = std::min(v.find(';', start), v.size());
    const std::string p = v.substr(start, end - start);
    if (p.size() > 255) {
      notes.push_back(
          fmt::format("Static peer {} specified to 'ROS_STATIC_PEERS' is too long (maximum of 255); skipping", p));
    } else if (!p.empty()) {
      peers.push_back(p);
    }
    start = end + 1;
  }
  return peers;
}

}  // namespace

const char* to_string(DiscoveryRange r) {
  switch (r) {
    case DiscoveryRange::Off: return "OFF";
    case DiscoveryRange::Localhost: return "LOCALHOST";
    case DiscoveryRange::Subnet: return "SUBNET";
    case DiscoveryRange::SystemDefault: return "SYSTEM_DEFAULT";
  }
  return "?";
}

int check_domain_id(long long id, const std::string& where) {
  // Ports are 7400 + 250 * domain + offsets: above 232 they leave 16 bits.
  if (id < 0 || id > 232) throw DdsError(fmt::format("{}: DDS domain id {} is outside 0..232", where, id));
  return static_cast<int>(id);
}

Settings Settings::from_environment() {
  Settings s;
  s.domain_id = read_domain_id();
  if (const char* uri = std::getenv("CYCLONEDDS_URI"); uri != nullptr && *uri != '\0') s.config = uri;
  s.shared_memory = env("TINYLINE_SHARED_MEMORY") == "1";
  // rcl: ROS_LOCALHOST_ONLY=1 forces LOCALHOST without static peers; any
  // other non-empty value hands over to the two newer variables.
  const std::string localhost_only = env("ROS_LOCALHOST_ONLY");
  if (!localhost_only.empty()) {
    s.notes.emplace_back(
        "ROS_LOCALHOST_ONLY is deprecated but still honored if it is enabled. "
        "Use ROS_AUTOMATIC_DISCOVERY_RANGE and ROS_STATIC_PEERS instead.");
  }
  if (localhost_only == "1") {
    s.notes.emplace_back(
        "'localhost_only' is enabled, 'automatic_discovery_range' and 'static_peers' will be ignored.");
    s.range = DiscoveryRange::Localhost;
    return s;
  }
  if (!localhost_only.empty()) {
    s.notes.emplace_back("'localhost_only' is disabled, 'automatic_discovery_range' and 'static_peers' will be used.");
  }
  s.range = read_range(s.notes);
  if (s.range == DiscoveryRange::Off) {
    if (!env("ROS_STATIC_PEERS").empty()) {
      s.notes.emplace_back(
          "Note: ROS_AUTOMATIC_DISCOVERY_RANGE is set to OFF, but found static peers in "
          "ROS_STATIC_PEERS. ROS_STATIC_PEERS will be ignored.");
    }
    return s;
  }
  s.static_peers = read_static_peers(s.notes);
  if (s.range == DiscoveryRange::SystemDefault && !s.static_peers.empty()) {
    s.notes.push_back(
        fmt::format("{} static peers were specified, but discovery is set to use the DDS default "
                    "(SYSTEM_DEFAULT), so these static peers will be ignored.",
                    s.static_peers.size()));
  }
  return s;
}

std::string Settings::effective_config() const {
  if (!range && static_peers.empty() && !config.empty()) return config;
  const DiscoveryRange r = range.value_or(DiscoveryRange::Localhost);
  const std::string generated = r == DiscoveryRange::Localhost
                                    ? this_machine_config(machine_interfaces(), static_peers)
                                    : discovery_config(r, static_peers, static_cast<long>(getpid()));
  if (config.empty()) return generated;
  if (generated.empty()) return config;
  return generated + "," + config;  // later fragments win, as in rmw_cyclonedds
}

std::string discovery_config(DiscoveryRange range, const std::vector<std::string>& static_peers, long pid) {
  switch (range) {
    case DiscoveryRange::Off:
      // A tag no other process has: nothing can join (rmw_cyclonedds' way);
      // no participant index, so no limit on processes per machine.
      return fmt::format(
          "<CycloneDDS><Domain Id=\"any\"><General><AllowMulticast>false</AllowMulticast></General>"
          "<Discovery><ParticipantIndex>none</ParticipantIndex><Tag>ros_discovery_off_{}</Tag>"
          "</Discovery></Domain></CycloneDDS>",
          pid);
    case DiscoveryRange::Localhost: return this_machine_config(machine_interfaces(), static_peers);
    case DiscoveryRange::Subnet:
      return fmt::format(
          "<CycloneDDS><Domain Id=\"any\"><Discovery><ParticipantIndex>auto</ParticipantIndex>"
          "<MaxAutoParticipantIndex>32</MaxAutoParticipantIndex>{}</Discovery></Domain></CycloneDDS>",
          static_peers.empty() ? "" : "<Peers>" + peer_elements(static_peers) + "</Peers>");
    case DiscoveryRange::SystemDefault: return {};
  }
  return {};
}

std::string this_machine_config(const std::vector<std::string>& interfaces,
                                const std::vector<std::string>& static_peers, const std::string& tag,
                                int max_participants) {
  const bool local = static_peers.empty();
  // Cyclone prefers loopback (priority 2) wherever it reaches a participant,
  // so processes here keep talking if a card goes away; it also sends to a
  // static peer through the highest-priority interface, where loopback
  // cannot reach another machine: with peers it yields to the cards.
  std::string nics;
  for (std::size_t i = 0; i < interfaces.size() && i < 3; ++i) {
    nics += "<NetworkInterface name=\"" + xml_escape(interfaces[i]) + "\"/>";
  }
  nics +=
      local ? "<NetworkInterface address=\"127.0.0.1\"/>" : "<NetworkInterface address=\"127.0.0.1\" priority=\"0\"/>";
  // Unicast discovery needs a participant index per process (its ports); the
  // peer 127.0.0.1 makes discovery probe the first `max_participants` of them.
  // Loopback has a 64 KiB MTU: fragments of 60 kB instead of Cyclone's
  // 1344 B, and room for 4 MB of unacknowledged data per writer, move
  // 64 KiB..1 MiB messages several times faster; they would only hurt on the
  // way to a static peer on another machine.
  return fmt::format(
      "<CycloneDDS><Domain Id=\"any\">"
      "<General><Interfaces>{}</Interfaces><AllowMulticast>false</AllowMulticast>{}</General>{}"
      "<Discovery><ParticipantIndex>auto</ParticipantIndex>"
      "<MaxAutoParticipantIndex>{}</MaxAutoParticipantIndex>"
      "<Peers><Peer address=\"127.0.0.1\"/>{}</Peers>"
      "<LeaseDuration>3s</LeaseDuration>{}</Discovery>"
      "</Domain></CycloneDDS>",
      nics, local ? "<MaxMessageSize>65500B</MaxMessageSize><FragmentSize>60000B</FragmentSize>" : "",
      local ? "<Internal><Watermarks><WhcHigh>4MB</WhcHigh></Watermarks></Internal>" : "", max_participants - 1,
      peer_elements(static_peers), tag.empty() ? std::string() : "<Tag>" + xml_escape(tag) + "</Tag>");
}

std::vector<std::string> machine_interfaces() {
  ifaddrs* list = nullptr;
  if (getifaddrs(&list) != 0) return {};
  std::vector<std::string> multicast, other;
  for (const ifaddrs* a = list; a != nullptr; a = a->ifa_next) {
    if (a->ifa_addr == nullptr || a->ifa_addr->sa_family != AF_INET) continue;
    if ((a->ifa_flags & IFF_UP) == 0 || (a->ifa_flags & IFF_LOOPBACK) != 0) continue;
    auto& into = (a->ifa_flags & IFF_MULTICAST) != 0 ? multicast : other;
    const std::string name = a->ifa_name;
    if (std::find(multicast.begin(), multicast.end(), name) == multicast.end() &&
        std::find(other.begin(), other.end(), name) == other.end()) {
      into.push_back(name);
    }
  }
  freeifaddrs(list);
  multicast.insert(multicast.end(), other.begin(), other.end());
  if (multicast.size() > 3) multicast.resize(3);
  return multicast;
}

bool roudi_running() {
  // iceoryx 2.0's RouDi listens on a datagram socket named after it in /tmp:
  // a connect succeeds only while it runs (a stale file refuses).
  const int fd = socket(AF_UNIX, SOCK_DGRAM | SOCK_CLOEXEC, 0);
  if (fd < 0) return false;
  sockaddr_un a{};
  a.sun_family = AF_UNIX;
  std::snprintf(a.sun_path, sizeof(a.sun_path), "/tmp/roudi");
  const bool up = connect(fd, reinterpret_cast<const sockaddr*>(&a), sizeof(a)) == 0;
  close(fd);
  return up;
}

std::string shared_memory_config() {
  return "<CycloneDDS><Domain Id=\"any\"><SharedMemory><Enable>true</Enable><LogLevel>error</LogLevel>"
         "</SharedMemory></Domain></CycloneDDS>";
}

std::string loopback_config(const std::string& tag, int max_participants) {
  return this_machine_config({}, {}, tag, max_participants);
}

}  // namespace tinyline::dds
