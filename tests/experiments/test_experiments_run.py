"""Every experiment runs end to end on the tiny configuration and writes JSON + Markdown + PNG with the
expected keys and numbers that follow from the setting."""

import json
import math
from pathlib import Path

import pytest

from lerobot_unidextok.experiments import (
    ablation_human,
    ablation_mapping,
    probe,
    transfer,
)

PROVENANCE_KEYS = {
    "data",
    "preset",
    "seed",
    "git_commit",
    "config",
    "wall_seconds",
    "date_utc",
}


def _files(cfg, name: str) -> dict:
    folder = Path(cfg.output_root) / name
    assert (folder / f"{name}.md").read_text().startswith(f"# {name}")
    result = json.loads((folder / f"{name}.json").read_text())
    assert PROVENANCE_KEYS <= set(result["provenance"])
    assert (
        result["provenance"]["preset"] == "tiny"
        and result["provenance"]["seed"] == cfg.seed
    )
    assert result["provenance"]["data"]["synthetic_sample"] is True
    for png in result.get("figures", {}).values():
        assert (
            Path(png).is_file() and Path(png).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
        )
        assert Path(png).stat().st_size < 300_000
    return result


def test_main_table(tiny_cfg, main_result):
    result = _files(tiny_cfg, "main_table")
    methods = {"UniDexTok", "uniform binning", "UniHM-style", "FSQ", "RVQ"}
    assert set(result["methods"]) == methods
    hands = {r["hand"] for r in result["rows"]}
    assert "human" in hands and len(hands) >= 3
    assert len(result["rows"]) == len(hands) * len(methods)
    by = {(r["method"], r["hand"]): r for r in result["rows"]}
    # rates: binning 8 bits per active DoF (176 for the human hand); tiny UniDexTok 4 tokens x 8 groups x 5 bits
    assert by[("uniform binning", "human")]["bits_per_state"] == 176
    assert by[("uniform binning", "human")]["tokens_per_state"] == 22
    assert by[("UniDexTok", "human")]["bits_per_state"] == 4 * 8 * 5
    assert (
        by[("FSQ", "human")]["bits_per_state"]
        == by[("RVQ", "human")]["bits_per_state"]
        == 320
    )
    # binning's error is bounded by half a bin: well under a degree on every hand
    for hand in hands:
        assert by[("uniform binning", hand)]["mpjae_deg"] < 1.0
        for m in methods:
            assert (
                math.isfinite(by[(m, hand)]["mpjae_deg"])
                and by[(m, hand)]["mpjpe_mm"] >= 0
            )
    assert {
        "rate_distortion_mpjae",
        "per_joint_errors",
        "codebook_usage",
        "render_human",
    } <= set(result["figures"])
    assert 0 < result["codebook"]["usage"] <= 1


def test_tokenizer_cache_is_reused(tiny_cfg, main_result):
    from lerobot_unidextok.experiments.common import (
        load_data,
        selection_split,
        trained_unidextok,
    )

    assert main_result["unidextok_training"]["cached"] is False
    data = load_data(tiny_cfg)  # the converted sample cache is valid: no new conversion
    fit, select = selection_split(data.train, tiny_cfg.seed)
    _, info = trained_unidextok(tiny_cfg, "all_hands", fit, select)
    assert (
        info["cached"] is True
        and info["dir"] == main_result["unidextok_training"]["dir"]
    )
    _, other = trained_unidextok(
        tiny_cfg, "no_human", fit.without("human"), select.without("human")
    )  # other rows: new model
    assert other["cached"] is False and other["dir"] != info["dir"]
    from dataclasses import replace

    _, changed = trained_unidextok(
        replace(tiny_cfg, lr=tiny_cfg.lr / 2), "all_hands", fit, select
    )  # other settings
    assert changed["cached"] is False and changed["dir"] != info["dir"]


def test_ablation_human(tiny_cfg, main_result):
    result = ablation_human.run(tiny_cfg)
    _files(tiny_cfg, "ablation_human")
    hands = [r["hand"] for r in result["rows"]]
    assert "human" not in hands and hands[-1] == "overall"
    assert (
        result["training"]["with human data"]["cached"] is True
    )  # the main table's tokenizer
    assert "human" not in result["training"]["without human data"]["train_hands"]
    for r in result["rows"]:
        w, wo = r["with human data"]["mpjae_deg"], r["without human data"]["mpjae_deg"]
        assert r["mpjae_reduction_pct"] == pytest.approx(100 * (wo - w) / wo)


