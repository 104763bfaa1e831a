"""Every number checked at its door (issue 54): a table that crosses each reader of statistics, share weights,
grasp centres and checkpoint tensors with each bad value (NaN, inf, negative, wrong length, absurd magnitude,
wrong type). Each cell is either one error of the reader's type whose message names the field, or, where the value
is a legitimate one for that reader (a negative grasp-centre coordinate, a negative weight in a network), a correct
result. A new reader of a number gets its row by being added to `READERS` and `TABLE`.

The readers run on real files: a copy of a real mix's `meta/` (tests/conftest.py `g1_l10_mix`, written by
unidextok-mix) with its record edited, a recorder's `unidextok_wrist_frame.json`, a `<type>_udt` config saved and
reloaded through LeRobot's `PreTrainedConfig`, a `unidextok.hand_normalizer` step's saved state, safetensors files.
"""

from __future__ import annotations

import copy
import json
import re
import shutil
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest
import torch
from l10_robot import HAND as L10
from robot_udhm import INSPIRE
from safetensors.torch import save_file

from lerobot_unidextok.blocks import udhm_state_names
from lerobot_unidextok.constants import ACTION, CONVERSION_PATH, OBS_STATE, UDHM_DIM
from lerobot_unidextok.conversion.hand_stats import recorded_hand_stats
from lerobot_unidextok.conversion.mix import MixOptions
from lerobot_unidextok.data import UdhmDatasetMeta
from lerobot_unidextok.data.wrist_frame import WRIST_FRAME_PATH, WristFrameError, read_recorded
from lerobot_unidextok.policies.checkpoint import PolicyCheckpointError, check_finite
from lerobot_unidextok.policies.deploy import DeployError, deploy
from lerobot_unidextok.processor import HandNormalizerStep
from lerobot_unidextok.utils.number_checks import MIN_SHARE, NumberError, checked_shares

BAD = ("nan", "inf", "negative", "wrong_length", "absurd", "wrong_type")
WRIST = ["wrist_x", "wrist_y", "wrist_z", "wrist_roll", "wrist_pitch", "wrist_yaw"]
HANDS = [INSPIRE, L10]  # the mix's vocabulary (tests/conftest.py g1_l10_mix)


def _bad_list(good: list[float], kind: str, at: int = 1):
    """`good` with the bad value of `kind` at index `at` (or as a whole)."""
    out = list(good)
    if kind == "wrong_length":
        return out[:-1]
    if kind == "wrong_type":
        return "abc"
    out[at] = {"nan": float("nan"), "inf": float("inf"), "negative": -0.05, "absurd": 1e6}[kind]
    return out


# ---------------------------------------------------------------------------------------------- the readers
def _stats_entry(kind: str | None) -> dict:
    """One hand's action statistics (mean/std as the policies keep them) with the bad value in its std (its mean
    for a wrong type: `"mean": "abc"`)."""
    entry = {"mean": [0.1] * UDHM_DIM, "std": [0.2] * UDHM_DIM, "frames": 40}
    if kind == "wrong_type":
        entry["mean"] = "abc"
    elif kind is not None:
        entry["std"] = _bad_list(entry["std"], kind)
    return entry


def read_record_hand_stats(kind: str, ctx: dict) -> None:
    """The mix's recorded hand_stats (meta/unidextok_conversion.json), read as lerobot-train reads it."""
    root = ctx["tmp"] / "mix"
    shutil.copytree(ctx["mix"] / "meta", root / "meta")
    path = root / CONVERSION_PATH
    record = json.loads(path.read_text())
    hand = record["hand_stats"][ACTION]["right"][L10]
    bad = _stats_entry(kind)
    hand["mean" if kind == "wrong_type" else "std"] = bad["mean" if kind == "wrong_type" else "std"]
    path.write_text(json.dumps(record))
    recorded_hand_stats(UdhmDatasetMeta(root))


