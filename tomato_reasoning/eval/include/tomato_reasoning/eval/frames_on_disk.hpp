// SPDX-License-Identifier: Apache-2.0
// A scenario's frames through files: each view written as an RGB-D folder
// (tomato_reasoning/io: rgb/000000.png, 16-bit depth/000000.png in mm,
// intrinsics.yaml) and read back by the io reader, so the pipeline sees what
// it would see on frames from disk (depth quantised to 1 mm, colour as PNG).
#pragma once

#include <string>

#include "tomato_reasoning/eval/scenario.hpp"

namespace tinyline::tomato_reasoning::eval {

/// Writes DIR/<class><seed>_v<view>/ for every view of `s` and replaces the
/// scenario's clouds with what the io reader makes of those files. Throws
/// the io's RgbdFileError when a file cannot be written or read.
void round_trip_through_files(Scenario& s, const std::string& dir);

}  // namespace tinyline::tomato_reasoning::eval
