// SPDX-License-Identifier: Apache-2.0
// Reading what users give us and writing what we make, safely.
//
//  read_text()     a hand-written text input (launch file, parameter or scene
//                  YAML, CSV): only a regular file (a FIFO would block, a
//                  device would never end), at most a given size.
//  check_input()   the same checks without reading (validate before starting).
//  AtomicFile      an output written to "<path>.part" beside it and renamed
//                  onto the path by commit(); dropped without commit(), the
//                  path keeps what it had. It refuses to replace a symbolic
//                  link, a device or anything not a regular file, and the
//                  command's own inputs; the .part file is created new
//                  (an existing one, a user's or a dead writer's, is refused,
//                  never reused) and locked while written.
//  AtomicStream    the same for code that writes with iostreams: the text is
//                  kept in memory and written through an AtomicFile by
//                  commit() (reports, CSV and JSON of the tools).
//
// Every error is a FileError whose message names the file and its role.
// Header-only (POSIX) and in common, so cores, nodes and tools share it.
#pragma once

#include <fcntl.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <stdexcept>
#include <string>
#include <sstream>
#include <string_view>
#include <utility>
#include <vector>

namespace tinyline::files {

class FileError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

namespace detail {

inline std::string errno_text(int e) { return std::strerror(e); }

inline std::string quoted(std::string_view what, const std::string& path) {
  return std::string(what) + " '" + path + "'";
}

/// "a FIFO", "a directory", ... for a file that is not a regular one.
inline std::string kind_of(mode_t m) {
  if (S_ISDIR(m)) return "a directory";
  if (S_ISFIFO(m)) return "a FIFO";
  if (S_ISCHR(m)) return "a character device";
  if (S_ISBLK(m)) return "a block device";
  if (S_ISSOCK(m)) return "a socket";
  if (S_ISLNK(m)) return "a symbolic link";
  return "not a regular file";
}

/// Closes the descriptor when it goes out of scope.
struct Fd {
  int fd = -1;
  explicit Fd(int f) : fd(f) {}
  ~Fd() {
    if (fd >= 0) ::close(fd);
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
};

/// Opens `path` read-only if it is a regular file of at most `max_bytes`
/// (0: no limit). O_NONBLOCK: opening a FIFO must not wait for a writer.
inline int open_regular(const std::string& path, std::string_view what, std::uint64_t max_bytes, std::uint64_t* size) {
  const int fd = ::open(path.c_str(), O_RDONLY | O_NONBLOCK | O_CLOEXEC);
  if (fd < 0) throw FileError(quoted(what, path) + ": cannot open: " + errno_text(errno));
  struct stat st {};
  if (::fstat(fd, &st) != 0) {
    const int e = errno;
    ::close(fd);
    throw FileError(quoted(what, path) + ": cannot stat: " + errno_text(e));
  }
  if (!S_ISREG(st.st_mode)) {
    ::close(fd);
    throw FileError(quoted(what, path) + " is " + kind_of(st.st_mode) + ", not a regular file");
  }
  const auto bytes = static_cast<std::uint64_t>(st.st_size);
  if (max_bytes != 0 && bytes > max_bytes) {
    ::close(fd);
    throw FileError(quoted(what, path) + " is " + std::to_string(bytes) + " bytes, more than the limit of " +
                    std::to_string(max_bytes));
  }
  if (size) *size = bytes;
  return fd;
}

}  // namespace detail

/// Checks that `path` is a regular file this process can open, of at most
/// `max_bytes` (0: any size). `what` names its role ("launch file").
inline void check_input(const std::string& path, std::string_view what, std::uint64_t max_bytes) {
  std::uint64_t size = 0;
  detail::Fd f(detail::open_regular(path, what, max_bytes, &size));
}

/// Reads a whole text input of at most `max_bytes` (0: any size); throws FileError naming it.
inline std::string read_text(const std::string& path, std::string_view what, std::uint64_t max_bytes) {
  std::uint64_t size = 0;
  detail::Fd f(detail::open_regular(path, what, max_bytes, &size));
  std::string out;
  out.reserve(static_cast<std::size_t>(size));
  char buf[65536];
  for (;;) {
    const ssize_t n = ::read(f.fd, buf, sizeof(buf));
    if (n < 0) {
      if (errno == EINTR) continue;
      throw FileError(detail::quoted(what, path) + ": read failed: " + detail::errno_text(errno));
    }
    if (n == 0) break;
    out.append(buf, static_cast<std::size_t>(n));
    if (max_bytes != 0 && out.size() > max_bytes) {  // it grew while we read
      throw FileError(detail::quoted(what, path) + " grew past the limit of " + std::to_string(max_bytes) +
                      " bytes while being read");
    }
  }
  return out;
}

struct OutputOptions {
  /// The command's input files: the output must not be one of them.
  std::vector<std::string> inputs;
  /// On failure keep "<path>.part" (a partial recording is still worth
  /// recovering) instead of removing it. A leftover one is always refused.
  bool keep_partial = false;
  /// fsync before the rename: the new content survives a power cut.
  bool sync = true;
  /// Its role in messages ("output", "calibration").
  std::string what = "output";
};

/// Default options with the output's role for messages ("calibration").
inline OutputOptions named(std::string what) {
  OutputOptions o;
  o.what = std::move(what);
  return o;
}

class AtomicFile {
 public:
  AtomicFile() = default;
  /// Checks `path` may be replaced and creates its locked "<path>.part".
  /// Throws FileError naming the file and the reason.
  explicit AtomicFile(std::string path, OutputOptions options = {})
      : path_(std::move(path)), temp_(path_ + ".part"), options_(std::move(options)) {
    check_destination();
    check_temp_is_no_input();
    open_temp();
  }
  ~AtomicFile() { abandon(); }
  AtomicFile(AtomicFile&& o) noexcept { *this = std::move(o); }
  AtomicFile& operator=(AtomicFile&& o) noexcept {
    if (this != &o) {
      abandon();
      path_ = std::move(o.path_);
      temp_ = std::move(o.temp_);
      options_ = std::move(o.options_);
      fd_ = std::exchange(o.fd_, -1);
      mode_ = o.mode_;
    }
    return *this;
  }
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  /// The constructor's checks, creating nothing: for a command that checks
  /// every output before its work and makes them one at a time.
  static void check(std::string path, OutputOptions options = {}) {
    AtomicFile f;
    f.path_ = std::move(path);
    f.temp_ = f.path_ + ".part";
    f.options_ = std::move(options);
    f.check_destination();
    f.check_temp_is_no_input();
    struct stat st {};
    if (::lstat(f.temp_.c_str(), &st) == 0) throw FileError(f.what() + f.existing_temp_reason());
  }

