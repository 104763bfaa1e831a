"""unidextok-mix: datasets of different robots and people in one LeRobot v3 dataset, each episode keeping its
source, every side a block, absent sides zero, splits per source, weights as repeats, one error per bad input."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest
from l10_robot import HAND as L10
from robot_udhm import INSPIRE

from lerobot_unidextok.blocks import udhm_state_names
from lerobot_unidextok.constants import ACTION, OBS_HAND_IDS, OBS_STATE, UDHM_DIM
from lerobot_unidextok.conversion.mix import MixError, MixOptions, mix, repeat_factors
from lerobot_unidextok.conversion.validate import validate_dataset
from lerobot_unidextok.data import UdhmDatasetMeta, load_udhm_frames
from lerobot_unidextok.data.destination import DestinationError
from lerobot_unidextok.utils.number_checks import NumberError

BIN = Path(sys.executable).parent


def _table(root: Path):
    return pq.read_table(sorted((root / "data").rglob("*.parquet")))


def test_the_mix_has_a_block_per_side_and_each_row_its_own_hands(g1_like, l10_robot, g1_l10_mix):
    meta = UdhmDatasetMeta(g1_l10_mix)
    record = meta.record
    assert meta.names(OBS_STATE) == meta.names(ACTION) == udhm_state_names(["left", "right"])  # --keep=hands
    assert record.hand_vocabulary == sorted([INSPIRE, L10]) and meta.names(OBS_HAND_IDS) == ["left_hand", "right_hand"]
    table = _table(g1_l10_mix)
    ids = np.stack(table.column(OBS_HAND_IDS).to_pylist())
    state = np.stack(table.column(OBS_STATE).to_pylist())
    mask = np.stack(table.column("udhm_mask").to_pylist())
    episodes = table.column("episode_index").to_numpy()
    src = {e.episode_index: e.origin["mix_source"] for e in record.episodes}
    l10_rows = np.array([src[e] == 1 for e in episodes])
    inspire, l10 = record.hand_vocabulary.index(INSPIRE), record.hand_vocabulary.index(L10)
    assert (ids[~l10_rows] == inspire).all()
    assert (ids[l10_rows, 0] == -1).all() and (ids[l10_rows, 1] == l10).all()
    # the L10 robot has no left hand: a zero block with a zero mask, never a fake hand
    assert not state[l10_rows, :UDHM_DIM].any() and not mask[l10_rows, :UDHM_DIM].any()
    assert mask[l10_rows, UDHM_DIM:].any()
    # its right block is its own converted block, bit for bit
    own = np.stack(_table(l10_robot).column(OBS_STATE).to_pylist())
    np.testing.assert_array_equal(state[l10_rows, UDHM_DIM:], own)
    # the G1's hands are its converted blocks; its arms are dropped (--keep=hands)
    g1_state = np.stack(_table(g1_like["root"]).column(OBS_STATE).to_pylist())
    np.testing.assert_array_equal(state[~l10_rows], g1_state[:, 14:])
    assert validate_dataset(g1_l10_mix).ok, validate_dataset(g1_l10_mix).table()


def test_every_episode_keeps_its_source_and_the_splits_stay_per_source(g1_like, l10_robot, g1_l10_mix):
    record = UdhmDatasetMeta(g1_l10_mix).record
    g1_meta, l10_meta = UdhmDatasetMeta(g1_like["root"]), UdhmDatasetMeta(l10_robot)
    assert [s.dataset for s in record.sources] == [str(g1_like["root"]), str(l10_robot)]
    assert [s.robot_type for s in record.sources] == [g1_meta.robot_type, l10_meta.robot_type]
    assert record.sources[1].native_layouts[ACTION] == l10_meta.native_layout(ACTION)
    origin = [(e.origin["mix_source"], e.origin["source_episode_index"]) for e in record.episodes]
    assert origin == [(0, e) for e in range(3)] + [(1, e) for e in range(5)]
    want = [i for i, (k, e) in enumerate(origin) if e in (g1_meta, l10_meta)[k].split("recorded").test]
    assert record.test_episodes == want and len(want) == 2
    assert all(record.episodes[i].split == "test" for i in want)
    train = load_udhm_frames(g1_l10_mix, split="train", holdout="recorded")
    assert not set(train.episode_index) & set(want)
    assert set(train.hands) == {INSPIRE, L10}  # the tokenizer's reader takes each row's own hand


def test_the_record_holds_each_hands_relative_action_scale_over_training_episodes(g1_l10_mix):
    """action_delta_stats: per block side and hand, mean and std of action - state over the training episodes'
    frames where the block holds that hand (recomputed here from the written rows, test episodes left out)."""
    record = UdhmDatasetMeta(g1_l10_mix).record
    table = _table(g1_l10_mix)
    ids = np.stack(table.column(OBS_HAND_IDS).to_pylist())
    delta = np.stack(table.column(ACTION).to_pylist()).astype(np.float64) - np.stack(table.column(OBS_STATE).to_pylist())
    train = ~np.isin(table.column("episode_index").to_numpy(), record.test_episodes)
    stats = record.action_delta_stats
    assert {side: sorted(hands) for side, hands in stats.items()} == {"left": [INSPIRE], "right": sorted([INSPIRE, L10])}
    for k, side in enumerate(["left", "right"]):
        for hand, entry in stats[side].items():
            rows = train & (ids[:, k] == record.hand_vocabulary.index(hand))
            block = delta[rows, k * UDHM_DIM : (k + 1) * UDHM_DIM]
            assert entry["frames"] == rows.sum() > 0
            np.testing.assert_allclose(entry["mean"], block.mean(0), atol=1e-6)
            np.testing.assert_allclose(entry["std"], block.std(0), atol=1e-6)
    # the two hands move at their own scales (what the per-hand scale is for)
    l10_std, inspire_std = np.max(stats["right"][L10]["std"]), np.max(stats["right"][INSPIRE]["std"])
    assert l10_std > 0 and inspire_std > 0 and l10_std != pytest.approx(inspire_std, rel=0.05)


def test_weights_repeat_the_small_inputs_training_episodes_not_its_test_episodes(g1_like, l10_robot, tmp_path):
    assert repeat_factors([400, 100], [1, 1]) == [1, 4] and repeat_factors([400, 100], []) == [1, 1]
    root = tmp_path / "weighted"
    report = mix(MixOptions(inputs=[str(g1_like["root"]), str(l10_robot)], root=str(root), weights=[1, 1],
                            weights_by="copies", progress=False))  # fmt: skip
    record = UdhmDatasetMeta(root).record
    l10 = [e for e in record.episodes if e.origin["mix_source"] == 1]
    train_frames = [80, 160]  # g1_like: 2 train episodes of 40 frames; the L10 robot: 4 of 40
    assert [s.repeats for s in record.sources] == repeat_factors(train_frames, [1, 1]) == [2, 1]
    assert report.train_shares == pytest.approx([0.5, 0.5])
    g1 = [e for e in record.episodes if e.origin["mix_source"] == 0]
    assert len(g1) == 2 * 2 + 1 and len(l10) == 5  # the test episode once
    assert sum(1 for e in g1 if e.split == "test") == 1
    assert UdhmDatasetMeta(root).total_episodes == len(record.episodes)
    assert [s.share for s in record.sources] == [0.0, 0.0]  # honoured by copies: no share to sample by


def test_weights_by_sampling_write_each_episode_once_and_record_the_shares(g1_like, l10_robot, tmp_path):
    from lerobot_unidextok.conversion.mix import budget_steps, format_report
    from lerobot_unidextok.data.share_sampler import episode_inputs

    root = tmp_path / "sampled"
    report = mix(MixOptions(inputs=[str(g1_like["root"]), str(l10_robot)], root=str(root), weights=[3, 1],
                            progress=False))  # fmt: skip
    record = UdhmDatasetMeta(root).record
    assert [s.repeats for s in record.sources] == [1, 1] and [s.share for s in record.sources] == [0.75, 0.25]
    assert len(record.episodes) == 3 + 5  # every episode once
    assert report.train_shares == pytest.approx([0.75, 0.25])
    text = format_report(report)
    assert "75% of the sampled training frames (share recorded)" in text
    assert "budget rule: 1.3x the updates" in text and "budget rule: 4.0x the updates" in text
    # the rule: an input at a quarter of the frames sees them as often as alone in four times the updates
    assert budget_steps(400, 0.25) == 1600 and budget_steps(400, 0.5) == 800 and budget_steps(400, 1.0) == 400
    for bad in (0.0, 1.5):
        with pytest.raises(MixError, match=r"must be in \(0, 1\]"):
            budget_steps(400, bad)
    inputs, shares = episode_inputs(record)  # what a <type>_udt policy weights each batch's rows by
    assert shares == [0.75, 0.25] and inputs == [e.origin["mix_source"] for e in record.episodes]
    with pytest.raises(MixError, match="weights_by must be one of"):
        MixOptions(inputs=["a"], root="b", weights_by="repeat")


def test_an_input_without_actions_gets_the_hand_k_frames_ahead(l10_robot, tmp_path):
    """A human dataset has no actions: action[t] = state[t + k], zero where the hand is absent at t."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples import write_samples

    raw = write_samples(tmp_path / "raw", sources=["egodex"], episodes_per_source=2, frames_per_episode=30)
    human = tmp_path / "human"
    convert(ConvertOptions(source="egodex", input=raw["egodex"], root=human, progress=False))
    assert not UdhmDatasetMeta(human).names(ACTION)
    root = tmp_path / "mix"
    mix(MixOptions(inputs=[str(l10_robot), str(human)], root=str(root), action_ahead=2, progress=False))
    record = UdhmDatasetMeta(root).record
    assert "state[t + 2]" in record.action_rule and [s.has_action for s in record.sources] == [True, False]
    table = _table(root)
    episodes = table.column("episode_index").to_numpy()
    human_episode = next(e.episode_index for e in record.episodes if e.origin["mix_source"] == 1)
    rows = episodes == human_episode
    state = np.stack(table.column(OBS_STATE).to_pylist())[rows]
    action = np.stack(table.column(ACTION).to_pylist())[rows]
    mask = np.stack(table.column("udhm_mask").to_pylist())[rows]
    ahead = np.minimum(np.arange(len(state)) + 2, len(state) - 1)
    np.testing.assert_array_equal(action, state[ahead] * mask)