def _udt_config_json(tmp: Path, stats: dict) -> Path:
    """A saved act_udt config.json of a mix policy whose udt_hand_stats are `stats`."""
    from lerobot.configs.types import FeatureType, PolicyFeature

    from lerobot_unidextok.policies import ACTUdtConfig

    names = udhm_state_names(["left", "right"])
    good = {"modes": {ACTION: "MEAN_STD"}, ACTION: {"right": {h: _stats_entry(None) for h in HANDS},
                                                    "left": {INSPIRE: _stats_entry(None)}}}  # fmt: skip
    cfg = ACTUdtConfig(
        input_features={OBS_STATE: PolicyFeature(FeatureType.STATE, (len(names),))},
        output_features={ACTION: PolicyFeature(FeatureType.ACTION, (len(names),))},
        udt_hand_vocabulary=list(HANDS), udt_sides=["left", "right"], udt_state_names=names, udt_action_names=names,
        udt_hand_stats=good, device="cpu",
    )  # fmt: skip
    folder = tmp / "policy"
    folder.mkdir(parents=True)
    cfg._save_pretrained(folder)
    saved = json.loads((folder / "config.json").read_text())
    saved["udt_hand_stats"] = stats if stats is not None else good
    (folder / "config.json").write_text(json.dumps(saved))
    return folder


def read_udt_config(kind: str, ctx: dict) -> None:
    """udt_hand_stats of a checkpoint's config.json, read through LeRobot's PreTrainedConfig (train resume,
    deploy, push, eval)."""
    from lerobot.configs.policies import PreTrainedConfig

    stats = {"modes": {ACTION: "MEAN_STD"}, ACTION: {"right": {INSPIRE: _stats_entry(None), L10: _stats_entry(kind)},
                                                     "left": {INSPIRE: _stats_entry(None)}}}  # fmt: skip
    folder = _udt_config_json(ctx["tmp"], stats)
    try:
        PreTrainedConfig.from_pretrained(folder)
    except Exception as err:  # noqa: BLE001  draccus wraps a __post_init__ refusal: find ours
        raise _ours(err) from None


def _ours(err: BaseException) -> BaseException:
    seen = err
    while seen is not None and not isinstance(seen, NumberError):
        seen = seen.__cause__ or seen.__context__
    return seen or err


def _normaliser(stats: dict | None = None) -> HandNormalizerStep:
    names = udhm_state_names(["right"])
    return HandNormalizerStep(mode="normalize", modes={ACTION: "MEAN_STD"}, state_names=names, action_names=names,
                              hand_vocabulary=list(HANDS), stats=stats or {}, dataset_stats={})  # fmt: skip


def read_normaliser_state(kind: str, ctx: dict) -> None:
    """A unidextok.hand_normalizer step's saved statistics (its safetensors state), through load_state_dict."""
    saved = _normaliser({ACTION: {"right": {h: _stats_entry(None) for h in HANDS}}}).state_dict()
    std = saved["action.std"]  # (blocks, hands, 22)
    if kind == "wrong_length":
        saved["action.std"] = std[..., :-1]
    else:  # (no wrong type: a safetensors file holds tensors only, see NOT_APPLICABLE)
        std[0, 1, 3] = {"nan": float("nan"), "inf": float("inf"), "negative": -0.05, "absurd": 1e6}[kind]
    _normaliser().load_state_dict(saved)


def read_mix_weights(kind: str, ctx: dict) -> None:
    """unidextok-mix --weights (MixOptions, what the CLI parses into)."""
    weights = [3.0, 1.0] if kind != "absurd" else [1e-300, 1.0]
    bad = weights if kind == "absurd" else _bad_list(weights, kind, at=0)
    MixOptions(inputs=["a", "b"], root=str(ctx["tmp"] / "mix_out"), weights=bad)


def read_grasp_centre_flag(kind: str, ctx: dict) -> None:
    """unidextok-deploy --grasp_centre_m, checked before anything is read."""
    with pytest.raises(DeployError, match="is not a LeRobot policy checkpoint"):  # past the flag: a good number
        deploy(ctx["tmp"] / "no_checkpoint", ctx["tmp"] / "no_robot", ctx["tmp"] / "out",
               grasp_centre_m=_bad_list([0.02, -0.01, 0.08], kind))  # fmt: skip


