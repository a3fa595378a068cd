# SPDX-License-Identifier: Apache-2.0
"""Conformance of `tinyline sim serve` with the sensor's public code.

Runs `tinyline sim serve SCENE --link L --truth T [--firmware F]` as a
subprocess, opens the pty the way any serial program does, and reads it with
the public driver's state machine re-implemented in public_driver.py (not
with tinyline's parser). Then it unplugs and replugs the device with SIGUSR1
and stops it with SIGTERM. It checks:

  * no frame is rejected once the reader is in sync, and the stream is the
    kind the public driver expects of that firmware;
  * every frame's values equal the ground truth the simulator wrote (raw:
    index word, packed word, both capacitors; published: the 272 distance
    words, or a tear between two consecutive buffer contents);
  * published: every buffer content equals what the firmware's main.c
    computes from the cycle's read-outs (re-implemented from reading it);
  * unplug removes the link and ends the open port's stream, replug brings
    both back, SIGTERM stops the server cleanly (exit 0, link removed).

usage: serve_check.py TINYLINE SCENE WORKDIR [published|thesis_raw|scene]
"""

import json
import os
import select
import signal
import subprocess
import sys
import termios
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from public_driver import PublicDriverReader, main_c_cycle  # noqa: E402


def fail(msg):
    print("FAIL:", msg)
    sys.exit(1)


def wait_for(pred, seconds, what):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        if pred():
            return
        time.sleep(0.02)
    fail("timed out waiting for " + what)


def open_port(path):
    fd = os.open(path, os.O_RDWR | os.O_NOCTTY | os.O_NONBLOCK)
    attrs = termios.tcgetattr(fd)
    attrs[0] = attrs[1] = attrs[3] = 0  # raw: no input, output or local processing
    attrs[2] = termios.CS8 | termios.CREAD | termios.CLOCAL
    attrs[4] = attrs[5] = termios.B2000000
    termios.tcsetattr(fd, termios.TCSANOW, attrs)
    return fd


def read_until(fd, reader, done, seconds):
    """Feeds the reader until done() or the deadline; False when the port ended (unplugged)."""
    end = time.monotonic() + seconds
    while not done() and time.monotonic() < end:
        r, _, _ = select.select([fd], [], [], 0.05)
        if not r:
            continue
        try:
            data = os.read(fd, 65536)
        except OSError:
            return False  # EIO: the device went away
        if not data:
            return False
        reader.feed(data)
    return True


def check_raw(frames, truth):
    by_key = {}
    for t in truth:
        if t["kind"] == "raw":
            by_key[(t["index_word"], t["packed"], tuple(t["a"]), tuple(t["b"]))] = t["seq"]
    last_seq = -1
    for f in frames:
        packed = f["temperature_decic"] * 100 + f["pulses"] // 10
        seq = by_key.get((f["index_word"], packed, tuple(f["a"]), tuple(f["b"])))
        if seq is None:
            fail("a raw frame the simulator never made (index word %d)" % f["index_word"])
        if seq <= last_seq:
            fail("raw frames out of order")
        last_seq = seq
    lasts = [f for f in frames if f["last"]]
    if not lasts or any(f["index_word"] <= 100 for f in lasts):
        fail("no frame the public driver reads as a set's last")
    return len(frames)


def torn_between(frame, before, after):
    fb = b"".join(v.to_bytes(2, "little") for v in frame)
    bb = b"".join(v.to_bytes(2, "little") for v in before)
    ab = b"".join(v.to_bytes(2, "little") for v in after)
    prefix = 0
    while prefix < len(fb) and fb[prefix] == bb[prefix]:
        prefix += 1
    suffix = 0
    while suffix < len(fb) and fb[-1 - suffix] == ab[-1 - suffix]:
        suffix += 1
    return prefix + suffix >= len(fb)


def check_published(frames, truth):
    cycles = [t for t in truth if t["kind"] == "published"]
    if len(cycles) < 3:
        fail("only %d buffer updates in the truth" % len(cycles))
    for c in cycles:
        fw = dict(c["firmware"])
        want = main_c_cycle(c["readouts"], c["ambient"], fw)
        if want != c["distance"]:
            bad = [i for i in range(len(want)) if want[i] != c["distance"][i]]
            fail("cycle %d: the simulator's words differ from main.c's at pixels %s" % (c["seq"], bad[:10]))
    contents = [tuple(c["distance"]) for c in cycles]
    index = {content: i for i, content in enumerate(contents)}
    torn = 0
    for f in frames:
        d = tuple(f["distance"])
        if d in index:
            continue
        if any(torn_between(d, contents[i - 1], contents[i]) for i in range(1, len(contents))):
            torn += 1
            continue
        fail("a distance frame that is neither a buffer content nor a tear between two")
    distinct = len({tuple(f["distance"]) for f in frames})
    if distinct < 2 or len(frames) < 5 * distinct:
        fail("expected the buffer repeated many times: %d frames of %d contents" % (len(frames), distinct))
    if sum(1 for v in cycles[-1]["distance"] if v) < 100:
        fail("fewer than 100 pixels with a distance in the last cycle")
    return torn


