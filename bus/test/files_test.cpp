// SPDX-License-Identifier: Apache-2.0
// Tests of the input and output helpers every reader and writer of files uses.
#include <gtest/gtest.h>
#include <sys/stat.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>

#include <tinyline/bus/files.hpp>

namespace fs = std::filesystem;
using tinyline::files::AtomicFile;
using tinyline::files::FileError;
using tinyline::files::OutputOptions;

namespace {

fs::path scratch(const std::string& name) {
  const fs::path d = fs::path(TINYLINE_BINARY_DIR) / "files_test" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void spit(const fs::path& p, const std::string& s) { std::ofstream(p) << s; }

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const FileError& e) {
    return e.what();
  }
  return "(no error)";
}

}  // namespace

TEST(Files, ReadTextReadsARegularFile) {
  const auto d = scratch("read");
  spit(d / "a.yaml", "launch: []\n");
  EXPECT_EQ(tinyline::files::read_text((d / "a.yaml").string(), "launch file", 1024), "launch: []\n");
}

TEST(Files, ReadTextRefusesAFifoWithoutBlocking) {
  const auto d = scratch("fifo");
  const auto fifo = (d / "pipe.yaml").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  const std::string e = error_of([&] { (void)tinyline::files::read_text(fifo, "launch file", 1024); });
  EXPECT_NE(e.find("launch file '" + fifo + "' is a FIFO, not a regular file"), std::string::npos) << e;
}

TEST(Files, ReadTextRefusesADeviceAndTooLargeFiles) {
  EXPECT_NE(error_of([] {
              (void)tinyline::files::read_text("/dev/zero", "scene", 1024);
            }).find("scene '/dev/zero' is a character device"),
            std::string::npos);
  const auto d = scratch("large");
  spit(d / "big.csv", std::string(2000, 'x'));
  const std::string e = error_of([&] { (void)tinyline::files::read_text((d / "big.csv").string(), "CSV", 1000); });
  EXPECT_NE(e.find("is 2000 bytes, more than the limit of 1000"), std::string::npos) << e;
  EXPECT_NE(
      error_of([&] { tinyline::files::check_input((d / "nope").string(), "calibration", 0); }).find("cannot open"),
      std::string::npos);
}

TEST(Files, AtomicFileReplacesOnlyOnCommit) {
  const auto d = scratch("commit");
  const auto out = d / "out.yaml";
  spit(out, "old");
  ::chmod(out.c_str(), 0600);
  {
    AtomicFile f(out.string());
    f.write("new");
    EXPECT_EQ(slurp(out), "old");  // still the old one while writing
    EXPECT_TRUE(fs::exists(out.string() + ".part"));
    f.commit();
  }
  EXPECT_EQ(slurp(out), "new");
  EXPECT_FALSE(fs::exists(out.string() + ".part"));
  EXPECT_EQ(fs::status(out).permissions() & fs::perms::all, fs::perms::owner_read | fs::perms::owner_write);
  {
    AtomicFile f(out.string());
    f.write("half");
  }  // dropped without commit: the old content stays, no temporary left
  EXPECT_EQ(slurp(out), "new");
  EXPECT_FALSE(fs::exists(out.string() + ".part"));
}

TEST(Files, AtomicStreamWritesItsTextOnlyOnCommitAndRefusesALinkBeforeAnyWork) {
  const auto d = scratch("stream");
  const auto out = d / "trials.csv";
  spit(out, "old");
  {
    tinyline::files::AtomicStream s(out.string());
    s << "seed,verdict\n" << 1 << ",aligned\n";
    EXPECT_EQ(slurp(out), "old");
    s.commit();
  }
  EXPECT_EQ(slurp(out), "seed,verdict\n1,aligned\n");
  {
    tinyline::files::AtomicStream s(out.string());
    s << "half a table";
  }  // an exception before commit(): the path keeps the last complete table
  EXPECT_EQ(slurp(out), "seed,verdict\n1,aligned\n");
  EXPECT_FALSE(fs::exists(out.string() + ".part"));
  fs::create_symlink(out, d / "link.csv");
  EXPECT_NE(error_of([&] {
              tinyline::files::AtomicStream s((d / "link.csv").string(), tinyline::files::named("trials"));
            }).find("trials '" + (d / "link.csv").string() + "' is a symbolic link"),
            std::string::npos);
}

TEST(Files, AtomicFileRefusesLinksDevicesDirectoriesAndItsInputs) {
  const auto d = scratch("refuse");
  spit(d / "target", "keep");
  fs::create_symlink(d / "target", d / "link");
  EXPECT_NE(error_of([&] { AtomicFile f((d / "link").string()); }).find("is a symbolic link: not replaced"),
            std::string::npos);
  EXPECT_EQ(slurp(d / "target"), "keep");
  EXPECT_NE(error_of([] { AtomicFile f("/dev/null"); }).find("'/dev/null' is a character device: not replaced"),
            std::string::npos);
  EXPECT_NE(error_of([&] { AtomicFile f(d.string()); }).find("is a directory: not replaced"), std::string::npos);
  OutputOptions o;
  o.inputs = {(d / "link").string()};  // the same file by another name
  EXPECT_NE(error_of([&] { AtomicFile f((d / "target").string(), o); }).find("is also an input of this command"),
            std::string::npos);
  EXPECT_EQ(slurp(d / "target"), "keep");
}

TEST(Files, ASecondWriterOfThePathFailsAndAStalePartialIsKeptWhenAsked) {
  const auto d = scratch("lock");
  const auto out = (d / "rec.mcap").string();
  OutputOptions keep;
  keep.keep_partial = true;
  {
    AtomicFile first(out, keep);
    EXPECT_NE(error_of([&] { AtomicFile second(out, keep); }).find("is being written by another process"),
              std::string::npos);
    first.write("partial");
  }  // not committed: the partial recording stays for recovery
  EXPECT_EQ(slurp(out + ".part"), "partial");
  EXPECT_NE(error_of([&] { AtomicFile again(out, keep); }).find("exists (an earlier write that did not finish"),
            std::string::npos);
  EXPECT_EQ(slurp(out + ".part"), "partial");
}

// Regression: a writer truncated and reused a leftover "<path>.part" (a
// crashed recording, a user's file), and `bag recover F.part F` its own input.
TEST(Files, AnExistingPartIsNeverReusedNorRemoved) {
  const auto d = scratch("leftover");
  const auto out = (d / "data.csv").string();
  spit(out + ".part", "a user's data");
  for (const bool keep : {false, true}) {
    OutputOptions o;
    o.keep_partial = keep;
    const std::string e = error_of([&] { AtomicFile f(out, o); });
    EXPECT_NE(e.find(out + ".part exists"), std::string::npos) << e;
    EXPECT_NE(e.find("remove or rename it to go on"), std::string::npos) << e;
    EXPECT_EQ(slurp(out + ".part"), "a user's data");
    EXPECT_FALSE(fs::exists(out));
  }
  OutputOptions o;
  o.inputs = {out + ".part"};
  const std::string e = error_of([&] { tinyline::files::write_atomically(out, "x", o); });
  EXPECT_NE(e.find("its temporary " + out + ".part is an input of this command"), std::string::npos) << e;
  EXPECT_EQ(slurp(out + ".part"), "a user's data");
  EXPECT_FALSE(fs::exists(out));
}
