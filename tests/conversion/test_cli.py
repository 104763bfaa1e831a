"""unidextok-convert: the installed entry point (config file, dotted flags), --validate, --push_to_hub."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from lerobot_unidextok.errors import ConfigError
from lerobot_unidextok.scripts.convert import ConvertConfig, run

BIN = Path(sys.executable).parent


def _env(**overrides: str) -> dict[str, str]:
    env = dict(os.environ)
    env.update(
        {
            "HTTPS_PROXY": "http://127.0.0.1:9",
            "HTTP_PROXY": "http://127.0.0.1:9",
            "NO_PROXY": "127.0.0.1,localhost",
        }
    )
    env.update(overrides)
    return env


@pytest.fixture(scope="module")
def raw(tmp_path_factory):
    from lerobot_unidextok.samples import write_samples

    return write_samples(
        tmp_path_factory.mktemp("raw"),
        sources=["let"],
        episodes_per_source=5,
        frames_per_episode=30,
    )["let"]


def test_validate_reports_ok_and_catches_corruption(raw, tmp_path, capsys):
    root = tmp_path / "let_udhm"
    assert run(ConvertConfig(source="let", input=str(raw), root=str(root), repo_id="lab/let")) == 0
    assert run(ConvertConfig(validate=True, root=str(root), repo_id="lab/let")) == 0
    out = capsys.readouterr().out
    assert "result: VALID" in out and "udhm_mask matches hand specs" in out and "LeRobotDataset loads" in out

    info_path = root / "meta/info.json"
    info = json.loads(info_path.read_text())
    info["splits"] = {"train": "0:9"}  # beyond the 5 episodes
    info["features"]["observation.state"]["names"][16] = "right_wrist_yaw"  # breaks the first UDHM block
    info_path.write_text(json.dumps(info))
    assert run(ConvertConfig(validate=True, root=str(root), repo_id="lab/let")) == 2
    out = capsys.readouterr().out
    assert "FAIL  state: passthrough columns then UDHM blocks" in out and "INVALID" in out


def test_bad_flags_exit_with_message(tmp_path, capsys):
    with pytest.raises(ConfigError, match="--source and --input are required"):
        run(ConvertConfig(root=str(tmp_path / "x")))
    with pytest.raises(ConfigError, match="--source_options must be a JSON object"):
        run(
            ConvertConfig(
                source="let",
                input=str(tmp_path),
                root=str(tmp_path / "y"),
                source_options="{bad",
            )
        )
    assert run(ConvertConfig(list_sources=True)) == 0
    assert "dexycb" in capsys.readouterr().out


def test_entry_point_config_file_flags_and_push_to_hub(raw, tmp_path, capsys):
    """One subprocess: --config_path plus a flag override, then push to a loopback Hub (HF_ENDPOINT)."""
    from lerobot_unidextok.hub import LoopbackHub

    root = tmp_path / "let_udhm"
    cfg = tmp_path / "convert.yaml"
    cfg.write_text(f"source: let\ninput: {raw}\nrepo_id: lab/let_udhm\nroot: {root}\non_error: raise\n")
    token = "hf_loopback_convert"
    with LoopbackHub(token=token) as hub:  # stops when the block ends, not after a fixed time
        env = _env(
            HF_ENDPOINT=hub.url,
            HF_TOKEN=token,
            HF_HUB_OFFLINE="0",
            HF_HOME=str(tmp_path / "hf"),
        )
        r = subprocess.run(
            [
                str(BIN / "unidextok-convert"),
                f"--config_path={cfg}",
                "--on_error=skip",
                "--push_to_hub=true",
            ],
            env=env,
            capture_output=True,
            text=True,
            timeout=300,
            check=False,
        )
        assert r.returncode == 0, r.stderr[-2000:]
        assert "5 episodes (4 train / 1 test)" in r.stdout and "frames/s" in r.stdout and "pushed" in r.stdout
        assert "lerobot-train without the 1 test episodes: --dataset.episodes=" in r.stdout
        repo = hub.repos[("dataset", "lab/let_udhm")]
        assert "v3.0" in repo.tags
        files = repo.commits[repo.tags["v3.0"]]
        assert {
            "README.md",
            "meta/info.json",
            "meta/stats.json",
            "data/chunk-000/file-000.parquet",
        } <= set(files)
        assert b"SYNTHETIC" in files["README.md"]
    assert json.loads((root / "meta/info.json").read_text())["splits"] == {"train": "0:5"}
    assert len(json.loads((root / "meta/unidextok_conversion.json").read_text())["test_episodes"]) == 1
    assert json.loads((root / "meta/unidextok_conversion.json").read_text())["on_error"] == "skip"  # flag beat file

    # re-running onto the existing dataset refuses clearly: one line, exit 2 (docs/lerobot.md §6)
    r = subprocess.run([str(BIN / "unidextok-convert"), "--source=let", f"--input={raw}", f"--root={root}"],
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 2 and r.stderr.startswith("error: ") and "already holds a dataset written by unidextok-convert" in r.stderr
    assert "Traceback" not in r.stderr


def test_source_options_json_flag_survives_draccus():
    """draccus turns a mapping-looking flag into the repr of the dict it parsed; the documented
    `--source_options='{"hands": ...}'` must still reach the reader as that dict."""
    from lerobot_unidextok.utils.draccus_cli import parse_config

    flag = '{"hands": {"left": "inspire_rh56_unitree:kLeftHand", "right": "inspire_rh56_unitree:kRightHand"}}'
    cfg = parse_config(ConvertConfig, args=["--source=lerobot", "--input=x", f"--source_options={flag}"])
    assert cfg.conversion().source_options == {
        "hands": {"left": "inspire_rh56_unitree:kLeftHand", "right": "inspire_rh56_unitree:kRightHand"}
    }
