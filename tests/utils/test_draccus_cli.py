"""draccus parsing for the CLIs: a config's own check as its error, whole-group values, help formatting."""

from dataclasses import dataclass, field

import pytest

from lerobot_unidextok.utils.draccus_cli import config_parser, parse_config, wrap


@dataclass
class Inner:
    name: str = "a"  # a name
    share: float = 0.5  # share of the rows (50 % by default)


@dataclass
class Outer:
    inner: Inner = field(default_factory=Inner)  # the inner group
    steps: int = 1  # steps

    def __post_init__(self) -> None:
        if self.steps < 1:
            raise ValueError(f"steps must be >= 1, got {self.steps}")


@dataclass
class Deep:
    outer: Outer = field(default_factory=Outer)  # two levels of groups


def test_a_check_in_post_init_is_raised_as_itself():
    with pytest.raises(ValueError, match="steps must be >= 1, got 0"):
        parse_config(Outer, ["--steps=0"])


def test_a_group_takes_its_fields_one_by_one_or_as_one_mapping(tmp_path):
    assert parse_config(Outer, ["--inner.name=b"]).inner == Inner("b", 0.5)
    assert parse_config(Outer, ["--inner={name: c, share: 0.25}"]).inner == Inner("c", 0.25)
    path = tmp_path / "inner.yaml"
    path.write_text("name: d\n")
    assert parse_config(Outer, [f"--inner=include {path}"]).inner == Inner("d", 0.5)
    with pytest.raises(ValueError, match=r"--inner=b: --inner is a group of flags \(--inner.<field>=..."):
        parse_config(Outer, ["--inner=b"])


def test_help_has_one_group_flag_per_group_and_survives_percent_signs():
    text = config_parser(Deep).parser.format_help()  # "50 %" in a comment broke argparse's formatting
    assert "50 %" in text
    options = [line.split()[0] for line in text.splitlines() if line.startswith("  --")]
    assert options.count("--outer") == 1 and options.count("--outer.inner") == 1 and "--inner" not in options
    assert "Config file for" not in text and "one YAML mapping" in text


def test_wrap_parses_the_command_line_unless_given_a_config(monkeypatch):
    seen = []

    @wrap()
    def cli(cfg: Outer) -> int:
        seen.append(cfg)
        return cfg.steps

    monkeypatch.setattr("sys.argv", ["prog", "--steps=3"])
    assert cli() == 3
    assert cli(Outer(steps=5)) == 5 and seen[-1].steps == 5


def test_a_value_yaml_cannot_read_names_its_flag():
    with pytest.raises(ValueError, match=r"--inner.name: '\{bad' is not valid YAML/JSON"):
        parse_config(Outer, ["--inner.name={bad"])
