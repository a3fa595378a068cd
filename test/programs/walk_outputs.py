#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Walks every output option of every program (test/programs/outputs.txt).

Each option gets, as its destination, a symbolic link, a device (a null
device of its own when run as root, else /dev/null),
a FIFO, an existing "<name>.part" and one of the command's own inputs. Each
run must exit non-zero within its time limit (a FIFO opened for writing would
hang), name the destination in its output, and leave the scratch folder (and
the device) exactly as it was. The programs' --help is read too: an option
that reads as an output and is not listed fails (--check-list).

  walk_outputs.py --source DIR --work DIR [--only TARGET] NAME=PROGRAM ...
"""
import argparse
import hashlib
import os
import re
import shutil
import stat
import struct
import subprocess
import sys
import zlib

TIMEOUT_S = 60
CASES = ("symlink", "device", "fifo", "part", "input")


# ------------------------------------------------------------------ the list
class Entry:
    def __init__(self, target, key, kind, source, args, line):
        self.target, self.key, self.kind, self.source, self.args, self.line = target, key, kind, source, args, line

    def __str__(self):
        return f"{self.target} {self.key}"


def read_list(path):
    entries, ignored = [], set()
    with open(path, encoding="utf-8") as f:
        for number, raw in enumerate(f, 1):
            line = raw.strip()
            if not line or line.startswith("#"):
                continue
            fields = [x.strip() for x in line.split("|")]
            if fields[0] == "ignore":
                ignored.add((fields[1], fields[2]))
                continue
            if len(fields) != 5:
                sys.exit(f"{path}:{number}: expected TARGET | KEY | KIND | IN | ARGUMENTS")
            entries.append(Entry(*fields, number))
    return entries, ignored


# ----------------------------------------------------------------- the inputs
def png_bytes(width, height, channels, bits, pixel):
    """A PNG of one colour (stdlib only): `pixel` is the bytes of one pixel."""
    colour_type = {1: 0, 3: 2}[channels]
    raw = b"".join(b"\0" + pixel * width for _ in range(height))

    def chunk(kind, data):
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, bits, colour_type, 0, 0, 0)
    return b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b"")


def make_frames(folder):
    os.makedirs(os.path.join(folder, "rgb"))
    os.makedirs(os.path.join(folder, "depth"))
    with open(os.path.join(folder, "intrinsics.yaml"), "w", encoding="utf-8") as f:
        f.write("width: 8\nheight: 6\nfx: 10\nfy: 10\ncx: 3.5\ncy: 2.5\n")
    with open(os.path.join(folder, "rgb", "f0.png"), "wb") as f:
        f.write(png_bytes(8, 6, 3, 8, b"\x20\xa0\x20"))
    with open(os.path.join(folder, "depth", "f0.png"), "wb") as f:
        f.write(png_bytes(8, 6, 1, 16, struct.pack(">H", 800)))


class Inputs:
    """Makes the inputs the list names, once, in `work`/inputs."""

    def __init__(self, source, work, programs):
        self.source, self.dir, self.programs, self.made = source, os.path.join(work, "inputs"), programs, {}
        shutil.rmtree(self.dir, ignore_errors=True)
        os.makedirs(self.dir)

    def get(self, spec):
        if spec not in self.made:
            self.made[spec] = self.make(spec)
        return self.made[spec]

    def make(self, spec):
        if spec.startswith("src:"):
            return os.path.join(self.source, spec[4:])
        out = os.path.join(self.dir, spec)
        if spec == "bag":
            out += ".mcap"
            run([self.programs["tinyline"], "bag", "record", "-o", out, "--launch",
                 os.path.join(self.source, "launch/demo.launch.yaml"), "rate_hz:=50", "--duration", "0.3"], self.dir)
        elif spec == "csv":
            out += ".csv"
            run([self.programs["calibration_synthetic_rail"], "-o", out], self.dir)
        elif spec == "frames":
            make_frames(out)
        else:
            sys.exit(f"unknown input '{spec}'")
        return out


def run(argv, cwd):
    r = subprocess.run(argv, cwd=cwd, stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=TIMEOUT_S)
    if r.returncode != 0:
        sys.exit(f"making an input failed: {' '.join(argv)}\n{r.stdout}{r.stderr}")


# ------------------------------------------------------------ one case's disk
def snapshot(root):
    """Every path under `root` with its kind and content (or link target)."""
    seen = {}
    for folder, dirs, files in os.walk(root):
        for name in dirs + files:
            p = os.path.join(folder, name)
            st = os.lstat(p)
            if stat.S_ISLNK(st.st_mode):
                seen[p] = ("link", os.readlink(p))
            elif stat.S_ISREG(st.st_mode):
                with open(p, "rb") as f:
                    seen[p] = ("file", hashlib.sha256(f.read()).hexdigest())
            else:
                seen[p] = (stat.S_IFMT(st.st_mode), st.st_rdev)
    return seen


def changes(before, after):
    out = [f"removed or changed: {p}" for p in before if after.get(p) != before[p]]
    return out + [f"created: {p}" for p in after if p not in before]


def copy_input(path, scratch):
    """The input, copied into the scratch folder (a folder whole). A file keeps
    its neighbours, as links: a scene names its sensor as ../sensors/x.yaml,
    a sensor its base file beside it."""
    if os.path.isdir(path):
        dest = os.path.join(scratch, "in_" + os.path.basename(path))
        shutil.copytree(path, dest, symlinks=True)
        return dest
    folder = os.path.dirname(path)
    dest_folder = os.path.join(scratch, "in_" + os.path.basename(folder))
    os.makedirs(dest_folder)
    for name in os.listdir(folder):
        if name != os.path.basename(path):
            os.symlink(os.path.join(folder, name), os.path.join(dest_folder, name))
    above = os.path.dirname(folder)
    for name in os.listdir(above):
        if name != os.path.basename(folder) and os.path.isdir(os.path.join(above, name)):
            os.symlink(os.path.join(above, name), os.path.join(scratch, name))
    dest = os.path.join(dest_folder, os.path.basename(path))
    shutil.copyfile(path, dest)
    return dest


def null_device(scratch):
    """A null device of the case's own: a program that replaces or removes its
    destination (as `sim serve --link /dev/null` did) must not take the
    machine's /dev/null with it. Only root may make one, and only root could
    replace /dev/null: anyone else gets /dev/null itself."""
    path = os.path.join(scratch, "null_device")
    try:
        os.mknod(path, 0o666 | stat.S_IFCHR, os.makedev(1, 3))
        return path
    except PermissionError:
        return "/dev/null"


def destination(case, entry, scratch, given_input):
    """Sets the case up; returns (OUT for the command line, the path a refusal must name) or None (no such case)."""
    kind = entry.kind
    if case == "device":
        device = null_device(scratch)
        return device, device
    if kind.startswith("dir:"):
        if case == "input":
            if given_input is None:
                return None
            target = os.path.join(given_input, "depth") if os.path.isdir(given_input) else given_input
            return target, target
        out = os.path.join(scratch, "out")
        os.makedirs(out)
        return out, place(case, os.path.join(out, kind[4:]), scratch)
    path = os.path.join(scratch, "out.dat")
    if case == "input":
        return (given_input, given_input) if given_input is not None else None
    if case == "part" and kind == "link":
        return None  # a link is made by symlink(2), with no temporary name
    return path, place(case, path, scratch)


def place(case, path, scratch):
    """Puts the case's thing at `path`; returns the path the message must name."""
    os.makedirs(os.path.dirname(path), exist_ok=True)  # a file a program writes into a folder of its own
    if case == "symlink":
        target = os.path.join(scratch, "link_target")
        with open(target, "w", encoding="utf-8") as f:
            f.write("the user's file\n")
        os.symlink(target, path)
        return path
    if case == "fifo":
        os.mkfifo(path)
        return path
    if case == "part":
        with open(path + ".part", "w", encoding="utf-8") as f:
            f.write("a crashed run's partial output, the user's to recover\n")
        return path + ".part"
    raise AssertionError(case)


