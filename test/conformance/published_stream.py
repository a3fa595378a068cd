# SPDX-License-Identifier: Apache-2.0
"""A byte stream laid out exactly as the published firmware sends it, for the
driver's conformance test (written from the firmware's Src/main.c and
Src/itcallback.cpp, not from tinyline's encoder):

  * the frame buffer is 274 little-endian uint16 words: 0xA1A2 (bytes A2 A1),
    272 distances in 0.1 mm ((uint16)(cm * 100), so 3.28-6.55 m are values
    above 32767), 0x2B2A (bytes 2A 2B);
  * a circular DMA sends it back to back at the link rate (2 Mbaud, 8N1:
    548 bytes in 2.74 ms, so about 36.5 frames per 100.1 ms cycle), while
    the buffer is rewritten once per cycle, in the middle of a frame: that
    frame goes out with its start old and its end new;
  * before sending, pixel 176 takes pixel 175's value and pixel 16 pixel 17's;
  * the reader joins mid-frame.

The scene: a wall at about 0.8 m with an opening onto a far wall at 4.2 m
(pixels 180-229, values above 32767), noise of a few mm per cycle, the dark
pixels (0-7, 264-271) at 0, and one stuck pixel whose value never changes.

usage: published_stream.py OUTDIR [CYCLES] [SEED]
writes OUTDIR/stream.bin and OUTDIR/expected.json
"""

import json
import math
import os
import random
import sys

PIXELS = 272
BAUD = 2_000_000
FRAME = 548
CYCLE_S = 1001 * 100e-6
STUCK = 120


def true_range_m(p):
    if 180 <= p < 230:
        return 4.2 / math.cos(math.radians((p - 135.5) * 0.13))
    return 0.8 / math.cos(math.radians((p - 135.5) * 0.13))


def cycle_words(rng, stuck_value):
    words = [0] * PIXELS
    for p in range(8, 264):
        cm = 100 * true_range_m(p) + rng.gauss(0.0, 0.3)
        words[p] = min(int(cm * 100), 0xFFFF)
    words[STUCK] = stuck_value
    words[176] = words[175]
    words[16] = words[17]
    return words


def frame_bytes(words):
    out = bytearray([0xA2, 0xA1])
    for w in words:
        out += w.to_bytes(2, "little")
    out += bytes([0x2A, 0x2B])
    return bytes(out)


def main():
    outdir = sys.argv[1]
    cycles = int(sys.argv[2]) if len(sys.argv) > 2 else 26
    rng = random.Random(int(sys.argv[3]) if len(sys.argv) > 3 else 7)
    os.makedirs(outdir, exist_ok=True)
    contents = [cycle_words(rng, 8123) for _ in range(cycles)]
    frames = [frame_bytes(w) for w in contents]
    # Byte n of the stream is byte n % 548 of the buffer as it is when the
    # DMA sends it; the buffer takes content c from byte c * bytes_per_cycle on.
    per_cycle = CYCLE_S * BAUD / 10
    total = int(cycles * per_cycle)
    stream = bytearray()
    for start in range(0, total - FRAME + 1, FRAME):
        c0 = min(int(start / per_cycle), cycles - 1)
        c1 = min(int((start + FRAME - 1) / per_cycle), cycles - 1)
        if c0 == c1:
            stream += frames[c0]
        else:  # rewritten while this frame was going out
            cut = math.ceil(c1 * per_cycle) - start
            stream += frames[c0][:cut] + frames[c1][cut:]
    join = 200  # the reader opens the port mid-frame
    expected = {"unit_m": 1e-4, "baud": BAUD, "frame_bytes": FRAME, "stuck_pixel": STUCK, "cycles": []}
    for c, words in enumerate(contents):
        first_start = math.ceil(c * per_cycle / FRAME) * FRAME  # the first frame wholly of this content
        if first_start < join:
            first_start += FRAME  # the reader missed the start of that one
        expected["cycles"].append({"words": words, "first_frame_end": first_start + FRAME - join})
    with open(os.path.join(outdir, "stream.bin"), "wb") as f:
        f.write(stream[join:])
    with open(os.path.join(outdir, "expected.json"), "w") as f:
        json.dump(expected, f)


if __name__ == "__main__":
    main()
