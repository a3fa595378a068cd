// SPDX-License-Identifier: Apache-2.0
// Our bags against independent implementations (Python `mcap`,
// `mcap-ros2-support`, `rosbags`), both ways. The Python side runs in the
// test virtual env (scripts/bootstrap makes it); interop_check.py next to
// this file does the reading, writing and comparing there.
#include <gtest/gtest.h>

#include <cstdio>
#include <filesystem>
#include <fstream>

#include <tinyline/bag/reader.hpp>
#include <tinyline/bag/ros2.hpp>

#include "sample_traffic.hpp"

namespace tinyline::bag {
namespace {

namespace fs = std::filesystem;

const char* kScript = TINYLINE_SOURCE_DIR "/bus/bag/test/interop_check.py";

// Runs the interop script; its output goes to the test log.
int run_python(const std::string& args, std::string& output) {
  const std::string cmd = std::string(TINYLINE_VENV_PYTHON) + " " + kScript + " " + args + " 2>&1";
  FILE* p = ::popen(cmd.c_str(), "r");
  if (p == nullptr) return -1;
  char buf[4096];
  while (std::fgets(buf, sizeof(buf), p) != nullptr) output += buf;
  const int rc = ::pclose(p);
  return WIFEXITED(rc) ? WEXITSTATUS(rc) : -1;
}

fs::path fresh_dir(const std::string& name) {
  const fs::path d = fs::path(TINYLINE_BINARY_DIR) / "bag_interop" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

void require_venv() {
  ASSERT_TRUE(fs::exists(TINYLINE_VENV_PYTHON))
      << "the test virtual env is missing (" << TINYLINE_VENV_PYTHON << "): run scripts/bootstrap";
}

TEST(Interop, PythonMcapAndRosbagsReadEveryVariantWeWrite) {
  require_venv();
  const fs::path dir = fresh_dir("ours");
  const auto samples = testing::sample_traffic(60);
  struct V {
    std::string name;
    WriterOptions opt;
  };
  std::vector<V> variants;
  for (Compression c : {Compression::None, Compression::Lz4, Compression::Zstd}) {
    WriterOptions o;
    o.compression = c;
    o.chunk_size_bytes = 32 * 1024;  // several chunks
    variants.push_back({std::string("ours_") + std::string(to_string(c)), o});
  }
  WriterOptions big;
  big.compression = Compression::Zstd;
  big.compression_level = 19;
  big.chunk_size_bytes = 8 << 20;  // one chunk
  variants.push_back({"ours_zstd19_one_chunk", big});
  WriterOptions unchunked;
  unchunked.chunked = false;
  variants.push_back({"ours_unchunked", unchunked});
  WriterOptions no_summary;
  no_summary.summary = false;
  variants.push_back({"ours_lz4_no_summary", no_summary});
  WriterOptions no_index;
  no_index.message_indexes = false;
  no_index.chunk_size_bytes = 16 * 1024;
  variants.push_back({"ours_lz4_no_message_index", no_index});
  for (const auto& v : variants) {
    ros2::Ros2Writer w;
    ASSERT_TRUE(w.open((dir / (v.name + ".mcap")).string(), v.opt).ok());
    ASSERT_TRUE(testing::write_samples(w, samples).ok());
    ASSERT_TRUE(w.close().ok());
    testing::write_expected((dir / (v.name + ".expected.yaml")).string(), samples);
  }
  std::string out;
  const int rc = run_python("check-ours " + dir.string(), out);
  std::cout << out;
  EXPECT_EQ(rc, 0) << out;
}

// Reads every message of a file two ways (through the index, and linearly),
// checks they agree, and writes what was decoded for the Python comparison.
void decode_file(const fs::path& bag, const fs::path& actual) {
  Reader r;
  const Status open = r.open(bag.string());
  ASSERT_TRUE(open.ok()) << open.str();
  std::ofstream f(actual);
  std::size_t indexed = 0;
  const Status s = r.for_each({}, [&](const MessageView& v) {
    std::string why;
    const msg::TypeSupport* ts = ros2::type_support_for(v.schema, *v.channel, &why);
    EXPECT_NE(ts, nullptr) << bag << ": " << why;
    if (ts == nullptr) return false;
    std::shared_ptr<void> m;
    try {
      m = ts->deserialize(v.message.data);
    } catch (const std::exception& e) {
      ADD_FAILURE() << bag << ": " << v.channel->topic << " at " << v.message.log_time << ": " << e.what();
      return false;
    }
    f << testing::yaml_doc(v.channel->topic, *ts, m.get(), v.message.log_time, v.message.publish_time,
                           v.message.sequence);
    ++indexed;
    return true;
  });
  EXPECT_TRUE(s.ok()) << bag << ": " << s.str();

  // The linear reader (CRCs checked) sees the same messages; verify() checks the data CRC and statistics.
  ReaderOptions lin;
  lin.ignore_summary = true;
  Reader lr;
  ASSERT_TRUE(lr.open(bag.string(), lin).ok());
  std::size_t linear = 0;
  EXPECT_TRUE(lr.for_each({}, [&](const MessageView&) {
                  ++linear;
                  return true;
                }).ok());
  EXPECT_EQ(linear, indexed) << bag;
  const Status v = r.verify();
  EXPECT_TRUE(v.ok()) << bag << ": " << v.str();
  if (!r.has_summary()) {
    EXPECT_TRUE(r.scan().ok());
    EXPECT_EQ(r.summary().statistics.message_count, indexed) << bag;
  } else {
    EXPECT_EQ(r.summary().statistics.message_count, indexed) << bag;
  }
}

TEST(Interop, WeReadWhatPythonMcapAndRosbagsWrite) {
  require_venv();
  const fs::path dir = fresh_dir("theirs");
  std::string out;
  int rc = run_python("write-theirs " + dir.string(), out);
  std::cout << out;
  ASSERT_EQ(rc, 0) << out;
  int files = 0;
  for (const auto& e : fs::directory_iterator(dir)) {
    if (e.path().extension() != ".mcap") continue;
    ++files;
    fs::path actual = e.path();
    actual.replace_extension(".actual.yaml");
    decode_file(e.path(), actual);
  }
  // mcap: 3 compressions x with/without summary; rosbags: none/zstd x with/without summary.
  EXPECT_EQ(files, 10);
  out.clear();
  rc = run_python("compare " + dir.string(), out);
  std::cout << out;
  EXPECT_EQ(rc, 0) << out;
}

}  // namespace
}  // namespace tinyline::bag
