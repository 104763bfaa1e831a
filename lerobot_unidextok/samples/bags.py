"""SYNTHETIC ROS bag samples: LET (ROS 1 bags) and LinkerHand (ROS 2 bags, sqlite3 and MCAP), written with
`rosbags`' own writers in the layout the real recordings have, from the upstream message definitions
(written out here, independently of the readers): jittered, slightly drifting stamps (a 30 Hz topic
measures ~30.14 Hz), a few dropped messages, topics at different rates, and the annotation sidecar.

Used by `samples.write_samples` (sources "let" and "linkerhand"); needs the `ros` extra.
"""

from __future__ import annotations

import json
from collections.abc import Callable
from pathlib import Path

import numpy as np

# kuavo_msgs, from LejuRobotics kuavo-ros-opensource (`src/kuavo_msgs/msg/*.msg`)
_KUAVO = {
    "kuavo_msgs/msg/robotHandPosition": "std_msgs/Header header\nuint8[] left_hand_position\nuint8[] right_hand_position\n",
    "kuavo_msgs/msg/jointData": "float64[] joint_q\nfloat64[] joint_v\nfloat64[] joint_vd\nfloat64[] joint_current\n",
    "kuavo_msgs/msg/imuData": "geometry_msgs/Vector3 gyro\ngeometry_msgs/Vector3 acc\ngeometry_msgs/Vector3 free_acc\n"
    "geometry_msgs/Quaternion quat\n",
    "kuavo_msgs/msg/endEffectorData": "string[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n",
    "kuavo_msgs/msg/sensorsData": "std_msgs/Header header\ntime sensor_time\nkuavo_msgs/jointData joint_data\n"
    "kuavo_msgs/imuData imu_data\nkuavo_msgs/endEffectorData end_effector_data\n",
}
KUAVO_HAND = ("thumb", "thumb_aux", "index", "middle", "ring", "pinky")  # dexhand/state order, l_ then r_


def message_times_s(rng: np.random.Generator, start_s: float, duration_s: float, rate_hz: float) -> np.ndarray:
    """Publish times of a nominal `rate_hz` topic as a recorder sees them: a slightly fast clock (1.5 %),
    1.5 ms jitter and ~1 % dropped messages, so a 30 Hz topic measures ~30.14 Hz."""
    nominal = np.arange(0.0, duration_s, 1.0 / (rate_hz * 1.015))
    times = start_s + nominal + rng.normal(0.0, 0.0015, len(nominal))
    keep = rng.random(len(times)) > 0.01
    keep[[0, -1]] = True
    return np.sort(times[keep])


def sample_at(track_times_s: np.ndarray, values: np.ndarray, times_s: np.ndarray) -> np.ndarray:
    """Values of a densely sampled track at message times (linear)."""
    return np.stack([np.interp(times_s, track_times_s, values[:, d]) for d in range(values.shape[1])], axis=1)


def _stamp(store, seconds: float):
    sec = int(np.floor(seconds))
    return store.types["builtin_interfaces/msg/Time"](
        sec=sec, nanosec=int(round((seconds - sec) * 1e9)) % 1_000_000_000
    )


def _header(store, seconds: float, ros1: bool, seq: int = 0):
    cls = store.types["std_msgs/msg/Header"]
    if ros1:
        return cls(seq=seq, stamp=_stamp(store, seconds), frame_id="")
    return cls(stamp=_stamp(store, seconds), frame_id="")


def _joint_state(store, seconds: float, names: list[str], position: np.ndarray, ros1: bool, seq: int = 0):
    return store.types["sensor_msgs/msg/JointState"](
        header=_header(store, seconds, ros1, seq),
        name=list(names),
        position=np.asarray(position, dtype=np.float64),
        velocity=np.zeros(len(position)),
        effort=np.zeros(len(position)),
    )


