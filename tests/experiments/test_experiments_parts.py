"""Pieces of the experiments: config parsing, probe metrics, the append-pad slot permutation."""

from pathlib import Path

import numpy as np
import pytest

from experiments import ExperimentConfig, parse_config
from experiments.ablation_mapping import append_to_semantic_perm
from experiments.common import reduction_pct, selection_split
from experiments.probe import knn_majority, linear_probe, probe_scores
from experiments.real_data import segment_split
from lerobot_unidextok.errors import ConfigError
from lerobot_unidextok.training import HandStates


def test_parse_config_is_draccus_with_yaml_presets(tmp_path):
    """One config system: draccus flags and --config_path, like the CLIs (the hand-written parser is gone)."""
    tiny = Path(__file__).resolve().parents[2] / "experiments" / "configs" / "tiny.yaml"
    cfg = parse_config([f"--config_path={tiny}", "--train.steps=7", "--datasets=[a,b]", "--with_qae=false"])
    assert cfg.train.preset == "tiny" and cfg.train.steps == 7 and cfg.datasets == ["a", "b"] and cfg.with_qae is False
    path = tmp_path / "c.yaml"
    path.write_text("train:\n  steps: 11\nseed: 3\n")
    cfg = parse_config([f"--config_path={path}", "--seed=4"])
    assert cfg.train.steps == 11 and cfg.seed == 4 and cfg.train.preset == "small"  # flags override the file
    path.write_text("stepz: 1\n")
    with pytest.raises(ConfigError, match="stepz"):
        parse_config([f"--config_path={path}"])
    with pytest.raises(ConfigError, match="with_qae"):
        parse_config(["--with_qae=maybe"])
    with pytest.raises(ValueError, match="fewshot_fraction"):
        ExperimentConfig(fewshot_fraction=0.0)
    with pytest.raises(ValueError, match="data must be one of"):
        ExperimentConfig(data="somewhere")
    # training settings are nested (--train.*) and keep the experiments' defaults around a changed one
    cfg = parse_config(["--train.steps=20"])
    assert (cfg.train.steps, cfg.train.lr, cfg.train.warmup_steps) == (20, 3e-3, 60)
    with pytest.raises(ValueError, match="train.seed is set by each experiment from --seed"):
        parse_config(["--train.seed=3"])


def test_tiny_yaml_is_the_tiny_preset():
    tiny = Path(__file__).resolve().parents[2] / "experiments" / "configs" / "tiny.yaml"
    assert parse_config([f"--config_path={tiny}"]) == ExperimentConfig.from_preset("tiny")


def test_default_paths_are_relative_to_the_checkout(monkeypatch):
    """The real data and URDFs default to ../shared beside the checkout (or UNIDEXTOK_REAL_DATA), never a
    machine path baked into the code."""
    monkeypatch.delenv("UNIDEXTOK_REAL_DATA", raising=False)
    cfg = ExperimentConfig()
    root = Path(__file__).resolve().parents[2]
    assert cfg.real_dir == root.parent / "shared" / "data" / "real"
    assert cfg.urdf_root == root.parent / "shared" / "data" / "urdf"
    assert cfg.linkerhand_presets_path == cfg.real_dir / "linkerhand-ros2-sdk" / "linkerhand_gui_preset_actions.json"
    monkeypatch.setenv("UNIDEXTOK_REAL_DATA", "/elsewhere/real")
    assert ExperimentConfig().real_dir == Path("/elsewhere/real")


def test_knn_majority_vote():
    """k = 3 takes the majority label of the 3 nearest (not "the label is among the 3", the old top-3)."""
    gallery = np.array([[1.0, 0.0], [0.9, 0.1], [0.8, 0.3], [0.0, 1.0]])
    labels = np.array(["b", "a", "a", "c"])
    query = np.array([[1.0, 0.02]])
    assert knn_majority(gallery, labels, query, 1).tolist() == ["b"]  # nearest is "b"
    assert knn_majority(gallery, labels, query, 3).tolist() == ["a"]  # 2 of the 3 nearest say "a"
    # a tie goes to the nearest neighbour's label among the tied ones
    assert knn_majority(gallery[[0, 1, 3]], np.array(["b", "a", "c"]), query, 3).tolist() == ["b"]
    s = probe_scores(gallery, labels, query, np.array(["b"]), seed=0)
    assert s["knn1"] == 1.0 and s["knn3"] == 0.0


