// SPDX-License-Identifier: Apache-2.0
// termios2 (arbitrary baud via BOTHER) lives in its own translation unit:
// <asm/termbits.h> and glibc's <termios.h> define the same structs.
#pragma once

namespace tinyline::tiny_laser_driver::io::detail {

/// Sets input and output speed of `fd` to `baud` with BOTHER. Returns 0 or an errno.
int set_custom_baud(int fd, unsigned baud);
/// Reads the output speed back (0 on failure).
unsigned get_baud(int fd);

}  // namespace tinyline::tiny_laser_driver::io::detail
