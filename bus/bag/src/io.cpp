#include <tinyline/bag/io.hpp>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>

#include <fmt/format.h>

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
  path_ = path;
  fd_ = ::open(path.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd_ < 0) return {StatusCode::OpenFailed, fmt::format("{}: cannot open for reading: {}", path, errno_text())};
  struct stat st {};
  if (::fstat(fd_, &st) != 0) return {StatusCode::OpenFailed, fmt::format("{}: cannot stat: {}", path, errno_text())};
  if (S_ISDIR(st.st_mode)) {
    ::close(fd_);
    fd_ = -1;
    return {StatusCode::OpenFailed, fmt::format("{}: is a directory, not an MCAP file", path)};
  }
  size_ = static_cast<std::uint64_t>(st.st_size);
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
      return {StatusCode::ReadFailed, fmt::format("{}: read at byte {} failed: {}", path_, offset + done, errno_text())};
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

FileWritable::~FileWritable() {
  if (fd_ >= 0) (void)close();
}

Status FileWritable::open(const std::string& path, FileWritableOptions options) {
  if (fd_ >= 0) (void)close();
  path_ = path;
  options_ = options;
  size_ = 0;
  fd_ = ::open(path.c_str(), O_WRONLY | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd_ < 0) return {StatusCode::OpenFailed, fmt::format("{}: cannot create: {}", path, errno_text())};
  buffer_.clear();
  buffer_.reserve(options_.buffer_bytes);
  return {};
}

Status FileWritable::write_all(const std::uint8_t* p, std::size_t n) {
  while (n > 0) {
    const ssize_t w = ::write(fd_, p, n);
    if (w < 0) {
      if (errno == EINTR) continue;
      return {StatusCode::WriteFailed, fmt::format("{}: write failed: {}", path_, errno_text())};
    }
    p += w;
    n -= static_cast<std::size_t>(w);
  }
  return {};
}

Status FileWritable::write(std::span<const std::uint8_t> bytes) {
  if (fd_ < 0) return {StatusCode::NotOpen, fmt::format("{}: file is not open for writing", path_)};
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
  if (fd_ < 0) return {StatusCode::NotOpen, fmt::format("{}: file is not open for writing", path_)};
  Status s = write_all(buffer_.data(), buffer_.size());
  buffer_.clear();
  return s;
}

Status FileWritable::close() {
  if (fd_ < 0) return {};
  Status s = flush();
  if (s.ok() && options_.fsync_on_close && ::fsync(fd_) != 0) {
    s = Status(StatusCode::WriteFailed, fmt::format("{}: fsync failed: {}", path_, errno_text()));
  }
  if (::close(fd_) != 0 && s.ok()) {
    s = Status(StatusCode::WriteFailed, fmt::format("{}: close failed: {}", path_, errno_text()));
  }
  fd_ = -1;
  return s;
}

// ---------------------------------------------------------------------------- MemoryWritable

Status MemoryWritable::write(std::span<const std::uint8_t> bytes) {
  if (closed_) return {StatusCode::NotOpen, fmt::format("{}: buffer is closed", name_)};
  data_.insert(data_.end(), bytes.begin(), bytes.end());
  return {};
}

}  // namespace tinyline::bag