def read_wrist_frame_json(kind: str, ctx: dict) -> None:
    """A recording's meta/unidextok_wrist_frame.json, read as unidextok-convert reads it."""
    root = ctx["tmp"] / "recorded"
    (root / "meta").mkdir(parents=True)
    centre = _bad_list([0.02, -0.01, 0.08], kind)
    (root / WRIST_FRAME_PATH).write_text(json.dumps({"columns": WRIST, "grasp_centre_in_wrist_m": {"shadow": centre}}))
    read_recorded(root)


def read_safetensors(kind: str, ctx: dict) -> None:
    """A checkpoint's safetensors file, scanned before push and deploy ship it."""
    weight = torch.full((4, 3), 0.5)
    weight[1, 2] = {"nan": float("nan"), "inf": float("inf"), "negative": -0.05, "absurd": 1e6}[kind]
    path = ctx["tmp"] / "model.safetensors"
    save_file({"model.head.weight": weight, "model.head.bias": torch.zeros(3)}, str(path))
    check_finite(path)


# reader -> (function, the error it raises, what its message must name)
READERS: dict[str, tuple[Callable[[str, dict], None], type[Exception], str]] = {
    "record hand_stats": (read_record_hand_stats, NumberError,
                          rf"unidextok_conversion.json hand_stats\['action'\]\['right'\]\['{L10}'\]\.(std|mean)"),
    "udt_hand_stats": (read_udt_config, NumberError, rf"udt_hand_stats\['action'\]\['right'\]\['{L10}'\]\.(std|mean)"),
    "normaliser state": (read_normaliser_state, (NumberError, ValueError), r"(tensor 'action.std'|saved action.std)"),
    "mix --weights": (read_mix_weights, NumberError, r"--weights"),
    "--grasp_centre_m": (read_grasp_centre_flag, WristFrameError, r"--grasp_centre_m: the grasp centre"),
    "wrist frame json": (read_wrist_frame_json, WristFrameError, r"unidextok_wrist_frame.json: the grasp centre of "
                                                                 r"'shadow'"),
    "safetensors": (read_safetensors, PolicyCheckpointError, r"model.safetensors: tensor model.head.weight"),
}  # fmt: skip
# what each bad value must be called; None: a legitimate value for that reader, which it accepts
PROBLEM = {"nan": "holds NaN", "inf": "holds inf", "negative": r"must be (>= 0|> 0)", "wrong_length": "must be",
           "absurd": "beyond the plausible", "wrong_type": "must be"}  # fmt: skip
ACCEPTED = {
    ("--grasp_centre_m", "negative"): "a centre behind or beside the wrist",
    ("wrist frame json", "negative"): "a centre behind or beside the wrist",
    ("safetensors", "negative"): "a negative weight",
    ("safetensors", "absurd"): "a large weight (the strict load checks shapes; magnitudes are the model's)",
}
NOT_APPLICABLE = {("normaliser state", "wrong_type"), ("safetensors", "wrong_length"), ("safetensors", "wrong_type")}
TABLE = [(r, k) for r in READERS for k in BAD if (r, k) not in NOT_APPLICABLE]
SPECIAL = {  # cells whose message differs from PROBLEM's
    ("normaliser state", "wrong_length"): r"has shape \(1, 2, 21\), this step's layout \(1, 2, 22\)",
    ("mix --weights", "absurd"): r"\[1e-300, 1\] give input 0 a share of 1e-300 of the training frames, below the "
                                 r"0\.001",
    ("safetensors", "nan"): "holds 1 NaN/inf of 12 values",
    ("safetensors", "inf"): "holds 1 NaN/inf of 12 values",
}  # fmt: skip


@pytest.fixture
def ctx(g1_l10_mix, tmp_path) -> dict:
    return {"mix": g1_l10_mix, "tmp": tmp_path}


@pytest.mark.parametrize("reader, kind", TABLE, ids=[f"{r}-{k}" for r, k in TABLE])
def test_each_reader_refuses_each_bad_number_naming_the_field(reader, kind, ctx):
    read, error, field = READERS[reader]
    if (reader, kind) in ACCEPTED:  # a legitimate value: read without a word
        read(kind, ctx)
        return
    with pytest.raises(error) as info:
        read(kind, ctx)
    message = str(info.value)
    assert "\n" not in message, message
    assert re.search(field, message), (field, message)
    assert re.search(SPECIAL.get((reader, kind), PROBLEM[kind]), message), message


