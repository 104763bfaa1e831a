"""The unseen-data experiments on a tiny configuration: k-fold over episodes of a converted dataset and a human
tokenizer scored on keypoint recordings it never saw, each next to 8-bit binning (no ../shared needed)."""

import json

import numpy as np
import pytest

from experiments import unseen_episodes, unseen_human
from experiments.unseen_data import all_episodes


@pytest.fixture(scope="module")
def converted_linker(tmp_path_factory):
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples import write_samples

    raw = write_samples(tmp_path_factory.mktemp("raw"), sources=["linkerhand"], episodes_per_source=4,
                        frames_per_episode=40)["linkerhand"]  # fmt: skip
    root = tmp_path_factory.mktemp("conv") / "linker"
    convert(ConvertOptions(source="linkerhand", input=raw, root=root, progress=False))
    return root


def test_unseen_episodes_kfold_scores_each_episode_once_and_caches_runs(converted_linker, tmp_path):
    argv = [f"--datasets=[{converted_linker}]", "--variants=[shipped]", "--folds=2", "--tiny=true",
            "--range_rows=50", f"--output_root={tmp_path}"]  # fmt: skip
    result = unseen_episodes.run(unseen_episodes.parse(argv))
    runs = {(r["variant"], r["fold"]): r for r in result["runs"]}
    assert set(runs) == {(v, k) for v in ("binning_8bit", "shipped") for k in (0, 1)}
    data = all_episodes([str(converted_linker)])
    # the two folds' test rows are all the rows, each once (held-out episodes, never a training frame)
    assert runs["shipped", 0]["test_rows"] + runs["shipped", 1]["test_rows"] == len(data)
    for k in (0, 1):
        held = runs["shipped", k]["heldout_deg"]
        assert np.isfinite(held["all"]) and held["all"] > 0
        assert runs["binning_8bit", k]["heldout_deg"]["all"] < 0.5  # 256 bins over ranges of a few radians
    s = result["summary"]["shipped"]
    assert s["folds"] == 2 and s["heldout_min"] <= s["heldout_mean"] <= s["heldout_max"]
    # the same models scored with the code search: closer on both sets (the search never worsens a row)
    for k in (0, 1):
        r = runs["shipped", k]
        assert r["searched_encoding"]["rounds"] == 2 and r["heldout_searched_deg"]["all"] < r["heldout_deg"]["all"]
        assert r["range_searched_deg"]["all"] < r["range_deg"]["all"]
    assert s["heldout_searched_mean"] < s["heldout_mean"]
    cache = tmp_path / "unseen_episodes" / "runs_tiny.jsonl"
    lines = cache.read_text().splitlines()
    assert len(lines) == 2 and all(json.loads(line)["variant"] == "shipped" for line in lines)
    # a second run with the same settings reuses the cached runs instead of training again
    again = unseen_episodes.run(unseen_episodes.parse(argv))
    assert len(cache.read_text().splitlines()) == 2
    assert again["summary"]["shipped"]["heldout_mean"] == s["heldout_mean"]
    assert "| shipped | 2 |" in (tmp_path / "unseen_episodes" / "unseen_episodes.md").read_text()
    # a run cached without the searched score (an older cache, or --searched=null) trains again when asked for it
    plain = unseen_episodes.run(unseen_episodes.parse([*argv, "--searched=null", f"--output_root={tmp_path / 'p'}"]))
    assert "heldout_searched_mean" not in plain["summary"]["shipped"]
    again = unseen_episodes.run(unseen_episodes.parse([*argv, f"--output_root={tmp_path / 'p'}"]))
    assert len((tmp_path / "p" / "unseen_episodes" / "runs_tiny.jsonl").read_text().splitlines()) == 4
    assert again["summary"]["shipped"]["heldout_mean"] == pytest.approx(s["heldout_mean"])  # deterministic


def test_unseen_episodes_rejects_unknown_variants(converted_linker, tmp_path):
    cfg = unseen_episodes.parse([f"--datasets=[{converted_linker}]", "--variants=[shiped]", "--tiny=true",
                                 f"--output_root={tmp_path}"])  # fmt: skip
    with pytest.raises(ValueError, match="unknown variants \\['shiped'\\]"):
        unseen_episodes.run(cfg)


def test_unseen_human_on_keypoint_files(tmp_path):
    """Train on one keypoint recording, score on another person's (a different skeleton and motion)."""
    from lerobot_unidextok import udhm
    from lerobot_unidextok.samples.motion import gesture_track

    files = []
    for i, scale in enumerate((1.0, 0.9)):
        q = gesture_track(np.random.default_rng(i), 90, 30.0).angles_rad
        kp = udhm.forward_kinematics(q, udhm.Skeleton.default().scaled(scale))
        files.append(tmp_path / f"person{i}.npy")
        np.save(files[-1], np.asarray(kp, np.float64))
    cfg = unseen_human.parse([f"--train_keypoints=[{files[0]}]", f"--unseen_keypoints=[{files[1]}]",
                              "--variants=[shipped]", "--tiny=true", "--synthetic_frames=60",
                              f"--output_root={tmp_path / 'out'}"])  # fmt: skip
    result = unseen_human.run(cfg)
    assert result["train_rows"] == 72  # 80 % of the first recording
    assert result["rows"] == {"synthetic (validation)": 60, "unseen": 90, "own last part": 18}
    for method in ("binning_8bit", "shipped"):
        scores = result["mpjae_deg"][method]
        assert all(np.isfinite(v) and v > 0 for v in scores.values()), (method, scores)
    assert result["mpjae_deg"]["binning_8bit"]["unseen"] < 0.5
    assert (tmp_path / "out" / "unseen_human" / "unseen_human.md").is_file()
