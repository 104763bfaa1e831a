"""ROS 1 / ROS 2 bags (and MCAP) for the LET and LinkerHand readers: listing, reading topics, resampling.

Read with `rosbags` (pure Python, no ROS install; the `ros` extra). Message types are the ROS 1 Noetic /
ROS 2 Humble standard types plus the vendor definitions below (`kuavo_msgs`, written from the upstream
`.msg` files); any other type is taken from the definition the bag embeds (ROS 1 connection headers,
MCAP schemas, rosbag2 metadata). `sensor_msgs/JointState`, the bulk of hand recordings, is decoded
straight from its bytes (`decode_joint_state`).

Recorded stamps jitter (a 30 Hz topic measures 30.14 Hz), and LeRobot stores a fixed integer fps, so
every stream is resampled onto one grid of `fps` frames per second over the time all required topics
cover (`_resample`): **nearest** sample for commands (a command holds until the next one; LejuRobotics'
converter `kuavo_data/common/kuavo_dataset.py` `align_frame_data` takes the nearest message of every
topic), **linear** interpolation for measured joint states (or nearest, per reader option).
"""

from __future__ import annotations

from collections.abc import Callable
from functools import lru_cache
from pathlib import Path

import numpy as np

from lerobot_unidextok.converters._resample import (  # noqa: F401  the bag readers' resampling, re-exported
    INTERPOLATIONS,
    Stream,
    grid_for,
    measured_rate_hz,
    resample,
    resampling_options,
)
from lerobot_unidextok.errors import SourceFormatError
from lerobot_unidextok.utils.imports import require_package

# kuavo_msgs (LejuRobotics kuavo-ros-opensource, `src/kuavo_msgs/msg/*.msg`); the LET bags embed these
# definitions too, these are the fallback for bags that do not.
KUAVO_MSGS: dict[str, str] = {
    "kuavo_msgs/msg/robotHandPosition": "std_msgs/Header header\nuint8[] left_hand_position\nuint8[] right_hand_position\n",
    "kuavo_msgs/msg/jointData": "float64[] joint_q\nfloat64[] joint_v\nfloat64[] joint_vd\nfloat64[] joint_current\n",
    "kuavo_msgs/msg/imuData": (
        "geometry_msgs/Vector3 gyro\ngeometry_msgs/Vector3 acc\ngeometry_msgs/Vector3 free_acc\n"
        "geometry_msgs/Quaternion quat\n"
    ),
    "kuavo_msgs/msg/endEffectorData": "string[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n",
    "kuavo_msgs/msg/sensorsData": (
        "std_msgs/Header header\ntime sensor_time\nkuavo_msgs/jointData joint_data\nkuavo_msgs/imuData imu_data\n"
        "kuavo_msgs/endEffectorData end_effector_data\n"
    ),
}
BAG_SUFFIXES = (".bag", ".mcap", ".db3")


class BagFormatError(SourceFormatError):
    """A bag is unreadable or lacks a topic/field; the message names the file and the topic."""


def require_rosbags() -> None:
    """ImportError naming the `ros` extra when rosbags is missing."""
    require_package("rosbags", "ros", purpose="reading ROS bags", hint=" (pure Python, no ROS install)")


def list_bags(root: Path, pattern: str = "*") -> list[Path]:
    """ROS 1 `.bag` files, ROS 2 bag folders (with metadata.yaml) and standalone `.mcap` / `.db3` files
    under `root` (or `root` itself), sorted by path."""
    root = Path(root)
    if root.is_file() or (root / "metadata.yaml").is_file():
        return [root]
    ros2_dirs = sorted(p.parent for p in root.rglob("metadata.yaml") if p.parent.match(pattern) or pattern == "*")
    inside = {d for d in ros2_dirs}
    files = [
        p
        for p in root.rglob("*")
        if p.suffix in BAG_SUFFIXES and p.is_file() and not any(d in p.parents for d in inside)
    ]
    return sorted(ros2_dirs + files, key=str)