def test_the_table_covers_every_reader_with_every_bad_value():
    """A cell left out must be one that cannot occur (a file format that holds only tensors of fixed shape)."""
    assert {(r, k) for r in READERS for k in BAD} - set(TABLE) == NOT_APPLICABLE
    assert set(ACCEPTED) <= set(TABLE)


# ---------------------------------------------------------------------------------------------- beyond the table
def test_a_hand_missing_or_renamed_in_the_statistics_is_named_not_pooled(ctx):
    """A hand missing from the statistics, or renamed, was silently normalised with the other hands' statistics."""
    stats = {ACTION: {"right": {INSPIRE: _stats_entry(None)}}}
    with pytest.raises(NumberError, match=rf"has no statistics for hands \['{L10}'\] .*other hands' statistics"):
        _normaliser(stats)
    stats[ACTION]["right"]["l10_renamed"] = _stats_entry(None)
    with pytest.raises(NumberError, match=r"names hands \['l10_renamed'\], which are not among the hands"):
        _normaliser(stats)
    saved = _normaliser({ACTION: {"right": {h: _stats_entry(None) for h in HANDS}}}).state_dict()
    saved["action.frames"][:, 1] = 0  # the saved statistics give L10 no frames: it would pass unnormalised
    with pytest.raises(NumberError, match=rf"tensor 'action.frames' gives hands \['{L10}'\] no frames"):
        _normaliser().load_state_dict(saved)
    for edit in ("missing", "renamed"):
        per = {INSPIRE: _stats_entry(None)} | ({"l10_renamed": _stats_entry(None)} if edit == "renamed" else {})
        stats = {"modes": {ACTION: "MEAN_STD"}, ACTION: {"right": per, "left": {INSPIRE: _stats_entry(None)}}}
        folder = _udt_config_json(ctx["tmp"] / edit, stats)
        from lerobot.configs.policies import PreTrainedConfig

        with pytest.raises(Exception) as info:
            PreTrainedConfig.from_pretrained(folder)
        assert isinstance(_ours(info.value), NumberError) and "udt_hand_stats['action']" in str(_ours(info.value))


def test_the_recorded_statistics_of_a_real_mix_pass_and_min_above_max_is_named(ctx):
    stats = recorded_hand_stats(UdhmDatasetMeta(ctx["mix"]))
    assert set(stats[ACTION]["right"]) == set(HANDS)
    entry = copy.deepcopy(stats[ACTION]["right"][L10])
    entry["min"], entry["max"] = entry["max"], entry["min"]
    from lerobot_unidextok.utils.number_checks import checked_hand_stats

    with pytest.raises(NumberError, match=rf"x\['action'\]\['right'\]\['{L10}'\] has min .* above max"):
        checked_hand_stats({ACTION: {"right": {L10: entry}}}, "x")


def test_weights_near_the_float_limit_are_normalised_not_dropped():
    """[1e308, 1e308] overflowed their sum to inf and became shares of 0 (the weights silently dropped)."""
    assert checked_shares([1e308, 1e308], "--weights") == [0.5, 0.5]
    assert checked_shares([3, 1], "--weights") == [0.75, 0.25]
    assert MIN_SHARE == 1e-3
    with pytest.raises(NumberError, match=r"give input 0 a share of 0\.000989 of the training frames"):
        checked_shares([0.00099, 1], "--weights")  # just under the floor
    opts = MixOptions(inputs=["a", "b"], root="out", weights=[1e308, 1e308])
    assert opts.weights == [1e308, 1e308]
    from lerobot_unidextok.conversion.mix import repeat_factors

    assert repeat_factors([100, 100], [1e308, 1e308]) == [1, 1]
    # a small share that passes is printed as a number, not as 0 %
    from lerobot_unidextok.conversion.mix import MixReport, format_report
    from lerobot_unidextok.data.record import MixedSource

    shares = checked_shares([0.002, 1], "--weights")
    sources = [MixedSource(f"in{k}", None, "src", ["right"], [L10], 4, [], weight=w, share=sh)
               for k, (w, sh) in enumerate(zip([0.002, 1], shares, strict=True))]  # fmt: skip
    text = format_report(MixReport(Path("out"), 8, 80, [], sources, shares, 0.1))
    assert "0.2% of the sampled training frames (share recorded); budget rule: 501.0x the updates" in text, text


