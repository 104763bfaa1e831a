"""unidextok-mix chooses each input's share of the sampled training frames by a rule (its training frames to the
power 0.43, π0's exponent) unless --weights are given: the rule's numbers on real mixes of converted datasets,
recorded beside the shares and printed; --weights override it; --share_rule=frames is the mix before the rule."""

import json
import subprocess
import sys
from pathlib import Path

import pytest
from l10_robot import HAND, PREFIX, write_l10_robot

from lerobot_unidextok.conversion.mix import MixError, MixOptions, chosen_shares, format_report, mix
from lerobot_unidextok.conversion.share_rule import power_shares
from lerobot_unidextok.data import UdhmDatasetMeta
from lerobot_unidextok.data.record import load_record
from lerobot_unidextok.data.share_sampler import episode_inputs

BIN = Path(sys.executable).parent
FRAMES = 20  # per episode: every input's episodes are of one length, so frame shares are episode shares


def _converted(base: Path, name: str, episodes: int, seed: int) -> Path:
    """An L10 robot of `episodes` episodes (its own motions: `seed`), converted with every episode for training."""
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    raw = write_l10_robot(base / f"{name}_raw", episodes=episodes, frames=FRAMES, seed=seed)
    convert(ConvertOptions(source="lerobot", input=raw, root=base / name, repo_id=f"test/{name}", test_fraction=0.0,
                           source_options={"hands": {"right": f"{HAND}:{PREFIX}"}}, progress=False))  # fmt: skip
    return base / name


@pytest.fixture(scope="module")
def pool(tmp_path_factory) -> list[Path]:
    """A small target (2 episodes) and five other inputs of 10 episodes each: the ratio of 10 target
    demonstrations beside 50 per other hand (docs/pooling.md), at a fifth of the size."""
    base = tmp_path_factory.mktemp("share_rule")
    return [_converted(base, "target", 2, seed=0)] + [_converted(base, f"other{k}", 10, seed=100 * (k + 1))
                                                      for k in range(5)]  # fmt: skip


def test_the_rule_gives_a_small_target_a_third_beside_one_hand_and_a_tenth_beside_five():
    assert power_shares([10, 50], 0.43) == pytest.approx([0.3336, 0.6664], abs=1e-3)
    assert power_shares([10] + [50] * 5, 0.43)[0] == pytest.approx(0.0910, abs=1e-3)
    # alpha 1: each input at its frame share; alpha 0: one equal share each; no overflow at any size
    assert power_shares([10, 50], 1.0) == pytest.approx([1 / 6, 5 / 6]) and power_shares([10, 50], 0.0) == [0.5, 0.5]
    assert power_shares([1, 10**300], 0.5) == pytest.approx([1e-150, 1.0])


def test_two_inputs_get_the_rules_shares_recorded_and_printed(pool, tmp_path):
    root = tmp_path / "two"
    report = mix(MixOptions(inputs=[str(pool[0]), str(pool[1])], root=str(root), progress=False))
    record = UdhmDatasetMeta(root).record
    shares = [s.share for s in record.sources]
    assert shares == pytest.approx([0.3336, 0.6664], abs=1e-3) and sum(shares) == pytest.approx(1.0)
    assert shares == pytest.approx(power_shares([2 * FRAMES, 10 * FRAMES], 0.43), abs=1e-8)
    assert record.share_rule == "power" and record.share_alpha == 0.43
    assert [s.repeats for s in record.sources] == [1, 1] and len(record.episodes) == 12  # each episode once
    assert report.train_shares == pytest.approx(shares)
    # what a <type>_udt policy weights each row's loss by, and the on-disk form beside the shares
    inputs, by_input = episode_inputs(record)
    assert by_input == shares and inputs == [0, 0] + [1] * 10
    on_disk = json.loads((root / "meta/unidextok_conversion.json").read_text())
    assert on_disk["share_rule"] == "power" and on_disk["share_alpha"] == 0.43
    text = format_report(report)
    assert "shares by the rule frames^0.43 (override with --weights): input 0 33.4 %, input 1 66.6 %" in text, text
    assert "33.4% of the sampled training frames (share recorded)" in text


