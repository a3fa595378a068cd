// SPDX-License-Identifier: Apache-2.0
// Transports without hardware: the in-memory link, the serial port on a
// pseudo-terminal (what the simulator's virtual device is), USB discovery on
// a fake sysfs tree, and the messages a user gets when something is wrong.
#include <gtest/gtest.h>

#include <fcntl.h>
#include <stdlib.h>
#include <unistd.h>

#include <cerrno>
#include <filesystem>
#include <fstream>
#include <thread>

#include <tiny_laser_driver/io/port.hpp>

#include <tinyline/bus/testing.hpp>

namespace io = tinyline::tiny_laser_driver::io;
namespace fs = std::filesystem;
using namespace std::chrono_literals;
using Bytes = std::vector<std::uint8_t>;

namespace {

// A pseudo-terminal pair: the test holds the master (the "device"), the code
// under test opens the slave path.
struct Pty {
  int master = -1;
  std::string slave;
  Pty() {
    master = ::posix_openpt(O_RDWR | O_NOCTTY);
    if (master < 0 || ::grantpt(master) != 0 || ::unlockpt(master) != 0) throw std::runtime_error("no pty");
    slave = ::ptsname(master);
  }
  ~Pty() { close(); }
  void close() {
    if (master >= 0) ::close(master);
    master = -1;
  }
  void write(const Bytes& b) const { ASSERT_EQ(::write(master, b.data(), b.size()), static_cast<ssize_t>(b.size())); }
  Bytes read_some() const {
    Bytes b(256);
    const ssize_t n = ::read(master, b.data(), b.size());
    b.resize(n > 0 ? static_cast<std::size_t>(n) : 0);
    return b;
  }
};

// Reads until `n` bytes came or the stream reports an error.
Bytes read_n(io::ByteStream& s, std::size_t n) {
  Bytes out;
  std::uint8_t buf[512];
  while (out.size() < n) {
    const auto r = s.read(buf, 5000ms);
    if (!r.status.ok()) break;
    out.insert(out.end(), buf, buf + r.bytes);
  }
  return out;
}

using TempDir = tinyline::bus::testing::TempDir;

void write_file(const fs::path& p, const std::string& text) {
  fs::create_directories(p.parent_path());
  std::ofstream(p) << text << "\n";
}

// A fake sysfs: an FT232R with a tty, a second one without a driver bound,
// and an unrelated adapter.
void make_fake_usb(const fs::path& root, const std::string& serial, const std::string& usb_path, const std::string& tty,
                   const std::string& vidpid = "0403:6001", bool bind_driver = true) {
  const fs::path dev = root / "sys/bus/usb/devices" / usb_path;
  write_file(dev / "idVendor", vidpid.substr(0, 4));
  write_file(dev / "idProduct", vidpid.substr(5, 4));
  write_file(dev / "serial", serial);
  write_file(dev / "manufacturer", "FTDI");
  write_file(dev / "product", "FT232R USB UART");
  if (!tty.empty()) {
    fs::create_directories(dev / (usb_path + ":1.0") / tty);
    if (bind_driver) {
      fs::create_directories(root / "sys/bus/usb-serial/drivers/ftdi_sio");
      fs::create_directories(root / "sys/class/tty" / tty / "device");
      fs::create_symlink(root / "sys/bus/usb-serial/drivers/ftdi_sio", root / "sys/class/tty" / tty / "device/driver");
    }
  }
}

}  // namespace

// ------------------------------------------------------------------ in-memory link

TEST(MemoryLink, DeliversBytesAndReportsUnplug) {
  auto link = io::MemoryLink::create("dev");
  auto opened = link->open();
  ASSERT_TRUE(opened.status.ok());
  EXPECT_EQ(link->open().status.error, io::IoError::kBusy);
  link->push(Bytes{1, 2, 3});
  std::uint8_t buf[2];
  auto r = opened.stream->read(buf, 0ms);
  EXPECT_EQ(r.bytes, 2u);
  r = opened.stream->read(buf, 0ms);
  EXPECT_EQ(r.bytes, 1u);
  r = opened.stream->read(buf, 0ms);  // nothing queued, no wait
  EXPECT_EQ(r.bytes, 0u);
  EXPECT_TRUE(r.status.ok());
  ASSERT_TRUE(opened.stream->write(Bytes{9, 8}).ok());
  EXPECT_EQ(link->take_written(), (Bytes{9, 8}));

  link->unplug();
  r = opened.stream->read(buf, 0ms);
  EXPECT_EQ(r.status.error, io::IoError::kDisconnected);
  EXPECT_EQ(link->open().status.error, io::IoError::kNotFound);
  link->replug();
  auto again = link->open();
  ASSERT_TRUE(again.status.ok());
  EXPECT_EQ(link->opens(), 2);
  // The old host side stays dead after the replug.
  EXPECT_EQ(opened.stream->read(buf, 0ms).status.error, io::IoError::kDisconnected);
}