def null_state():
    try:
        st = os.lstat("/dev/null")
    except FileNotFoundError:
        return None
    return stat.S_IFMT(st.st_mode), st.st_rdev


def walk_case(case, entry, program, inputs, work):
    scratch = os.path.join(work, "cases", f"{entry.target}_{entry.line}_{case}")
    shutil.rmtree(scratch, ignore_errors=True)
    os.makedirs(scratch)
    given_input = None if entry.source == "-" else copy_input(inputs.get(entry.source), scratch)
    dest = destination(case, entry, scratch, given_input)
    if dest is None:
        shutil.rmtree(scratch)
        return "skip"
    out, named = dest
    argv = [program] + [out if a == "OUT" else given_input if a == "IN" else a for a in entry.args.split()]
    before = snapshot(scratch)
    null_before = null_state()
    try:
        r = subprocess.run(argv, cwd=scratch, stdin=subprocess.DEVNULL, capture_output=True, text=True,
                           timeout=TIMEOUT_S)
    except subprocess.TimeoutExpired:
        return f"{entry} ({case}): still running after {TIMEOUT_S} s: {' '.join(argv)}"
    problems = []
    said = r.stdout + r.stderr
    if r.returncode == 0:
        problems.append("exit code 0")
    if r.returncode < 0:
        problems.append(f"killed by signal {-r.returncode}")
    if named not in said:
        problems.append(f"the message does not name {named}")
    problems += changes(before, snapshot(scratch))
    if null_state() != null_before:
        problems.append("/dev/null is no longer the null device")
    if not problems:
        shutil.rmtree(scratch)
        return None
    return f"{entry} ({case}): {'; '.join(problems)}\n  $ {' '.join(argv)}\n  " + said.strip().replace("\n", "\n  ")


