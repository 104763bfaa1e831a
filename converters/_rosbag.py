"""ROS 1 / ROS 2 bags (and MCAP) for the LET and LinkerHand readers: listing, reading topics, resampling.

Read with `rosbags` (pure Python, no ROS install; the `ros` extra). Message types come from the
definitions embedded in the bag (ROS 1 connection headers, MCAP schemas); types a bag does not define
are taken from the ROS 2 Humble / ROS 1 Noetic standard types plus the vendor definitions below
(`kuavo_msgs`, written from the upstream `.msg` files).

Recorded stamps jitter (a 30 Hz topic measures 30.14 Hz), and LeRobot stores a fixed integer fps, so
every stream is resampled onto one grid of `fps` frames per second over the time all required topics
cover (`resample`): **nearest** sample for commands (a command holds until the next one; LejuRobotics'
converter `kuavo_data/common/kuavo_dataset.py` `align_frame_data` takes the nearest message of every
topic), **linear** interpolation for measured joint states (or nearest, per reader option).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

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
INTERPOLATIONS = ("linear", "nearest")


class BagFormatError(ValueError):
    """A bag is unreadable or lacks a topic/field; the message names the file and the topic."""


def require_rosbags():
    try:
        import rosbags  # noqa: F401
    except ImportError as exc:
        raise ImportError("reading ROS bags needs rosbags (pure Python): pip install 'lerobot-unidextok[ros]'") from exc


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


def _fallback_typestore(ros1: bool):
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    for name, text in KUAVO_MSGS.items():
        store.register(get_types_from_msg(text, name))
    return store


@dataclass
class Stream:
    """One topic of one bag: log-time stamps (s) and per-message values (and names, e.g. JointState.name)."""

    topic: str
    stamps_s: np.ndarray  # (N,) float64, strictly increasing after `read_streams`
    values: np.ndarray  # (N, D) float64
    names: tuple[str, ...] | None = None


Extractor = Callable[[object], tuple[np.ndarray, tuple[str, ...] | None]]


def read_streams(path: Path, extractors: dict[str, Extractor]) -> dict[str, Stream]:
    """Every message of the `extractors`' topics present in the bag, in log-time order.

    Stamps are the bag's log (receive) times, as LejuRobotics' converter uses them (it overrides header
    stamps with the bag time: `kuavo_dataset.py` `process_rosbag`). Repeated stamps keep the last message.
    """
    require_rosbags()
    from rosbags.highlevel import AnyReader, AnyReaderError
    from rosbags.typesys import get_types_from_msg

    path = Path(path)
    ros1 = path.suffix == ".bag"
    try:
        reader = AnyReader([path], default_typestore=_fallback_typestore(ros1))
        reader.open()
    except (AnyReaderError, OSError, ValueError, KeyError) as exc:
        raise BagFormatError(f"{path}: unreadable bag ({type(exc).__name__}: {exc})") from exc
    try:
        for name, text in KUAVO_MSGS.items():  # types the bag itself does not define
            if name not in reader.typestore.fielddefs:
                reader.typestore.register(get_types_from_msg(text, name))
        connections = [c for c in reader.connections if c.topic in extractors]
        rows: dict[str, list] = {t: [] for t in extractors}
        names: dict[str, tuple[str, ...] | None] = {}
        for conn, timestamp_ns, raw in reader.messages(connections=connections):
            try:
                msg = reader.deserialize(raw, conn.msgtype)
                values, msg_names = extractors[conn.topic](msg)
            except Exception as exc:  # noqa: BLE001 - any decode/field error names the topic
                raise BagFormatError(
                    f"{path}: topic {conn.topic!r} ({conn.msgtype}): {type(exc).__name__}: {exc}"
                ) from exc
            rows[conn.topic].append((timestamp_ns, np.asarray(values, dtype=np.float64).reshape(-1)))
            if msg_names:
                names[conn.topic] = tuple(msg_names)
    except BagFormatError:
        raise
    except Exception as exc:  # noqa: BLE001 - truncated bags raise from inside rosbags
        raise BagFormatError(f"{path}: unreadable bag, truncated? ({type(exc).__name__}: {exc})") from exc
    finally:
        reader.close()
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


def grid_for(streams: list[Stream], fps: int, path: Path) -> np.ndarray:
    """Frame times (s) every 1/fps over the span every stream covers."""
    start = max(s.stamps_s[0] for s in streams)
    stop = min(s.stamps_s[-1] for s in streams)
    if stop <= start:
        raise BagFormatError(f"{path}: topics {[s.topic for s in streams]} do not overlap in time")
    num = int(np.floor((stop - start) * fps + 1e-9)) + 1
    return start + np.arange(num) / fps


def resample(stream: Stream, grid_s: np.ndarray, method: str) -> np.ndarray:
    """(len(grid), D) values of `stream` at the grid times: "nearest" sample or "linear" interpolation."""
    if method not in INTERPOLATIONS:
        raise ValueError(f"interpolation must be one of {INTERPOLATIONS}, got {method!r}")
    t, v = stream.stamps_s, stream.values
    if len(t) == 1:
        return np.repeat(v, len(grid_s), axis=0)
    if method == "nearest":
        right = np.clip(np.searchsorted(t, grid_s), 1, len(t) - 1)
        left = right - 1
        pick = np.where(np.abs(grid_s - t[left]) <= np.abs(t[right] - grid_s), left, right)
        return v[pick]
    out = np.empty((len(grid_s), v.shape[1]), dtype=np.float64)
    for d in range(v.shape[1]):
        out[:, d] = np.interp(grid_s, t, v[:, d])
    return out


def measured_rate_hz(stream: Stream) -> float:
    """Mean message rate of a stream (for reports: jittered stamps are expected)."""
    span = stream.stamps_s[-1] - stream.stamps_s[0]
    return (len(stream.stamps_s) - 1) / span if span > 0 else float("nan")