TEST(MemoryLink, UnplugCanLeaveQueuedBytesToRead) {
  auto link = io::MemoryLink::create("dev");
  auto opened = link->open();
  link->push(Bytes{1, 2, 3});
  link->unplug(/*keep_queued=*/true);
  std::uint8_t buf[8];
  auto r = opened.stream->read(buf, 0ms);
  EXPECT_EQ(r.bytes, 3u);
  EXPECT_EQ(opened.stream->read(buf, 0ms).status.error, io::IoError::kDisconnected);
}

// ------------------------------------------------------------------ serial port on a pty

TEST(SerialPort, ReadsAndWritesThroughAPty) {
  Pty pty;
  auto opened = io::SerialPort::open(pty.slave);
  ASSERT_TRUE(opened.status.ok()) << opened.status.message;
  auto& port = *opened.port;
  EXPECT_TRUE(port.is_pty());
  EXPECT_DOUBLE_EQ(port.baud(), 2'000'000.0);
  Bytes frame(1096);
  for (std::size_t i = 0; i < frame.size(); ++i) frame[i] = static_cast<std::uint8_t>(i * 7);
  pty.write(frame);
  EXPECT_EQ(read_n(port, frame.size()), frame);
  ASSERT_TRUE(port.write(Bytes{0xF8, 0x02, 0x10, 0x01, 0x8F}).ok());
  EXPECT_EQ(pty.read_some(), (Bytes{0xF8, 0x02, 0x10, 0x01, 0x8F}));
  // A timeout is not an error.
  std::uint8_t buf[4];
  const auto r = port.read(buf, 1ms);
  EXPECT_EQ(r.bytes, 0u);
  EXPECT_TRUE(r.status.ok());
}

TEST(SerialPort, SetsNonStandardRatesThroughTermios2) {
  Pty pty;
  io::SerialOptions o;
  o.baud = 1'234'567;  // no Bxxx constant: BOTHER
  auto opened = io::SerialPort::open(pty.slave, o);
  ASSERT_TRUE(opened.status.ok()) << opened.status.message;
  EXPECT_DOUBLE_EQ(opened.port->baud(), 1'234'567.0);
  o.baud = 0;
  EXPECT_EQ(io::SerialPort::open(pty.slave, o).status.error, io::IoError::kBadSetting);
}

TEST(SerialPort, HangUpReadsAsDisconnected) {
  Pty pty;
  auto opened = io::SerialPort::open(pty.slave);
  ASSERT_TRUE(opened.status.ok());
  pty.write(Bytes{1, 2, 3});
  EXPECT_EQ(read_n(*opened.port, 3), (Bytes{1, 2, 3}));
  pty.close();  // the virtual device goes away
  std::uint8_t buf[8];
  const auto r = opened.port->read(buf, 5000ms);
  EXPECT_EQ(r.status.error, io::IoError::kDisconnected) << r.status.message;
}

TEST(SerialPort, InterruptEndsAWaitingRead) {
  Pty pty;
  auto opened = io::SerialPort::open(pty.slave);
  ASSERT_TRUE(opened.status.ok());
  // If interrupt() did not work this read would wait a day (ctest's timeout fails it).
  std::thread t([&] { opened.port->interrupt(); });
  std::uint8_t buf[8];
  const auto r = opened.port->read(buf, std::chrono::hours(24));
  t.join();
  EXPECT_EQ(r.bytes, 0u);
  EXPECT_TRUE(r.status.ok());
}

