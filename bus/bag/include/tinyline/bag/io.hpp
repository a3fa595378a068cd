// SPDX-License-Identifier: Apache-2.0
// Byte sources and sinks of the MCAP codec. The reader reads at offsets from a
// Readable, the writer appends to a Writable; files and memory buffers both
// implement them, so tests and fuzzers need no files.
#pragma once

#include <cstdint>
#include <span>
#include <string>
#include <vector>

#include <tinyline/bag/status.hpp>
#include <tinyline/bus/files.hpp>

namespace tinyline::bag {

class Readable {
 public:
  virtual ~Readable() = default;
  /// Total size in bytes.
  virtual std::uint64_t size() const = 0;
  /// Fills `out` with the bytes at [offset, offset + out.size()); a range past
  /// the end is a Truncated status.
  virtual Status read(std::uint64_t offset, std::span<std::uint8_t> out) = 0;
  /// For error messages: the path, or "<memory>".
  virtual const std::string& name() const = 0;
};

class Writable {
 public:
  virtual ~Writable() = default;
  /// Appends bytes (may buffer).
  virtual Status write(std::span<const std::uint8_t> bytes) = 0;
  /// Hands buffered bytes to the OS (a file) so a killed process loses nothing written so far.
  virtual Status flush() = 0;
  /// Finishes the content (a file: puts it in place) and releases the sink; further writes fail.
  virtual Status close() = 0;
  /// Releases the sink without finishing: the content is incomplete (a file
  /// leaves its destination as it was).
  virtual void abandon() { (void)close(); }
  /// Bytes appended so far (buffered ones included).
  virtual std::uint64_t size() const = 0;
  virtual const std::string& name() const = 0;
};

/// A file read with pread(): no shared file position, so readers can share it.
class FileReadable final : public Readable {
 public:
  FileReadable() = default;
  ~FileReadable() override;
  FileReadable(const FileReadable&) = delete;
  FileReadable& operator=(const FileReadable&) = delete;

  Status open(const std::string& path);
  std::uint64_t size() const override { return size_; }
  Status read(std::uint64_t offset, std::span<std::uint8_t> out) override;
  const std::string& name() const override { return path_; }

 private:
  int fd_ = -1;
  std::uint64_t size_ = 0;
  std::string path_;
};

/// A view of bytes owned elsewhere, or an owned copy.
class MemoryReadable final : public Readable {
 public:
  explicit MemoryReadable(std::span<const std::uint8_t> bytes, std::string name = "<memory>")
      : view_(bytes), name_(std::move(name)) {}
  explicit MemoryReadable(std::vector<std::uint8_t> owned, std::string name = "<memory>")
      : owned_(std::move(owned)), view_(owned_), name_(std::move(name)) {}
  MemoryReadable(const MemoryReadable&) = delete;
  MemoryReadable& operator=(const MemoryReadable&) = delete;

  std::uint64_t size() const override { return view_.size(); }
  Status read(std::uint64_t offset, std::span<std::uint8_t> out) override;
  const std::string& name() const override { return name_; }

 private:
  std::vector<std::uint8_t> owned_;
  std::span<const std::uint8_t> view_;
  std::string name_;
};

struct FileWritableOptions {
  std::size_t buffer_bytes = 1 << 20;  ///< user-space buffer before write(2)
  bool fsync_on_close = false;         ///< also survive a power cut, not just a killed process
  /// The writing command's inputs: the output never replaces one of them.
  std::vector<std::string> inputs;
  /// Keep "<path>.part" when the file does not finish (a partial recording
  /// is worth recovering) instead of removing it.
  bool keep_partial = false;
};

/// A file written to "<path>.part" with write(2) through a user-space buffer
/// and renamed onto the path by close() (files::AtomicFile): the path holds
/// either its old content or a finished file, and the .part file is locked
/// so a second writer of the same path fails. flush() empties the buffer
/// into the kernel, which keeps the bytes if the process dies.
class FileWritable final : public Writable {
 public:
  FileWritable() = default;
  ~FileWritable() override;
  FileWritable(const FileWritable&) = delete;
  FileWritable& operator=(const FileWritable&) = delete;

  /// Creates "<path>.part"; refuses a path that is a link, a device, or one
  /// of options.inputs, and one that another writer holds.
  Status open(const std::string& path, FileWritableOptions options = {});
  Status write(std::span<const std::uint8_t> bytes) override;
  Status flush() override;
  /// Flushes and renames the file into place (after a write error: abandons it).
  Status close() override;
  void abandon() override;
  std::uint64_t size() const override { return size_; }
  const std::string& name() const override { return path_; }
  /// Where the bytes are until close(): "<path>.part".
  const std::string& temp_name() const { return file_.temp_path(); }

 private:
  Status write_all(const std::uint8_t* p, std::size_t n);

  files::AtomicFile file_;
  FileWritableOptions options_;
  std::vector<std::uint8_t> buffer_;
  std::uint64_t size_ = 0;
  std::string path_;
  Status error_;
};

/// Appends to a byte vector.
class MemoryWritable final : public Writable {
 public:
  explicit MemoryWritable(std::string name = "<memory>") : name_(std::move(name)) {}
  Status write(std::span<const std::uint8_t> bytes) override;
  Status flush() override { return {}; }
  Status close() override {
    closed_ = true;
    return {};
  }
  std::uint64_t size() const override { return data_.size(); }
  const std::string& name() const override { return name_; }

  const std::vector<std::uint8_t>& data() const { return data_; }
  std::vector<std::uint8_t> take() { return std::move(data_); }

 private:
  std::vector<std::uint8_t> data_;
  std::string name_;
  bool closed_ = false;
};

/// Forwards to a sink the caller keeps (a writer owns its sink; this lets the
/// caller read a MemoryWritable after the writer is gone).
class WritableRef final : public Writable {
 public:
  explicit WritableRef(Writable& target) : target_(target) {}
  Status write(std::span<const std::uint8_t> bytes) override { return target_.write(bytes); }
  Status flush() override { return target_.flush(); }
  Status close() override { return target_.flush(); }  // the owner closes the target
  void abandon() override {}                           // the owner decides
  std::uint64_t size() const override { return target_.size(); }
  const std::string& name() const override { return target_.name(); }

 private:
  Writable& target_;
};

}  // namespace tinyline::bag