  bool is_open() const { return fd_ >= 0; }
  int fd() const { return fd_; }
  const std::string& path() const { return path_; }
  const std::string& temp_path() const { return temp_; }

  /// Appends bytes to the temporary; throws FileError (a full disk names it).
  void write(std::string_view bytes) {
    if (fd_ < 0) throw FileError(what() + ": not open for writing");
    const char* p = bytes.data();
    std::size_t n = bytes.size();
    while (n > 0) {
      const ssize_t w = ::write(fd_, p, n);
      if (w < 0) {
        if (errno == EINTR) continue;
        throw FileError(what() + ": writing " + temp_ + " failed: " + detail::errno_text(errno));
      }
      p += w;
      n -= static_cast<std::size_t>(w);
    }
  }

  /// Makes the written content the file at path(): (fsync,) rename, close.
  /// On failure the path keeps its old content and the temporary is dropped.
  void commit() {
    if (fd_ < 0) throw FileError(what() + ": not open for writing");
    std::string failed;
    if (options_.sync && ::fsync(fd_) != 0) failed = "fsync of " + temp_ + " failed: " + detail::errno_text(errno);
    if (failed.empty() && ::rename(temp_.c_str(), path_.c_str()) != 0) {
      failed = "renaming " + temp_ + " onto it failed: " + detail::errno_text(errno);
    }
    if (!failed.empty()) {
      abandon();
      throw FileError(what() + ": " + failed);
    }
    ::close(std::exchange(fd_, -1));  // after the rename: the lock covers the whole write
  }

  /// Drops what was written: removes the temporary (unless keep_partial) and
  /// leaves path() as it was. Safe to call twice.
  void abandon() noexcept {
    if (fd_ < 0) return;
    if (!options_.keep_partial) ::unlink(temp_.c_str());  // before closing: we still hold the lock
    ::close(std::exchange(fd_, -1));
  }

 private:
  std::string what() const { return detail::quoted(options_.what, path_); }

