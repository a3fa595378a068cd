#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Generate C++ message types from ROS 2 .msg files.

For each `<pkg>/<Type>.msg` this writes
  include/tinyline/msg/<pkg>/<type_snake>.hpp   the struct (namespace tinyline::<pkg>::msg)
  src/<pkg>/<type_snake>.cpp                    CDR (XCDR1) write/read, YAML, type support
and one `src/type_registry.cpp` listing every type by its full name.

Standard library only: this runs at build time on a bare Debian python3.
The schema text of a type is its .msg text followed by every dependency,
each after a line of 80 '=' and 'MSG: pkg/Type', the way rosbag2 writes
`ros2msg` schemas into MCAP. The type hash is REP 2011's RIHS01: SHA-256 of
the type description (the type and every type it references, fields without
default values) written as compact JSON, as rosidl writes it for Jazzy.
"""
from __future__ import annotations

import argparse
import hashlib
import json
import os
import re
import sys
from dataclasses import dataclass, field

PRIMITIVES = {
    # ros type: (c++ type, size in bytes)
    "bool": ("bool", 1),
    "byte": ("std::uint8_t", 1),
    "char": ("std::uint8_t", 1),
    "int8": ("std::int8_t", 1),
    "uint8": ("std::uint8_t", 1),
    "int16": ("std::int16_t", 2),
    "uint16": ("std::uint16_t", 2),
    "int32": ("std::int32_t", 4),
    "uint32": ("std::uint32_t", 4),
    "int64": ("std::int64_t", 8),
    "uint64": ("std::uint64_t", 8),
    "float32": ("float", 4),
    "float64": ("double", 8),
}
CPP_KEYWORDS = {
    "alignas", "alignof", "and", "asm", "auto", "bool", "break", "case", "catch", "char",
    "class", "const", "constexpr", "continue", "default", "delete", "do", "double", "else",
    "enum", "explicit", "export", "extern", "false", "float", "for", "friend", "goto", "if",
    "inline", "int", "long", "mutable", "namespace", "new", "noexcept", "not", "nullptr",
    "operator", "or", "private", "protected", "public", "register", "return", "short",
    "signed", "sizeof", "static", "struct", "switch", "template", "this", "throw", "true",
    "try", "typedef", "typeid", "typename", "union", "unsigned", "using", "virtual", "void",
    "volatile", "while", "xor",
}

TYPE_RE = re.compile(
    r"^(?P<base>[A-Za-z][A-Za-z0-9_]*(?:/[A-Za-z][A-Za-z0-9_]*)?)"
    r"(?:<=(?P<strbound>\d+))?"
    r"(?P<array>\[(?P<arrsize><=\d+|\d+)?\])?$"
)


class MsgError(Exception):
    pass


@dataclass
class FieldType:
    base: str                 # primitive name, 'string', or 'pkg/Type'
    string_bound: int = 0     # string<=N
    is_array: bool = False
    array_size: int = 0       # fixed size N (T[N])
    seq_bound: int = 0        # bounded sequence T[<=N]

    @property
    def is_primitive(self) -> bool:
        return self.base in PRIMITIVES

    @property
    def is_string(self) -> bool:
        return self.base == "string"

    @property
    def is_message(self) -> bool:
        return not self.is_primitive and not self.is_string

    @property
    def is_fixed(self) -> bool:
        return self.is_array and self.array_size > 0

    @property
    def is_sequence(self) -> bool:
        return self.is_array and self.array_size == 0


@dataclass
class Field:
    name: str
    type: FieldType
    default: str | None
    line: int


@dataclass
class Constant:
    name: str
    type: str
    value: str


@dataclass
class Message:
    pkg: str
    name: str
    path: str
    text: str
    fields: list[Field] = field(default_factory=list)
    constants: list[Constant] = field(default_factory=list)

    @property
    def full_name(self) -> str:
        return f"{self.pkg}/msg/{self.name}"

    @property
    def snake(self) -> str:
        return snake_case(self.name)


def snake_case(name: str) -> str:
    s = re.sub(r"([a-z0-9])([A-Z])", r"\1_\2", name)
    s = re.sub(r"([A-Z]+)([A-Z][a-z])", r"\1_\2", s)
    return s.lower()


def parse_type(token: str, pkg: str, where: str) -> FieldType:
    m = TYPE_RE.match(token)
    if not m:
        raise MsgError(f"{where}: cannot parse type '{token}'")
    base = m.group("base")
    ft = FieldType(base=base)
    if m.group("strbound"):
        if base != "string":
            raise MsgError(f"{where}: only string takes a <=N bound, not '{base}'")
        ft.string_bound = int(m.group("strbound"))
    if m.group("array"):
        ft.is_array = True
        size = m.group("arrsize")
        if size:
            if size.startswith("<="):
                ft.seq_bound = int(size[2:])
            else:
                ft.array_size = int(size)
                if ft.array_size == 0:
                    raise MsgError(f"{where}: fixed array of size 0")
    if base in PRIMITIVES or base == "string":
        return ft
    if base == "wstring":
        raise MsgError(f"{where}: wstring is not supported")
    if base == "Header":
        raise MsgError(f"{where}: write std_msgs/Header, not Header (ROS 2 syntax)")
    if "/" not in base:
        ft.base = f"{pkg}/{base}"
    return ft


def parse_msg(path: str, pkg: str) -> Message:
    name = os.path.splitext(os.path.basename(path))[0]
    with open(path, encoding="utf-8") as f:
        text = f.read()
    msg = Message(pkg=pkg, name=name, path=path, text=text.rstrip("\n"))
    names = set()
    for lineno, raw in enumerate(text.splitlines(), 1):
        where = f"{path}:{lineno}"
        line = raw.split("#", 1)[0].strip() if not _hash_in_string(raw) else _strip_comment(raw)
        if not line:
            continue
        m = re.match(r"^(\S+)\s+([A-Za-z][A-Za-z0-9_]*)\s*=\s*(.+)$", line)
        if m:
            ctype, cname, value = m.groups()
            if ctype not in PRIMITIVES and ctype != "string":
                raise MsgError(f"{where}: constant '{cname}' must have a primitive or string type")
            msg.constants.append(Constant(cname, ctype, value.strip()))
            continue
        parts = line.split(None, 2)
        if len(parts) < 2:
            raise MsgError(f"{where}: expected 'type name [default]', got '{line}'")
        ftype = parse_type(parts[0], pkg, where)
        fname = parts[1]
        if not re.match(r"^[a-z][a-z0-9_]*$", fname):
            raise MsgError(f"{where}: field name '{fname}' must be lower_snake_case")
        if fname in names:
            raise MsgError(f"{where}: duplicate field '{fname}'")
        names.add(fname)
        default = parts[2].strip() if len(parts) > 2 else None
        msg.fields.append(Field(fname, ftype, default, lineno))
    return msg


def _hash_in_string(raw: str) -> bool:
    return '"' in raw or "'" in raw


def _strip_comment(raw: str) -> str:
    out, quote = [], None
    for ch in raw:
        if quote:
            out.append(ch)
            if ch == quote:
                quote = None
        elif ch in "\"'":
            quote = ch
            out.append(ch)
        elif ch == "#":
            break
        else:
            out.append(ch)
    return "".join(out).strip()


# ----------------------------------------------------------------------------- type hash (REP 2011)

# type_description_interfaces/msg/FieldType ids. A .msg `char` is an IDL
# uint8 and `byte` an octet (rosidl_adapter), hence their ids.
FIELD_TYPE_IDS = {
    "int8": 2, "uint8": 3, "int16": 4, "uint16": 5, "int32": 6, "uint32": 7,
    "int64": 8, "uint64": 9, "float32": 10, "float64": 11, "char": 3,
    "bool": 15, "byte": 16, "string": 17,
}
NESTED_TYPE_ID = 1
BOUNDED_STRING_ID = 21
# Added to the element's id for T[N], T[<=N] and T[].
ARRAY_OFFSET, BOUNDED_SEQUENCE_OFFSET, UNBOUNDED_SEQUENCE_OFFSET = 48, 96, 144


def field_type_description(ft: FieldType) -> dict:
    if ft.is_message:
        type_id = NESTED_TYPE_ID
    elif ft.is_string and ft.string_bound:
        type_id = BOUNDED_STRING_ID
    else:
        type_id = FIELD_TYPE_IDS[ft.base]
    if ft.is_fixed:
        type_id += ARRAY_OFFSET
    elif ft.is_sequence:
        type_id += BOUNDED_SEQUENCE_OFFSET if ft.seq_bound else UNBOUNDED_SEQUENCE_OFFSET
    return {
        "type_id": type_id,
        "capacity": ft.array_size or ft.seq_bound,
        "string_capacity": ft.string_bound,
        "nested_type_name": full_type_name(ft.base) if ft.is_message else "",
    }


def full_type_name(pkg_type: str) -> str:
    pkg, name = pkg_type.split("/")
    return f"{pkg}/msg/{name}"


def individual_type_description(msg: Message) -> dict:
    # rosidl gives a message without fields one uint8 member of this name.
    fields = [{"name": f.name, "type": field_type_description(f.type)} for f in msg.fields] or [
        {"name": "structure_needs_at_least_one_member", "type": field_type_description(FieldType("uint8"))}]
    return {"type_name": msg.full_name, "fields": fields}


def type_description(msg: Message, all_msgs: dict[str, Message]) -> dict:
    """The TypeDescription REP 2011 hashes: the type and every type it
    references (sorted by name), without default values."""
    refs = sorted(deps_of(msg, all_msgs), key=full_type_name)
    return {
        "type_description": individual_type_description(msg),
        "referenced_type_descriptions": [individual_type_description(all_msgs[r]) for r in refs],
    }


def type_hash(msg: Message, all_msgs: dict[str, Message]) -> str:
    text = json.dumps(type_description(msg, all_msgs), ensure_ascii=True, separators=(", ", ": "))
    return "RIHS01_" + hashlib.sha256(text.encode("utf-8")).hexdigest()


# ----------------------------------------------------------------------------- C++ emission

def cpp_ident(name: str) -> str:
    return name + "_" if name in CPP_KEYWORDS else name


def msg_cpp_type(full: str) -> str:
    pkg, name = full.split("/")
    return f"::tinyline::{pkg}::msg::{name}"


def elem_cpp_type(ft: FieldType) -> str:
    if ft.is_primitive:
        return PRIMITIVES[ft.base][0]
    if ft.is_string:
        return "std::string"
    return msg_cpp_type(ft.base)


def field_cpp_type(ft: FieldType) -> str:
    e = elem_cpp_type(ft)
    if ft.is_fixed:
        return f"std::array<{e}, {ft.array_size}>"
    if ft.is_sequence:
        return f"std::vector<{e}>"
    return e


def cpp_literal(ros_type: str, value: str, where: str) -> str:
    value = value.strip()
    if ros_type == "bool":
        v = value.lower()
        if v in ("true", "1"):
            return "true"
        if v in ("false", "0"):
            return "false"
        raise MsgError(f"{where}: bad bool literal '{value}'")
    if ros_type == "string":
        if len(value) >= 2 and value[0] == value[-1] and value[0] in "\"'":
            value = value[1:-1]
        return '"' + value.replace("\\", "\\\\").replace('"', '\\"') + '"'
    if ros_type in ("float32", "float64"):
        try:
            f = float(value)
        except ValueError:
            raise MsgError(f"{where}: bad float literal '{value}'")
        lit = repr(f)
        if "e" not in lit and "." not in lit and "inf" not in lit and "nan" not in lit:
            lit += ".0"
        return lit + ("f" if ros_type == "float32" else "")
    try:
        iv = int(value, 0)
    except ValueError:
        raise MsgError(f"{where}: bad integer literal '{value}'")
    ctype = PRIMITIVES[ros_type][0]
    if ros_type == "int64" and iv == -(2 ** 63):
        return "std::numeric_limits<std::int64_t>::min()"
    suffix = "ULL" if ros_type == "uint64" else ("LL" if ros_type == "int64" else "")
    return f"static_cast<{ctype}>({iv}{suffix})"


def default_init(f: Field, where: str) -> str:
    ft = f.type
    if f.default is None:
        if ft.is_primitive and not ft.is_array:
            return "{}"
        return ""
    if ft.is_array:
        v = f.default.strip()
        if not (v.startswith("[") and v.endswith("]")):
            raise MsgError(f"{where}: array default must be [a, b, ...]")
        items = [x for x in (s.strip() for s in v[1:-1].split(",")) if x]
        lits = [cpp_literal(ft.base, x, where) for x in items]
        if ft.is_fixed and len(lits) != ft.array_size:
            raise MsgError(f"{where}: default has {len(lits)} values, array needs {ft.array_size}")
        return "{" + ", ".join(lits) + "}"
    return "{" + cpp_literal(ft.base, f.default, where) + "}"


def deps_of(msg: Message, all_msgs: dict[str, Message]) -> list[str]:
    """Dependencies in depth-first order of first use, each once."""
    order: list[str] = []

    def visit(m: Message):
        for f in m.fields:
            if f.type.is_message:
                dep = f.type.base
                if dep not in all_msgs:
                    raise MsgError(f"{m.path}:{f.line}: unknown type '{dep}'")
                if dep not in order:
                    order.append(dep)
                    visit(all_msgs[dep])

    visit(msg)
    return order


def schema_text(msg: Message, all_msgs: dict[str, Message]) -> str:
    parts = [msg.text]
    for dep in deps_of(msg, all_msgs):
        d = all_msgs[dep]
        parts.append("=" * 80 + "\n" + f"MSG: {d.pkg}/{d.name}\n" + d.text)
    return "\n".join(parts) + "\n"


def cpp_string_literal(s: str) -> str:
    # A raw string literal keeps the schema readable in the generated source.
    delim = "tlmsg"
    assert f"){delim}\"" not in s
    return f'R"{delim}({s}){delim}"'


def header_path(full: str) -> str:
    parts = full.split("/")
    pkg, name = parts[0], parts[-1]
    return f"tinyline/msg/{pkg}/{snake_case(name)}.hpp"


def emit_header(msg: Message, all_msgs: dict[str, Message]) -> str:
    direct = []
    for f in msg.fields:
        if f.type.is_message and f.type.base not in direct:
            direct.append(f.type.base)
    includes = "\n".join(f"#include <{header_path(d)}>" for d in direct)
    lines = []
    for c in msg.constants:
        where = f"{msg.path}: constant {c.name}"
        if c.type == "string":
            lines.append(f"  static constexpr std::string_view {c.name} = {cpp_literal('string', c.value, where)};")
        else:
            lines.append(f"  static constexpr {PRIMITIVES[c.type][0]} {c.name} = {cpp_literal(c.type, c.value, where)};")
    for f in msg.fields:
        where = f"{msg.path}:{f.line}"
        lines.append(f"  {field_cpp_type(f.type)} {cpp_ident(f.name)}{default_init(f, where)};")
    body = "\n".join(lines)
    name = msg.name
    visit = "\n".join(f'  f("{f.name}", m.{cpp_ident(f.name)});' for f in msg.fields) or "  (void)m; (void)f;"
    return f"""// Generated by msg/gen/msggen.py from {msg.pkg}/msg/{name}.msg. Do not edit.