# ---------------------------------------------------------------------------------------------
# LET: ROS 1 bags of a Kuavo 4 Pro with two 6-DoF hands
# ---------------------------------------------------------------------------------------------
def write_let_bag(
    path: Path,
    rng: np.random.Generator,
    start_s: float,
    duration_s: float,
    hands_0_100: Callable[[np.ndarray], dict[str, np.ndarray]],
    arms_rad: Callable[[np.ndarray], np.ndarray],
) -> dict[str, float]:
    """One LET episode bag. `hands_0_100(times) -> {"left": (N, 6), "right": (N, 6)}` commands on the
    0-100 scale (0 = open); the measured state follows them; `arms_rad(times) -> (N, 14)`.
    Returns each topic's measured rate (Hz)."""
    from rosbags.rosbag1 import Writer
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC)
    for name, text in _KUAVO.items():
        store.register(get_types_from_msg(text, name))
    topics = {
        "/control_robot_hand_position": ("kuavo_msgs/msg/robotHandPosition", 30.0),
        "/dexhand/state": ("sensor_msgs/msg/JointState", 100.0),
        "/sensors_data_raw": ("kuavo_msgs/msg/sensorsData", 100.0),
        "/kuavo_arm_traj": ("sensor_msgs/msg/JointState", 30.0),
    }
    rates = {}
    with Writer(path) as writer:
        connections = {t: writer.add_connection(t, msgtype, typestore=store) for t, (msgtype, _) in topics.items()}
        messages = []
        for topic, (msgtype, rate) in topics.items():
            times = message_times_s(rng, start_s, duration_s, rate)
            rates[topic] = (len(times) - 1) / (times[-1] - times[0])
            if topic == "/control_robot_hand_position":
                cmd = hands_0_100(times)
                for k, t in enumerate(times):
                    msg = store.types[msgtype](
                        header=_header(store, t, True, k),
                        left_hand_position=np.round(cmd["left"][k]).clip(0, 100).astype(np.uint8),
                        right_hand_position=np.round(cmd["right"][k]).clip(0, 100).astype(np.uint8),
                    )
                    messages.append((t, topic, msgtype, msg))
            elif topic == "/dexhand/state":
                lag = hands_0_100(times - 0.05)  # the hand follows its command ~50 ms later
                names = [f"l_{j}" for j in KUAVO_HAND] + [f"r_{j}" for j in KUAVO_HAND]
                for k, t in enumerate(times):
                    pos = np.concatenate([lag["left"][k], lag["right"][k]]).clip(0, 100)
                    messages.append((t, topic, msgtype, _joint_state(store, t, names, pos, True, k)))
            elif topic == "/sensors_data_raw":
                arms = arms_rad(times)
                for k, t in enumerate(times):
                    q = np.concatenate([np.zeros(12), arms[k], np.zeros(2)])  # 12 legs, 14 arms, 2 head
                    vec = store.types["geometry_msgs/msg/Vector3"]
                    msg = store.types[msgtype](
                        header=_header(store, t, True, k),
                        sensor_time=_stamp(store, t),
                        joint_data=store.types["kuavo_msgs/msg/jointData"](
                            joint_q=q, joint_v=np.zeros(28), joint_vd=np.zeros(28), joint_current=np.zeros(28)
                        ),
                        imu_data=store.types["kuavo_msgs/msg/imuData"](
                            gyro=vec(x=0.0, y=0.0, z=0.0),
                            acc=vec(x=0.0, y=0.0, z=9.81),
                            free_acc=vec(x=0.0, y=0.0, z=0.0),
                            quat=store.types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
                        ),
                        end_effector_data=store.types["kuavo_msgs/msg/endEffectorData"](
                            name=[], position=np.zeros(0), velocity=np.zeros(0), effort=np.zeros(0)
                        ),
                    )
                    messages.append((t, topic, msgtype, msg))
            else:  # /kuavo_arm_traj: arm targets in degrees
                arms = arms_rad(times + 0.03)
                names = [f"arm_joint_{i}" for i in range(1, 15)]
                for k, t in enumerate(times):
                    messages.append((t, topic, msgtype, _joint_state(store, t, names, np.rad2deg(arms[k]), True, k)))
        for t, topic, msgtype, msg in sorted(messages, key=lambda m: m[0]):
            writer.write(connections[topic], int(round(t * 1e9)), store.serialize_ros1(msg, msgtype))
    return rates