@lru_cache(maxsize=2)
def _base_typestore(ros1: bool):
    """The standard types plus the vendor ones, built once per process (building a store costs ~0.2 s)."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    for name, text in KUAVO_MSGS.items():
        store.register(get_types_from_msg(text, name))
    return store


def _store_for(connections: list, ros1: bool):
    """A typestore knowing every connection's type: the cached base store, or a copy extended with the
    definitions a bag embeds for types the base store lacks (or defines differently)."""
    from rosbags.interfaces import MessageDefinitionFormat
    from rosbags.typesys import get_types_from_idl, get_types_from_msg

    base = _base_typestore(ros1)
    missing = [c for c in connections if c.msgtype not in base.fielddefs]
    if not missing:
        return base
    from copy import copy

    store = copy(base)
    store.fielddefs, store.types, store.cache = dict(base.fielddefs), dict(base.types), {}
    for conn in missing:
        if conn.msgdef.format == MessageDefinitionFormat.MSG:
            store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
        elif conn.msgdef.format == MessageDefinitionFormat.IDL:
            store.register(get_types_from_idl(conn.msgdef.data))
        else:
            raise ValueError(f"type {conn.msgtype} of topic {conn.topic!r} is not defined in the bag nor known")
    return store


Extractor = Callable[[object], tuple[np.ndarray, tuple[str, ...] | None]]
JOINT_STATE_TYPE = "sensor_msgs/msg/JointState"


def joint_state(msg) -> tuple[np.ndarray, tuple[str, ...]]:
    """Extractor of `sensor_msgs/JointState`: (position, name). `read_streams` decodes this one directly
    from the serialized bytes (`decode_joint_state`), without building message objects."""
    return np.asarray(msg.position), tuple(msg.name)


def decode_joint_state(
    raw: bytes | memoryview, ros1: bool, seen: dict | None = None
) -> tuple[np.ndarray, tuple[str, ...]]:
    """(position, name) of a serialized `sensor_msgs/JointState`: ROS 1 (packed, little endian) or ROS 2
    CDR little endian (4-byte encapsulation, fields aligned to their size). Same values as rosbags'
    deserializer (tests/conversion/test_rosbag.py); raises ValueError on anything else. `seen` (one dict per
    topic) remembers the frame_id + name bytes of the previous message: a topic repeats them, so later
    messages skip straight to the positions."""
    buf = memoryview(raw)
    if ros1:
        start, base, align = 12, 0, False  # header: seq, stamp.sec, stamp.nsec
    else:
        if bytes(buf[:2]) != b"\x00\x01":
            raise ValueError("not little-endian CDR")
        start, base, align = 12, 4, True  # 4-byte encapsulation, then stamp.sec, stamp.nanosec
    pos = start

    def u32() -> int:
        nonlocal pos
        if align:
            pos += (-(pos - base)) % 4
        value = int.from_bytes(buf[pos : pos + 4], "little")
        pos += 4
        return value

    def string() -> str:
        nonlocal pos
        size = u32()
        text = bytes(buf[pos : pos + size]).decode()
        pos += size
        return text.rstrip("\x00")

    if seen and buf[start : seen["end"]] == seen["prefix"]:
        pos, names = seen["end"], seen["names"]
    else:
        string()  # header.frame_id
        names = tuple(string() for _ in range(u32()))
        if seen is not None:
            seen.update(prefix=bytes(buf[start:pos]), end=pos, names=names)
    count = u32()
    if align:
        pos += (-(pos - base)) % 8
    if pos + 8 * count > len(buf):
        raise ValueError("JointState.position runs past the message")
    position = np.frombuffer(buf[pos : pos + 8 * count], dtype="<f8").copy()
    return position, names


def decode_joint_states(raws: list[bytes], ros1: bool) -> tuple[np.ndarray, tuple[str, ...]]:
    """(N, D) positions of many serialized JointStates of one topic. When every message has the same
    length and the same frame_id + names (the usual case: a driver publishing at a fixed size), the
    positions sit at one offset and are read for all messages at once; otherwise message by message."""
    seen: dict = {}
    first, names = decode_joint_state(raws[0], ros1, seen)
    size = len(raws[0])
    if len(first) and all(len(r) == size for r in raws):
        block = np.frombuffer(b"".join(raws), dtype=np.uint8).reshape(len(raws), size)
        start = 12
        prefix = np.frombuffer(seen["prefix"], dtype=np.uint8)
        offset = size - _tail_bytes(raws[0], ros1, seen["end"], len(first))
        if (block[:, start : seen["end"]] == prefix).all():
            positions = block[:, offset : offset + 8 * len(first)].copy().view("<f8")
            return positions.astype(np.float64), names
    rows = [decode_joint_state(r, ros1, seen) for r in raws]
    widths = {len(v) for v, _ in rows}
    if len(widths) != 1:
        raise ValueError(f"messages have different numbers of positions {sorted(widths)}")
    return np.stack([v for v, _ in rows]), rows[-1][1]


def _tail_bytes(raw: bytes, ros1: bool, end: int, count: int) -> int:
    """Bytes from the first position value to the end of the message (the offset is the same in every
    message of equal length and prefix)."""
    pos = end
    base = 0 if ros1 else 4
    if not ros1:
        pos += (-(pos - base)) % 4
    pos += 4  # position count
    if not ros1:
        pos += (-(pos - base)) % 8
    return len(raw) - pos


def read_streams(path: Path, extractors: dict[str, Extractor]) -> dict[str, Stream]:
    """Every message of the `extractors`' topics present in the bag, in log-time order.

    Stamps are the bag's log (receive) times, as LejuRobotics' converter uses them (it overrides header
    stamps with the bag time: `kuavo_dataset.py` `process_rosbag`). Repeated stamps keep the last message.
    """
    require_rosbags()
    from rosbags.rosbag1 import Reader as Reader1
    from rosbags.rosbag2 import Reader as Reader2

    path = Path(path)
    ros1 = path.suffix == ".bag"
    rows: dict[str, list] = {t: [] for t in extractors}
    names: dict[str, tuple[str, ...] | None] = {}
    joint_raw: dict[str, list] = {}  # JointState topics: (stamp, bytes), decoded together afterwards
    try:
        with (Reader1 if ros1 else Reader2)(path) as reader:
            connections = [c for c in reader.connections if c.topic in extractors]
            store = _store_for(connections, ros1)
            deserialize = store.deserialize_ros1 if ros1 else store.deserialize_cdr
            for conn, timestamp_ns, raw in reader.messages(connections=connections):
                if extractors[conn.topic] is joint_state and conn.msgtype == JOINT_STATE_TYPE:
                    joint_raw.setdefault(conn.topic, []).append((timestamp_ns, bytes(raw)))  # the hot path
                    continue
                try:
                    values, msg_names = extractors[conn.topic](deserialize(raw, conn.msgtype))
                except Exception as exc:  # noqa: BLE001 - any decode/field error names the topic
                    raise BagFormatError(
                        f"{path}: topic {conn.topic!r} ({conn.msgtype}): {type(exc).__name__}: {exc}"
                    ) from exc
                rows[conn.topic].append((timestamp_ns, np.asarray(values, dtype=np.float64).reshape(-1)))
                if msg_names:
                    names[conn.topic] = tuple(msg_names)
    except BagFormatError:
        raise
    except Exception as exc:  # noqa: BLE001 - truncated or foreign files raise from inside rosbags
        raise BagFormatError(f"{path}: unreadable bag, truncated? ({type(exc).__name__}: {exc})") from exc
    for topic, items in joint_raw.items():
        try:
            values, names[topic] = decode_joint_states([r for _, r in items], ros1)
        except (ValueError, UnicodeDecodeError) as exc:
            raise BagFormatError(f"{path}: topic {topic!r} ({JOINT_STATE_TYPE}): {type(exc).__name__}: {exc}") from exc
        rows[topic] = [(t, v) for (t, _), v in zip(items, values, strict=True)]
    out = {}
    for topic, items in rows.items():
        if not items:
            continue
        widths = {len(v) for _, v in items}
        if len(widths) != 1:
            raise BagFormatError(f"{path}: topic {topic!r} messages have different lengths {sorted(widths)}")
        stamps = np.array([t for t, _ in items], dtype=np.int64)
        order = np.argsort(stamps, kind="stable")
        stamps, values = stamps[order], np.stack([v for _, v in items])[order]
        keep = np.append(stamps[1:] != stamps[:-1], True)  # equal stamps: the last message wins
        out[topic] = Stream(topic, stamps[keep] / 1e9, values[keep], names.get(topic))
    return out
