#!/usr/bin/env python3
# SPDX-License-Identifier: Apache-2.0
"""Interop checks of tinyline's MCAP bags against independent implementations.

  check-ours DIR    every DIR/*.mcap (written by tinyline) must be read by the
                    `mcap` package with CRC validation (indexed and streaming
                    readers), decode with `mcap-ros2-support`, and open in
                    `rosbags` (AnyReader), each giving exactly the messages in
                    DIR/<name>.expected.yaml; the summary CRC and summary
                    offsets are checked by hand.
  write-theirs DIR  writes bags with the `mcap` writer (+ mcap-ros2-support)
                    and with `rosbags`, each compression they offer, with and
                    without a summary, plus DIR/<name>.expected.json.
  compare DIR       compares DIR/<name>.actual.yaml (what tinyline decoded)
                    with DIR/<name>.expected.json.
  check-echo TINYLINE BAG
                    `TINYLINE bag echo BAG TOPIC --full` for every topic of
                    BAG: the output must be YAML (a general parser reads it),
                    one document per message, each equal to the message as
                    `mcap-ros2-support` decodes it.

Exit status 0 when everything matches; every mismatch is printed with the
file, the message index and the field path.
"""

from __future__ import annotations

import dataclasses
import json
import re
import math
import shutil
import struct
import sys
import zlib
from pathlib import Path

import numpy as np
from ruamel.yaml import YAML

FAILURES: list[str] = []


def fail(msg: str) -> None:
    FAILURES.append(msg)
    print('FAIL', msg)


# ---------------------------------------------------------------------------- normalising values


def norm(x):
    """Plain Python values from whatever a decoder returned."""
    if isinstance(x, (bytes, bytearray, memoryview)):
        return list(bytes(x))
    if isinstance(x, np.ndarray):
        return [norm(v) for v in x.tolist()]
    if isinstance(x, np.generic):
        return norm(x.item())
    if isinstance(x, (list, tuple)):
        return [norm(v) for v in x]
    if isinstance(x, dict):
        return {k: norm(v) for k, v in x.items()}
    if isinstance(x, (bool, int, float, str)) or x is None:
        return x
    if dataclasses.is_dataclass(x):  # rosbags: constants are fields annotated 'ClassVar[...]' (as text)
        notes = type(x).__annotations__
        return {f.name: norm(getattr(x, f.name)) for f in dataclasses.fields(x)
                if 'ClassVar' not in str(notes.get(f.name, ''))}
    slots = getattr(type(x), '__slots__', None)  # mcap_ros2 dynamic classes
    if slots:
        return {k: norm(getattr(x, k)) for k in slots if not k.startswith('_')}
    raise TypeError(f'cannot normalise {type(x)!r}')


def same(a, b, path: str = '') -> str | None:
    """None if equal, else where they differ. Floats compare exactly (NaN == NaN)."""
    if isinstance(a, float) or isinstance(b, float):
        if not isinstance(a, (int, float)) or not isinstance(b, (int, float)) or isinstance(a, bool) or isinstance(b, bool):
            return f'{path}: {a!r} != {b!r}'
        if math.isnan(a) and math.isnan(b):
            return None
        return None if float(a) == float(b) else f'{path}: {a!r} != {b!r}'
    if isinstance(a, dict) and isinstance(b, dict):
        if set(a) != set(b):
            return f'{path}: keys {sorted(a)} != {sorted(b)}'
        for k in a:
            if (d := same(a[k], b[k], f'{path}.{k}')) is not None:
                return d
        return None
    if isinstance(a, list) and isinstance(b, list):
        if len(a) != len(b):
            return f'{path}: length {len(a)} != {len(b)}'
        for i, (x, y) in enumerate(zip(a, b)):
            if (d := same(x, y, f'{path}[{i}]')) is not None:
                return d
        return None
    # A `byte` field: one decoder gives an int, another a 1-byte bytes object (normalised to a list).
    if isinstance(a, int) and isinstance(b, list) and len(b) == 1:
        return same(a, b[0], path)
    if isinstance(b, int) and isinstance(a, list) and len(a) == 1:
        return same(a[0], b, path)
    return None if a == b and type(a) is type(b) else f'{path}: {a!r} != {b!r}'