#pragma once

#include <array>
#include <cstdint>
#include <limits>
#include <string>
#include <string_view>
#include <vector>

#include <tinyline/msg/cdr.hpp>
#include <tinyline/msg/type_support.hpp>
{includes}

namespace tinyline::{msg.pkg}::msg {{

struct {name} {{
  static constexpr std::string_view kTypeName = "{msg.full_name}";
{body}

  bool operator==(const {name}&) const = default;
}};

void cdr_write(::tinyline::cdr::Writer& w, const {name}& m);
void cdr_read(::tinyline::cdr::Reader& r, {name}& m);
void yaml_write(::tinyline::msg::YamlWriter& y, const {name}& m);

/// Calls f(name, field) for every field in declaration order.
template <class F>
void for_each_field({name}& m, F&& f) {{
{visit}
}}
template <class F>
void for_each_field(const {name}& m, F&& f) {{
{visit}
}}

}}  // namespace tinyline::{msg.pkg}::msg

namespace tinyline::msg {{
template <>
const TypeSupport& type_support<::tinyline::{msg.pkg}::msg::{name}>();
}}  // namespace tinyline::msg
"""


def emit_write(f: Field) -> list[str]:
    ft = f.type
    m = f"m.{cpp_ident(f.name)}"
    out = []
    if ft.is_sequence:
        bound = ft.seq_bound
        out.append(f"  w.put_count({m}.size(), {bound}, \"{f.name}\");")
    if not ft.is_array:
        if ft.is_primitive:
            out.append(f"  w.put({m});")
        elif ft.is_string:
            out.append(f"  w.put_string({m}, {ft.string_bound}, \"{f.name}\");")
        else:
            out.append(f"  cdr_write(w, {m});")
        return out
    if ft.is_primitive and ft.base != "bool":
        out.append(f"  w.put_array({m}.data(), {m}.size());")
    elif ft.is_primitive:
        out.append(f"  for (bool v : {m}) w.put(v);")
    elif ft.is_string:
        out.append(f"  for (const auto& v : {m}) w.put_string(v, {ft.string_bound}, \"{f.name}\");")
    else:
        out.append(f"  for (const auto& v : {m}) cdr_write(w, v);")
    return out


def min_wire_size(ft: FieldType, all_msgs: dict[str, Message]) -> int:
    """Smallest number of bytes one element can occupy (for sequence sanity checks)."""
    if ft.is_primitive:
        return PRIMITIVES[ft.base][1]
    if ft.is_string:
        return 4
    total = 0
    for f in all_msgs[ft.base].fields:
        sub = f.type
        if sub.is_sequence:
            total += 4
        elif sub.is_fixed:
            total += sub.array_size * min_wire_size(FieldType(sub.base, sub.string_bound), all_msgs)
        else:
            total += min_wire_size(sub, all_msgs)
    return total


def emit_read(f: Field, all_msgs: dict[str, Message]) -> list[str]:
    ft = f.type
    m = f"m.{cpp_ident(f.name)}"
    out = [f"  r.at(\"{f.name}\");"]
    if not ft.is_array:
        if ft.is_primitive:
            out.append(f"  {m} = r.get<{PRIMITIVES[ft.base][0]}>();")
        elif ft.is_string:
            out.append(f"  r.get_string({m}, {ft.string_bound});")
        else:
            out.append(f"  cdr_read(r, {m});")
        return out
    if ft.is_sequence:
        elem = FieldType(ft.base, ft.string_bound)
        out.append(f"  {m}.resize(r.get_count({max(1, min_wire_size(elem, all_msgs))}, {ft.seq_bound}));")
    if ft.is_primitive and ft.base != "bool":
        out.append(f"  r.get_array({m}.data(), {m}.size());")
    elif ft.is_primitive:
        out.append(f"  for (std::size_t i = 0; i < {m}.size(); ++i) {m}[i] = r.get<bool>();")
    elif ft.is_string:
        out.append(f"  for (auto& v : {m}) {{ r.at(\"{f.name}\"); r.get_string(v, {ft.string_bound}); }}")
    else:
        out.append(f"  for (auto& v : {m}) cdr_read(r, v);")
    return out


def emit_yaml(f: Field) -> list[str]:
    ft = f.type
    m = f"m.{cpp_ident(f.name)}"
    key = f'y.key("{f.name}");'
    if not ft.is_array:
        if ft.is_message:
            return [f"  {key} y.begin_map(); yaml_write(y, {m}); y.end_map();"]
        return [f"  {key} y.scalar({m});"]
    if ft.is_message:
        return [f"  {key} y.begin_list({m}.size());",
                f"  for (const auto& v : {m}) {{ y.item(); y.begin_map(); yaml_write(y, v); y.end_map(); }}",
                "  y.end_list();"]
    if ft.base == "bool":
        return [f"  {key} y.begin_list({m}.size());",
                f"  for (bool v : {m}) {{ y.item(); y.scalar(v); }}",
                "  y.end_list();"]
    return [f"  {key} y.scalar_list({m}.data(), {m}.size());"]


def emit_source(msg: Message, all_msgs: dict[str, Message]) -> str:
    name = msg.name
    w = [l for f in msg.fields for l in emit_write(f)]
    r = [l for f in msg.fields for l in emit_read(f, all_msgs)]
    y = [l for f in msg.fields for l in emit_yaml(f)]
    unused_w = "" if msg.fields else "  (void)w; (void)m;\n"
    unused_r = "" if msg.fields else "  (void)r; (void)m;\n"
    unused_y = "" if msg.fields else "  (void)y; (void)m;\n"
    if not msg.fields:
        # An empty message still carries one byte on the wire (ROS 2 convention).
        w = ["  w.put(std::uint8_t{0});"]
        r = ["  (void)r.get<std::uint8_t>();"]
        unused_w = unused_r = ""
    cpp_t = f"::tinyline::{msg.pkg}::msg::{name}"
    return f"""// Generated by msg/gen/msggen.py from {msg.pkg}/msg/{name}.msg. Do not edit.
