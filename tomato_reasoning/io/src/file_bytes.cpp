#include "file_bytes.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "tomato_reasoning/io/rgbd_files.hpp"

namespace tinyline::tomato_reasoning::io::detail {

namespace {

std::string named(std::string_view what, const std::string& path) { return std::string(what) + " '" + path + "'"; }

std::string kind_of(mode_t m) {
  if (S_ISDIR(m)) return "a directory";
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISCHR(m) || S_ISBLK(m)) return "a device";
  if (S_ISSOCK(m)) return "a socket";
  return "not a regular file";
}

struct Fd {
  int fd = -1;
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
};

}  // namespace

std::vector<std::uint8_t> read_bytes(const std::string& path, std::string_view what, std::uint64_t max_bytes) {
  Fd f{::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC)};
  if (f.fd < 0) throw RgbdFileError(named(what, path) + ": " + std::strerror(errno));
  struct stat st {};
  if (::fstat(f.fd, &st) != 0) throw RgbdFileError(named(what, path) + ": " + std::strerror(errno));
  if (!S_ISREG(st.st_mode)) throw RgbdFileError(named(what, path) + " is " + kind_of(st.st_mode) + ", not a regular file");
  if (std::uint64_t(st.st_size) > max_bytes)
    throw RgbdFileError(named(what, path) + " has " + std::to_string(st.st_size) + " bytes, more than the " +
                        std::to_string(max_bytes) + " accepted");
  std::vector<std::uint8_t> out(std::size_t(st.st_size));
  std::size_t got = 0;
  while (got < out.size()) {
    const ssize_t n = ::read(f.fd, out.data() + got, out.size() - got);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw RgbdFileError(named(what, path) + ": " + std::strerror(errno));
    if (n == 0) break;  // shrank while read: what is there
    got += std::size_t(n);
  }
  out.resize(got);
  return out;
}

namespace {

void refuse_odd_target(const std::string& path, std::string_view what) {
  struct stat st {};
  if (::lstat(path.c_str(), &st) != 0) return;  // not there yet: fine
  if (S_ISLNK(st.st_mode)) throw RgbdFileError(named(what, path) + " is a symbolic link; not replaced");
  if (!S_ISREG(st.st_mode)) throw RgbdFileError(named(what, path) + " is " + kind_of(st.st_mode) + "; not replaced");
}

void write_all(int fd, const std::string& part, std::string_view what, const void* bytes, std::size_t size) {
  const auto* p = static_cast<const std::uint8_t*>(bytes);
  std::size_t done = 0;
  while (done < size) {
    const ssize_t n = ::write(fd, p + done, size - done);
    if (n < 0 && errno == EINTR) continue;
    if (n < 0) throw RgbdFileError(named(what, part) + ": " + std::strerror(errno));
    done += std::size_t(n);
  }
  if (::fsync(fd) != 0) throw RgbdFileError(named(what, part) + ": " + std::strerror(errno));
}

}  // namespace

void write_atomically(const std::string& path, std::string_view what, const void* bytes, std::size_t size) {
  refuse_odd_target(path, what);
  const std::string part = path + ".part";
  // O_EXCL: a second writer of the same path (or a stale .part) is an error, not a mix of both.
  Fd f{::open(part.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0644)};
  if (f.fd < 0) throw RgbdFileError(named(what, part) + ": " + std::strerror(errno));
  try {
    write_all(f.fd, part, what, bytes, size);
    const int fd = f.fd;
    f.fd = -1;
    if (::close(fd) != 0) throw RgbdFileError(named(what, part) + ": " + std::strerror(errno));
    if (::rename(part.c_str(), path.c_str()) != 0) throw RgbdFileError(named(what, path) + ": " + std::strerror(errno));
  } catch (...) {
    ::unlink(part.c_str());
    throw;
  }
}

}  // namespace tinyline::tomato_reasoning::io::detail
