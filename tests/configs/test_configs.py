"""Shipped configs by name: the same command from a clone or a pip install, for our CLIs and LeRobot's."""

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from lerobot_unidextok.configs import main, resolve_config_path, shipped_config, shipped_configs
from lerobot_unidextok.training import TrainConfig
from lerobot_unidextok.utils.draccus_cli import parse_config

BIN = Path(sys.executable).parent


def test_every_shipped_config_is_found_by_group_name_and_file_name():
    configs = shipped_configs()
    assert {"train/small", "train/universal", "lerobot/act_udt_cpu", "convert/slurm"} <= set(configs)
    for name, path in configs.items():
        assert path.is_file() and yaml.safe_load(path.read_text())
        assert shipped_config(name) == shipped_config(f"{name}.yaml") == path
    assert shipped_config("act_udt_cpu") == configs["lerobot/act_udt_cpu"]  # unique bare name
    assert shipped_config("no_such_config") is None


def test_our_clis_take_a_shipped_name_or_a_file(tmp_path):
    by_name = parse_config(TrainConfig, ["--config_path=train/tiny"])
    by_file = parse_config(TrainConfig, [f"--config_path={shipped_config('train/tiny')}"])
    assert by_name == by_file and by_name.preset == "tiny"
    own = tmp_path / "mine.yaml"
    own.write_text("preset: small\nsteps: 7\n")
    assert parse_config(TrainConfig, ["--config_path", str(own)]).steps == 7  # a file wins over a name
    with pytest.raises(FileNotFoundError, match="--config_path nowhere.yaml not found: .*train/small"):
        parse_config(TrainConfig, ["--config_path=nowhere.yaml"])
    with pytest.raises(FileNotFoundError, match="recipe x not found"):
        resolve_config_path("x", "recipe")


def test_unidextok_config_prints_the_path_lerobot_train_takes(capsys):
    main(["lerobot/act_udt_cpu"])
    path = Path(capsys.readouterr().out.strip())
    assert path == shipped_config("lerobot/act_udt_cpu") and yaml.safe_load(path.read_text())["policy"]["type"] == "act_udt"
    main([])
    assert "train/small" in capsys.readouterr().out
    r = subprocess.run([str(BIN / "unidextok-config"), "nope"], capture_output=True, text=True, check=False)
    assert r.returncode == 2 and r.stderr.startswith("error: no shipped config 'nope'") and not r.stdout
