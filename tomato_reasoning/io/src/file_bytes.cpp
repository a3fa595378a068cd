// SPDX-License-Identifier: Apache-2.0
#include "file_bytes.hpp"

#include <tinyline/common/files.hpp>

#include "tomato_reasoning/io/rgbd_files.hpp"

namespace tinyline::tomato_reasoning::io::detail {

std::vector<std::uint8_t> read_bytes(const std::string& path, std::string_view what, std::uint64_t max_bytes) {
  try {
    const std::string bytes = files::read_text(path, what, max_bytes);
    return {bytes.begin(), bytes.end()};
  } catch (const files::FileError& e) {
    throw RgbdFileError(e.what());
  }
}

void write_atomically(const std::string& path, std::string_view what, const void* bytes, std::size_t size) {
  try {
    files::OutputOptions options;
    options.what = std::string(what);
    files::write_atomically(path, std::string_view(static_cast<const char*>(bytes), size), options);
  } catch (const files::FileError& e) {
    throw RgbdFileError(e.what());
  }
}

}  // namespace tinyline::tomato_reasoning::io::detail
