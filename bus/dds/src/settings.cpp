#include <tinyline/dds/settings.hpp>

#include <cerrno>
#include <cstdlib>

#include <fmt/format.h>

namespace tinyline::dds {

int check_domain_id(long long id, const std::string& where) {
  // Ports are 7400 + 250 * domain + offsets: above 232 they leave 16 bits.
  if (id < 0 || id > 232) throw DdsError(fmt::format("{}: DDS domain id {} is outside 0..232", where, id));
  return static_cast<int>(id);
}

Settings Settings::from_environment() {
  Settings s;
  if (const char* d = std::getenv("ROS_DOMAIN_ID"); d != nullptr && *d != '\0') {
    char* end = nullptr;
    errno = 0;
    const long long v = std::strtoll(d, &end, 10);
    if (errno != 0 || end == d || *end != '\0') {
      throw DdsError(fmt::format("ROS_DOMAIN_ID='{}' is not a number (expected 0..232)", d));
    }
    s.domain_id = check_domain_id(v, "ROS_DOMAIN_ID");
  }
  if (const char* uri = std::getenv("CYCLONEDDS_URI"); uri != nullptr && *uri != '\0') s.config = uri;
  return s;
}

std::string Settings::effective_config() const { return config.empty() ? loopback_config() : config; }

std::string loopback_config(const std::string& tag, int max_participants) {
  // Unicast discovery needs a participant index per process (its ports); the
  // peer 127.0.0.1 makes discovery probe the first `max_participants` of them.
  // Loopback has a 64 KiB MTU: fragments of 60 kB instead of Cyclone's
  // 1344 B, and room for 4 MB of unacknowledged data per writer, move
  // 64 KiB..1 MiB messages several times faster (docs/benchmarks.md, DDS).
  return fmt::format(
      "<CycloneDDS><Domain Id=\"any\">"
      "<General><Interfaces><NetworkInterface address=\"127.0.0.1\"/></Interfaces>"
      "<AllowMulticast>false</AllowMulticast>"
      "<MaxMessageSize>65500B</MaxMessageSize><FragmentSize>60000B</FragmentSize></General>"
      "<Internal><Watermarks><WhcHigh>4MB</WhcHigh></Watermarks></Internal>"
      "<Discovery><ParticipantIndex>auto</ParticipantIndex>"
      "<MaxAutoParticipantIndex>{}</MaxAutoParticipantIndex>"
      "<Peers><Peer address=\"127.0.0.1\"/></Peers>"
      "<LeaseDuration>3s</LeaseDuration>{}</Discovery>"
      "</Domain></CycloneDDS>",
      max_participants - 1, tag.empty() ? std::string() : "<Tag>" + tag + "</Tag>");
}

}  // namespace tinyline::dds