def test_six_inputs_give_the_small_target_about_a_tenth(pool, tmp_path):
    root = tmp_path / "six"
    report = mix(MixOptions(inputs=[str(p) for p in pool], root=str(root), progress=False))
    record = UdhmDatasetMeta(root).record
    assert record.sources[0].share == pytest.approx(0.0910, abs=1e-3)
    assert [s.share for s in record.sources[1:]] == pytest.approx([0.1818] * 5, abs=1e-3)
    assert "input 0 9.1 %, input 1 18.2 %" in format_report(report)


def test_the_rule_counts_training_frames_only(g1_l10_mix):
    """The G1-like robot: 2 training episodes of 40 frames (and 1 test); the L10 robot 4 of 40 (and 1 test). The
    rule's shares come from 80 and 160 frames, not from the 120 and 200 with the test episodes."""
    record = UdhmDatasetMeta(g1_l10_mix).record
    assert [s.share for s in record.sources] == pytest.approx(power_shares([80, 160], 0.43), abs=1e-8)
    assert record.sources[0].share == pytest.approx(1 / (1 + 2**0.43), abs=1e-8) != pytest.approx(0.4454, abs=1e-3)


def test_another_alpha_and_weights_override(pool, tmp_path):
    two = [str(pool[0]), str(pool[1])]
    root = tmp_path / "alpha1"
    mix(MixOptions(inputs=two, root=str(root), share_alpha=1.0, progress=False))
    record = UdhmDatasetMeta(root).record
    assert [s.share for s in record.sources] == pytest.approx([1 / 6, 5 / 6]) and record.share_alpha == 1.0
    # --weights override the rule: recorded as the shares, the rule as "weights" and no exponent
    root = tmp_path / "weighted"
    report = mix(MixOptions(inputs=two, root=str(root), weights=[1, 1], progress=False))
    record = UdhmDatasetMeta(root).record
    assert [s.share for s in record.sources] == [0.5, 0.5] and [s.weight for s in record.sources] == [1.0, 1.0]
    assert record.share_rule == "weights" and record.share_alpha is None
    assert "shares by --weights (recorded): input 0 50.0 %, input 1 50.0 %" in format_report(report)
    # by copies: the weights' repeats, no share recorded (as before the rule)
    root = tmp_path / "copies"
    report = mix(MixOptions(inputs=two, root=str(root), weights=[1, 1], weights_by="copies", progress=False))
    record = UdhmDatasetMeta(root).record
    assert [s.repeats for s in record.sources] == [5, 1] and [s.share for s in record.sources] == [0.0, 0.0]
    assert record.share_rule == "weights" and "shares by --weights (as copies, none recorded)" in format_report(report)


def test_share_rule_frames_and_copies_without_weights_mix_as_before_the_rule(pool, tmp_path):
    """--share_rule=frames: each episode once, each input at its frame share, no share recorded, so a policy on it
    weights no row (episode_inputs gives nothing); copies without --weights likewise; so does a mix of one input."""
    two = [str(pool[0]), str(pool[1])]
    for name, opts in (("frames", {"share_rule": "frames"}), ("copies", {"weights_by": "copies"})):
        root = tmp_path / name
        report = mix(MixOptions(inputs=two, root=str(root), progress=False, **opts))
        record = UdhmDatasetMeta(root).record
        assert [s.share for s in record.sources] == [0.0, 0.0] and [s.repeats for s in record.sources] == [1, 1]
        assert record.share_rule == "frames" and record.share_alpha is None and episode_inputs(record) == ([], [])
        assert report.train_shares == pytest.approx([1 / 6, 5 / 6]) and len(record.episodes) == 12
        text = format_report(report)
        assert "shares: each input at its frame share (no share recorded): input 0 16.7 %, input 1 83.3 %" in text
        assert "16.7% of the training frames" in text and "share recorded" not in text.split("\n", 2)[2]
    root = tmp_path / "one"
    report = mix(MixOptions(inputs=[str(pool[0])], root=str(root), progress=False))
    record = UdhmDatasetMeta(root).record
    assert [s.share for s in record.sources] == [0.0] and record.share_rule == "frames"
    assert report.train_shares == [1.0] and "shares" not in format_report(report)