# tinyline's YamlWriter emits a small regular subset of YAML (block maps and
# lists, inline scalar lists, double-quoted strings); this parser reads exactly
# that, two orders of magnitude faster than a general YAML parser in pure Python.
# A general parser (ruamel) cross-checks it on a small document in self_test().
_TOKEN = re.compile(r'"(?:[^"\\]|\\.)*"|[^,\[\]\s]+')
_KEY = re.compile(r'^[A-Za-z_][A-Za-z0-9_]*:(?: |$)')
_ESCAPES = {'"': '"', '\\': '\\', 'n': '\n', 't': '\t', 'r': '\r', '0': '\0', '/': '/'}


def _unquote(tok: str) -> str:
    def repl(m):
        e = m.group(1)
        return chr(int(e[1:], 16)) if e[0] == 'x' else _ESCAPES[e]
    return re.sub(r'\\(x[0-9a-fA-F]{2}|.)', repl, tok[1:-1])


def _scalar(tok: str):
    if tok.startswith('"'):
        return _unquote(tok)
    special = {'true': True, 'false': False, '.nan': math.nan, '.inf': math.inf, '-.inf': -math.inf}
    if tok in special:
        return special[tok]
    try:
        return int(tok)
    except ValueError:
        return float(tok)


def _value(text: str):
    text = text.strip()
    if text.startswith('['):
        return [_scalar(t) for t in _TOKEN.findall(text[1:text.rindex(']')])]
    if text == '{}':
        return {}
    return _scalar(text)


def _block(lines, i, indent):
    if lines[i][1].startswith('- '):
        return _list(lines, i, indent)
    return _map(lines, i, indent)


def _map(lines, i, indent):
    d = {}
    while i < len(lines) and lines[i][0] == indent and not lines[i][1].startswith('- '):
        key, _, rest = lines[i][1].partition(':')
        i += 1
        if rest.strip():
            d[key] = _value(rest)
        elif i < len(lines) and lines[i][0] > indent:
            d[key], i = _block(lines, i, lines[i][0])
        else:
            d[key] = None
    return d, i


def _list(lines, i, indent):
    out = []
    while i < len(lines) and lines[i][0] == indent and lines[i][1].startswith('- '):
        rest = lines[i][1][2:]
        if _KEY.match(rest):  # a map item: its first key follows the dash
            lines[i] = (indent + 2, rest)
            item, i = _map(lines, i, indent + 2)
            out.append(item)
        else:
            out.append(_value(rest))
            i += 1
    return out, i


def parse_docs(text: str) -> list[dict]:
    docs = []
    for chunk in text.split('---\n'):
        lines = [(len(ln) - len(ln.lstrip(' ')), ln.lstrip(' ')) for ln in chunk.split('\n') if ln.strip()]
        if lines:
            doc, end = _map(lines, 0, 0)
            if end != len(lines):
                raise ValueError(f'unparsed line {lines[end]!r}')
            docs.append(doc)
    return docs


def load_docs(path: Path) -> list[dict]:
    return parse_docs(path.read_text(encoding='utf-8'))


def self_test() -> None:
    """The fast parser agrees with ruamel on a document with every construct."""
    text = ('---\ntopic: "/a"\nmessage:\n  header:\n    stamp:\n      sec: 1\n    frame_id: "x\\ty\\"z\\x01 \u00e9"\n'
            '  values: [1.5, .nan, -.inf, 1e-300, -0.0]\n  names: ["a, b", ""]\n  empty: []\n'
            '  items:\n    - key: "k"\n      value: 3\n    - {}\n  flag: true\n')
    fast = parse_docs(text)
    slow = [d for d in YAML(typ='safe', pure=True).load_all(text) if d is not None]
    if (d := same(fast, slow, 'self_test')) is not None:
        fail(f'fast YAML parser disagrees with ruamel: {d}')