TEST(SerialPort, ASecondOpenIsRefusedAsBusy) {
  Pty pty;
  auto first = io::SerialPort::open(pty.slave);
  ASSERT_TRUE(first.status.ok());
  auto second = io::SerialPort::open(pty.slave);
  EXPECT_EQ(second.status.error, io::IoError::kBusy);
  EXPECT_NE(second.status.message.find("busy"), std::string::npos) << second.status.message;
  EXPECT_NE(second.status.message.find(pty.slave), std::string::npos);
  first.port.reset();  // closing releases the lock
  EXPECT_TRUE(io::SerialPort::open(pty.slave).status.ok());
}

TEST(SerialPort, MissingDeviceAndNonSerialFilesSayWhatTheyAre) {
  const auto missing = io::SerialPort::open("/dev/ttyUSB_tinyline_missing");
  EXPECT_EQ(missing.status.error, io::IoError::kNotFound);
  EXPECT_EQ(missing.status.code, tinyline::common::StatusCode::NotFound);
  EXPECT_NE(missing.status.message.find("/dev/ttyUSB_tinyline_missing"), std::string::npos);
  EXPECT_NE(missing.status.message.find("tinyline sensors"), std::string::npos);
  TempDir tmp;
  write_file(tmp.path / "plain", "x");
  const auto plain = io::SerialPort::open((tmp.path / "plain").string());
  EXPECT_EQ(plain.status.error, io::IoError::kNotSerial);
  EXPECT_EQ(plain.status.code, tinyline::common::StatusCode::InvalidArgument);
}

TEST(SerialPort, PermissionErrorsNameTheGroupAndTheUdevRule) {
  // Tests may run as root (which opens anything), so the errno is given here.
  const auto s = io::open_error_status(EACCES, "/dev/null");
  EXPECT_EQ(s.error, io::IoError::kPermission);
  EXPECT_NE(s.message.find("/dev/null"), std::string::npos);
  EXPECT_NE(s.message.find("usermod -aG"), std::string::npos);
  EXPECT_NE(s.message.find("99-tinyline-laser.rules"), std::string::npos);
  EXPECT_NE(s.message.find("owned by"), std::string::npos);
  EXPECT_EQ(io::open_error_status(EIO, "/dev/x").error, io::IoError::kDisconnected);
}