def test_ablation_mapping(tiny_cfg, main_result):
    result = ablation_mapping.run(tiny_cfg)
    _files(tiny_cfg, "ablation_mapping")
    assert (
        result["layout_check_max_abs_rad"] < 1e-6
    )  # append-pad rows permuted back == semantic rows
    assert result["training"]["semantic"]["cached"] is True
    assert (
        result["training"]["append_pad"]["train_rows"]
        == result["training"]["semantic"]["train_rows"]
    )
    assert {"semantic", "append_pad"} <= set(result["rows"][0])


def test_transfer(tiny_cfg, main_result):
    result = transfer.run(tiny_cfg)
    _files(tiny_cfg, "transfer")
    hand = result["holdout_hand"]
    assert "inspire" in hand
    assert hand not in result["training"]["base_without_holdout"]["train_hands"]
    assert hand in result["training"]["reference_with_holdout"]["train_hands"]
    fs = result["fewshot"]
    assert fs["frames"] == max(1, round(tiny_cfg.fewshot_fraction * fs["of_frames"]))
    assert set(result["summary"]) == {
        "zero-shot",
        "few-shot, embedding row",
        "few-shot, whole tokenizer (paper)",
        "in training (reference)",
    }
    for label in ("few-shot, embedding row", "few-shot, whole tokenizer (paper)"):
        assert len(result["summary"][label]["mpjae_deg_repeats"]) == tiny_cfg.fewshot_repeats
    assert set(result["per_finger_tip_mm"]) == {
        "thumb_tip",
        "index_tip",
        "middle_tip",
        "ring_tip",
        "pinky_tip",
    }
    assert len(result["per_joint_deg"]) == 6  # the Inspire hand's active DoFs


def test_transfer_unknown_holdout(tiny_cfg):
    from dataclasses import replace

    with pytest.raises(ValueError, match="not in the data"):
        transfer.run(replace(tiny_cfg, holdout_hand="no_such_hand"))


def test_probe(tiny_cfg, main_result, real_data_dir):
    from dataclasses import replace

    result = probe.run(tiny_cfg)  # presets path absent -> skipped cleanly
    _files(tiny_cfg, "probe")
    assert result["linkerhand_presets"] is None
    sg = result["sample_gestures"]
    assert [r["feature"] for r in sg["rows"]] == list(probe.FEATURES)
    for r in sg["rows"]:
        assert 0 <= r["linear_probe"] <= 1 and 0 <= r["knn_top1"] <= r["knn_top3"] <= 1
    presets = (
        real_data_dir / "linkerhand-ros2-sdk" / "linkerhand_gui_preset_actions.json"
    )
    if not presets.is_file():
        pytest.skip("LinkerHand preset file absent")
    real = probe.run(replace(tiny_cfg, linkerhand_presets=str(presets)))[
        "linkerhand_presets"
    ]
    assert {"linkerhand_l10", "linkerhand_l20"} <= set(real["hands"]) and {
        "open",
        "fist",
    } <= set(real["classes"])
    assert all(0 <= r["knn_top1"] <= r["knn_top3"] <= 1 for r in real["rows"])
    # with input angles as features, identical vendor gestures must mostly find each other across models
    assert real["rows"][0]["knn_top3"] > 0.5


def test_results_page(tiny_cfg, main_result, tmp_path):
    from lerobot_unidextok.experiments.results_page import build_page

    for mod in (ablation_human, ablation_mapping, transfer, probe):
        if not (Path(tiny_cfg.output_root) / mod.NAME / f"{mod.NAME}.json").is_file():
            mod.run(tiny_cfg)
    page = tmp_path / "bench" / "RESULTS.md"
    text = build_page(tiny_cfg.output_root, page)
    for name in (
        "main_table",
        "ablation_human",
        "ablation_mapping",
        "transfer",
        "probe",
    ):
        assert f"## {name}" in text and f"python experiments/{name}.py" in text
    result = json.loads(
        (Path(tiny_cfg.output_root) / "main_table" / "main_table.json").read_text()
    )
    first = result["rows"][0]
    assert (
        f"| {first['hand']} | {first['method']} | {first['tokens_per_state']} |" in text
    )  # numbers from the JSON
    assert result["provenance"]["git_commit"][:12] in text
    links = [
        line.split("](")[1].rstrip(")")
        for line in text.splitlines()
        if line.startswith("![")
    ]
    assert links and all((page.parent / link).is_file() for link in links)


def test_results_page_without_results(tmp_path):
    from lerobot_unidextok.experiments.results_page import build_page

    with pytest.raises(FileNotFoundError, match="run e.g."):
        build_page(tmp_path, tmp_path / "RESULTS.md")