def test_linear_probe_separates_separable_classes():
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.normal(0, 0.1, (40, 5)), rng.normal(2, 0.1, (40, 5))])
    y = np.array(["a"] * 40 + ["b"] * 40)
    assert (linear_probe(x[::2], y[::2], x[1::2], seed=0) == y[1::2]).mean() == 1.0
    shuffled = rng.permutation(y)  # labels unrelated to features: near chance, far from perfect
    assert (linear_probe(x[::2], shuffled[::2], x[1::2], seed=0) == shuffled[1::2]).mean() < 0.9


def test_human_clip_segments_split_like_the_converter():
    """The real clip is cut into consecutive segments; ~20 % of them (whole segments) are held out."""
    segment, test = segment_split(621, 60)
    assert segment.max() == 9 and (segment[-21:] == 9).all()  # the short tail joins the last segment
    held = np.unique(segment[test])
    assert len(held) == 2 and all(test[segment == s].all() for s in held)


@pytest.mark.parametrize("hand", ["inspire_rh56_unitree", "linkerhand_l10", "xhand1", "brainco_revo1"])
def test_append_pad_permutation_matches_the_spec(hand):
    """append_pad position k holds semantic slot perm[k], on poses whose active values all differ.

    The old check compared the two mappings of UDHM zero (all zeros), which any permutation passes."""
    from lerobot_unidextok import hands

    spec = hands.get(hand)
    perm = append_to_semantic_perm(hand)
    assert sorted(perm.tolist()) == np.flatnonzero(spec.mask("semantic")).tolist()
    lo, hi = spec.raw_range("right").T
    raw = np.random.default_rng(0).uniform(lo, hi, size=(16, len(lo)))  # (16, J) native values
    sem = np.asarray(spec.to_udhm(raw, mapping="semantic"))
    app = np.asarray(spec.to_udhm(raw, mapping="append_pad"))
    active = sem[:, perm]  # (16, A)
    assert np.abs(np.diff(np.sort(active, axis=1), axis=1)).min() > 1e-6  # distinct values: order is visible
    np.testing.assert_array_equal(active, app[:, : len(perm)])
    assert np.count_nonzero(app[:, len(perm) :]) == 0  # padded tail
    assert append_to_semantic_perm("human") is None


def test_selection_split_holds_back_whole_episodes():
    eps = np.repeat(np.arange(10), 5)
    data = HandStates(np.zeros((50, 22)), np.array(["human"] * 50), np.ones((50, 22), bool), eps)
    fit, sel = selection_split(data, seed=0)
    assert len(fit) + len(sel) == 50 and len(sel) == 5
    assert not set(fit.episode_index) & set(sel.episode_index)


def test_reduction_pct():
    assert reduction_pct(10.0, 7.5) == pytest.approx(25.0)
    assert reduction_pct(None, 1.0) is None and reduction_pct(0.0, 1.0) is None


def test_pca_verdict_is_per_hand_and_follows_the_rows():
    """The PCA verdict reads the rows: per hand, not only the row-weighted overall mean (which one hand with
    many held-out rows can dominate)."""
    from experiments.main_table import pca_verdict

    def row(method, hand, mae):
        return {"protocol": "a", "method": method, "hand": hand, "mpjae_deg": mae, "tokens_per_state": 8,
                "bits_per_state": 64.0}  # fmt: skip

    rows = [row("UniDexTok", "human", 3.0), row("PCA-8 x 8-bit", "human", 4.0),
            row("UniDexTok", "robot", 1.2), row("PCA-8 x 8-bit", "robot", 0.1)]  # fmt: skip
    result = {"pca_method": "PCA-8 x 8-bit", "rows": rows,
              "overall": {"a": {"UniDexTok": {"mpjae_deg": 1.3}, "PCA-8 x 8-bit": {"mpjae_deg": 0.5}}}}  # fmt: skip
    (line,) = pca_verdict(result)
    assert "beats UniDexTok on 1 of 2 hands (robot)" in line and "human 4.00 vs 3.00 deg" in line
    assert "over all rows 0.50 vs 1.30 deg" in line