def test_bad_inputs_are_one_clear_error_and_nothing_is_written(g1_like, l10_robot, tmp_path):
    root = tmp_path / "out"
    raw = l10_robot.parent / "raw"  # the plain LeRobot recording the L10 robot was converted from
    with pytest.raises(MixError, match="was not converted by unidextok-convert"):
        mix(MixOptions(inputs=[str(raw), str(l10_robot)], root=str(root)))
    slow = tmp_path / "l10_at_15"
    shutil.copytree(l10_robot, slow)
    info = json.loads((slow / "meta/info.json").read_text())
    (slow / "meta/info.json").write_text(json.dumps({**info, "fps": 15}))
    # both are fixed-rate LeRobot recordings: convert cannot resample them, so the fix is not --fps
    with pytest.raises(MixError, match=r"different frame rates .*30.*15.*keep the rate they were recorded at") as err:
        mix(MixOptions(inputs=[str(g1_like["root"]), str(slow)], root=str(root)))
    assert "--fps" not in str(err.value)
    # the same dataset twice, under another spelling of its path: each episode would be written twice
    again = f"{l10_robot.parent}/../{l10_robot.parent.name}/{l10_robot.name}/"
    with pytest.raises(MixError, match=r"are the same dataset \(one folder\).*Pass each dataset once"):
        mix(MixOptions(inputs=[str(l10_robot), again], root=str(root)))
    with pytest.raises(NumberError, match=r"--weights holds NaN at index 0 .*one positive number per input"):
        MixOptions(inputs=["a", "b"], root=str(root), weights=[float("nan"), 1])
    with pytest.raises(DestinationError, match="is, holds or sits inside the input"):
        mix(MixOptions(inputs=[str(g1_like["root"]), str(l10_robot)], root=str(l10_robot / "mix")))
    with pytest.raises(NumberError, match=r"--weights must be 2 numbers, got 1; pass one positive number per input"):
        MixOptions(inputs=["a", "b"], root=str(root), weights=[1])
    # every episode of an input in its recorded test split: its hand would have no per-hand statistics, which the
    # mix wrote and only training then refused, blaming an edited file
    all_test = tmp_path / "l10_all_test"
    shutil.copytree(l10_robot, all_test)
    record = json.loads((all_test / "meta/unidextok_conversion.json").read_text())
    record["test_episodes"] = list(range(record["num_episodes"]))
    (all_test / "meta/unidextok_conversion.json").write_text(json.dumps(record))
    with pytest.raises(MixError, match=rf"input {all_test} has no training episodes: all 5 .*smaller --test_fraction"):
        mix(MixOptions(inputs=[str(g1_like["root"]), str(all_test)], root=str(root)))
    assert not root.exists() and not list(tmp_path.glob(".out*"))
    other = tmp_path / "not_a_mix"
    other.mkdir()
    (other / "keep.txt").write_text("mine")
    with pytest.raises(DestinationError, match="holds other files, not a mixed dataset"):
        mix(MixOptions(inputs=[str(g1_like["root"]), str(l10_robot)], root=str(other), overwrite=True))
    assert (other / "keep.txt").read_text() == "mine"


