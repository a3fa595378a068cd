// Where a process finds the rest of its graph over DDS: the domain, the
// Cyclone DDS configuration, and how this process introduces itself.
//
// The defaults are safe: loopback only, no multicast, unicast discovery of the
// participants on this machine. A real network is one CYCLONEDDS_URI away
// (docs/dds.md), read the way ROS 2 reads it, so a ROS 2 node on
// rmw_cyclonedds with the same environment joins the same graph.
#pragma once

#include <cstddef>
#include <stdexcept>
#include <string>

namespace tinyline::dds {

/// A DDS set-up or I/O failure; the text says what and on which topic.
class DdsError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

struct Settings {
  /// DDS domain id (0..232; ROS_DOMAIN_ID). Processes see each other only
  /// within one domain.
  int domain_id = 0;
  /// Cyclone DDS configuration: XML text and/or file:// URIs, exactly what
  /// CYCLONEDDS_URI holds. Empty: loopback_config().
  std::string config;
  /// How this process is named to the others (loss reports, `topic list`).
  std::string process_name;
  /// Largest sample accepted from the network [bytes]; bigger ones are dropped
  /// and counted as errors (a peer must not make us allocate gigabytes).
  std::size_t max_sample_bytes = std::size_t{256} << 20;

  /// ROS_DOMAIN_ID and CYCLONEDDS_URI as ROS 2 reads them; the loopback
  /// default when CYCLONEDDS_URI is unset. Throws DdsError on a bad domain id.
  static Settings from_environment();
  /// The configuration actually used (config, or loopback_config() if empty).
  std::string effective_config() const;
};

/// The default: the loopback interface only, multicast off, unicast discovery
/// of up to `max_participants` participants on this machine, and a 3 s lease
/// so a killed process is noticed within seconds. A non-empty `tag` isolates
/// graphs that share a domain (tests running side by side).
std::string loopback_config(const std::string& tag = "", int max_participants = 64);

/// Checks a domain id (0..232, the range whose ports fit in 16 bits); throws
/// DdsError naming `where` otherwise.
int check_domain_id(long long id, const std::string& where);

}  // namespace tinyline::dds