# ------------------------------------------------------- the list's coverage
OUTPUT_WORDS = re.compile(r"\b(write|writes|written|output|outputs|directory to write|report|symlink|stdout)\b",
                          re.IGNORECASE)


def help_of(program, words):
    r = subprocess.run([program] + words + ["--help"], stdin=subprocess.DEVNULL, capture_output=True, text=True,
                       timeout=TIMEOUT_S)
    return r.stdout + r.stderr


def subcommands(text):
    block = text.split("Subcommands:", 1)
    if len(block) < 2:
        return []
    return re.findall(r"^  (\w[\w-]*)\s", block[1], re.MULTILINE)


def output_options(program, words=()):
    """(key, help line) of the options of `program words...` whose help reads as an output."""
    text = help_of(program, list(words))
    found = []
    prefix = " ".join(words) + " " if words else ""
    lines = text.split("Subcommands:", 1)[0].splitlines()
    for i, line in enumerate(lines):
        m = re.match(r"^\s+((?:-\w|--[\w-]+)(?:,--?[\w-]+)*|[A-Za-z][A-Za-z_]*)\s+([A-Z][A-Z_]*(?:[:=]\S*)?)(?=\s|$)\s*(.*)$", line)
        if not m:
            continue
        described = m.group(3) or (lines[i + 1].strip() if i + 1 < len(lines) else "")  # a long default wraps
        if OUTPUT_WORDS.search(described):
            found.append((prefix + m.group(1).split(",")[-1], line.strip()))
    for sub in subcommands(text):
        found += output_options(program, list(words) + [sub])
    return found


def check_list(entries, ignored, programs):
    listed = {(e.target, e.key) for e in entries} | ignored
    missing = []
    for target, program in programs.items():
        options = output_options(program)
        for key, line in options:
            if (target, key) not in listed:
                missing.append(f"{target}: '{key}' reads as an output ({line}): add it to outputs.txt")
    for e in entries:
        if e.target in programs and not any(k == e.key for k, _ in output_options_cached(e.target, programs)):
            missing.append(f"{e}: listed, but its --help has no such output option (outputs.txt:{e.line})")
    return missing


_cache = {}


def output_options_cached(target, programs):
    if target not in _cache:
        _cache[target] = output_options(programs[target])
    return _cache[target]


# ----------------------------------------------------------------------- main
def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--source", required=True)
    ap.add_argument("--work", required=True)
    ap.add_argument("--list", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), "outputs.txt"))
    ap.add_argument("--only", help="walk only this target's options")
    ap.add_argument("--check-list", action="store_true", help="only check the list against the programs' --help")
    ap.add_argument("programs", nargs="*", metavar="NAME=PROGRAM")
    a = ap.parse_args()
    programs = {k: os.path.abspath(v) for k, v in (p.split("=", 1) for p in a.programs)}
    a.source, a.work = os.path.abspath(a.source), os.path.abspath(a.work)
    entries, ignored = read_list(a.list)
    if a.check_list:
        problems = check_list(entries, ignored, programs)
    else:
        os.makedirs(a.work, exist_ok=True)
        inputs = Inputs(a.source, a.work, programs)
        problems, walked, options = [], 0, 0
        for e in entries:
            if e.target not in programs or (a.only and e.target != a.only):
                continue
            options += 1
            for case in CASES:
                p = walk_case(case, e, programs[e.target], inputs, a.work)
                walked += p != "skip"
                if p and p != "skip":
                    problems.append(p)
        print(f"walked {walked} cases of {options} output options ({len(entries)} listed)")
    for p in problems:
        print("FAIL " + p)
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
