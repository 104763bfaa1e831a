"""Zero-shot on hands added by a YAML spec only: the O6 / L7 specs in experiments/hands/ load, validate, follow
the LinkerHand SDK's own raw -> radian table, stay out of the registry, map the real vendor presets into range,
and the experiment scores them end to end through the unknown-hand embedding.

The SDK tables are typed here from linker-bot/linkerhand-ros2-sdk @ bba0b9d, LinkerHand/utils/mapping.py, not
read from the specs under test.
"""

import json

import numpy as np
import pytest
import yaml

from experiments.universal_zeroshot import (
    GUI_PRESETS,
    SDK_DIR,
    ZeroShotConfig,
    markdown,
    run_and_write,
    spec_path,
    vendor_presets,
)
from lerobot_unidextok import hands
from lerobot_unidextok.constants import UDHM_INDEX
from lerobot_unidextok.pretrained import UNIVERSAL_SMALL
from lerobot_unidextok.tokenizer import UniDexTok
from lerobot_unidextok.training.coverage import range_states

# mapping.py: (min, max, derict) per side; derict -1: rad = max - v/255*(max-min), 0: rad = min + v/255*(max-min)
SDK = {
    "O6": {side: ([0] * 6, [0.58, 1.36, 1.6, 1.6, 1.6, 1.6], [-1] * 6) for side in ("left", "right")},
    "L7": {"left": ([0] * 7, [0.44, 1.43, 1.62, 1.62, 1.62, 1.62, 1.01], [-1] * 7),
           "right": ([0, -1.43, 0, 0, 0, 0, 0], [0.75, 0, 1.62, 1.62, 1.62, 1.62, 1.54], [-1, 0, -1, -1, -1, -1, -1])},
}  # fmt: skip
# native channel -> UDHM slot (L6 layout; the L7's thumb roll has none)
SLOTS = ["thumb_mcp_flex", "thumb_cmc_flex", "index_mcp_flex", "middle_mcp_flex", "ring_mcp_flex", "pinky_mcp_flex"]


def sdk_radians(model: str, side: str, raw: np.ndarray) -> np.ndarray:
    lo, hi, direction = (np.asarray(a, dtype=float) for a in SDK[model][side])
    return np.where(direction == -1, hi - raw / 255 * (hi - lo), lo + raw / 255 * (hi - lo))


@pytest.fixture(scope="module")
def specs() -> dict:
    return {hands.load_spec(spec_path(p)).name.removeprefix("linkerhand_").upper(): hands.load_spec(spec_path(p))
            for p in ZeroShotConfig().specs}  # fmt: skip


def test_the_yaml_only_specs_load_and_stay_outside_the_registry_and_the_shipped_vocabulary(specs):
    assert set(specs) == {"O6", "L7"}
    shipped = UniDexTok.from_pretrained(UNIVERSAL_SMALL)
    for spec in specs.values():
        assert spec.name not in hands.names()
        assert not shipped.knows_hand(spec.name)
        assert spec.active_mask.sum() == 6 and spec.path.parent.name == "hands"
    assert specs["L7"].dropped_joints == ("thumb_roll",)


@pytest.mark.parametrize("model", ["O6", "L7"])
@pytest.mark.parametrize("side", ["right", "left"])
def test_the_specs_follow_the_sdk_table(specs, model, side):
    spec = specs[model]
    raw = np.array([[0] * spec.num_native, [255] * spec.num_native, [67, 151, 0, 37, 200, 255, 93][: spec.num_native]])
    np.testing.assert_allclose(spec.to_radians(raw, side), sdk_radians(model, side, raw), atol=1e-12)
    udhm = spec.to_udhm(raw, side)
    assert np.all(udhm[1] == 0)  # 255 = open = UDHM zero on every slot (no rest offsets without a URDF)
    # fully closed: every slot at the magnitude of its SDK range, positive (right L7 thumb abduction: sign -1)
    expected = np.abs(sdk_radians(model, side, raw[:1]))[0, :6]
    np.testing.assert_allclose(udhm[0, [UDHM_INDEX[s] for s in SLOTS]], expected, atol=1e-12)
    np.testing.assert_allclose(spec.from_udhm(udhm[2], side)[:6], raw[2, :6], atol=1e-9)


def test_range_states_of_a_yaml_only_spec_stay_in_its_ranges(specs):
    spec = specs["L7"]
    data = range_states(spec, 2000, seed=0)
    assert set(data.hands) == {"linkerhand_l7"}
    lo = np.min([spec.udhm_limits_rad(s)[0] for s in spec.sides], 0)
    hi = np.max([spec.udhm_limits_rad(s)[1] for s in spec.sides], 0)
    assert np.all(data.states_rad >= lo - 1e-6) and np.all(data.states_rad <= hi + 1e-6)
    thumb = data.states_rad[:, UDHM_INDEX["thumb_mcp_flex"]]
    assert thumb.max() > 0.6  # the right side's 0.75 rad thumb flex is drawn, not only the left's 0.44


