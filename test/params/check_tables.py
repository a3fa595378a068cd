# SPDX-License-Identifier: Apache-2.0
"""Every field of every core settings struct has a parameter.

A package describes its settings once, in `param_tables.hpp` next to its core
headers: one `for_each_param` table per struct. This check reads the sources:
each `struct ...Params` of a package that has tables must have a table, and
each table must show every field of its struct (`p.<field>`); a field added
to a struct without a parameter fails here. `--self-test` shows that it does.

    python3 check_tables.py ROOT
"""
import pathlib
import re
import sys
import tempfile

# Settings structs of a core that no node declares, and why.
NOT_NODE_SETTINGS = {
    "DepthCorrectionParams": "tomato_reasoning's camera calibration tool, not a node",
    "HandToHeadParams": "tomato_reasoning's camera calibration tool, not a node",
    "RectangleFitParams": "hydrus_fitting's rectangle fit, used by no node",
    "CutProbeParams": "the harvest evaluation's nearby cuts (tomato_eval --harvest-set probe_*), used by no node",
    "PedicelSearchParams": "the tomato verification's pedicel search (tomato_eval --verify-set sweep_*), used by no node",
}

TABLE = re.compile(r"SettingsOf<S,\s*(\w+)>\s*void for_each_param\(S& p, V&& v\) \{(.*?)\n\}", re.S)
STRUCT = re.compile(r"^struct (\w+) \{(.*?)^\};", re.S | re.M)


def strip_comments(text):
    text = re.sub(r"/\*.*?\*/", "", text, flags=re.S)
    return re.sub(r"//[^\n]*", "", text)


def drop_nested_blocks(body):
    """The struct's own declarations: nested types and function bodies removed."""
    out, depth, i = [], 0, 0
    # Nested type definitions (enum class X { ... };, struct X { ... };) go whole.
    body = re.sub(r"\b(enum(\s+class)?|struct|class)\s+\w+(\s*:\s*\w+)?\s*\{[^{}]*\};", "", body)
    while i < len(body):
        c = body[i]
        if c == "{":
            depth += 1
            out.append("{}" if depth == 1 else "")
        elif c == "}":
            depth -= 1
        elif depth == 0:
            out.append(c)
        i += 1
    return "".join(out)


def fields(body):
    names = []
    for decl in drop_nested_blocks(strip_comments(body)).split(";"):
        decl = decl.strip()
        if not decl or decl.startswith(("static", "using", "friend", "template", "enum", "public", "private")):
            continue
        head = re.split(r"=|\{\}", decl)[0].strip()
        if "(" in head:  # a member function
            continue
        m = re.search(r"(\w+)\s*(\[[^\]]*\])?$", head)
        if m:
            names.append(m.group(1))
    return names


def check(root):
    root = pathlib.Path(root)
    problems, checked = [], 0
    for tables in sorted(root.glob("**/include/**/param_tables.hpp")):
        if "build" in tables.relative_to(root).parts[0]:
            continue
        include = next(p for p in tables.parents if p.name == "include")
        structs = {}
        for h in include.rglob("*.hpp"):
            for m in STRUCT.finditer(h.read_text()):
                structs[m.group(1)] = (h, m.group(2))
        bodies = {m.group(1): m.group(2) for m in TABLE.finditer(tables.read_text())}
        for name in sorted(structs):
            if name.endswith("Params") and name not in bodies and name not in NOT_NODE_SETTINGS:
                problems.append(f"{structs[name][0].relative_to(root)}: {name} has no parameter table in "
                                f"{tables.relative_to(root)}")
        for name, body in sorted(bodies.items()):
            if name not in structs:
                problems.append(f"{tables.relative_to(root)}: table of {name}, a struct not found under {include}")
                continue
            for f in fields(structs[name][1]):
                checked += 1
                if not re.search(rf"\bp\.{f}\b", body):
                    problems.append(f"{structs[name][0].relative_to(root)}: {name}::{f} has no parameter "
                                    f"(add it to {name}'s table in {tables.relative_to(root)})")
    return problems, checked


def self_test():
    with tempfile.TemporaryDirectory() as d:
        inc = pathlib.Path(d, "pkg", "include", "pkg")
        inc.mkdir(parents=True)
        (inc / "a.hpp").write_text(
            "struct AParams {\n  /// radius [m]\n  double eps = 0.1;\n  int n{3};\n"
            "  enum class M { kX, kY };\n  M m = M::kX;\n  bool ok() const { return true; }\n};\n"
            "struct BParams {\n  double x = 1;\n};\n")
        (inc / "param_tables.hpp").write_text(
            "template <class S, class V>\n  requires common::SettingsOf<S, AParams>\n"
            "void for_each_param(S& p, V&& v) {\n  v(p.eps, {});\n  v(p.m, {}, kM);\n}\n")
        problems, _ = check(d)
        want = ["AParams::n has no parameter", "BParams has no parameter table"]
        for w in want:
            if not any(w in p for p in problems):
                print(f"self-test: the check missed '{w}' in {problems}")
                return 1
        if len(problems) != len(want):
            print(f"self-test: unexpected findings {problems}")
            return 1
    print("self-test: a missing field and a missing table are found")
    return 0


def main():
    if sys.argv[1] == "--self-test":
        return self_test()
    problems, checked = check(sys.argv[1])
    for p in problems:
        print(p)
    print(f"{checked} settings fields checked, {len(problems)} problem(s)")
    return 1 if problems or checked == 0 else 0


if __name__ == "__main__":
    sys.exit(main())