TEST(SerialPort, FtdiRatesAreTheOnesItsDivisorMakes) {
  EXPECT_DOUBLE_EQ(io::ftdi_rate(2'000'000).actual_baud, 2'000'000.0);
  EXPECT_DOUBLE_EQ(io::ftdi_rate(3'000'000).actual_baud, 3'000'000.0);
  EXPECT_DOUBLE_EQ(io::ftdi_rate(1'000'000).actual_baud, 1'000'000.0);  // divisor 3
  const auto r = io::ftdi_rate(921'600);                                // 3e6 / 3.25
  EXPECT_NEAR(r.actual_baud, 3e6 / 3.25, 1e-6);
  EXPECT_LT(r.relative_error, 0.002);
  EXPECT_GT(io::ftdi_rate(2'500'000).relative_error, 0.19);         // between divisors 1 and 1.5
  EXPECT_NEAR(io::ftdi_rate(115'200).actual_baud, 3e6 / 26, 1e-6);  // the FT232R's well-known 115,384
}

// ------------------------------------------------------------------ USB discovery on a fake sysfs

TEST(UsbDiscovery, FindsFtdiAdaptersAndTheirTtys) {
  TempDir tmp;
  make_fake_usb(tmp.path, "A50285BI", "1-1.2", "ttyUSB0");
  make_fake_usb(tmp.path, "FT0001", "1-1.4", "ttyUSB1");
  make_fake_usb(tmp.path, "CP9", "2-1", "ttyUSB2", "10c4:ea60");
  fs::create_directories(tmp.path / "sys/bus/usb/devices/usb1");  // a root hub
  io::DiscoveryOptions o;
  o.sysfs_root = tmp.path.string();
  o.dev_root = "/fake/dev";
  const auto d = io::discover_usb_serial(o);
  EXPECT_EQ(d.backend, "sysfs");
  ASSERT_EQ(d.devices.size(), 2u);
  EXPECT_EQ(d.devices[0].usb_path, "1-1.2");
  EXPECT_EQ(d.devices[0].serial, "A50285BI");
  EXPECT_EQ(d.devices[0].tty, "/fake/dev/ttyUSB0");
  EXPECT_EQ(d.devices[0].driver, "ftdi_sio");
  EXPECT_EQ(d.devices[0].vendor_id, 0x0403);
  EXPECT_EQ(d.devices[1].serial, "FT0001");
  o.any_device = true;
  EXPECT_EQ(io::discover_usb_serial(o).devices.size(), 3u);
}

TEST(UsbDiscovery, FindsASensorBySerialOrSaysWhatIsThere) {
  TempDir tmp;
  make_fake_usb(tmp.path, "A50285BI", "1-1.2", "ttyUSB0");
  make_fake_usb(tmp.path, "NODRV", "1-1.3", "", "0403:6001");
  io::DiscoveryOptions o;
  o.sysfs_root = tmp.path.string();
  const auto found = io::find_sensor_tty("A50285BI", o);
  ASSERT_TRUE(found.status.ok()) << found.status.message;
  EXPECT_EQ(found.tty, "/dev/ttyUSB0");

  const auto missing = io::find_sensor_tty("ZZZ", o);
  EXPECT_EQ(missing.status.error, io::IoError::kNotFound);
  EXPECT_NE(missing.status.message.find("A50285BI"), std::string::npos) << missing.status.message;
  EXPECT_NE(missing.status.message.find("tinyline sensors"), std::string::npos);

  const auto unbound = io::find_sensor_tty("NODRV", o);
  EXPECT_EQ(unbound.status.error, io::IoError::kNotFound);
  EXPECT_NE(unbound.status.message.find("modprobe ftdi_sio"), std::string::npos) << unbound.status.message;
}

TEST(UsbDiscovery, AMachineWithoutUsbIsAnEmptyListWithAReason) {
  TempDir tmp;
  io::DiscoveryOptions o;
  o.sysfs_root = tmp.path.string();
  const auto d = io::discover_usb_serial(o);
  EXPECT_TRUE(d.devices.empty());
  EXPECT_NE(d.note.find("does not exist"), std::string::npos) << d.note;
}

TEST(UsbDiscovery, ParsesVidPid) {
  const auto v = io::parse_vid_pid("0403:6001");
  ASSERT_TRUE(v);
  EXPECT_EQ(v->first, 0x0403);
  EXPECT_EQ(v->second, 0x6001);
  EXPECT_FALSE(io::parse_vid_pid("0403"));
  EXPECT_FALSE(io::parse_vid_pid("0403:"));
  EXPECT_FALSE(io::parse_vid_pid("xyz:6001"));
  EXPECT_FALSE(io::parse_vid_pid("10000:1"));
}

// ------------------------------------------------------------------ port specs

TEST(PortSpec, UsbSerialOpensTheTtyFoundAndFollowsAReplug) {
  // The fake sensor's tty is a symlink to a pty slave; after a "replug" it
  // comes back under another name and another USB path.
  TempDir tmp;
  Pty first;
  make_fake_usb(tmp.path / "root", "A50285BI", "1-1.2", "ttyUSB0");
  fs::create_directories(tmp.path / "dev");
  fs::create_symlink(first.slave, tmp.path / "dev/ttyUSB0");
  io::PortOptions o;
  o.discovery.sysfs_root = (tmp.path / "root").string();
  o.discovery.dev_root = (tmp.path / "dev").string();
  auto opener = io::make_port_opener("usb:A50285BI", o);
  EXPECT_EQ(opener->describe(), "usb:A50285BI");
  EXPECT_EQ(opener->hardware_id(), "A50285BI");
  auto s = opener->open();
  ASSERT_TRUE(s.status.ok()) << s.status.message;
  first.write(Bytes{0xA2, 0xA1});
  EXPECT_EQ(read_n(*s.stream, 2), (Bytes{0xA2, 0xA1}));

  // Unplug: the device and its sysfs entry go away.
  first.close();
  fs::remove_all(tmp.path / "root");
  fs::remove(tmp.path / "dev/ttyUSB0");
  std::uint8_t buf[4];
  EXPECT_EQ(s.stream->read(buf, 5000ms).status.error, io::IoError::kDisconnected);
  s.stream.reset();
  EXPECT_EQ(opener->open().status.error, io::IoError::kNotFound);

  // Replug into another socket: new tty name, same serial number.
  Pty second;
  make_fake_usb(tmp.path / "root", "A50285BI", "1-1.3", "ttyUSB1");
  fs::create_symlink(second.slave, tmp.path / "dev/ttyUSB1");
  auto again = opener->open();
  ASSERT_TRUE(again.status.ok()) << again.status.message;
  second.write(Bytes{7});
  EXPECT_EQ(read_n(*again.stream, 1), (Bytes{7}));
}

TEST(PortSpec, AnFtdiAdapterRefusesARateItCannotMake) {
  TempDir tmp;
  Pty pty;
  make_fake_usb(tmp.path / "root", "A1", "1-1", "ttyUSB0");
  fs::create_directories(tmp.path / "dev");
  fs::create_symlink(pty.slave, tmp.path / "dev/ttyUSB0");
  io::PortOptions o;
  o.discovery.sysfs_root = (tmp.path / "root").string();
  o.discovery.dev_root = (tmp.path / "dev").string();
  o.serial.baud = 2'500'000;
  const auto bad = io::make_port_opener("usb:A1", o)->open();
  EXPECT_EQ(bad.status.error, io::IoError::kBadSetting);
  EXPECT_NE(bad.status.message.find("FTDI"), std::string::npos) << bad.status.message;
  o.serial.baud = 921'600;  // made as 3 MHz / 3.25: the timestamps use that rate
  const auto good = io::make_port_opener("usb:A1", o)->open();
  ASSERT_TRUE(good.status.ok()) << good.status.message;
  EXPECT_NEAR(good.stream->baud(), 3e6 / 3.25, 1e-6);
}

TEST(PortSpec, MalformedSpecsAndUnknownSchemesAreRefusedWithTheForms) {
  EXPECT_THROW((void)io::make_port_opener(""), std::invalid_argument);
  try {
    (void)io::make_port_opener("bogus:thing");
    FAIL() << "unknown scheme accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("usb:SERIAL"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("'bogus'"), std::string::npos) << e.what();
  }
  EXPECT_THROW((void)io::make_port_opener("ttyUSB0"), std::invalid_argument);
  EXPECT_THROW((void)io::make_port_opener("usb:"), std::invalid_argument);
}

TEST(PortSpec, MemoryLinksAreReachableByName) {
  auto link = io::MemoryLink::create("unit");
  io::register_memory_link("unit", link);
  auto opener = io::make_port_opener("mem:unit");
  auto s = opener->open();
  ASSERT_TRUE(s.status.ok());
  link->push(Bytes{5});
  std::uint8_t b[1];
  EXPECT_EQ(s.stream->read(b, 0ms).bytes, 1u);
  io::unregister_memory_link("unit");
  s.stream.reset();
  EXPECT_EQ(opener->open().status.error, io::IoError::kNotFound);
}

TEST(UsbDiscovery, TheSensorListGivesThePortToUseAndTheAccess) {
  TempDir tmp;
  Pty pty;
  make_fake_usb(tmp.path / "root", "A50285BI", "1-1.2", "ttyUSB0");
  make_fake_usb(tmp.path / "root", "NODRV", "1-1.3", "");
  fs::create_directories(tmp.path / "dev");
  fs::create_symlink(pty.slave, tmp.path / "dev/ttyUSB0");
  io::DiscoveryOptions o;
  o.sysfs_root = (tmp.path / "root").string();
  o.dev_root = (tmp.path / "dev").string();
  const auto listing = io::format_sensor_list(io::discover_usb_serial(o), o);
  EXPECT_NE(listing.find("usb:A50285BI"), std::string::npos) << listing;
  EXPECT_NE(listing.find("ready"), std::string::npos) << listing;
  EXPECT_NE(listing.find("modprobe ftdi_sio"), std::string::npos) << listing;
  auto held = io::SerialPort::open((tmp.path / "dev/ttyUSB0").string());
  ASSERT_TRUE(held.status.ok());
  const auto busy = io::format_sensor_list(io::discover_usb_serial(o), o);
  EXPECT_NE(busy.find("in use"), std::string::npos) << busy;

  io::DiscoveryOptions none;
  none.sysfs_root = (tmp.path / "nothing").string();
  const auto empty = io::format_sensor_list(io::discover_usb_serial(none), none);
  EXPECT_NE(empty.find("no 0403:6001 adapters found"), std::string::npos) << empty;
}