def write_presets(root, o6_yaml: dict, gui: dict) -> None:
    (root / SDK_DIR).mkdir(parents=True)
    (root / SDK_DIR / "O6_positions.yaml").write_text(yaml.safe_dump(o6_yaml, allow_unicode=True))
    (root / SDK_DIR / GUI_PRESETS).write_text(json.dumps(gui, ensure_ascii=False))


def test_vendor_presets_take_each_sdk_pose_on_its_side_and_gui_poses_on_both(specs, tmp_path):
    spec = specs["O6"]
    fist, opened = [67, 151, 0, 0, 0, 0], [255, 70, 255, 255, 255, 255]
    write_presets(tmp_path, {"LEFT_HAND": [{"ACTION_NAME": "fist", "POSITION": fist}],
                             "RIGHT_HAND": [{"ACTION_NAME": "open", "POSITION": opened}]},
                  {"O6": {"preset_actions": {"open": opened, "ok": [139, 91, 103, 250, 250, 250]}}})  # fmt: skip
    data, counts = vendor_presets(spec, tmp_path)
    assert counts == {"sdk_yaml": 2, "gui": 4, "unique": 5}  # GUI "open" on the right repeats the SDK's pose
    assert len(data) == 5 and set(data.hands) == {"linkerhand_o6"}
    np.testing.assert_allclose(data.states_rad[0], spec.to_udhm(np.array(fist, float), "left"), atol=1e-6)
    assert vendor_presets(specs["L7"], tmp_path)[0] is None  # no L7 presets in this folder


def test_the_real_vendor_presets_map_into_range(specs, real_data_dir):
    for model, spec in specs.items():
        data, counts = vendor_presets(spec, real_data_dir)
        assert counts["sdk_yaml"] == 3 and counts["gui"] > 0
        sdk = yaml.safe_load((real_data_dir / SDK_DIR / f"{model}_positions.yaml").read_text())
        for key, side in (("RIGHT_HAND", "right"), ("LEFT_HAND", "left")):
            lo, hi = spec.udhm_limits_rad(side)
            for preset in sdk[key]:
                state = spec.to_udhm(np.array(preset["POSITION"], float), side)  # raises when out of range
                assert np.all(state >= lo - 1e-9) and np.all(state <= hi + 1e-9)
        assert np.all(np.abs(data.states_rad) <= 1.62 + 1e-6)


def test_the_experiment_scores_yaml_only_hands_zero_shot_end_to_end(tmp_path):
    real = tmp_path / "real"
    opened = [255, 70, 255, 255, 255, 255]
    write_presets(real, {"RIGHT_HAND": [{"ACTION_NAME": "open", "POSITION": opened}]},
                  {"O6": {"preset_actions": {"fist": [102, 18, 0, 0, 0, 0]}}})  # fmt: skip
    cfg = ZeroShotConfig(rows=64, real_data_dir=str(real), output_root=str(tmp_path / "out"))
    result = run_and_write(cfg)
    got = [(r["hand"], r["states"], r["tokenizer_row"], r["zero_shot"], r["rows"]) for r in result["rows"]]
    in_range = "in-range (64, seed 0)"
    assert got == [
        ("linkerhand_o6", in_range, "unknown", True, 64),
        ("linkerhand_o6", "vendor presets", "unknown", True, 3),
        ("linkerhand_l7", in_range, "unknown", True, 64),
        ("linkerhand_l6", in_range, "own", False, 64),
        ("linkerhand_l6", in_range, "unknown", True, 64),
    ]
    for r in result["rows"]:
        assert np.isfinite(r["mpjae_deg"]) and r["mpjae_deg"] > 0 and 0 < r["binning_mpjae_deg"] < 0.2
    own, unknown = result["rows"][3], result["rows"][4]
    assert own["binning_mpjae_deg"] == unknown["binning_mpjae_deg"] and own["mpjae_deg"] != unknown["mpjae_deg"]
    written = json.loads((tmp_path / "out" / "universal_zeroshot" / "universal_zeroshot.json").read_text())
    assert written["rows"] == result["rows"] and written["model"]["checkpoint"] == UNIVERSAL_SMALL
    table = markdown(result).splitlines()
    assert len(table) == 2 + 5 and "unknown (zero-shot)" in table[2]


def test_a_hand_in_the_vocabulary_is_refused_and_a_newer_registered_one_is_scored(tmp_path):
    """Zero-shot means outside the tokenizer's vocabulary: the L6 (trained) is refused, by file or by name; the
    Dex3-1, registered after `unidextok/universal-small` was trained (named by its id: the residual one trained on
    it), is scored through the unknown-hand row."""
    for spec in (str(hands.SPECS_DIR / "linkerhand_l6.yaml"), "linkerhand_l6"):
        with pytest.raises(ValueError, match=r"\['linkerhand_l6'\] are in the tokenizer's vocabulary"):
            run_and_write(ZeroShotConfig(specs=[spec], rows=8, output_root=str(tmp_path)))
    result = run_and_write(ZeroShotConfig(specs=["unitree_dex3_1"], relatives=[], rows=8, output_root=str(tmp_path),
                                          checkpoint=UNIVERSAL_SMALL))  # fmt: skip
    (row,) = result["rows"]
    assert row["hand"] == "unitree_dex3_1" and row["zero_shot"] and row["rows"] == 8
