"""Real push / pull round trips through the unidextok-push / unidextok-pull CLIs against a loopback Hub.

The server (lerobot_unidextok.hub.LoopbackHub) binds 127.0.0.1 and stops itself; subprocesses get
HTTPS_PROXY/HTTP_PROXY=127.0.0.1:9 with NO_PROXY=127.0.0.1, so any non-loopback request fails.
No client patching is needed: our push writes the README itself, and the loopback Hub answers
/api/validate-yaml.
"""

import json
import os
import subprocess
import sys
import time
import urllib.error
import urllib.request
from pathlib import Path

import pytest
import torch
from linkerhand_udhm import subprocess_env

from lerobot_unidextok.hub import LoopbackHub, cached_snapshot, pull, tokenizer_card
from lerobot_unidextok.hub.card import eval_table, infer_preset
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

BIN = Path(sys.executable).parent
TOKEN = "hf_loopback_secret"
EVAL = {
    "results": {
        "human": {"mpjae_deg": 3.25, "mpjpe_mm": 4.5},
        "linkerhand_l10": {"mpjae_deg": 1.5, "mpjpe_mm": 2.0},
    }
}


@pytest.fixture(scope="module")
def hub():
    with LoopbackHub(lifetime_s=300, token=TOKEN) as server:
        yield server


@pytest.fixture(scope="module")
def tok_dir(tmp_path_factory):
    torch.manual_seed(1)
    path = tmp_path_factory.mktemp("tok") / "ckpt"
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["human", "linkerhand_l10"])).save_pretrained(path)
    (path / "README.md").unlink()  # let unidextok-push generate the card
    (path / "eval.json").write_text(json.dumps(EVAL))
    return path


def run_cli(args: list[str], **env: str) -> subprocess.CompletedProcess:
    return subprocess.run(
        [str(BIN / args[0]), *args[1:]],
        env=subprocess_env(**env),
        check=False,
        capture_output=True,
        text=True,
        timeout=180,
    )


def test_round_trip_tokenizer_and_dataset(hub, tok_dir, l10_dataset, tmp_path):
    # one online process runs the CLI entry points (draccus parsing included) for 2 pushes + 2 pulls,
    # pulling into an HF cache nothing was downloaded into before
    cache = tmp_path / "hf-fresh"
    cli = f"""
import sys
from lerobot_unidextok.scripts.hub import pull_main, push_main
for argv, main in [
    (["--local_dir={tok_dir}", "--repo_id=lab/unidextok-tiny", "--training_data=[lab/l10_udhm]"], push_main),
    (["--local_dir={l10_dataset}", "--repo_id=lab/l10_udhm"], push_main),
    (["--repo_id=lab/unidextok-tiny"], pull_main),
    (["--repo_id=lab/l10_udhm", "--repo_type=dataset"], pull_main),
]:
    sys.argv = ["unidextok", *argv]
    main()
"""
    r = subprocess.run(
        [sys.executable, "-c", cli],
        check=False,
        capture_output=True,
        text=True,
        timeout=300,
        env=subprocess_env(HF_ENDPOINT=hub.url, HF_TOKEN=TOKEN, HF_HUB_OFFLINE="0", HF_HOME=str(cache)),
    )
    assert r.returncode == 0, r.stderr[-3000:]
    lines = r.stdout.strip().splitlines()
    assert lines[0].startswith("pushed") and lines[1].startswith("pushed")
    model_snapshot, ds_snapshot = Path(lines[-2]), Path(lines[-1])
    assert ("model", "lab/unidextok-tiny") in hub.repos
    assert "v3.0" in hub.repos[("dataset", "lab/l10_udhm")].tags  # LeRobot resolves this tag
    assert not (tok_dir / "README.md").exists()  # the card is staged, the user's folder untouched
    assert model_snapshot.is_relative_to(cache / "hub") and ds_snapshot.is_relative_to(cache / "hub")
    card = (model_snapshot / "README.md").read_text()
    assert "- `linkerhand_l10`" in card and "preset: `tiny`" in card and "- `lab/l10_udhm`" in card
    assert "| linkerhand_l10 | 1.5 | 2 |" in card

    # offline, in a fresh process: tokenizer by repo id (bit-exact), processor step by repo id, dataset
    check = f"""
import torch
import lerobot_unidextok  # registration on package import (checked here to save a process)
from lerobot.processor import ProcessorStepRegistry
from lerobot.configs.policies import PreTrainedConfig
assert "unidextok.state_tokenizer" in ProcessorStepRegistry.list()
assert "act_udt" in PreTrainedConfig.get_known_choices()
from safetensors.torch import load_file
from lerobot_unidextok.tokenizer import UniDexTok
from lerobot_unidextok.processor import UniDexTokStateTokenizerStep
from lerobot.datasets import LeRobotDataset
tok = UniDexTok.from_pretrained("lab/unidextok-tiny")
ref = load_file("{tok_dir / "model.safetensors"}")
assert all(torch.equal(v, tok.state_dict()[k]) for k, v in ref.items()), "weights differ"
step = UniDexTokStateTokenizerStep(hand_layout=["linkerhand_l10"] * 2, pretrained="lab/unidextok-tiny")
ds = LeRobotDataset("lab/l10_udhm", root="{ds_snapshot}")
out = step.observation({{"observation.state": ds[0]["observation.state"]}})
print(len(ds), tuple(out["observation.hand_tokens"].shape))
"""
    r = subprocess.run(
        [sys.executable, "-c", check],
        check=False,
        env=subprocess_env(HF_HUB_OFFLINE="1", HF_HOME=str(cache)),
        capture_output=True,
        text=True,
        timeout=180,
    )
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.split()[-3:] == ["36", "(64,)"]


