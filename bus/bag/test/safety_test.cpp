// SPDX-License-Identifier: Apache-2.0
// What a bag command must never do to the files around it: wait forever on a
// FIFO, replace an existing file with a half-written one, overwrite its own
// input, or let two recorders share one file.
#include <gtest/gtest.h>

#include <signal.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <fcntl.h>

#include <chrono>
#include <filesystem>
#include <fstream>
#include <future>

#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/recorder.hpp>
#include <tinyline/bag/recover.hpp>
#include <tinyline/bag/ros2.hpp>
#include <tinyline/bus/executor.hpp>
#include <tinyline/msg/std_msgs/string.hpp>

namespace tinyline::bag {
namespace {

namespace fs = std::filesystem;
using namespace std::chrono_literals;

fs::path scratch(const std::string& name) {
  const fs::path d = fs::path(TINYLINE_BINARY_DIR) / "bag_safety" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in), {});
}

void spit(const fs::path& p, const std::string& s) { std::ofstream(p, std::ios::binary) << s; }

// A small complete bag with `n` messages on /chatter.
void write_bag(const fs::path& p, int n) {
  ros2::Ros2Writer w;
  ASSERT_TRUE(w.open(p.string()).ok());
  ChannelId id;
  ASSERT_TRUE(w.add_topic("/chatter", msg::type_support<std_msgs::msg::String>(), id).ok());
  for (int i = 0; i < n; ++i) {
    std_msgs::msg::String m;
    m.data = "message " + std::to_string(i);
    ASSERT_TRUE(w.write(id, m, 1000 + static_cast<Timestamp>(i), 1000, static_cast<std::uint32_t>(i)).ok());
  }
  ASSERT_TRUE(w.close().ok());
}

bus::NodeOptions opts(const std::shared_ptr<bus::Context>& ctx, std::string name) {
  bus::NodeOptions o;
  o.name = std::move(name);
  o.context = ctx;
  return o;
}

TEST(BagFiles, AFifoGivenAsABagIsRefusedInsteadOfWaitedOn) {
  const auto d = scratch("fifo");
  const std::string fifo = (d / "bag.mcap").string();
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  auto opened = std::async(std::launch::async, [&] {
    Reader r;
    return r.open(fifo);
  });
  const bool returned = opened.wait_for(30s) == std::future_status::ready;
  if (!returned) {  // the old reader waits for a writer: give it one so the test ends
    const int w = ::open(fifo.c_str(), O_WRONLY);
    if (w >= 0) ::close(w);
  }
  const Status s = opened.get();
  ASSERT_TRUE(returned) << "opening a FIFO as a bag blocked";
  EXPECT_EQ(s.code, StatusCode::OpenFailed);
  EXPECT_NE(s.message.find("is a FIFO, not a regular file"), std::string::npos) << s.str();
}

TEST(BagFiles, AFailedRecoverLeavesAnExistingOutputUntouched) {
  const auto d = scratch("recover_fails");
  spit(d / "junk.mcap", "this is not an MCAP file at all");
  spit(d / "out.mcap", "precious");
  RecoverReport rep;
  const Status s = recover((d / "junk.mcap").string(), (d / "out.mcap").string(), {}, rep);
  EXPECT_FALSE(s.ok());
  EXPECT_EQ(slurp(d / "out.mcap"), "precious");
  EXPECT_FALSE(fs::exists(d / "out.mcap.part"));
}

TEST(BagFiles, RecoverNeverWritesOverItsInputUnderAnotherName) {
  const auto d = scratch("recover_self");
  write_bag(d / "in.mcap", 20);
  const std::string before = slurp(d / "in.mcap");
  fs::create_hard_link(d / "in.mcap", d / "same.mcap");
  fs::create_symlink(d / "in.mcap", d / "link.mcap");
  for (const char* out : {"same.mcap", "link.mcap", "./in.mcap"}) {
    SCOPED_TRACE(out);
    RecoverReport rep;
    const Status s = recover((d / "in.mcap").string(), (d / out).string(), {}, rep);
    EXPECT_FALSE(s.ok());
    EXPECT_EQ(slurp(d / "in.mcap"), before);
  }
}

TEST(BagFiles, AWriteErrorLeavesTheExistingFileAsItWas) {
  // A file size limit makes write(2) fail like a full disk, in a child.
  const auto d = scratch("write_error");
  const fs::path out = d / "out.mcap";
  spit(out, "the previous recording");
  const pid_t child = ::fork();
  ASSERT_GE(child, 0);
  if (child == 0) {
    ::signal(SIGXFSZ, SIG_IGN);
    rlimit lim{64 * 1024, 64 * 1024};
    ::setrlimit(RLIMIT_FSIZE, &lim);
    ros2::Ros2Writer w;
    WriterOptions o;
    o.compression = Compression::None;
    o.chunk_size_bytes = 4096;
    if (!w.open(out.string(), o).ok()) ::_exit(2);
    ChannelId id;
    if (!w.add_topic("/chatter", msg::type_support<std_msgs::msg::String>(), id).ok()) ::_exit(2);
    bool failed = false;
    for (std::uint32_t i = 0; i < 2000 && !failed; ++i) {
      std_msgs::msg::String m;
      m.data = std::string(200, 'x');
      failed = !w.write(id, m, 1000 + i, 1000, i).ok();
    }
    const Status closed = w.close();
    ::_exit(failed && !closed.ok() && closed.message.find("File too large") != std::string::npos ? 0 : 3);
  }
  int status = 0;
  ASSERT_EQ(::waitpid(child, &status, 0), child);
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_EQ(WEXITSTATUS(status), 0) << "the write did not fail, or close() did not report it";
  EXPECT_EQ(slurp(out), "the previous recording");
  EXPECT_FALSE(fs::exists(out.string() + ".part"));
}

