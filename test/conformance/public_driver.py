# SPDX-License-Identifier: Apache-2.0
"""The sensor's public code, re-implemented in Python from reading it (not
from tinyline's parser), for conformance checks.

Two parts:

* ``PublicDriverReader``: the byte state machine of the public ROS 1 driver
  (``src/serial_comm.cpp`` of the sensor's public driver): hunt for the first
  header byte 0xA2, then the second 0xA1, then read a fixed number of bytes
  (546 after the header with ``onlydistdata``, 1094 otherwise) and check the
  ender 0x2A 0x2B at their end. A frame whose ender is wrong is rejected and
  the hunt starts again *after* it (the driver does not back up). In raw
  frames the first word is the frame index (above 100 on the last frame of a
  set, ``num > 100``) and the second the packed word (``word / 100``
  temperature in 0.1 degC, ``word % 100`` pulses / 10), then 272 int16 for
  capacitor A and 272 for B. Distance frames carry 272 values; the firmware
  stores them as uint16 in 0.1 mm, so they are decoded unsigned here (the
  public driver's ``short`` turns everything beyond 3.2767 m negative).

* ``main_c_cycle``: what the published firmware's main loop (``Src/main.c``,
  with the timer interrupt of ``Src/itcallback.cpp``) computes from one
  accumulation cycle's read-outs: per read-out and pixel, the discharges with
  an ambient level subtracted from both and capacitor A scaled by the
  sensitivity ratio (and once more on pixel 176), k = top / (bot + top), the
  validity tests, a 6th-degree polynomial in k plus 3.4 - 10 k [cm], stored
  as (uint16)(cm * 100) only when the pixel is not saturated (so a saturated
  pixel keeps the value of the last read-out that was not); before sending,
  pixel 176 takes pixel 175's value and pixel 16 pixel 17's.
"""

HEADER = (0xA2, 0xA1)
ENDER = (0x2A, 0x2B)
PIXELS = 272
DISTANCE_BODY = 546  # bytes after the header: 272 x 2 + ender
RAW_BODY = 1094      # index, packed word, 272 x 2 x 2, ender


def u16(b, i):
    return b[i] | (b[i + 1] << 8)


def i16(b, i):
    v = u16(b, i)
    return v - 0x10000 if v >= 0x8000 else v


class PublicDriverReader:
    """The public driver's state machine; feed bytes in any chunking."""

    FIRST, SECOND, DATA = 0, 1, 2

    def __init__(self, only_distance):
        self.only_distance = only_distance
        self.stage = self.FIRST
        self.body = bytearray()
        self.frames = []           # decoded frames, in order
        self.rejected = 0          # frames whose ender was wrong
        self.rejected_after_sync = 0
        self.hunted = 0            # bytes skipped looking for a header
        self.bytes = 0

    def feed(self, data):
        need = DISTANCE_BODY if self.only_distance else RAW_BODY
        for byte in data:
            self.bytes += 1
            if self.stage == self.FIRST:
                if byte == HEADER[0]:
                    self.stage = self.SECOND
                else:
                    self.hunted += 1
            elif self.stage == self.SECOND:
                if byte == HEADER[1]:
                    self.stage = self.DATA
                    self.body = bytearray()
                else:
                    self.hunted += 2
                    self.stage = self.FIRST
            else:
                self.body.append(byte)
                if len(self.body) == need:
                    self._frame(bytes(self.body))
                    self.stage = self.FIRST

    def _frame(self, body):
        if (body[-2], body[-1]) != ENDER:
            self.rejected += 1
            if self.frames:
                self.rejected_after_sync += 1
            return
        if self.only_distance:
            self.frames.append({"kind": "distance", "distance": [u16(body, 2 * i) for i in range(PIXELS)]})
            return
        num = u16(body, 0)
        packed = u16(body, 2)
        self.frames.append({
            "kind": "raw",
            "index_word": num,
            "last": num > 100,
            "index": num - 100 if num > 100 else num,
            "temperature_decic": packed // 100,
            "pulses": (packed % 100) * 10,
            "a": [i16(body, 4 + 2 * i) for i in range(PIXELS)],
            "b": [i16(body, 4 + 2 * PIXELS + 2 * i) for i in range(PIXELS)],
        })


def polynomial_cm(poly, k):
    """main.c's polynomial, written as main.c writes it (left to right)."""
    return (poly[0] * k * k * k * k * k * k + poly[1] * k * k * k * k * k + poly[2] * k * k * k * k
            + poly[3] * k * k * k + poly[4] * k * k + poly[5] * k + poly[6] + 3.4 - 10 * k)


def main_c_pixel(a, b, pulses, pixel, ambient, fw):
    """One read-out of one pixel: the distance main.c writes [cm] (0: none)."""
    ambient_coef = ambient * pulses
    top = b - ambient_coef
    bot = fw["sensitivity_ratio"] * a - ambient_coef
    if pixel == fw["compensated_pixel"]:
        bot *= fw["compensated_pixel_factor"]
    if bot > 2500 or bot < 0:
        return 0.0
    if bot + top > 100 + 0.4 * pulses:
        k = top / (bot + top)
        dist = polynomial_cm(fw["poly"], k)
    else:
        dist = 0.0
    return dist if dist > 0 else 0.0


def main_c_cycle(readouts, ambient, fw):
    """The distance words (0.1 mm) one accumulation cycle leaves to send.

    readouts: [{"pulses": p, "a": [discharge counts], "b": [...]}, ...] in
    pulse order; ambient: counts per pulse; fw: the profile's constants
    (sensitivity_ratio, compensated_pixel, compensated_pixel_factor,
    saturation_counts, poly, copies)."""
    words = [0] * PIXELS  # the cycle starts from cleared data
    for r in readouts:
        for i in range(PIXELS):
            a, b = r["a"][i], r["b"][i]
            if a >= fw["saturation_counts"] or b >= fw["saturation_counts"]:
                continue  # saturated: keeps what an earlier read-out wrote
            dist = main_c_pixel(a, b, r["pulses"], i, ambient, fw)
            words[i] = min(int(dist * 100), 0xFFFF)
    for dst, src in fw["copies"]:
        words[dst] = words[src]
    return words