#include <{header_path(msg.full_name)}>

#include <memory>

namespace tinyline::{msg.pkg}::msg {{

void cdr_write(::tinyline::cdr::Writer& w, const {name}& m) {{
{unused_w}{chr(10).join(w)}
}}

void cdr_read(::tinyline::cdr::Reader& r, {name}& m) {{
{unused_r}{chr(10).join(r)}
}}

void yaml_write(::tinyline::msg::YamlWriter& y, const {name}& m) {{
{unused_y}{chr(10).join(y)}
}}

}}  // namespace tinyline::{msg.pkg}::msg

namespace tinyline::msg {{

template <>
const TypeSupport& type_support<{cpp_t}>() {{
  static const TypeSupport ts = make_type_support<{cpp_t}>(
      "{msg.full_name}",
      {cpp_string_literal(schema_text(msg, all_msgs))},
      "{type_hash(msg, all_msgs)}");
  return ts;
}}

}}  // namespace tinyline::msg
"""


def emit_registry(msgs: list[Message]) -> str:
    incs = "\n".join(f"#include <{header_path(m.full_name)}>" for m in msgs)
    entries = "\n".join(
        f"      &type_support<::tinyline::{m.pkg}::msg::{m.name}>()," for m in msgs)
    return f"""// Generated by msg/gen/msggen.py. Do not edit.