def compare_lists(name: str, what: str, expected: list[dict], got: list[dict]) -> None:
    if len(expected) != len(got):
        fail(f'{name} [{what}]: {len(got)} messages, expected {len(expected)}')
        return
    for i, (e, g) in enumerate(zip(expected, got)):
        for key in ('topic', 'type', 'log_time', 'publish_time', 'sequence'):
            if key in g and g[key] != e[key]:
                fail(f'{name} [{what}] message {i}: {key} {g[key]!r} != expected {e[key]!r}')
                return
        if (d := same(e['message'], g['message'], 'message')) is not None:
            fail(f'{name} [{what}] message {i} on {e["topic"]} ({e["type"]}): {d}')
            return


# ---------------------------------------------------------------------------- check-ours


def check_summary_by_hand(path: Path) -> None:
    """Summary CRC and summary offsets, which the mcap package does not validate."""
    data = path.read_bytes()
    name = path.name
    magic = b'\x89MCAP0\r\n'
    if not data.startswith(magic) or not data.endswith(magic):
        fail(f'{name}: magic missing')
        return
    footer = len(data) - 8 - 29
    op, length, summary_start, summary_offset_start, summary_crc = struct.unpack_from('<BQQQI', data, footer)
    if op != 0x02 or length != 20:
        fail(f'{name}: footer record malformed')
        return
    if summary_start == 0:
        return
    if summary_crc != 0:
        crc = zlib.crc32(data[summary_start:footer + 1 + 8 + 16])
        if crc != summary_crc:
            fail(f'{name}: summary CRC {crc:#x} != stored {summary_crc:#x}')
    if summary_offset_start:
        pos = summary_offset_start
        groups = 0
        while pos < footer:
            op, length = struct.unpack_from('<BQ', data, pos)
            if op != 0x0E:
                fail(f'{name}: record {op:#x} in the summary offset section')
                return
            group_op, start, glen = struct.unpack_from('<BQQ', data, pos + 9)
            q = start
            while q < start + glen:
                rop, rlen = struct.unpack_from('<BQ', data, q)
                if rop != group_op:
                    fail(f'{name}: summary offset group {group_op:#x} holds a {rop:#x} record at {q}')
                    return
                q += 9 + rlen
            if q != start + glen:
                fail(f'{name}: summary offset group {group_op:#x} length does not end on a record')
            groups += 1
            pos += 9 + length
        if groups == 0:
            fail(f'{name}: empty summary offset section')


def check_rosbags(bag: Path, expected: list[dict]) -> None:
    from rosbags.highlevel import AnyReader

    name = bag.name
    with AnyReader([bag]) as reader:
        got = []
        for connection, timestamp, rawdata in reader.messages():
            if not connection.ext.offered_qos_profiles:
                fail(f'{name}: rosbags found no QoS profile on {connection.topic}')
            got.append({'topic': connection.topic, 'type': connection.msgtype, 'log_time': timestamp,
                        'message': norm(reader.deserialize(rawdata, connection.msgtype))})
        # rosbags yields by timestamp; ties keep file order like the expected list.
        compare_lists(name, 'rosbags AnyReader', expected, got)
        counts = {c.topic: c.msgcount for c in reader.connections}
        for topic in {e['topic'] for e in expected}:
            want = sum(1 for e in expected if e['topic'] == topic)
            if counts.get(topic) != want:
                fail(f'{name}: rosbags counts {counts.get(topic)} messages on {topic}, expected {want}')


