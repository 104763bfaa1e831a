"""Setup mistakes (unknown hand, option typo, wrong columns, --fps on a fixed-rate source) fail once,
before any episode is read, with the fix in the message; nothing is written."""

from __future__ import annotations

import json

import pytest

from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
from lerobot_unidextok.conversion.registry import SetupError, register_source, unregister_source
from lerobot_unidextok.errors import ConfigError
from lerobot_unidextok.scripts.convert import ConvertConfig, run

READS: list[str] = []


def _empty(folder):
    """An input folder apart from the output (a root inside the input is refused)."""
    folder.mkdir(exist_ok=True)
    return folder


@register_source("_counting_test")
class CountingSource:
    """Counts episode reads: a setup error must come before any."""

    license = "test"
    description = "records read_episode calls"

    def __init__(self, hand: str = "linkerhand_l10") -> None:
        from lerobot_unidextok.conversion.registry import check_hand

        self.hand = check_hand(hand, "--source_options hand")

    def list_episodes(self, input_path):
        return ["a", "b", "c"]

    def read_episode(self, ref):
        READS.append(ref)
        raise AssertionError("no episode may be read after a setup error")


def teardown_module():
    unregister_source("_counting_test")


@pytest.fixture
def g1_sample(tmp_path_factory):
    from lerobot_unidextok.samples import write_samples

    return write_samples(
        tmp_path_factory.mktemp("raw"), sources=["lerobot"], episodes_per_source=2, frames_per_episode=20
    )["lerobot"]


def test_unknown_hand_fails_once_before_reading(tmp_path):
    """Catches the old behaviour: an unknown hand name failed every episode with '--on_error=skip'."""
    READS.clear()
    with pytest.raises(SetupError) as err:
        convert(ConvertOptions(source="_counting_test", input=_empty(tmp_path / "in"), root=tmp_path / "out",
                               source_options={"hand": "linkerhand_l99"}, on_error="skip", progress=False))  # fmt: skip
    text = str(err.value)
    assert "unknown hand 'linkerhand_l99'" in text and "linkerhand_l10" in text and "--on_error" not in text
    assert READS == [] and not (tmp_path / "out").exists()


def test_option_typo_names_the_valid_options(tmp_path):
    """Catches the old behaviour: a misspelt option was a TypeError traceback from the reader class."""
    with pytest.raises(SetupError, match=r"has no option\(s\) \['hnad'\]; its options are: hand='linkerhand_l10'"):
        convert(ConvertOptions(source="_counting_test", input=_empty(tmp_path / "in"), root=tmp_path / "out",
                               source_options={"hnad": "x"}, progress=False))  # fmt: skip
    assert READS == []


def test_lerobot_source_checks_hands_and_columns_at_setup(g1_sample, tmp_path, capsys):
    bad_hand = {"hands": {"left": "inspyre_rh56:kLeftHand"}}
    with pytest.raises(SetupError, match="unknown hand 'inspyre_rh56'"):
        run(ConvertConfig(source="lerobot", input=str(g1_sample), root=str(tmp_path / "a"),
                          source_options=str(bad_hand)))  # fmt: skip
    bad_prefix = {"hands": {"left": "inspire_rh56_unitree:kLeftHnd"}}
    with pytest.raises(SetupError, match=r"cannot list .*no names start with prefix 'kLeftHnd'; available names"):
        convert(ConvertOptions(source="lerobot", input=g1_sample, root=tmp_path / "b", source_options=bad_prefix,
                               progress=False))  # fmt: skip
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_fps_flag_only_for_time_stamped_sources(g1_sample, tmp_path):
    with pytest.raises(SetupError, match="fixed frame rate: drop --fps"):
        convert(ConvertOptions(source="lerobot", input=g1_sample, root=tmp_path / "c", fps=25,
                               source_options={"hands": {"left": "inspire_rh56_unitree:kLeftHand"}}, progress=False))  # fmt: skip


def test_sides_leaving_out_a_hand_of_the_source_is_one_setup_error(g1_sample, tmp_path, monkeypatch, capsys):
    """`--sides=right` on a two-hand source ended in "use --on_error=skip", which would skip every episode; it is one
    error naming both fixes (all sides, or only the right hand in the source's options), skip or not."""
    import sys

    from lerobot_unidextok.samples import SAMPLE_SOURCE_OPTIONS
    from lerobot_unidextok.scripts.convert import main

    options = SAMPLE_SOURCE_OPTIONS["lerobot"]
    for on_error in ("raise", "skip"):
        with pytest.raises(SetupError) as err:
            convert(ConvertOptions(source="lerobot", input=g1_sample, root=tmp_path / "d", sides="right",
                                   source_options=options, on_error=on_error, progress=False))  # fmt: skip
        text = str(err.value)
        assert text.startswith("--sides=right leaves out the left hand that ") and "--sides=right,left" in text
        assert "name only it in the source's options" in text and "use --on_error=skip" not in text
        assert not (tmp_path / "d").exists()
    monkeypatch.setattr(sys, "argv", ["unidextok-convert", "--source=lerobot", f"--input={g1_sample}", "--sides=right",
                                      f"--root={tmp_path / 'd'}", f"--source_options={json.dumps(options)}"])  # fmt: skip
    with pytest.raises(SystemExit) as exit_info:
        main()
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert exit_info.value.code == 2 and len(errors) == 1 and "--sides=right leaves out the left hand" in errors[0]


def test_source_options_naming_a_side_twice_is_refused(g1_sample, tmp_path, monkeypatch, capsys):
    """`{"hands": {"left": <left columns>, "left": <right columns>}}` kept the last entry: a one-hand dataset of the
    right hand's joints labelled left. A key given twice is one error naming it, on the command line and as text."""
    import sys

    from lerobot_unidextok.scripts.convert import main

    twice = '{"hands": {"left": "inspire_rh56_unitree:kLeftHand", "left": "inspire_rh56_unitree:kRightHand"}}'
    monkeypatch.setattr(sys, "argv", ["unidextok-convert", "--source=lerobot", f"--input={g1_sample}",
                                      f"--root={tmp_path / 'e'}", f"--source_options={twice}"])  # fmt: skip
    with pytest.raises(SystemExit) as exit_info:
        main()
    errors = [line for line in capsys.readouterr().err.splitlines() if line.startswith("error:")]
    assert exit_info.value.code == 2 and len(errors) == 1, errors
    assert errors[0].startswith("error: --source_options: ") and "names the key 'left' twice" in errors[0]
    with pytest.raises(ConfigError, match="--source_options must be a JSON object with each key once: names the key "
                                          "'left' twice"):  # fmt: skip
        ConvertConfig(source="lerobot", input=str(g1_sample), root=str(tmp_path / "e"), source_options=twice)
    assert not (tmp_path / "e").exists()