// Every message type of this build, findable by its full name.
{incs}

#include <algorithm>

namespace tinyline::msg {{

const std::vector<const TypeSupport*>& all_type_supports() {{
  static const std::vector<const TypeSupport*> all = {{
{entries}
  }};
  return all;
}}

const TypeSupport* find_type_support(std::string_view full_name) {{
  for (const TypeSupport* ts : all_type_supports()) {{
    if (ts->name == full_name) return ts;
  }}
  return nullptr;
}}

}}  // namespace tinyline::msg
"""


def emit_all_types(msgs: list[Message]) -> str:
    incs = "\n".join(f"#include <{header_path(m.full_name)}>" for m in msgs)
    xs = " \\\n".join(f"  X({m.pkg}, {m.name})" for m in msgs)
    return f"""// Generated by msg/gen/msggen.py. Do not edit.
// Every message type of this build, for code that must visit them all
// (interop tests, fuzzers): TINYLINE_FOR_EACH_MESSAGE(X) expands X(pkg, Type).
#pragma once
{incs}

#define TINYLINE_FOR_EACH_MESSAGE(X) \\
{xs}
"""


def write_if_changed(path: str, content: str) -> None:
    os.makedirs(os.path.dirname(path), exist_ok=True)
    try:
        with open(path, encoding="utf-8") as f:
            if f.read() == content:
                return
    except FileNotFoundError:
        pass
    with open(path, "w", encoding="utf-8") as f:
        f.write(content)


def main(argv: list[str]) -> int:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--out", required=True, help="output directory")
    ap.add_argument("--list-outputs", action="store_true",
                    help="print the files that would be generated and exit")
    ap.add_argument("msgs", nargs="+", help="<pkg>/<Type>.msg files (the parent folder names the package)")
    args = ap.parse_args(argv)

    try:
        msgs = []
        for p in args.msgs:
            pkg = os.path.basename(os.path.dirname(os.path.abspath(p)))
            msgs.append(parse_msg(p, pkg))
        all_msgs = {m.full_name.replace("/msg/", "/"): m for m in msgs}
        for m in msgs:
            deps_of(m, all_msgs)  # validates references
        if args.list_outputs:
            for m in msgs:
                print(os.path.join(args.out, "include", header_path(m.full_name)))
                print(os.path.join(args.out, "src", m.pkg, m.snake + ".cpp"))
            print(os.path.join(args.out, "src", "type_registry.cpp"))
            print(os.path.join(args.out, "include", "tinyline", "msg", "all_types.hpp"))
            return 0
        for m in msgs:
            write_if_changed(os.path.join(args.out, "include", header_path(m.full_name)),
                             emit_header(m, all_msgs))
            write_if_changed(os.path.join(args.out, "src", m.pkg, m.snake + ".cpp"),
                             emit_source(m, all_msgs))
        write_if_changed(os.path.join(args.out, "src", "type_registry.cpp"), emit_registry(msgs))
        write_if_changed(os.path.join(args.out, "include", "tinyline", "msg", "all_types.hpp"), emit_all_types(msgs))
    except MsgError as e:
        print(f"msggen: error: {e}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