def main():
    tinyline, scene, work = sys.argv[1:4]
    firmware = sys.argv[4] if len(sys.argv) > 4 else "scene"
    os.makedirs(work, exist_ok=True)
    link = os.path.join(work, "ttyTINY")
    truth_path = os.path.join(work, "truth.jsonl")
    cmd = [tinyline, "sim", "serve", scene, "--link", link, "--truth", truth_path]
    if firmware != "scene":
        cmd += ["--firmware", firmware]
    server = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        run(server, link, firmware)
    finally:
        if server.poll() is None:
            server.kill()
    out = server.stdout.read()
    print(out)
    if server.returncode != 0:
        fail("the server exited with %d" % server.returncode)
    if os.path.lexists(link):
        fail("the link outlived the server")
    if "firmware " + ("published" if firmware == "scene" else firmware) not in out:
        fail("the server did not say which firmware it runs")
    published = firmware in ("published", "scene")
    expect = "received 5 bytes: 1 commands (1 ignored)" if published else "received 10 bytes: 2 commands (0 ignored)"
    if expect not in out:
        fail("the status line does not show the commands the host sent (%r)" % expect)
    truth = [json.loads(line) for line in open(truth_path)]
    check(truth, firmware)


FRAMES = {}


def run(server, link, firmware):
    wait_for(lambda: os.path.islink(link), 60, "the link " + link)
    published = firmware in ("published", "scene")
    reader = PublicDriverReader(only_distance=published)
    fd = open_port(link)
    os.write(fd, bytes([0xF8, 0x02, 0x10, 0x00, 0x8F]))  # laser off: the published firmware ignores it
    if published:
        want = lambda: len({tuple(f["distance"]) for f in reader.frames}) >= 4  # noqa: E731
    else:
        want = lambda: sum(1 for f in reader.frames if f["last"]) >= 4 or (reader.frames and len(reader.frames) >= 25)  # noqa: E731
    if not published:
        os.write(fd, bytes([0xF8, 0x02, 0x10, 0x01, 0x8F]))  # and on again for the thesis firmware
    read_until(fd, reader, want, 30)
    if not want():
        fail("too few frames: %d" % len(reader.frames))
    if reader.rejected_after_sync:
        fail("%d frames rejected after the first good one" % reader.rejected_after_sync)
    # Unplug: the link goes away and the open port ends; replug: both come back.
    server.send_signal(signal.SIGUSR1)
    wait_for(lambda: not os.path.lexists(link), 10, "the link to disappear on unplug")
    if read_until(fd, reader, lambda: False, 5):
        fail("the open port kept going after the unplug")
    os.close(fd)
    server.send_signal(signal.SIGUSR1)
    wait_for(lambda: os.path.islink(link), 10, "the link to come back on replug")
    again = PublicDriverReader(only_distance=published)
    fd = open_port(link)
    read_until(fd, again, lambda: len(again.frames) >= 3, 30)
    os.close(fd)
    if len(again.frames) < 3 or again.rejected_after_sync:
        fail("after the replug: %d frames, %d rejected" % (len(again.frames), again.rejected_after_sync))
    time.sleep(1.2)  # one more status line with the command counts
    server.send_signal(signal.SIGTERM)
    server.wait(60)
    FRAMES["all"] = reader.frames + again.frames
    FRAMES["reader"] = reader


def check(truth, firmware):
    frames = FRAMES["all"]
    reader = FRAMES["reader"]
    if firmware in ("published", "scene"):
        torn = check_published(frames, truth)
        print("conformance: %d distance frames read with the public driver's state machine, 0 rejected after sync, "
              "every one a buffer content (or %d tears between two); every content equals main.c's arithmetic on "
              "its read-outs" % (len(frames), torn))
    else:
        n = check_raw(frames, truth)
        print("conformance: %d raw frames read with the public driver's state machine, 0 rejected after sync, "
              "every value equal to the ground truth" % n)
    print("(%d bytes skipped while hunting for the first header)" % reader.hunted)


if __name__ == "__main__":
    main()
