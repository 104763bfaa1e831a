"""Pieces of the experiments: config parsing, probe metrics, the append-pad slot permutation."""

import numpy as np
import pytest

from lerobot_unidextok.experiments import ExperimentConfig, parse_config
from lerobot_unidextok.experiments.ablation_mapping import append_to_semantic_perm
from lerobot_unidextok.experiments.common import reduction_pct, selection_split
from lerobot_unidextok.experiments.probe import knn_topk, linear_probe
from lerobot_unidextok.training import HandStates


def test_parse_config_flags_and_yaml(tmp_path):
    cfg = parse_config(["--tiny", "--steps=7", "--datasets=a,b", "--with_qae=false"])
    assert (
        cfg.preset == "tiny"
        and cfg.steps == 7
        and cfg.datasets == ["a", "b"]
        and cfg.with_qae is False
    )
    path = tmp_path / "c.yaml"
    path.write_text("steps: 11\nseed: 3\n")
    cfg = parse_config([f"--config_path={path}", "--seed=4"])
    assert (
        cfg.steps == 11 and cfg.seed == 4 and cfg.preset == "small"
    )  # flags override the file
    path.write_text("stepz: 1\n")
    with pytest.raises(ValueError, match="unknown fields"):
        parse_config([f"--config_path={path}"])
    with pytest.raises(ValueError, match="--with_qae"):
        parse_config(["--with_qae=maybe"])
    with pytest.raises(ValueError, match="fewshot_fraction"):
        ExperimentConfig(fewshot_fraction=0.0)


def test_knn_topk_exact():
    gallery = np.array([[1.0, 0.0], [0.0, 1.0], [-1.0, 0.0]])
    labels = np.array(["a", "b", "c"])
    queries = np.array([[2.0, 0.1], [0.1, 3.0], [-1.0, -0.5]])
    r = knn_topk(gallery, labels, queries, np.array(["a", "a", "b"]))
    assert r["knn_top1"] == pytest.approx(
        1 / 3
    )  # only the first query's nearest is right
    assert r["knn_top3"] == pytest.approx(
        1.0
    )  # with 3 neighbours every label is in reach


def test_linear_probe_separates_separable_classes():
    rng = np.random.default_rng(0)
    x = np.concatenate([rng.normal(0, 0.1, (40, 5)), rng.normal(2, 0.1, (40, 5))])
    y = np.array(["a"] * 40 + ["b"] * 40)
    assert linear_probe(x[::2], y[::2], x[1::2], y[1::2], seed=0) == 1.0
    shuffled = rng.permutation(
        y
    )  # labels unrelated to features: near chance, far from perfect
    assert linear_probe(x[::2], shuffled[::2], x[1::2], shuffled[1::2], seed=0) < 0.9


@pytest.mark.parametrize(
    "hand", ["inspire_rh56_unitree", "linkerhand_l10", "xhand1", "brainco_revo1"]
)
def test_append_pad_permutation_matches_the_spec(hand):
    from lerobot_unidextok import hands

    spec = hands.get(hand)
    perm = append_to_semantic_perm(hand)
    assert sorted(perm.tolist()) == np.flatnonzero(spec.mask("semantic")).tolist()
    raw = spec.from_udhm(np.zeros(22))
    sem = np.asarray(spec.to_udhm(raw, mapping="semantic"))
    app = np.asarray(spec.to_udhm(raw, mapping="append_pad"))
    assert np.allclose(sem[perm], app[: len(perm)])
    assert append_to_semantic_perm("human") is None


def test_selection_split_holds_back_whole_episodes():
    eps = np.repeat(np.arange(10), 5)
    data = HandStates(
        np.zeros((50, 22)), np.array(["human"] * 50), np.ones((50, 22), bool), eps
    )
    fit, sel = selection_split(data, seed=0)
    assert len(fit) + len(sel) == 50 and len(sel) == 5
    assert not set(fit.episode_index) & set(sel.episode_index)


def test_reduction_pct():
    assert reduction_pct(10.0, 7.5) == pytest.approx(25.0)
    assert reduction_pct(None, 1.0) is None and reduction_pct(0.0, 1.0) is None