def test_a_grasp_centre_written_by_a_recorder_is_checked_before_it_is_written(tmp_path):
    from lerobot_unidextok.data.wrist_frame import WristFrame, write_recorded

    (tmp_path / "meta").mkdir()
    with pytest.raises(WristFrameError, match=r"the grasp centre of 'shadow' holds 1000 m .*plausible 0.3 m"):
        write_recorded(tmp_path, WristFrame(WRIST, grasp_centre_in_wrist_m={"shadow": [1000.0, 0.0, 0.0]}))
    assert not (tmp_path / WRIST_FRAME_PATH).exists()
    np.testing.assert_equal(read_recorded(tmp_path), None)


def test_training_on_a_mix_whose_record_holds_a_nan_std_is_refused_naming_the_file(ctx):
    """Case 1 of issue 54: `lerobot-train` on a mix whose recorded hand_stats hold NaN exited 0 and its policy
    never moved that hand. The <type>_udt config's fill from the dataset (what lerobot-train runs) refuses it."""
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.datasets import LeRobotDatasetMetadata

    from lerobot_unidextok.policies import ACTUdtConfig

    root = ctx["tmp"] / "mix"
    shutil.copytree(ctx["mix"] / "meta", root / "meta")
    record = json.loads((root / CONVERSION_PATH).read_text())
    record["hand_stats"][ACTION]["left"][INSPIRE]["std"][4] = float("nan")
    (root / CONVERSION_PATH).write_text(json.dumps(record))  # JSON's NaN, as json.dumps writes it
    meta = LeRobotDatasetMetadata("test/g1_l10_mix", root=root)
    cfg = ACTUdtConfig(
        input_features={OBS_STATE: PolicyFeature(FeatureType.STATE, tuple(meta.features[OBS_STATE]["shape"]))},
        output_features={ACTION: PolicyFeature(FeatureType.ACTION, tuple(meta.features[ACTION]["shape"]))},
        udt_preset="tiny", device="cpu",
    )  # fmt: skip
    cfg._runtime_dataset_meta = meta
    with pytest.raises(NumberError, match=rf"{CONVERSION_PATH} hand_stats\['action'\]\['left'\]\['{INSPIRE}'\]\.std "
                                          r"holds NaN at index 4 .*mix the datasets again"):  # fmt: skip
        cfg.validate_features()


def test_a_one_robot_config_needs_statistics_for_its_layouts_hands_and_may_keep_the_trained_others():
    """One robot's checkpoint bound zero-shot to some of the hands it trained on keeps every trained hand's
    statistics (they are what it normalises with); a hand of its layout without any, not bound zero-shot, is named."""
    from lerobot.configs.types import FeatureType, PolicyFeature

    from lerobot_unidextok.policies import ACTUdtConfig

    names = udhm_state_names(["left", "right"])
    stats = {"modes": {ACTION: "MEAN_STD"}, ACTION: {"left": {INSPIRE: _stats_entry(None)},
                                                     "right": {L10: _stats_entry(None)}}}  # fmt: skip

    def config(layout: list[str]) -> ACTUdtConfig:
        return ACTUdtConfig(
            input_features={OBS_STATE: PolicyFeature(FeatureType.STATE, (len(names),))},
            output_features={ACTION: PolicyFeature(FeatureType.ACTION, (len(names),))},
            udt_hand_layout=layout, udt_sides=["left", "right"], udt_state_names=names, udt_action_names=names,
            udt_hand_stats=copy.deepcopy(stats), device="cpu",
        )  # fmt: skip

    assert set(config([INSPIRE, INSPIRE]).udt_hand_stats[ACTION]["right"]) == {L10}
    with pytest.raises(NumberError, match=r"udt_hand_stats\['action'\] has no statistics for hands \['shadow'\]"):
        config([INSPIRE, "shadow"])