def test_wrong_token_is_rejected(hub, tok_dir, tmp_path):
    r = run_cli(
        ["unidextok-push", f"--local_dir={tok_dir}", "--repo_id=lab/other"],
        HF_ENDPOINT=hub.url,
        HF_TOKEN="wrong",
        HF_HUB_OFFLINE="0",
        HF_HOME=str(tmp_path),
    )
    assert r.returncode != 0 and "401" in r.stderr
    assert ("model", "lab/other") not in hub.repos


def test_offline_errors_name_the_fix(tmp_path, monkeypatch):
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    with pytest.raises(RuntimeError, match="unset HF_HUB_OFFLINE"):
        pull("lab/unidextok-tiny")
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path))
    with pytest.raises(FileNotFoundError, match=r"unidextok-pull --repo_id=lab/nothing-here"):
        cached_snapshot("lab/nothing-here")
    with pytest.raises(ValueError, match="namespace/name"):
        pull("no-namespace")


def test_loopback_hub_stops_by_itself():
    server = LoopbackHub(lifetime_s=0.5).start()
    url = server.url
    with urllib.request.urlopen(f"{url}/api/whoami-v2", timeout=5) as resp:  # NO_PROXY covers 127.0.0.1
        assert json.load(resp)["name"] == "loopback"
    deadline = time.monotonic() + 10
    while time.monotonic() < deadline:
        try:
            urllib.request.urlopen(f"{url}/api/whoami-v2", timeout=1).close()
        except (urllib.error.URLError, ConnectionError):
            break
        time.sleep(0.2)
    else:
        pytest.fail("loopback hub still answering after its lifetime")


def test_card_helpers(tok_dir, tmp_path):
    cfg = json.loads((tok_dir / "config.json").read_text())
    assert infer_preset(cfg) == "tiny"
    assert infer_preset({**cfg, "hidden_dim": 96}) == "custom"
    assert eval_table({"mpjae_deg": 2.0}).splitlines()[-1] == "| all | 2 |"
    (tmp_path / "config.json").write_text(json.dumps(cfg))
    card = tokenizer_card(tmp_path, "a/b")
    assert "No evaluation file" in card and "not recorded" in card and "library_name: lerobot-unidextok" in card
    with pytest.raises(FileNotFoundError, match="not a UniDexTok checkpoint"):
        tokenizer_card(tmp_path / "empty", "a/b")


def test_proxy_blocks_non_loopback_traffic():
    assert os.environ["NO_PROXY"] == "127.0.0.1,localhost"
    code = "import httpx; httpx.get('https://huggingface.co/api/whoami-v2', timeout=5)"
    r = subprocess.run(
        [sys.executable, "-c", code],
        env=subprocess_env(),
        check=False,
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode != 0 and ("ProxyError" in r.stderr or "ConnectError" in r.stderr)


def test_cache_via_loopback_then_offline_load(tok_dir, tmp_path):
    code = f"""
from lerobot_unidextok.hub import cache_via_loopback
from lerobot_unidextok.tokenizer import UniDexTok
path = cache_via_loopback("{tok_dir}", "demo/unidextok-tiny")
tok = UniDexTok.from_pretrained("demo/unidextok-tiny", local_files_only=True)
print(path.parent.parent.name, tok.config.num_tokens)
"""
    r = subprocess.run([sys.executable, "-c", code], check=False, env=subprocess_env(HF_HUB_OFFLINE="0", HF_HOME=str(tmp_path)),
                       capture_output=True, text=True, timeout=180)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.split()[-2:] == ["models--demo--unidextok-tiny", "4"]