def check_ours(directory: Path) -> None:
    from mcap.reader import NonSeekingReader, SeekingReader
    from mcap_ros2.decoder import DecoderFactory

    self_test()
    bags = sorted(directory.glob('*.mcap'))
    parsed: dict[str, list[dict]] = {}
    if not bags:
        fail(f'no .mcap files in {directory}')
    for bag in bags:
        name = bag.name
        expected_text = bag.with_suffix('.expected.yaml').read_text(encoding='utf-8')
        if expected_text not in parsed:
            parsed.clear()
            parsed[expected_text] = parse_docs(expected_text)
        expected = parsed[expected_text]
        n_before = len(FAILURES)

        # mcap: indexed (seeking) reader, chunk CRCs validated, ros2 decoding.
        with bag.open('rb') as f:
            reader = SeekingReader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
            header = reader.get_header()
            if header.profile != 'ros2':
                fail(f'{name}: profile {header.profile!r}')
            got = []
            for schema, channel, message, decoded in reader.iter_decoded_messages(log_time_order=True):
                if schema.encoding != 'ros2msg' or channel.message_encoding != 'cdr':
                    fail(f'{name}: encodings {schema.encoding}/{channel.message_encoding}')
                if 'offered_qos_profiles' not in channel.metadata:
                    fail(f'{name}: channel {channel.topic} has no offered_qos_profiles')
                got.append({'topic': channel.topic, 'type': schema.name, 'log_time': message.log_time,
                            'publish_time': message.publish_time, 'sequence': message.sequence,
                            'message': norm(decoded)})
            compare_lists(name, 'mcap SeekingReader', expected, got)
            summary = reader.get_summary()
            if summary is not None and summary.statistics is not None:
                if summary.statistics.message_count != len(expected):
                    fail(f'{name}: statistics message_count {summary.statistics.message_count} != {len(expected)}')
                per_topic: dict[str, int] = {}
                for e in expected:
                    per_topic[e['topic']] = per_topic.get(e['topic'], 0) + 1
                for cid, count in summary.statistics.channel_message_counts.items():
                    topic = summary.channels[cid].topic
                    if per_topic.get(topic) != count:
                        fail(f'{name}: statistics count {count} on {topic}, expected {per_topic.get(topic)}')

        # mcap: streaming reader, chunk and data section CRCs validated.
        with bag.open('rb') as f:
            reader = NonSeekingReader(f, validate_crcs=True, decoder_factories=[DecoderFactory()])
            got = [{'topic': c.topic, 'type': s.name, 'log_time': m.log_time, 'publish_time': m.publish_time,
                    'sequence': m.sequence, 'message': norm(d)}
                   for s, c, m, d in reader.iter_decoded_messages()]
            compare_lists(name, 'mcap NonSeekingReader', expected, got)

        check_summary_by_hand(bag)

        # rosbags: its own MCAP storage and CDR deserializer, types from the bag's schemas.
        # It picks chunks by their message indexes, so a file written without them
        # (an option our writer has, off by default) reads as empty there.
        if 'no_message_index' in name:
            print(f'note {name}: rosbags check skipped (rosbags needs message indexes)')
        else:
            check_rosbags(bag, expected)

        if len(FAILURES) == n_before:
            print(f'ok   {name}: {len(expected)} messages agree in mcap (seeking, streaming) and rosbags')


# ---------------------------------------------------------------------------- write-theirs


