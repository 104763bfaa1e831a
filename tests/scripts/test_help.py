"""Every `unidextok-*` command's real `--help`: each flag listed once, no section divider glued into a
flag's or a group's help, no stale tuning figures. The entry points run in this process (their `main`, as
the console scripts call it); `sys.argv` is the only thing set."""

import re
import sys
from importlib.metadata import entry_points

import pytest

from experiments.config import ExperimentConfig
from lerobot_unidextok.utils.draccus_cli import config_parser

COMMANDS = sorted(ep.name for ep in entry_points(group="console_scripts") if ep.name.startswith("unidextok-"))
FLAG_LINE = re.compile(r"^  (--[\w.]+)")  # an option's first help line: two spaces, then the flag
DIVIDER = re.compile(r"-{4,}|(^|\s)-{2,3} \w")  # "--- data -----", "-- modes": a section comment, not help


def _help(name: str, monkeypatch, capsys) -> str:
    (ep,) = [ep for ep in entry_points(group="console_scripts") if ep.name == name]
    monkeypatch.setattr(sys, "argv", [name, "--help"])
    with pytest.raises(SystemExit) as exit_info:
        ep.load()()
    assert exit_info.value.code in (0, None)
    return capsys.readouterr().out


def _check(text: str) -> list[str]:
    flags = [m.group(1) for line in text.splitlines() if (m := FLAG_LINE.match(line))]
    assert flags, text
    twice = sorted({f for f in flags if flags.count(f) > 1})
    assert not twice, f"listed more than once: {twice}"
    body = text.split("\n\n", 1)[1]  # after the usage block
    glued = [line for line in body.splitlines() if DIVIDER.search(line)]
    assert not glued, f"section dividers in the help: {glued}"
    for group_flag in (f for f in flags if f"{f}." in " ".join(flags)):  # a nested config's whole-group flag
        assert any(f.startswith(f"{group_flag}.") for f in flags)
    return flags


def test_every_command_is_checked():
    assert COMMANDS == ["unidextok-config", "unidextok-convert", "unidextok-demo", "unidextok-deploy", "unidextok-eval",
                        "unidextok-mix", "unidextok-pull", "unidextok-push", "unidextok-sim-record",
                        "unidextok-sim-success", "unidextok-train", "unidextok-view"]  # fmt: skip


@pytest.mark.parametrize("name", COMMANDS)
def test_help_lists_each_flag_once_without_dividers(name, monkeypatch, capsys):
    _check(_help(name, monkeypatch, capsys))


def test_nested_groups_have_one_whole_group_flag_each(monkeypatch, capsys):
    """draccus registered `--coverage` twice and, one level down, a `--slurm` that leads nowhere."""
    train = _check(_help("unidextok-train", monkeypatch, capsys))
    assert train.count("--coverage") == 1 and "--coverage.robot" in train
    convert = _check(_help("unidextok-convert", monkeypatch, capsys))
    assert "--slurm" not in convert and {"--executor", "--executor.slurm", "--executor.slurm.partition"} <= set(convert)


def test_train_help_says_what_flags_do(monkeypatch, capsys):
    text = _help("unidextok-train", monkeypatch, capsys)
    flat = " ".join(text.split())
    assert "0.909" not in flat and "339 s" not in flat and "6-hand" not in flat  # tuning results are in the docs
    hand_names = flat.split("--hand_names list[str] ", 1)[1].split(" --init_from", 1)[0]
    assert "preset's default list" not in hand_names and "training hands" in hand_names


def test_experiment_help_lists_each_flag_once_without_dividers():
    flags = _check(config_parser(ExperimentConfig).parser.format_help())
    assert "--train.steps" in flags and "--steps" not in flags
