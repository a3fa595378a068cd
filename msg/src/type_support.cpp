// SPDX-License-Identifier: Apache-2.0
#include <tinyline/msg/type_support.hpp>

namespace tinyline::msg {

std::string TypeSupport::dds_type_name() const {
  // "pkg/msg/Type" -> "pkg::msg::dds_::Type_" (the rmw_cyclonedds convention)
  const std::string n(name);
  const auto last = n.rfind('/');
  const auto first = n.find('/');
  if (last == std::string::npos || first == last) return n;
  return n.substr(0, first) + "::" + n.substr(first + 1, last - first - 1) + "::dds_::" + n.substr(last + 1) + "_";
}

cdr::Reader open_encapsulated(std::span<const std::uint8_t> bytes) {
  if (bytes.size() < 4) {
    throw cdr::Error("buffer of " + std::to_string(bytes.size()) +
                     " bytes is shorter than the 4-byte CDR encapsulation header");
  }
  if (bytes[0] != 0x00 || (bytes[1] != 0x00 && bytes[1] != 0x01)) {
    throw cdr::Error("unsupported CDR encapsulation 0x" + std::to_string(bytes[0]) + "/" + std::to_string(bytes[1]) +
                     " (expected plain CDR, 0x0000 big-endian or 0x0001 little-endian)");
  }
  return cdr::Reader(bytes.subspan(4), bytes[1] == 0x01);
}

}  // namespace tinyline::msg