def write_let_sidecar(path: Path, task_folder: str, start_s: float, duration_s: float) -> None:
    """The per-bag annotation JSON (scene metadata and per-step skill marks)."""
    detail = task_folder.split("-P4-")[0].replace("_", " ")
    half = start_s + duration_s / 2
    payload = {
        "synthetic": True,
        "taskName": task_folder,
        "marks": [
            {"skillAtomic": "grasp", "enSkillDetail": f"{detail}: grasp", "startTime": start_s, "endTime": half},
            {"skillAtomic": "release", "enSkillDetail": f"{detail}: release", "startTime": half,
             "endTime": start_s + duration_s},
        ],
    }  # fmt: skip
    path.write_text(json.dumps(payload))


# ---------------------------------------------------------------------------------------------
# LinkerHand: ROS 2 bags of the linker_hand_ros2_sdk topics
# ---------------------------------------------------------------------------------------------
def write_linkerhand_bag(
    path: Path,
    rng: np.random.Generator,
    start_s: float,
    duration_s: float,
    model: str,
    hands_0_255: Callable[[np.ndarray], dict[str, np.ndarray]],
    arc: Callable[[dict[str, np.ndarray]], dict[str, np.ndarray]],
    mcap: bool = False,
) -> dict[str, float]:
    """One LinkerHand episode as a ROS 2 bag folder (sqlite3, or MCAP storage): per side
    `/cb_<side>_hand_state` (JointState 0-255, ~60 Hz), `_control_cmd` (30 Hz), `_state_arc` (radians)
    and `/cb_<side>_hand_info` (String JSON with `hand_joint`). Returns measured rates (Hz)."""
    from rosbags.rosbag2 import StoragePlugin, Writer
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS2_HUMBLE)
    messages, rates, connections = [], {}, {}
    plugin = StoragePlugin.MCAP if mcap else StoragePlugin.SQLITE3
    with Writer(path, version=9, storage_plugin=plugin) as writer:
        for side in ("left", "right"):
            for suffix, msgtype in (("state", "sensor_msgs/msg/JointState"), ("control_cmd", "sensor_msgs/msg/JointState"),
                                    ("state_arc", "sensor_msgs/msg/JointState"), ("info", "std_msgs/msg/String")):  # fmt: skip
                topic = f"/cb_{side}_hand_{suffix}"
                connections[topic] = writer.add_connection(topic, msgtype, typestore=store)
            cmd_times = message_times_s(rng, start_s, duration_s, 30.0)
            state_times = message_times_s(rng, start_s, duration_s, 60.0)
            rates[f"/cb_{side}_hand_control_cmd"] = (len(cmd_times) - 1) / (cmd_times[-1] - cmd_times[0])
            rates[f"/cb_{side}_hand_state"] = (len(state_times) - 1) / (state_times[-1] - state_times[0])
            cmd = np.round(hands_0_255(cmd_times)[side]).clip(0, 255)
            state = np.round(hands_0_255(state_times - 0.04)[side]).clip(0, 255)  # follows ~40 ms later
            state_arc = arc({side: state})[side]
            names = [f"joint{71 + i}" for i in range(cmd.shape[1])]
            jtype = "sensor_msgs/msg/JointState"
            for k, t in enumerate(cmd_times):
                messages.append((t, f"/cb_{side}_hand_control_cmd", jtype, _joint_state(store, t, [], cmd[k], False)))
            for k, t in enumerate(state_times):
                messages.append((t, f"/cb_{side}_hand_state", jtype, _joint_state(store, t, names, state[k], False)))
                messages.append(
                    (t, f"/cb_{side}_hand_state_arc", jtype, _joint_state(store, t, names, state_arc[k], False))
                )
            info = {
                "version": [int(model[1:]), 0, 0, 76 if side == "left" else 82],
                "hand_joint": model,
                "is_touch": False,
            }
            for t in np.arange(start_s + 0.2, start_s + duration_s, 1.0):
                messages.append(
                    (
                        t,
                        f"/cb_{side}_hand_info",
                        "std_msgs/msg/String",
                        store.types["std_msgs/msg/String"](data=json.dumps(info)),
                    )
                )
        for t, topic, msgtype, msg in sorted(messages, key=lambda m: m[0]):
            writer.write(connections[topic], int(round(t * 1e9)), store.serialize_cdr(msg, msgtype))
    return rates