TEST(BagFiles, TwoRecordersOnOnePathTheSecondFailsWithAClearError) {
  const auto d = scratch("two_recorders");
  auto ctx = bus::Context::create(bus::ContextOptions{bus::ClockType::Sim, std::make_shared<bus::CaptureSink>()});
  RecorderOptions ro;
  ro.path = (d / "rec.mcap").string();
  Recorder first(opts(ctx, "first"), ro);
  Recorder second(opts(ctx, "second"), ro);
  first.start();
  try {
    second.start();
    FAIL() << "the second recorder started on the same file";
  } catch (const BagError& e) {
    EXPECT_NE(std::string(e.what()).find("is being written by another process"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(first.stop().ok());
  Reader r;
  ASSERT_TRUE(r.open(ro.path).ok());
  EXPECT_TRUE(r.verify().ok()) << r.verify().str();
}

TEST(BagFiles, ARecorderGivenARelativeTopicRecordsItLikeRos) {
  // `tinyline bag record -o x.mcap demo/raw` used to record nothing: the
  // name was compared with "/demo/raw" as given.
  const auto d = scratch("relative");
  auto ctx = bus::Context::create(bus::ContextOptions{bus::ClockType::Sim, std::make_shared<bus::CaptureSink>()});
  bus::DeterministicExecutor ex(ctx->clock());
  RecorderOptions ro;
  ro.path = (d / "rel.mcap").string();
  ro.topics = {"demo/raw"};
  auto rec = std::make_shared<Recorder>(opts(ctx, "recorder"), ro);
  auto src = std::make_shared<bus::Node>(opts(ctx, "src"));
  auto pub = src->create_publisher<std_msgs::msg::String>("/demo/raw");
  ex.add_node(rec);
  ex.add_node(src);
  ex.advance_to(bus::Time::from_seconds(1));
  for (int i = 0; i < 3; ++i) {
    pub->publish(std::make_unique<std_msgs::msg::String>());
    ex.spin_until_idle();
  }
  ASSERT_TRUE(rec->stop().ok());
  EXPECT_EQ(rec->stats().written, 3U);
  // In a namespace, relative names resolve against it; bad names stop the build.
  bus::NodeOptions ns = opts(ctx, "r2");
  ns.ns = "/robot";
  ns.param("topics", std::vector<std::string>{"scan", "/abs", "~/own"});
  Recorder r2(ns);
  EXPECT_THROW(Recorder(opts(ctx, "r3").param("topics", std::vector<std::string>{"bad name"})), bus::ParamError);
}

TEST(BagFiles, ARecorderThatCannotFinishItsFileFailsItsStop) {
  // A full disk used to end a launch with exit code 0: on_stop() swallowed it.
  struct FailingSink : Writable {
    Status write(std::span<const std::uint8_t> b) override {
      if (size_ + b.size() > 2000) return {StatusCode::WriteFailed, "sink: No space left on device"};
      size_ += b.size();
      return {};
    }
    Status flush() override { return {}; }
    Status close() override { return {}; }
    std::uint64_t size() const override { return size_; }
    const std::string& name() const override { return name_; }
    std::uint64_t size_ = 0;
    std::string name_ = "full.mcap";
  };
  auto ctx = bus::Context::create(bus::ContextOptions{bus::ClockType::Sim, std::make_shared<bus::CaptureSink>()});
  bus::DeterministicExecutor ex(ctx->clock());
  RecorderOptions ro;
  ro.writer.writer.chunk_size_bytes = 1024;
  auto rec = std::make_shared<Recorder>(opts(ctx, "recorder"), ro, std::make_unique<FailingSink>());
  auto src = std::make_shared<bus::Node>(opts(ctx, "src"));
  auto pub = src->create_publisher<std_msgs::msg::String>("/x");
  ex.add_node(rec);
  ex.add_node(src);
  ex.advance_to(bus::Time::from_seconds(1));
  for (int i = 0; i < 50; ++i) {
    auto m = std::make_unique<std_msgs::msg::String>();
    m->data = std::string(100, 'x');
    pub->publish(std::move(m));
    ex.spin_until_idle();
  }
  try {
    rec->on_stop();
    FAIL() << "on_stop() reported success for a file it could not write";
  } catch (const BagError& e) {
    EXPECT_NE(std::string(e.what()).find("No space left on device"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace tinyline::bag
