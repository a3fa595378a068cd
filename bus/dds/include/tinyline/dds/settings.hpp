// SPDX-License-Identifier: Apache-2.0
// Where a process finds the rest of its graph over DDS: the domain, how far
// discovery reaches, the Cyclone DDS configuration, and how this process
// introduces itself.
//
// The environment is read the way rcl and rmw_cyclonedds_cpp read it in ROS 2
// Jazzy (ROS_DOMAIN_ID, ROS_AUTOMATIC_DISCOVERY_RANGE, ROS_STATIC_PEERS, the
// deprecated ROS_LOCALHOST_ONLY, CYCLONEDDS_URI on top), with one difference:
// left unset, the range is this machine only, where ROS 2's is the subnet.
// This machine only still meets a default ROS 2 node on the same machine: see
// this_machine_config() and docs/dds.md.
#pragma once

#include <cstddef>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

namespace tinyline::dds {

/// A DDS set-up or I/O failure; the text says what and on which topic.
class DdsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// ROS_AUTOMATIC_DISCOVERY_RANGE's values.
enum class DiscoveryRange {
  Off,            ///< no discovery beyond this process
  Localhost,      ///< processes on this machine (unicast on it), plus the static peers
  Subnet,         ///< multicast discovery on the network, plus the static peers
  SystemDefault,  ///< whatever the Cyclone configuration says, nothing added
};
const char* to_string(DiscoveryRange r);

struct Settings {
  /// DDS domain id (0..232; ROS_DOMAIN_ID). Processes see each other only
  /// within one domain.
  int domain_id = 0;
  /// How far automatic discovery reaches (ROS_AUTOMATIC_DISCOVERY_RANGE).
  /// Unset: this machine only, and nothing but `config` if that is set.
  std::optional<DiscoveryRange> range;
  /// Hosts (names or addresses) discovery also contacts by unicast
  /// (ROS_STATIC_PEERS), for the Localhost and Subnet ranges.
  std::vector<std::string> static_peers;
  /// Cyclone DDS configuration: XML text and/or file:// URIs, exactly what
  /// CYCLONEDDS_URI holds. Applied after what the range and peers generate,
  /// so each of its settings wins.
  std::string config;
  /// How this process is named to the others (loss reports, `topic list`).
  std::string process_name;
  /// Largest sample accepted from the network [bytes]; bigger ones are dropped
  /// and counted as errors (a peer must not make us allocate gigabytes).
  std::size_t max_sample_bytes = std::size_t{256} << 20;
  /// Use Cyclone's shared-memory transport (iceoryx) to processes on this
  /// machine when a RouDi (`iox-roudi`) runs here; over loopback as before
  /// when none does (TINYLINE_SHARED_MEMORY=1; a launch file's
  /// `dds: {shared_memory: true}`). Serves keep-last, volatile topics only.
  bool shared_memory = false;
  /// What reading the environment decided that the user should hear, as rcl
  /// warns it (a deprecated or ignored variable); logged when DDS starts.
  std::vector<std::string> notes;

  /// The environment as ROS 2 Jazzy reads it. Throws DdsError on a bad domain id.
  static Settings from_environment();
  /// The configuration actually used: the range's and peers' settings
  /// followed by `config`; `config` alone if neither range nor peers is set.
  std::string effective_config() const;
};

/// The Cyclone settings a range and static peers stand for, as rmw_cyclonedds
/// generates them; Localhost is this_machine_config(). `pid` tags an Off
/// domain so that no other process can join it. Empty for SystemDefault.
std::string discovery_config(DiscoveryRange range, const std::vector<std::string>& static_peers, long pid);

/// This machine only (the default): multicast off, discovery by unicast to
/// the participant ports of 127.0.0.1, a 3 s lease so a killed process is
/// noticed within seconds. Besides loopback, Cyclone knows this machine's
/// network interfaces (`interfaces`, up to three): a ROS 2 node on Fast DDS
/// announces only its non-loopback addresses, and Cyclone accepts a peer
/// only at an address of an interface it knows. Packets to the machine's own
/// addresses never leave it, and nothing is sent but to 127.0.0.1 and to the
/// participants that answer. Without static peers, loopback-sized fragments
/// and write window (docs/benchmarks.md, DDS). A non-empty `tag` isolates
/// graphs that share a domain (tests running side by side).
std::string this_machine_config(const std::vector<std::string>& interfaces,
                                const std::vector<std::string>& static_peers = {}, const std::string& tag = "",
                                int max_participants = 64);

/// The up IPv4 interfaces of this machine other than loopback, the
/// multicast-capable ones first (at most three: Cyclone takes four).
std::vector<std::string> machine_interfaces();

/// this_machine_config() on the loopback interface alone: tests and
/// benchmarks that must not depend on the machine's network cards.
std::string loopback_config(const std::string& tag = "", int max_participants = 64);

/// Whether an iceoryx RouDi daemon answers on this machine (its socket in
/// /tmp). Cyclone with shared memory enabled and no RouDi would wait for one
/// for a minute and then abort the process, so this is asked first.
bool roudi_running();

/// The Cyclone settings that turn shared memory on.
std::string shared_memory_config();

/// Checks a domain id (0..232, the range whose ports fit in 16 bits); throws
/// DdsError naming `where` otherwise.
int check_domain_id(long long id, const std::string& where);

}  // namespace tinyline::dds
