"""The direct JointState decoder of `converters/_rosbag.py` against rosbags' own deserializer."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_unidextok.converters._rosbag import decode_joint_state, decode_joint_states


@pytest.mark.parametrize("ros1", [True, False])
@pytest.mark.parametrize("frame_id, names, count", [("", [], 6), ("hand", ["joint71", "j"], 2), ("abc", [], 0)])
def test_decode_joint_state_matches_rosbags(ros1, frame_id, names, count):
    """Same position and names as rosbags for both serialisations, odd string lengths (CDR padding) included."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    t = store.types
    stamp = t["builtin_interfaces/msg/Time"](sec=1_720_000_123, nanosec=456_789)
    header = t["std_msgs/msg/Header"](**({"seq": 7} if ros1 else {}), stamp=stamp, frame_id=frame_id)
    position = np.random.default_rng(count).uniform(0, 255, count)
    msg = t["sensor_msgs/msg/JointState"](header=header, name=names, position=position,
                                          velocity=np.zeros(count), effort=np.zeros(1))  # fmt: skip
    raw = (
        store.serialize_ros1(msg, "sensor_msgs/msg/JointState")
        if ros1
        else store.serialize_cdr(msg, "sensor_msgs/msg/JointState")
    )
    got, got_names = decode_joint_state(raw, ros1)
    ref = (
        store.deserialize_ros1(raw, "sensor_msgs/msg/JointState")
        if ros1
        else store.deserialize_cdr(raw, "sensor_msgs/msg/JointState")
    )
    np.testing.assert_array_equal(got, ref.position)
    assert got_names == tuple(ref.name) == tuple(names)
    seen: dict = {}
    for k in range(3):  # the names-skipping path decodes the same as the full one, and notices new names
        msg.position = position + k
        if k == 2:
            msg.name = [n + "x" for n in names]
        raw = (
            store.serialize_ros1(msg, "sensor_msgs/msg/JointState")
            if ros1
            else store.serialize_cdr(msg, "sensor_msgs/msg/JointState")
        )
        got, got_names = decode_joint_state(raw, ros1, seen)
        np.testing.assert_array_equal(got, position + k)
        assert got_names == tuple(msg.name)
    batch = []  # many messages at once: the vectorised path (same size and names) and the fallback
    for k in range(4):
        msg.position, msg.name = position * k, list(names) if k < 3 else [n + "y" for n in names]
        batch.append(
            bytes(
                store.serialize_ros1(msg, "sensor_msgs/msg/JointState")
                if ros1
                else store.serialize_cdr(msg, "sensor_msgs/msg/JointState")
            )
        )
    for part in (batch[:3], batch):
        values, _ = decode_joint_states(part, ros1)
        np.testing.assert_array_equal(
            values, np.stack([position * k for k in range(len(part))]).reshape(len(part), count)
        )
