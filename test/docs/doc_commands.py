#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Runs every ```sh and ```console block of README.md and docs/*.md as printed.

usage: doc_commands.py SOURCE_DIR BUILD_DIR WORK_DIR [FILTER]

A ```sh block is a script; in a ```console block the commands are the lines
that start with "$ " (and their backslash continuations), the rest is their
output, shown, not compared. A block runs with bash (-e -o pipefail) in a scratch folder that looks like a
fresh build's root (every entry of the source root linked, `build` the build
folder), with build/tools on PATH as after `cmake --install`. The comment on
the line just before the fence says when a block cannot run as printed:

  <!-- doc-test: hardware -->  needs the sensor, a ROS 2 install or another
                               machine: only checked to be valid bash.
  <!-- doc-test: long -->      a long evaluation, a build or a command that runs
                               until Ctrl-C: each tinyline program in it (build/...
                               or tinyline) runs with TINYLINE_CHECK_OPTIONS=1 (it
                               parses and checks its options, then stops), a
                               benchmark lists its benchmarks, a Python script
                               compiles; the rest is checked as bash.
  <!-- doc-test: fails -->     shows a command refusing: it must exit non-zero.

Every fence must name its language (```sh, ```text, ```yaml, ...), so a
command cannot hide in a block this test does not see. FILTER (a substring of
"file:line") runs only the matching blocks.
"""
import os
import re
import shlex
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

MARKER = re.compile(r"^\s*<!--\s*doc-test:\s*(hardware|long|fails)\b.*-->\s*$")
FENCE = re.compile(r"^(\s*)```(\S*)\s*$")
BLOCK_TIMEOUT_S = 600
# Parses a Python script without running it or writing bytecode beside it.
PARSE_PY = "python3 -c 'import ast, sys; ast.parse(open(sys.argv[1]).read())'"


@dataclass
class Block:
    where: str  # file:line of the opening fence
    mode: str  # run, hardware or long
    text: str


def blocks_of(path: Path, rel: str):
    """The fenced blocks of one Markdown file; unnamed fences are errors."""
    lines = path.read_text().split("\n")
    errors, found, i = [], [], 0
    while i < len(lines):
        m = FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        indent = len(m.group(1))
        end = next((j for j in range(i + 1, len(lines)) if lines[j].strip().startswith("```")), len(lines))
        where = f"{rel}:{i + 1}"
        lang = m.group(2)
        if not lang:
            errors.append(f"{where}: a fence without a language (```sh runs in this test; ```text for output)")
        elif lang in ("sh", "console"):
            prev = next((lines[k] for k in range(i - 1, -1, -1) if lines[k].strip()), "")
            mark = MARKER.match(prev)
            body = [line[indent:] for line in lines[i + 1 : end]]
            text = "\n".join(body if lang == "sh" else console_commands(body)) + "\n"
            found.append(Block(where, mark.group(1) if mark else "run", text))
        i = end + 1
    return found, errors


def console_commands(lines):
    """The commands of a console transcript: "$ " lines and their continuations."""
    out, more = [], False
    for line in lines:
        if line.startswith("$ ") or more:
            out.append(line[2:] if line.startswith("$ ") and not more else line)
            more = line.endswith("\\")
    return out


def scratch_root(source: Path, build: Path, work: Path) -> Path:
    """A folder like a fresh build's root, where files the commands write land."""
    root = work / "root"
    root.mkdir(parents=True)
    for entry in source.iterdir():
        if entry.name != "build":
            (root / entry.name).symlink_to(entry)
    (root / "build").symlink_to(build)
    return root


def logical_lines(text: str):
    """Command lines with their backslash continuations joined, comments and blanks dropped."""
    out, cur = [], ""
    for line in text.split("\n"):
        cur += line
        if cur.endswith("\\"):
            cur = cur[:-1] + " "
            continue
        if cur.strip() and not cur.strip().startswith("#"):
            out.append(cur.strip())
        cur = ""
    return out


def strip_prefixes(words):
    """The command under nice, taskset and VAR=value prefixes; output redirections dropped."""
    while words:
        if re.match(r"^[A-Z_][A-Z0-9_]*=", words[0]):
            words = words[1:]
        elif words[0] == "nice" and len(words) > 2 and words[1] == "-n":
            words = words[3:]
        elif words[0] == "taskset" and len(words) > 2 and words[1] == "-c":
            words = words[3:]
        else:
            break
    cut = next((i for i, w in enumerate(words) if w in ("|", "&&", ";", ">", "2>", ">>") or w.startswith(">")), None)
    return words[:cut]


def quoted(word: str) -> str:
    """A word for bash again; one that uses a variable ($PWD) keeps it."""
    return f'"{word}"' if "$" in word and '"' not in word else shlex.quote(word)


def long_block_script(text: str) -> str:
    """The script that checks a long block: programs parse options, scripts compile."""
    steps = []
    for line in logical_lines(text):
        words = shlex.split(line, comments=True)
        if not words:
            continue
        words = strip_prefixes(words)
        prog = words[0] if words else ""
        command = " ".join(quoted(w) for w in words)
        if prog.startswith("build/bench/") and prog.endswith("_bench"):
            steps.append(f"{command} --benchmark_list_tests=true >/dev/null")
        elif prog.startswith("build/") or prog == "tinyline":
            steps.append(f"TINYLINE_CHECK_OPTIONS=1 {command}")
        elif prog.endswith("python") and len(words) > 1 and words[1].endswith(".py"):
            steps.append(f"test -x {shlex.quote(prog)} && {PARSE_PY} {shlex.quote(words[1])}")
        elif prog.endswith(".py"):
            steps.append(f"test -x {shlex.quote(prog)} && {PARSE_PY} {shlex.quote(prog)}")
    return "\n".join(steps) + "\n"


def builds(text: str) -> bool:
    """A block that configures or builds: run here it would rebuild the build under test."""
    return any(shlex.split(line, comments=True)[:1] in (["make"], ["cmake"]) for line in logical_lines(text))


def run_block(block: Block, root: Path, env: dict) -> tuple[bool, str]:
    syntax = subprocess.run(["bash", "-n"], input=block.text, text=True, capture_output=True)
    if syntax.returncode != 0:
        return False, "not valid bash:\n" + syntax.stderr
    if block.mode == "run" and builds(block.text):
        return False, "builds (make, cmake): mark it <!-- doc-test: long -->"
    if block.mode == "hardware":
        return True, "checked as bash (needs hardware)"
    script = long_block_script(block.text) if block.mode == "long" else block.text
    try:
        r = subprocess.run(["bash", "-e", "-o", "pipefail", "-c", script], cwd=root, env=env, text=True,
                           capture_output=True, timeout=BLOCK_TIMEOUT_S, stdin=subprocess.DEVNULL)
    except subprocess.TimeoutExpired:
        return False, f"still running after {BLOCK_TIMEOUT_S} s"
    tail = (r.stdout[-1500:] + r.stderr[-1500:]).strip()
    if block.mode == "fails":
        refused = r.returncode not in (0, 126, 127)  # 126, 127: not runnable, not found
        return refused, f"refused as shown (exit {r.returncode})" if refused else f"exit {r.returncode}\n{tail}"
    return r.returncode == 0, f"exit {r.returncode}\n{tail}" if r.returncode else "ok"


def main() -> int:
    source, build, work = (Path(a).resolve() for a in sys.argv[1:4])
    only = sys.argv[4] if len(sys.argv) > 4 else ""
    blocks, errors = [], []
    for md in [source / "README.md"] + sorted((source / "docs").glob("*.md")):
        found, errs = blocks_of(md, str(md.relative_to(source)))
        blocks += [b for b in found if only in b.where]
        errors += errs
    work.mkdir(parents=True, exist_ok=True)
    env = dict(os.environ, PATH=f"{build / 'tools'}:{os.environ['PATH']}")
    env.pop("TINYLINE_CHECK_OPTIONS", None)
    with tempfile.TemporaryDirectory(dir=work) as tmp:
        root = scratch_root(source, build, Path(tmp))
        for b in blocks:
            t0 = time.monotonic()
            ok, what = run_block(b, root, env)
            print(f"{'ok  ' if ok else 'FAIL'} {b.where} [{b.mode}] {time.monotonic() - t0:.1f} s: {what}", flush=True)
            if not ok:
                errors.append(b.where)
    print(f"{len(blocks)} sh block(s); {len(errors)} problem(s)")
    for e in errors:
        print("  " + e)
    return 1 if errors else 0


if __name__ == "__main__":
    sys.exit(main())
