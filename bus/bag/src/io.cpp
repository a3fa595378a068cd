// SPDX-License-Identifier: Apache-2.0
#include <tinyline/bag/io.hpp>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <fmt/format.h>

#include <tinyline/bus/files.hpp>

namespace tinyline::bag {

namespace {
std::string errno_text() { return std::strerror(errno); }
}  // namespace

// ---------------------------------------------------------------------------- FileReadable

FileReadable::~FileReadable() {
  if (fd_ >= 0) ::close(fd_);
}

Status FileReadable::open(const std::string& path) {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  path_ = path;
  try {
    fd_ = files::detail::open_regular(path, "bag", 0, &size_);  // a FIFO or device is refused, not waited on
  } catch (const files::FileError& e) {
    return {StatusCode::OpenFailed, e.what()};
  }
  return {};
}

Status FileReadable::read(std::uint64_t offset, std::span<std::uint8_t> out) {
  if (fd_ < 0) return {StatusCode::NotOpen, fmt::format("{}: file is not open", path_)};
  if (offset > size_ || out.size() > size_ - offset) {
    return {StatusCode::Truncated, fmt::format("{}: read of {} bytes at byte {} runs past the end ({} bytes)", path_,
                                               out.size(), offset, size_)};
  }
  std::size_t done = 0;
  while (done < out.size()) {
    const ssize_t n = ::pread(fd_, out.data() + done, out.size() - done, static_cast<off_t>(offset + done));
    if (n < 0) {
      if (errno == EINTR) continue;
      return {StatusCode::ReadFailed,
              fmt::format("{}: read at byte {} failed: {}", path_, offset + done, errno_text())};
    }
    if (n == 0) {
      return {StatusCode::Truncated,
              fmt::format("{}: file shrank while reading: nothing at byte {}", path_, offset + done)};
    }
    done += static_cast<std::size_t>(n);
  }
  return {};
}

// ---------------------------------------------------------------------------- MemoryReadable

Status MemoryReadable::read(std::uint64_t offset, std::span<std::uint8_t> out) {
  if (offset > view_.size() || out.size() > view_.size() - offset) {
    return {StatusCode::Truncated, fmt::format("{}: read of {} bytes at byte {} runs past the end ({} bytes)", name_,
                                               out.size(), offset, view_.size())};
  }
  if (!out.empty()) std::memcpy(out.data(), view_.data() + offset, out.size());
  return {};
}

// ---------------------------------------------------------------------------- FileWritable

FileWritable::~FileWritable() { file_.abandon(); }

Status FileWritable::open(const std::string& path, FileWritableOptions options) {
  file_.abandon();
  path_ = path;
  options_ = options;
  size_ = 0;
  error_ = {};
  try {
    files::OutputOptions o;
    o.inputs = options_.inputs;
    o.keep_partial = options_.keep_partial;
    o.sync = options_.fsync_on_close;
    o.what = "bag";
    file_ = files::AtomicFile(path, std::move(o));
  } catch (const files::FileError& e) {
    return {StatusCode::OpenFailed, e.what()};
  }
  buffer_.clear();
  buffer_.reserve(options_.buffer_bytes);
  return {};
}

Status FileWritable::write_all(const std::uint8_t* p, std::size_t n) {
  if (!error_.ok()) return error_;
  try {
    file_.write(std::string_view(reinterpret_cast<const char*>(p), n));
  } catch (const files::FileError& e) {
    error_ = Status(StatusCode::WriteFailed, e.what());  // sticky: the file lacks bytes from here on
  }
  return error_;
}

Status FileWritable::write(std::span<const std::uint8_t> bytes) {
  if (!file_.is_open()) return {StatusCode::NotOpen, fmt::format("{}: file is not open for writing", path_)};
  size_ += bytes.size();
  if (buffer_.size() + bytes.size() <= options_.buffer_bytes) {
    buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
    return {};
  }
  if (Status s = flush(); !s.ok()) return s;
  if (bytes.size() >= options_.buffer_bytes) return write_all(bytes.data(), bytes.size());  // large: no copy
  buffer_.insert(buffer_.end(), bytes.begin(), bytes.end());
  return {};
}

Status FileWritable::flush() {
  if (!file_.is_open()) return {StatusCode::NotOpen, fmt::format("{}: file is not open for writing", path_)};
  Status s = write_all(buffer_.data(), buffer_.size());
  buffer_.clear();
  return s;
}

Status FileWritable::close() {
  if (!file_.is_open()) return error_;
  Status s = flush();
  if (!s.ok()) {
    abandon();
    return s;
  }
  try {
    file_.commit();
  } catch (const files::FileError& e) {
    error_ = Status(StatusCode::WriteFailed, e.what());
  }
  return error_;
}

void FileWritable::abandon() {
  buffer_.clear();
  file_.abandon();
}

// ---------------------------------------------------------------------------- MemoryWritable

Status MemoryWritable::write(std::span<const std::uint8_t> bytes) {
  if (closed_) return {StatusCode::NotOpen, fmt::format("{}: buffer is closed", name_)};
  data_.insert(data_.end(), bytes.begin(), bytes.end());
  return {};
}

}  // namespace tinyline::bag
