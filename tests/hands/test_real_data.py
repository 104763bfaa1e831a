"""Real vendor data: LinkerHand SDK presets, G1 Inspire teleoperation episodes, the Allegro home pose.

Expectations come from the gesture names (Chinese finger counting, fist, open, thumbs up) and the task
("pick up the bottle"), not from the numbers.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
import yaml

from lerobot_unidextok import hands
from lerobot_unidextok.constants import UDHM_INDEX
from lerobot_unidextok.udhm import JOINT_LIMITS_RAD

FINGERS4 = ("index", "middle", "ring", "pinky")
# Extended digits per gesture name (Chinese counting: 6 = thumb + little, 8 = thumb + index).
EXTENDED = {
    "open": {"thumb", *FINGERS4},
    "count_5": {"thumb", *FINGERS4},
    "fist": set(),
    "thumbs_up": {"thumb"},
    "count_1": {"index"},
    "count_2": {"index", "middle"},
    "count_3": {"index", "middle", "ring"},
    "count_4": set(FINGERS4),
    "count_6": {"thumb", "pinky"},
    "count_8": {"thumb", "index"},
}
SPEC_FOR_MODEL = {"L6": "linkerhand_l6", "L10": "linkerhand_l10", "L20": "linkerhand_l20"}


@pytest.fixture(scope="module")
def presets(real_data_dir):
    return json.loads((real_data_dir / "linkerhand-ros2-sdk" / "linkerhand_gui_preset_actions.json").read_text())


def _flex_fraction(spec: hands.HandSpec, state: np.ndarray, digit: str, side: str = "right") -> float:
    """Flexion of a digit's bending joint as a fraction of the hand's range for it (0 = open end).

    The LinkerHand thumb "flex" channels curl the thumb; the URDF check puts them in thumb_mcp_flex (the
    thumb's CMC slots are its swing out of and inside the palm plane).
    """
    slot = "thumb_mcp_flex" if digit == "thumb" else f"{digit}_mcp_flex"
    lo, hi = spec.udhm_limits_rad(side)
    i = UDHM_INDEX[slot]
    return float((state[i] - lo[i]) / (hi[i] - lo[i]))


def _check_gesture(spec, state, extended, side, where):
    for digit in ("thumb", *FINGERS4):
        frac = _flex_fraction(spec, state, digit, side)
        if digit in extended:
            assert frac <= 0.1, f"{where}: {digit} should be extended, flex at {frac:.0%} of max"
        elif digit == "thumb":
            assert frac >= 0.3, f"{where}: thumb should be folded, flex at {frac:.0%} of max"
        else:
            assert frac >= 0.9, f"{where}: {digit} should be flexed, flex at {frac:.0%} of max"


@pytest.mark.parametrize("model", sorted(SPEC_FOR_MODEL))
def test_linkerhand_gui_presets_match_their_names(presets, model):
    spec = hands.get(SPEC_FOR_MODEL[model])
    actions = presets[model]["preset_actions_en"]
    assert len(presets[model]["init_pos"]) == spec.num_native
    checked = 0
    for gesture, extended in EXTENDED.items():
        if gesture not in actions:
            continue
        for side in spec.sides:
            state = spec.to_udhm(np.array(actions[gesture], dtype=float), side)
            assert state.shape == (22,)
            _check_gesture(spec, state, extended, side, f"{model} {gesture} ({side})")
        checked += 1
    assert checked >= 4, f"{model}: only {checked} named gestures found"


@pytest.mark.parametrize("model", sorted(SPEC_FOR_MODEL))
def test_every_linkerhand_preset_is_in_range_and_round_trips(presets, model):
    spec = hands.get(SPEC_FOR_MODEL[model])
    raw = np.array(list(presets[model]["preset_actions_en"].values()), dtype=float)  # (P, J)
    active = np.array([j.slot is not None for j in spec.joints])
    for side in spec.sides:
        state = spec.to_udhm(raw, side)  # raises if any value is outside 0-255
        np.testing.assert_allclose(spec.from_udhm(state, side)[:, active], raw[:, active], atol=1e-9)


def test_linkerhand_open_pose_spreads_fingers_the_same_way_on_both_sides(presets):
    """L20 open preset: same raw values on both sides give index toward the thumb, little away from it."""
    spec = hands.get("linkerhand_l20")
    raw = np.array(presets["L20"]["preset_actions_en"]["open"], dtype=float)
    for side in spec.sides:
        state = spec.to_udhm(raw, side)
        assert state[UDHM_INDEX["index_mcp_abd"]] > 0.1
        assert state[UDHM_INDEX["pinky_mcp_abd"]] < -0.1


@pytest.mark.parametrize(
    ("file", "spec_name"), [("L6_positions.yaml", "linkerhand_l6"), ("L10_positions.yaml", "linkerhand_l10")]
)
def test_linkerhand_yaml_presets(real_data_dir, file, spec_name):
    """ROS2 SDK preset files: 张开 open, 握拳 fist, 食指弯曲 index bent."""
    spec = hands.get(spec_name)
    data = yaml.safe_load((real_data_dir / "linkerhand-ros2-sdk" / file).read_text())
    seen = 0
    for key, side in (("LEFT_HAND", "left"), ("RIGHT_HAND", "right")):
        for entry in data.get(key) or []:
            state = spec.to_udhm(np.array(entry["POSITION"], dtype=float), side)
            fingers = {f: _flex_fraction(spec, state, f, side) for f in FINGERS4}
            name = entry["ACTION_NAME"]
            if name == "张开":  # open
                assert max(fingers.values()) <= 0.1, (file, side, name, fingers)
            elif name == "握拳":  # fist
                assert min(fingers.values()) >= 0.9, (file, side, name, fingers)
            elif name == "食指弯曲":  # index bent, the others straight
                assert fingers["index"] >= 0.9 and max(fingers[f] for f in FINGERS4[1:]) <= 0.1
            else:
                continue
            seen += 1
    assert seen >= 2


# ---------------------------------------------------------------------------------------------
# G1 + Inspire (Unitree-normalised 0-1) LeRobot episodes
# ---------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def g1(real_data_dir):
    pd = pytest.importorskip("pandas")
    root = real_data_dir / "g1-inspire"
    info = json.loads((root / "meta" / "info.json").read_text())
    names = info["features"]["observation.state"]["names"]
    names = names[0] if isinstance(names[0], list) else names
    episodes = []
    for path in sorted((root / "data" / "chunk-000").glob("episode_*.parquet")):
        df = pd.read_parquet(path, columns=["observation.state", "action"])
        episodes.append({k: np.stack(df[k].to_numpy()).astype(np.float64) for k in ("observation.state", "action")})
    return names, episodes


def _hand_columns(names: list[str], side: str) -> list[int]:
    prefix = f"k{side.capitalize()}Hand"
    order = ["Pinky", "Ring", "Middle", "Index", "ThumbBend", "ThumbRotation"]  # = inspire spec order
    cols = [names.index(prefix + o) for o in order]
    assert hands.get("inspire_rh56_unitree").joint_names == (
        "little", "ring", "middle", "index", "thumb_bend", "thumb_rotation",
    )  # fmt: skip
    return cols


def test_g1_inspire_episodes_map_into_joint_limits(g1):
    """Every frame maps inside the spec's UDHM limits. Robot thumbs are not held to the human limits: the
    URDF check puts the Inspire thumb's open pose at a CMC spread of about 60 deg (rest offset)."""
    names, episodes = g1
    spec = hands.get("inspire_rh56_unitree")
    total = 0
    for side in ("left", "right"):
        cols = _hand_columns(names, side)
        lo, hi = spec.udhm_limits_rad(side)
        for ep in episodes:
            for key in ("observation.state", "action"):
                hands.check_units(spec, ep[key][:, cols], side)  # the real normalised data passes the units guard
                state = spec.to_udhm(ep[key][:, cols], side)  # raises on any value outside [0, 1]
                assert (state >= lo - 1e-9).all() and (state <= hi + 1e-9).all()
                fingers = [UDHM_INDEX[f"{f}_mcp_flex"] for f in FINGERS4]
                assert (state[:, fingers] >= JOINT_LIMITS_RAD[fingers, 0]).all()
                assert (state[:, fingers] <= JOINT_LIMITS_RAD[fingers, 1]).all()
                total += len(state)
    assert total == 2 * 2 * 4236


def test_g1_inspire_through_the_register_spec_is_caught(g1):
    """Unitree's 0-1 values through the 0-1000 `inspire_rh56` spec would convert into a hand held closed and
    validate; the units guard raises and names the Unitree spec as the fix."""
    names, episodes = g1
    values = episodes[0]["observation.state"][:, _hand_columns(names, "right")]
    with pytest.raises(hands.NativeUnitsError, match="inspire_rh56_unitree"):
        hands.check_units(hands.get("inspire_rh56"), values, "right")


def test_g1_inspire_grasp_flexes_right_hand_fingers(g1):
    """Pick-up task: the right hand closes mid-episode (not at the ends) and opens; the left hand stays idle."""
    names, episodes = g1
    spec = hands.get("inspire_rh56_unitree")
    finger_slots = [UDHM_INDEX[f"{f}_mcp_flex"] for f in FINGERS4]
    right_cols, left_cols = _hand_columns(names, "right"), _hand_columns(names, "left")
    for i, ep in enumerate(episodes):
        right = spec.to_udhm(ep["observation.state"][:, right_cols], "right")[:, finger_slots].mean(1)  # (T,)
        left = spec.to_udhm(ep["observation.state"][:, left_cols], "left")[:, finger_slots].mean(1)
        t = int(right.argmax())
        n = len(right)
        assert 0.1 * n < t < 0.9 * n, f"episode {i}: peak right-hand flexion at frame {t} of {n}"
        swing = right[t] - right.min()
        assert swing > 0.3, f"episode {i}: right-hand finger flexion varies by only {swing:.2f} rad"
        assert np.ptp(left) < 0.5 * swing, f"episode {i}: the idle left hand moves as much as the grasping right"


# ---------------------------------------------------------------------------------------------
# Allegro vendor home pose (degrees)
# ---------------------------------------------------------------------------------------------
def test_allegro_home_pose_maps_into_limits(real_data_dir):
    data = yaml.safe_load((real_data_dir / "allegro_hand_ros_v4" / "initial_position.yaml").read_text())
    pose = data["initial_position"]
    spec = hands.get("allegro")
    # jFK = finger F (0 index, 1 middle, 2 ring, 3 thumb), joint K -> joint_{4F+K}.0
    rad = np.deg2rad([pose[f"j{f}{k}"] for f in range(4) for k in range(4)])
    assert spec.joint_names[:2] == ("joint_0.0", "joint_1.0")
    state = spec.to_udhm(rad)  # raises if the vendor home pose were outside the URDF limits
    assert state[UDHM_INDEX["index_mcp_abd"]] == pytest.approx(0.0)
    assert state[UDHM_INDEX["index_pip_flex"]] == pytest.approx(np.deg2rad(45))
    active = np.array([j.slot is not None for j in spec.joints])  # joint 13 (thumb axial twist) is dropped
    np.testing.assert_allclose(spec.from_udhm(state)[active], rad[active], atol=1e-12)


def test_linkerhand_l6_channel_order_matches_linker_sim_decoder(real_data_dir):
    """linker-sim's L6 decoder (SDK channel -> URDF joint) agrees with the spec's order: ring before pinky."""
    decoder = yaml.safe_load((real_data_dir / "linker-sim" / "linkerhand_l6" / "decoder.yaml").read_text())
    channels = [c.replace("{S}h_", "") for c in decoder["channels"]]
    spec = hands.get("linkerhand_l6")
    assert channels[0] == spec.joint_names[0] == "thumb_cmc_pitch"
    assert channels[2:] == list(spec.joint_names[2:])


def test_linkerhand_conversion_is_the_sdk_formula():
    """derict = -1: rad = max - raw / 255 * (max - min), e.g. L10 right index: 1.62 - raw / 255 * 1.62."""
    offset, scale = hands.get("linkerhand_l10").conversion("right")
    assert offset[2] == pytest.approx(1.62) and scale[2] == pytest.approx(-1.62 / 255)
    assert offset[9] == pytest.approx(1.01) and scale[9] == pytest.approx(-1.53 / 255)  # thumb roll, min -0.52