def test_the_cli_mixes_and_prints_the_training_flag(g1_like, l10_robot, tmp_path):
    out = tmp_path / "cli_mix"
    r = subprocess.run([str(BIN / "unidextok-mix"), f"--inputs=[{g1_like['root']},{l10_robot}]", f"--root={out}",
                        "--progress=false"], capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    assert "training episodes x1" in r.stdout and "--dataset.episodes='[" in r.stdout
    r = subprocess.run([str(BIN / "unidextok-mix"), f"--inputs=[{g1_like['root']}]", f"--root={out}"],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 2 and r.stderr.startswith("error: ") and "already holds a mixed dataset" in r.stderr
    r = subprocess.run([str(BIN / "unidextok-mix"), "--inputs=[a,b]", "--weights=[nan,1]", f"--root={out}"],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 2 and r.stderr.startswith("error: --weights holds NaN at index 0"), r.stderr


def test_mix_overwrite_replaces_a_mix_and_never_a_converted_dataset(g1_like, l10_robot, tmp_path):
    """`unidextok-mix --overwrite=true` onto a dataset written by unidextok-convert used to replace it with a
    mix (rc 0); its help says it replaces an earlier mix and nothing else."""
    converted = tmp_path / "converted"
    shutil.copytree(l10_robot, converted)
    before = sorted(p.name for p in converted.rglob("*"))
    with pytest.raises(DestinationError, match=r"holds a dataset written by unidextok-convert, not a mixed dataset"):
        mix(MixOptions(inputs=[str(g1_like["root"]), str(l10_robot)], root=str(converted), overwrite=True,
                       progress=False))  # fmt: skip
    assert sorted(p.name for p in converted.rglob("*")) == before
    out = tmp_path / "mix"
    mix(MixOptions(inputs=[str(g1_like["root"])], root=str(out), progress=False))
    mix(MixOptions(inputs=[str(g1_like["root"]), str(l10_robot)], root=str(out), overwrite=True, progress=False))
    assert len(UdhmDatasetMeta(out).record.sources) == 2


def test_an_input_whose_episodes_have_different_hands_is_mixed_episode_by_episode(g1_like, tmp_path):
    """The LinkerHand sample holds L10 episodes and L20 episodes under one dataset. The mix places each
    episode with its own hands: the rows of an L10 episode carry the L10's id, those of an L20 episode the
    L20's."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples import write_samples

    raw = write_samples(tmp_path / "raw", sources=["linkerhand"], episodes_per_source=4, frames_per_episode=20)
    lh = tmp_path / "lh"
    convert(ConvertOptions(source="linkerhand", input=raw["linkerhand"], root=lh, progress=False))
    assert len(UdhmDatasetMeta(lh).hand_types) == 2
    root = tmp_path / "mix"
    mix(MixOptions(inputs=[str(g1_like["root"]), str(lh)], root=str(root), progress=False))
    record = UdhmDatasetMeta(root).record
    table = _table(root)
    ids = np.stack(table.column(OBS_HAND_IDS).to_pylist())
    episodes = table.column("episode_index").to_numpy()
    own = {e.episode_index: e for e in record.episodes}
    for e in np.unique(episodes):
        hands = own[e].hand_type.split(",")
        want = [record.hand_vocabulary.index(h) for h in hands]
        got = ids[episodes == e]
        present = got >= 0
        assert (got == np.array(want)[None, :])[present].all() and present.any(), (e, hands)


def test_the_same_episodes_given_twice_are_refused_by_content(g1_like, l10_robot, tmp_path, monkeypatch, capsys):
    """The mix wrote data it was given twice: the literal repeat `--inputs='[a, a]'`, a `cp -r` copy, and two
    conversions of one source (here with other settings: the arms kept, another test split). Each is refused,
    naming both inputs and the three ways out; nothing is written. `--allow_repeats=true` repeats on purpose."""
    from l10_robot import HAND, PREFIX, convert_l10_robot

    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.scripts.mix import main

    root = tmp_path / "out"
    copy = tmp_path / "copy_of_l10"
    shutil.copytree(l10_robot, copy)
    again = convert_l10_robot(l10_robot.parent / "raw", tmp_path / "l10_again")
    other = tmp_path / "l10_other_settings"  # hands only, another test split, another repo id
    convert(ConvertOptions(source="lerobot", input=l10_robot.parent / "raw", root=other, repo_id="me/l10",
                           source_options={"hands": {"right": f"{HAND}:{PREFIX}"}}, keep="hands", test_fraction=0.5,
                           progress=False))  # fmt: skip
    part = tmp_path / "l10_first_two"  # some of the episodes are the same: those would be written twice
    convert(ConvertOptions(source="lerobot", input=l10_robot.parent / "raw", root=part, max_episodes=2,
                           source_options={"hands": {"right": f"{HAND}:{PREFIX}"}}, progress=False))  # fmt: skip
    fix = r"Pass each dataset once \(--weights gives an input a larger share .*\), or --allow_repeats=true"
    cases = [
        ([l10_robot, l10_robot], rf"inputs {l10_robot} and {l10_robot} are the same dataset \(one folder\)"),
        ([g1_like["root"], l10_robot, copy], rf"inputs {l10_robot} and {copy} hold the same episodes \(5 of 5"),
        ([l10_robot, g1_like["root"], again], rf"inputs {l10_robot} and {again} hold the same episodes \(5 of 5"),
        ([other, g1_like["root"], l10_robot], rf"inputs {other} and {l10_robot} hold the same episodes \(5 of 5"),
        ([l10_robot, part], rf"inputs {l10_robot} and {part} hold the same episodes \(2 of 5 by content, e.g. "
                            rf"{l10_robot}#0 = {part}#0, {l10_robot}#1 = {part}#1"),
    ]
    for inputs, why in cases:
        with pytest.raises(MixError, match=f"{why}.*{fix}"):
            mix(MixOptions(inputs=[str(i) for i in inputs], root=str(root), progress=False))
        assert not root.exists() and not list(tmp_path.glob(".out*"))
    monkeypatch.setattr(sys, "argv", ["unidextok-mix", f"--inputs=[{l10_robot}, {l10_robot}]", f"--root={root}"])
    with pytest.raises(SystemExit) as exit_info:
        main()
    err = capsys.readouterr().err
    assert exit_info.value.code == 2 and err.startswith(f"error: inputs {l10_robot} and {l10_robot}"), err
    # on purpose: both written, each episode twice
    report = mix(MixOptions(inputs=[str(l10_robot), str(copy)], root=str(root), allow_repeats=True, progress=False))
    assert report.num_episodes == 2 * UdhmDatasetMeta(l10_robot).total_episodes