def sample_messages(typestore, seed: int = 3):
    """The messages the Python writers write: rosbags objects, with exact dtypes."""
    rng = np.random.default_rng(seed)
    T = typestore.types
    Time = T['builtin_interfaces/msg/Time']
    Header = T['std_msgs/msg/Header']
    out = []
    t0 = 1_700_000_100_000_000_000
    for i in range(40):
        t = t0 + i * 25_000_000
        stamp = Time(sec=t // 1_000_000_000, nanosec=t % 1_000_000_000)
        ranges = rng.uniform(0.05, 2.0, 256).astype(np.float32)
        ranges[::29] = np.nan
        out.append(('/scan', 'sensor_msgs/msg/LaserScan', T['sensor_msgs/msg/LaserScan'](
            header=Header(stamp=stamp, frame_id='laser'), angle_min=np.float32(-0.5).item(),
            angle_max=np.float32(0.5).item(), angle_increment=np.float32(1 / 256).item(), time_increment=0.0,
            scan_time=np.float32(0.01).item(), range_min=np.float32(0.05).item(), range_max=2.0,
            ranges=ranges, intensities=rng.uniform(0, 100, 256 if i % 2 else 0).astype(np.float32))))
        out.append(('/tiny/raw', 'tinyline_msgs/msg/RawScan', T['tinyline_msgs/msg/RawScan'](
            header=Header(stamp=stamp, frame_id='tiny'), set_index=i, temperature_c=np.float32(30 + i / 8).item(),
            pixels=272, pulses=np.array([10, 40, 160], dtype=np.uint16),
            a=rng.integers(-30000, 30000, 816).astype(np.int16), b=rng.integers(-30000, 30000, 816).astype(np.int16))))
        status = rng.integers(0, 5, 256).astype(np.uint8)
        dist = rng.uniform(0.05, 2.0, 256).astype(np.float32)
        dist[status != 0] = np.nan
        out.append(('/tiny/scan', 'tinyline_msgs/msg/LineScan', T['tinyline_msgs/msg/LineScan'](
            header=Header(stamp=stamp, frame_id='tiny'), set_index=i, temperature_c=np.float32(31.25).item(),
            angles=np.linspace(-0.5, 0.5, 256, dtype=np.float32), distance_m=dist,
            range_sd_m=rng.uniform(0.001, 0.05, 256).astype(np.float32),
            intensity=rng.uniform(0, 50, 256).astype(np.float32), reflectance=rng.uniform(0, 1e4, 256).astype(np.float32),
            pulses=rng.integers(10, 200, 256).astype(np.uint16), status=status)))
        if i % 4 == 0:
            PF = T['sensor_msgs/msg/PointField']
            out.append(('/camera/points', 'sensor_msgs/msg/PointCloud2', T['sensor_msgs/msg/PointCloud2'](
                header=Header(stamp=stamp, frame_id='camera'), height=1, width=32,
                fields=[PF(name=n, offset=4 * k, datatype=7, count=1) for k, n in enumerate('xyz')],
                is_bigendian=False, point_step=12, row_step=384,
                data=rng.integers(0, 256, 384).astype(np.uint8), is_dense=True)))
        if i % 3 == 0:
            out.append(('/joint_states', 'sensor_msgs/msg/JointState', T['sensor_msgs/msg/JointState'](
                header=Header(stamp=stamp, frame_id=''), name=['j1', 'j2 ✓'],
                position=np.array([0.1 * i, -1e-300]), velocity=np.array([], dtype=np.float64),
                effort=np.array([2.5, -0.0]))))
        if i % 5 == 0:
            DS = T['diagnostic_msgs/msg/DiagnosticStatus']
            KV = T['diagnostic_msgs/msg/KeyValue']
            out.append(('/diagnostics', 'diagnostic_msgs/msg/DiagnosticArray', T['diagnostic_msgs/msg/DiagnosticArray'](
                header=Header(stamp=stamp, frame_id=''),
                status=[DS(level=1, name='driver', message='warm "up"\n', hardware_id='SN-1',
                           values=[KV(key='t', value='40.5')])])))
        out.append(('/chatter', 'std_msgs/msg/String', T['std_msgs/msg/String'](data=f'hello {i} \\ "ü"\t')))
        out.append(('/pose', 'geometry_msgs/msg/PoseStamped', T['geometry_msgs/msg/PoseStamped'](
            header=Header(stamp=stamp, frame_id='base'),
            pose=T['geometry_msgs/msg/Pose'](position=T['geometry_msgs/msg/Point'](x=1 / 3, y=0.0, z=-2.0),
                                             orientation=T['geometry_msgs/msg/Quaternion'](x=0.0, y=0.0, z=0.0, w=1.0)))))
    timed = []
    for k, (topic, typ, m) in enumerate(out):
        # Strictly increasing log times (each message 1 us after the previous).
        timed.append((topic, typ, m, t0 + k * 1000, t0 + k * 1000 - 7, k + 1))
    return timed


def make_typestore():
    from rosbags.typesys import Stores, get_typestore, get_types_from_msg

    store = get_typestore(Stores.ROS2_HUMBLE)
    root = Path(__file__).resolve().parents[3] / 'msg' / 'msg' / 'tinyline_msgs'
    types = {}
    for p in sorted(root.glob('*.msg')):
        types.update(get_types_from_msg(p.read_text(), f'tinyline_msgs/msg/{p.stem}'))
    store.register(types)
    return store


def write_expected(path: Path, msgs) -> None:
    docs = [{'topic': topic, 'type': typ, 'log_time': lt, 'publish_time': pt, 'sequence': seq, 'message': norm(m)}
            for topic, typ, m, lt, pt, seq in msgs]
    path.write_text(json.dumps(docs, allow_nan=True))


def write_theirs(directory: Path) -> None:
    from mcap.writer import CompressionType, IndexType
    from mcap.writer import Writer as McapWriter
    from mcap_ros2._dynamic import serialize_dynamic
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.rosbag2.enums import CompressionFormat, CompressionMode

    directory.mkdir(parents=True, exist_ok=True)
    store = make_typestore()
    msgs = sample_messages(store)
    types = sorted({typ for _, typ, *_ in msgs})

    # The mcap writer with mcap-ros2-support encoders.
    for comp_name, comp in (('none', CompressionType.NONE), ('lz4', CompressionType.LZ4), ('zstd', CompressionType.ZSTD)):
        for with_summary in (True, False):
            name = f'py_mcap_{comp_name}_{"summary" if with_summary else "nosummary"}'
            path = directory / f'{name}.mcap'
            with path.open('wb') as f:
                opts = {} if with_summary else dict(index_types=IndexType.NONE, repeat_channels=False,
                                                   repeat_schemas=False, use_statistics=False,
                                                   use_summary_offsets=False)
                w = McapWriter(f, chunk_size=16 * 1024, compression=comp, enable_data_crcs=True, **opts)
                w.start(profile='ros2', library='mcap-python interop')
                schema_ids, encoders, channel_ids = {}, {}, {}
                for typ in types:
                    text, _ = store.generate_msgdef(typ, ros_version=2)
                    schema_ids[typ] = w.register_schema(typ, 'ros2msg', text.encode())
                    encoders[typ] = serialize_dynamic(typ, text)[typ]
                for topic, typ, m, lt, pt, seq in msgs:
                    if topic not in channel_ids:
                        channel_ids[topic] = w.register_channel(
                            topic, 'cdr', schema_ids[typ],
                            {'offered_qos_profiles': '- history: 1\n  depth: 10\n  reliability: 1\n  durability: 2\n'
                             '  deadline:\n    sec: 0\n    nsec: 0\n  lifespan:\n    sec: 0\n    nsec: 0\n'
                             '  liveliness: 1\n  liveliness_lease_duration:\n    sec: 0\n    nsec: 0\n'
                             '  avoid_ros_namespace_conventions: false'})
                    w.add_message(channel_ids[topic], lt, encoders[typ](to_dict(m)), pt, seq)
                w.finish()
            write_expected(directory / f'{name}.expected.json', msgs)

    # rosbags: a rosbag2 directory with MCAP storage; chunk compression none or zstd.
    for comp_name, mode in (('none', None), ('zstd', CompressionMode.STORAGE)):
        bagdir = directory / f'rosbags_{comp_name}'
        if bagdir.exists():
            shutil.rmtree(bagdir)
        w = Writer(bagdir, version=9, storage_plugin=StoragePlugin.MCAP)
        if mode is not None:
            w.set_compression(mode, CompressionFormat.ZSTD)
        with w:
            conns = {}
            for topic, typ, m, lt, pt, seq in msgs:
                if topic not in conns:
                    conns[topic] = w.add_connection(topic, typ, typestore=store)
                w.write(conns[topic], lt, store.serialize_cdr(m, typ))
        src = next(bagdir.glob('*.mcap'))
        # rosbags stores no publish time or sequence: publish time = log time, sequence 0.
        ros_msgs = [(topic, typ, m, lt, lt, 0) for topic, typ, m, lt, _, _ in msgs]
        for with_summary in (True, False):
            name = f'rosbags_{comp_name}_{"summary" if with_summary else "nosummary"}'
            data = src.read_bytes()
            if not with_summary:
                data = strip_summary(data)
            (directory / f'{name}.mcap').write_bytes(data)
            write_expected(directory / f'{name}.expected.json', ros_msgs)
        shutil.rmtree(bagdir)
    print(f'wrote {len(list(directory.glob("*.mcap")))} bags of {len(msgs)} messages to {directory}')


def strip_summary(data: bytes) -> bytes:
    """The same file with its summary removed: data section, then an empty footer."""
    footer = len(data) - 8 - 29
    _, _, summary_start, _, _ = struct.unpack_from('<BQQQI', data, footer)
    end = summary_start if summary_start else footer
    return data[:end] + struct.pack('<BQQQI', 0x02, 20, 0, 0, 0) + b'\x89MCAP0\r\n'


def to_dict(m):
    """rosbags message object -> the dict mcap-ros2-support's encoder takes."""
    if hasattr(m, '__dataclass_fields__'):
        return {k: to_dict(getattr(m, k)) for k in m.__dataclass_fields__ if not k.startswith('__')}
    if isinstance(m, np.ndarray):
        return bytes(m.tobytes()) if m.dtype == np.uint8 else m.tolist()
    if isinstance(m, list):
        return [to_dict(v) for v in m]
    return m


# ---------------------------------------------------------------------------- compare


def compare(directory: Path) -> None:
    expected_files = sorted(directory.glob('*.expected.json'))
    if not expected_files:
        fail(f'no expected files in {directory}')
    for exp in expected_files:
        name = exp.name.removesuffix('.expected.json')
        actual = directory / f'{name}.actual.yaml'
        if not actual.exists():
            fail(f'{name}: tinyline wrote no {actual.name}')
            continue
        expected = json.loads(exp.read_text())
        n_before = len(FAILURES)
        compare_lists(name, 'tinyline reader', expected, load_docs(actual))
        if len(FAILURES) == n_before:
            print(f'ok   {name}: tinyline decoded all {len(expected)} messages to the written values')


# ---------------------------------------------------------------------------- check-echo


def check_echo(tinyline: Path, bag: Path) -> None:
    import subprocess
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    self_test()
    by_topic: dict[str, list] = {}
    with bag.open('rb') as f:
        reader = make_reader(f, decoder_factories=[DecoderFactory()])
        for _, channel, _, decoded in reader.iter_decoded_messages(log_time_order=True):
            by_topic.setdefault(channel.topic, []).append(norm(decoded))
    if not by_topic:
        fail(f'{bag}: no messages')
    general = YAML(typ='safe', pure=True)
    for topic, expected in sorted(by_topic.items()):
        run = subprocess.run([str(tinyline), 'bag', 'echo', str(bag), topic, '--full'],
                             capture_output=True, text=True, check=False)
        if run.returncode != 0:
            fail(f'echo {topic}: exit {run.returncode}: {run.stderr.strip()}')
            continue
        # The general (slow, pure Python) parser reads the first documents, the
        # fast one all; both must agree where both ran.
        cut = run.stdout.find('\n---', 50_000)
        head = run.stdout if cut < 0 else run.stdout[:cut + 1]
        slow = [d for d in general.load_all(head) if d is not None]
        fast = parse_docs(re.sub(r'^--- #.*$', '---', run.stdout, flags=re.M))  # the fast parser knows no comments
        if not slow:
            fail(f'echo {topic}: a general YAML parser finds no document')
        elif (d := same(slow, fast[:len(slow)], f'echo {topic}')) is not None:
            fail(f'echo {topic}: general and fast YAML parsers disagree: {d}')
        n_before = len(FAILURES)
        if len(fast) != len(expected):
            fail(f'echo {topic}: {len(fast)} documents, {len(expected)} messages in the bag')
        for i, (got, exp) in enumerate(zip(fast, expected)):
            if (d := same(got, exp, f'echo {topic}[{i}]')) is not None:
                fail(d)
                break
        if len(FAILURES) == n_before:
            print(f'ok   echo {topic}: {len(fast)} YAML documents equal the mcap-ros2-support decoding '
                  f'({len(slow)} also read by a general YAML parser)')


def main() -> int:
    if len(sys.argv) == 4 and sys.argv[1] == 'check-echo':
        check_echo(Path(sys.argv[2]), Path(sys.argv[3]))
        print(f'{len(FAILURES)} failure(s)' if FAILURES else 'all echo output agrees')
        return 1 if FAILURES else 0
    if len(sys.argv) != 3 or sys.argv[1] not in ('check-ours', 'write-theirs', 'compare'):
        print(__doc__)
        return 2
    directory = Path(sys.argv[2])
    {'check-ours': check_ours, 'write-theirs': write_theirs, 'compare': compare}[sys.argv[1]](directory)
    if FAILURES:
        print(f'{len(FAILURES)} failure(s)')
        return 1
    return 0


if __name__ == '__main__':
    sys.exit(main())