def test_a_record_written_before_the_rule_still_loads(g1_l10_mix, tmp_path):
    """Records without share_rule / share_alpha (mixed before the rule) load with "" and None."""
    import shutil

    old = tmp_path / "old_mix"
    shutil.copytree(g1_l10_mix, old)
    path = old / "meta/unidextok_conversion.json"
    data = json.loads(path.read_text())
    for key in ("share_rule", "share_alpha"):
        del data[key]
    for source in data["sources"]:
        source["share"] = 0.0
    path.write_text(json.dumps(data))
    record = load_record(old)
    assert record.share_rule == "" and record.share_alpha is None and episode_inputs(record) == ([], [])


@pytest.mark.parametrize(
    ("opts", "error"),
    [
        (
            {"share_alpha": 1.5},
            r"^share_alpha must be in \[0, 1\] \(0: one equal share per input, 1: each input at "
            r"its frame share\), got 1.5$",
        ),
        ({"share_alpha": -0.1}, r"^share_alpha must be in \[0, 1\] .*got -0.1$"),
        ({"share_alpha": float("nan")}, r"^share_alpha must be a finite number in \[0, 1\], got nan$"),
        ({"share_rule": "sqrt"}, r"^share_rule must be one of \('power', 'frames'\), got 'sqrt'$"),
        ({"share_rule": "frames", "weights": [1, 2]}, r"^--weights and --share_rule=frames contradict each other"),
    ],
    ids=["alpha_above_1", "alpha_below_0", "alpha_nan", "unknown_rule", "frames_with_weights"],
)
def test_a_bad_rule_is_one_line(opts, error):
    with pytest.raises(MixError, match=error) as err:
        MixOptions(inputs=["a", "b"], root="out", **opts)
    assert "\n" not in str(err.value)


def test_a_rule_share_below_the_floor_is_refused_naming_the_fix():
    """alpha 1 with 1 frame beside 10,000: the input would be 1e-4 of the frames, below what --weights may give."""
    opts = MixOptions(inputs=["a", "b"], root="out", share_alpha=1.0)
    with pytest.raises(MixError, match=r"^the share rule frames\^1 gives input 0 \(1 training frames\) a share of "
                                       r"0.0001, below the 0.001 .*lower --share_alpha, pass --weights"):  # fmt: skip
        chosen_shares([1, 10_000], opts)
    assert chosen_shares([1, 10_000], MixOptions(inputs=["a", "b"], root="out"))[0][0] > 1e-3  # 0.43: 0.019


def test_the_cli_prints_the_rule_and_a_bad_alpha_is_one_error_line(pool, tmp_path):
    out = tmp_path / "cli"
    r = subprocess.run([str(BIN / "unidextok-mix"), f"--inputs=[{pool[0]},{pool[1]}]", f"--root={out}",
                        "--progress=false"], capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    assert "shares by the rule frames^0.43 (override with --weights): input 0 33.4 %, input 1 66.6 %" in r.stdout
    r = subprocess.run([str(BIN / "unidextok-mix"), "--inputs=[a,b]", "--share_alpha=2", f"--root={out}_bad"],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    want = (
        "error: share_alpha must be in [0, 1] (0: one equal share per input, 1: each input at its frame share), got 2"
    )
    assert r.returncode == 2 and r.stderr.splitlines()[0] == want, r.stderr
    r = subprocess.run([str(BIN / "unidextok-mix"), "--help"], capture_output=True, text=True, timeout=300)
    assert "share_rule" in r.stdout and "share_alpha" in r.stdout