  // Refuses what must never be replaced: links, devices, directories, inputs.
  void check_destination() {
    struct stat st {};
    if (::lstat(path_.c_str(), &st) != 0) {
      if (errno != ENOENT) throw FileError(what() + ": cannot stat: " + detail::errno_text(errno));
      return;  // a new file
    }
    if (S_ISLNK(st.st_mode)) {
      throw FileError(what() +
                      " is a symbolic link: not replaced (give the path of the file itself, or remove the "
                      "link)");
    }
    if (!S_ISREG(st.st_mode)) throw FileError(what() + " is " + detail::kind_of(st.st_mode) + ": not replaced");
    if (const std::string in = input_named_by(st); !in.empty())
      throw FileError(what() + " is also an input of this command ('" + in + "'): not replaced");
    mode_ = st.st_mode & 07777;
  }

  // The input that is the file `st` describes ("" if none).
  std::string input_named_by(const struct stat& st) const {
    for (const auto& in : options_.inputs) {
      struct stat is {};
      if (::stat(in.c_str(), &is) == 0 && is.st_dev == st.st_dev && is.st_ino == st.st_ino) return in;
    }
    return {};
  }

  // Refuses a temporary name that is one of the inputs (`bag recover F.part F`).
  void check_temp_is_no_input() const {
    struct stat st {};
    if (::lstat(temp_.c_str(), &st) != 0) return;
    if (const std::string in = input_named_by(st); !in.empty()) {
      throw FileError(what() + ": its temporary " + temp_ + " is an input of this command ('" + in +
                      "'): not touched; write the output under another name");
    }
  }

  // Creates and locks "<path>.part", which must not exist: a file there is a
  // writer still at work (locked), or one that died, or a user's own file (a
  // crashed recording is worth recovering); none of them is ours to reuse.
  void open_temp() {
    const int fd = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC | O_NOFOLLOW, 0644);
    if (fd < 0 && errno == EEXIST) throw FileError(what() + existing_temp_reason());
    if (fd < 0) throw FileError(what() + ": cannot create " + temp_ + ": " + detail::errno_text(errno));
    detail::Fd guard(fd);
    if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
      throw FileError(what() + " is being written by another process (" + temp_ + " is locked)");
    }
    if (mode_ != 0) (void)::fchmod(fd, mode_);  // the replaced file's permissions
    fd_ = std::exchange(guard.fd, -1);
  }

  // Why an existing temporary is left alone, for the message after what().
  std::string existing_temp_reason() const {
    const int fd = ::open(temp_.c_str(), O_RDONLY | O_CLOEXEC | O_NOFOLLOW | O_NONBLOCK);
    if (fd >= 0) {
      detail::Fd guard(fd);
      if (::flock(fd, LOCK_EX | LOCK_NB) != 0) return " is being written by another process (" + temp_ + " is locked)";
    }
    return ": " + temp_ +
           " exists (an earlier write that did not finish, or a file of yours): left as it is; a recording is "
           "saved by `tinyline bag recover " +
           temp_ + " FIXED.mcap`; remove or rename it to go on";
  }

  std::string path_;
  std::string temp_;
  OutputOptions options_;
  int fd_ = -1;
  mode_t mode_ = 0;
};

/// AtomicFile::check at a program's start, before its work: false, with
/// "PROGRAM: reason" on stderr, when `path` must not be written.
inline bool output_allowed(const char* program, const std::string& path, OutputOptions options = {}) {
  try {
    AtomicFile::check(path, std::move(options));
    return true;
  } catch (const FileError& e) {
    std::fprintf(stderr, "%s: %s\n", program, e.what());
    return false;
  }
}

/// Writes `content` to `path` through an AtomicFile.
inline void write_atomically(const std::string& path, std::string_view content, OutputOptions options = {}) {
  AtomicFile f(path, std::move(options));
  f.write(content);
  f.commit();
}

/// An output stream whose text becomes the file at `path` on commit(), through
/// an AtomicFile: until then (and if commit() is never reached, e.g. on an
/// exception) the path keeps what it had. The destination is checked when the
/// stream is made, so a refused path fails before any work is done.
class AtomicStream : public std::ostringstream {
 public:
  explicit AtomicStream(std::string path, OutputOptions options = {}) : file_(std::move(path), std::move(options)) {}

  const std::string& path() const { return file_.path(); }

  /// Writes the text and renames it into place; throws FileError.
  void commit() {
    if (fail()) throw FileError(detail::quoted("output", file_.path()) + ": formatting the text failed");
    file_.write(view());
    file_.commit();
  }

 private:
  AtomicFile file_;
};

}  // namespace tinyline::files
