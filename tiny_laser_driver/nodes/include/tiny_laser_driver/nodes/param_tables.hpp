// SPDX-License-Identifier: Apache-2.0
// The parameter table of the driver node's settings (DriverParams), described
// once (<tinyline/common/param_table.hpp>): the node declares its parameters
// from it, `tinyline describe` and docs/parameters.md show it.
#pragma once

#include <string_view>

#include <tinyline/common/param_table.hpp>

#include <tiny_laser_driver/nodes/laser_driver.hpp>
#include <tiny_laser_driver/param_tables.hpp>

namespace tinyline::tiny_laser_driver {

/// Values of `calibration` that name no file.
inline constexpr std::string_view kCalibrationNotAFile[] = {"default", "public:"};

/// The words DriverParams::mode takes.
inline constexpr std::string_view kDriverModes[] = {"auto", "raw", "distance"};

template <class S, class V>
requires common::SettingsOf<S, DriverParams>
void for_each_param(S& p, V&& v) {
  v(p.port, {"port",
             "",
             {},
             {},
             "/dev/ttyUSB0 (a path), usb:SERIAL (found by USB serial number), sim:SCENE.yaml (simulated sensor "
             "in-process), mem:NAME (tests)"});
  v(p.mode,
    {"mode",
     "",
     {},
     {},
     "the frames expected, only checked and reported (both kinds are always read): auto (either), raw (the host "
     "computes distance from all read-outs, thesis 5.3.1) or distance (the firmware sends distances, 4.4.1)"},
    kDriverModes);
  v(p.baud, {"baud", "bit/s", 1200, 12'000'000, "link rate (the sensor's FT232R: 2000000)"});
  v(p.readouts_per_set, {"readouts_per_set", "", 1, 99, "raw mode: read-outs (frames) per set"});
  common::nest(p.optics, "", v);
  v(p.frame_id, {"frame_id", "", {}, {}, "frame of RawScan/LineScan: z forward, x along the line"});
  v(p.scan_frame_id,
    {"scan_frame_id", "", {}, {}, "frame of the LaserScan (x = sensor z, y = sensor x); empty: frame_id + '_scan'"});
  v(p.calibration,
    {"calibration",
     "",
     {},
     {},
     "calibration YAML (tinyline calib fit), public:NAME (R J S K T of the public driver), or default "
     "(the simulated 8 mm sensor's)"},
    common::InputFile{kMaxCalibrationFileBytes, kCalibrationNotAFile});
  v(p.distance_unit_m, {"distance_unit_m", "m", 1e-6, 1.0,
                        "distance frames: unit of the firmware's distances (the published firmware: 0.1 mm)"});
  v(p.stale_after, {"stale_after", "", 2, 100000,
                    "fresh measurements a pixel's value may stay unchanged while its neighbours' change before it "
                    "is flagged stale"});
  v(p.sensor_name, {"sensor_name", "", {}, {}, "name in LaserCommand.sensors; empty: the node's name"});
  v(p.sequence_slot, {"sequence_slot", "", -1, 65535,
                      "sequence mode slot (thesis 6.2.1): >= 0 keeps the laser off until a LaserCommand lists the "
                      "slot; -1: not in sequence mode"});
  v(p.send_stream_mode,
    {"send_stream_mode",
     "",
     {},
     {},
     "send the stream-mode command (0x11, a tinyline extension) for `mode` on connect (not with auto)"});
  v(p.reconnect_min_s, {"reconnect_min_s", "s", 0.001, 60.0, "first retry after a disconnect"});
  v(p.reconnect_max_s, {"reconnect_max_s", "s", 0.001, 600.0, "longest wait between reconnect attempts"});
  v(p.diagnostics_period_s, {"diagnostics_period_s", "s", 0.01, 3600.0, "diagnostics period"});
  v(p.stall_timeout_s, {"stall_timeout_s", "s", 0.01, 3600.0, "connected but no complete frame for this long: WARN"});
  v(p.threaded, {"threaded", "", {}, {}, "run the I/O thread; false: the embedding code calls pump()"});
  v(p.publish_raw, {"publish_raw", "", {}, {}, "publish tinyline_msgs/RawScan (raw sets)"});
  v(p.publish_cloud, {"publish_cloud",
                      "",
                      {},
                      {},
                      "also publish the line on 'cloud' as sensor_msgs/PointCloud2 (x y z intensity float32, in "
                      "frame_id, one point per pixel, NaN where the pixel has no valid distance)"});
}

}  // namespace tinyline::tiny_laser_driver
