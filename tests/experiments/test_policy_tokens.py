"""The policy-tokens experiment on a tiny configuration: a synthetic whole-robot dataset in the converted
contract (14 G1 arm joints + two Inspire UDHM blocks, `g1_like` in tests/conftest.py), every hand input, k-fold
over its episodes, a few ACT steps (no ../shared needed)."""

import json

import numpy as np
import pytest

from experiments import policy_tokens
from experiments.policy_data import (
    chunk_index,
    copy_state_prediction,
    hand_input,
    load_frames,
    open_loop_errors,
)

TINY = ["--folds=3", "--seeds=[0,1]", "--act.steps=3", "--act.batch_size=8", "--act.dim_model=16",
        "--act.dim_feedforward=32", "--act.n_heads=2", "--act.chunk_size=4", "--tokenizer.preset=tiny",
        "--tokenizer.steps=6", "--tokenizer.batch_size=32", "--tokenizer.warmup_steps=1", "--tokenizer.eval_every=3"]  # fmt: skip


@pytest.fixture(scope="module")
def frames(g1_like):
    return load_frames(g1_like["root"])


def test_native_input_is_the_robots_own_state(frames, g1_like):
    native = hand_input("native", frames)
    np.testing.assert_allclose(native, g1_like["native_state"][:, 14:], atol=1e-5)
    assert hand_input("udhm", frames).shape == (len(frames.state), 44)
    binned = hand_input("binned_8bit", frames)
    # 256 bins over each Inspire joint's range: within half a bin (< 0.5 deg) of the state, never equal everywhere
    assert 0 < np.abs(binned - hand_input("udhm", frames)).max() < np.radians(0.5)


def test_open_loop_errors_measure_each_part_in_its_units(frames):
    rows = np.flatnonzero(frames.episode == 1)
    index, pad = chunk_index(frames.episode, 4)
    assert pad[rows[-1]].tolist() == [False, True, True, True]  # past the episode's end: padded
    assert (index[rows] <= rows.max()).all()
    target = frames.action[index[rows]]
    off = target.copy()
    off[..., frames.passthrough_columns] += np.radians(2.0)
    err = open_loop_errors(off, frames, rows, 4)
    assert err["arms_deg_first"] == pytest.approx(2.0) and err["arms_deg_chunk"] == pytest.approx(2.0)
    assert err["hands_udhm_deg_chunk"] == 0.0 and err["hands_native_chunk"] == 0.0
    # copying the state: the synthetic action is the next frame's state
    copy = open_loop_errors(copy_state_prediction(frames, rows, 4), frames, rows, 4)
    arms = frames.passthrough_columns
    expected = np.degrees(np.abs(frames.action[rows][:, arms] - frames.state[rows][:, arms]).mean())
    assert copy["arms_deg_first"] == pytest.approx(expected)
    assert copy["arms_deg_chunk"] > copy["arms_deg_first"]  # farther ahead, farther from the current state


def test_policy_tokens_runs_every_input_on_every_fold_and_caches(g1_like, tmp_path):
    argv = [f"--datasets=[{g1_like['root']}]", f"--output_root={tmp_path}", *TINY]
    result = policy_tokens.run(policy_tokens.parse(argv))
    s = result["summary"]
    assert list(s) == ["copy_state", *policy_tokens.HAND_INPUTS]
    assert sorted(e for t in result["fold_tests"] for e in t) == [0, 1, 2]  # each episode held out once
    for kind, v in s.items():
        assert v["folds"] == 3 and v["seeds"] == (0 if kind == "copy_state" else 2)
        assert all(np.isfinite(v[m]["mean"]) and v[m]["mean"] > 0 for m in policy_tokens.METRICS), kind
    runs = [r for r in result["runs"] if r["input"] != "copy_state"]
    assert len(runs) == 5 * 3 * 2 and all(r["test_rows"] == 40 and r["train_rows"] == 80 for r in runs)
    widths = {r["input"]: r["hand_input_width"] for r in runs}
    assert widths["native"] == 12 and widths["udhm"] == widths["tokens_dequantized"] == widths["binned_8bit"] == 44
    assert all(f["trained_on_fold"] for f in result["tokenizers"].values())
    cache = tmp_path / "policy_tokens" / "runs.jsonl"
    assert len(cache.read_text().splitlines()) == 30
    again = policy_tokens.run(policy_tokens.parse(argv))  # cached: nothing retrained
    assert len(cache.read_text().splitlines()) == 30
    assert again["summary"]["udhm"] == s["udhm"]
    md = (tmp_path / "policy_tokens" / "policy_tokens.md").read_text()
    assert "| tokens_dequantized |" in md and "| copy_state |" in md
    json.loads((tmp_path / "policy_tokens" / "policy_tokens.json").read_text())


def test_policy_tokens_on_the_results_page(g1_like, tmp_path):
    from experiments.make_results import build_page, update_sections

    argv = [f"--datasets=[{g1_like['root']}]", f"--output_root={tmp_path}", "--inputs=[udhm]", *TINY]
    policy_tokens.run(policy_tokens.parse(argv))
    page = build_page(tmp_path, tmp_path / "RESULTS.md")
    # the command that reproduces the table: every flag that differs from the defaults
    assert "Command: `python experiments/policy_tokens.py --datasets='[" in page and "--inputs='[udhm]'" in page
    assert "| udhm |" in page and "## main_table\n\nNot run yet" in page
    # a page whose other sections came from JSON files this checkout does not have: only ours is replaced
    kept = "# Results\n\nintro\n\n## main_table\n\nmeasured elsewhere\n\n## probe\n\nalso elsewhere\n"
    (tmp_path / "page.md").write_text(kept)
    text = update_sections(tmp_path, tmp_path / "page.md", ["policy_tokens"])
    assert text.startswith("# Results\n\nintro\n") and "measured elsewhere" in text and "also elsewhere" in text
    assert text.index("## main_table") < text.index("## probe") < text.index("## policy_tokens")
    assert "| udhm |" in text
    again = update_sections(tmp_path, tmp_path / "page.md", ["policy_tokens"])
    assert again == text  # replaced in place, not appended twice
    # another run of the same experiment, labelled, sits beside the first and survives a rebuilt page
    labelled = update_sections(tmp_path, tmp_path / "page.md", ["policy_tokens"], label="second run")
    assert labelled.startswith(text.rstrip()) and labelled.count("| udhm |") == 2
    assert labelled.index("## policy_tokens\n") < labelled.index("## policy_tokens (second run)\n")
    rebuilt = build_page(tmp_path, tmp_path / "page.md")
    assert "## policy_tokens (second run)\n" in rebuilt and "measured elsewhere" not in rebuilt
    assert rebuilt.index("## policy_tokens\n") < rebuilt.index("## policy_tokens (second run)\n")
    assert rebuilt.index("## policy_tokens (second run)\n") < rebuilt.index("## rate_distortion")


def test_policy_tokens_rejects_unknown_inputs():
    with pytest.raises(ValueError, match=r"unknown inputs \['tokens'\]"):
        policy_tokens.PolicyTokensConfig(inputs=["tokens"])
