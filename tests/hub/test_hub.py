"""Real push / pull round trips through the unidextok-push / unidextok-pull CLIs against a loopback Hub.

The server (lerobot_unidextok.hub.LoopbackHub) binds 127.0.0.1 and stops when the test module ends;
subprocesses get HTTPS_PROXY/HTTP_PROXY=127.0.0.1:9 with NO_PROXY=127.0.0.1, so any non-loopback request
fails. The dataset is the synthetic whole-robot fixture (tests/fixtures/robot_udhm.py), in the repository.
"""

import dataclasses
import json
import os
import shutil
import subprocess
import sys
import urllib.error
import urllib.request
from pathlib import Path

import pytest
import torch
from cli_main import run_main
from linkerhand_udhm import subprocess_env
from robot_udhm import INSPIRE

from lerobot_unidextok.hub import LoopbackHub, cached_snapshot, model_card, pull, tokenizer_card
from lerobot_unidextok.hub.card import CARD_MARKER, card_status, eval_table, infer_preset
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

BIN = Path(sys.executable).parent
TOKEN = "hf_loopback_secret"
EVAL = {"results": {"human": {"mpjae_deg": 3.25, "mpjpe_mm": 4.5}, INSPIRE: {"mpjae_deg": 1.5, "mpjpe_mm": 2.0}}}


@pytest.fixture(scope="module")
def hub():
    with LoopbackHub(token=TOKEN) as server:  # stops when the module's tests are done
        yield server


@pytest.fixture(scope="module")
def tok_dir(tmp_path_factory):
    """A tokenizer folder as UniDexTok.save_pretrained leaves it: huggingface_hub's generic README."""
    torch.manual_seed(1)
    path = tmp_path_factory.mktemp("tok") / "ckpt"
    cfg = UniDexTokConfig.from_preset("tiny", hand_names=["human", INSPIRE], trained_hands=["human", INSPIRE])
    UniDexTok(cfg).save_pretrained(path)
    assert card_status(path / "README.md") == "generic"
    (path / "eval.json").write_text(json.dumps(EVAL))
    return path


def run_cli(args: list[str], **env: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / args[0]), *args[1:]], env=subprocess_env(**env), check=False,
                          capture_output=True, text=True, timeout=180)  # fmt: skip


def _files(root: Path) -> dict[str, bytes]:
    """Relative POSIX path -> content of every file under `root` (snapshot symlinks followed)."""
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_round_trip_tokenizer_and_dataset(hub, tok_dir, g1_like_hands, tmp_path):
    """Pulls resolve by repo id everywhere: cached_snapshot(dataset) failed right after the documented pull
    (tag v3.0), and unidextok-train/-eval only looked in $HF_HOME/lerobot; the generic README of a
    saved tokenizer was uploaded instead of the documented card, ignoring --training_data.
    The pulled dataset is compared file by file, byte for byte (catches a push or pull that drops, renames
    or rewrites a file: the old check counted files only)."""
    cache = tmp_path / "hf-fresh"
    cli = f"""
import sys
from lerobot_unidextok.scripts.hub import pull_main, push_main
for argv, main in [
    (["--local_dir={tok_dir}", "--repo_id=lab/unidextok-tiny", "--training_data=[lab/g1_udhm]"], push_main),
    (["--local_dir={g1_like_hands["root"]}", "--repo_id=lab/g1_udhm"], push_main),
    (["--repo_id=lab/unidextok-tiny"], pull_main),
    (["--repo_id=lab/g1_udhm", "--repo_type=dataset"], pull_main),
]:
    sys.argv = ["unidextok", *argv]
    main()
"""
    r = subprocess.run([sys.executable, "-c", cli], check=False, capture_output=True, text=True, timeout=300,
                       env=subprocess_env(HF_ENDPOINT=hub.url, HF_TOKEN=TOKEN, HF_HUB_OFFLINE="0",
                                          HF_HOME=str(cache), HF_LEROBOT_HOME=str(cache / "lerobot")))  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    lines = r.stdout.strip().splitlines()
    assert lines[0].startswith("pushed") and lines[1].startswith("pushed")
    model_snapshot, ds_snapshot = Path(lines[-2]), Path(lines[-1])
    assert "v3.0" in hub.repos[("dataset", "lab/g1_udhm")].tags  # LeRobot resolves this tag
    # every file of the dataset comes back byte for byte (the pull is checked by content, not by count)
    local, pulled = _files(g1_like_hands["root"]), _files(ds_snapshot)
    assert set(pulled) - set(local) <= {"README.md", ".gitattributes"}, sorted(set(pulled) - set(local))
    assert any(name.endswith(".parquet") for name in local) and "meta/unidextok_conversion.json" in local
    changed = [name for name, data in local.items() if pulled.get(name) != data]
    assert not changed, changed
    assert card_status(tok_dir / "README.md") == "generic"  # the card is staged, the user's folder untouched
    assert model_snapshot.is_relative_to(cache / "hub") and ds_snapshot.is_relative_to(cache / "hub")
    card = (model_snapshot / "README.md").read_text()
    assert CARD_MARKER in card and "## Hands trained" in card and f"- `{INSPIRE}`" in card
    assert "preset: `tiny`" in card and "- `lab/g1_udhm`" in card and "datasets:\n- lab/g1_udhm" in card
    assert f"| {INSPIRE} | 1.5 | 2 |" in card

    # offline, in a fresh process: tokenizer by repo id (bit-exact), dataset by repo id in every reader
    check = f"""
import torch
import lerobot_policy_unidextok  # registration by LeRobot's plugin package (checked here to save a process)
from lerobot.processor import ProcessorStepRegistry
from lerobot.configs.policies import PreTrainedConfig
assert "unidextok.state_tokenizer" in ProcessorStepRegistry.list()
assert {{"act_udt", "diffusion_udt"}} <= set(PreTrainedConfig.get_known_choices())
from safetensors.torch import load_file
from lerobot_unidextok.tokenizer import UniDexTok
from lerobot_unidextok.processor import UniDexTokStateTokenizerStep
from lerobot_unidextok.hub import cached_snapshot
from lerobot_unidextok.data.reader import load_udhm_frames
from lerobot.datasets import LeRobotDataset
tok = UniDexTok.from_pretrained("lab/unidextok-tiny")
ref = load_file("{tok_dir / "model.safetensors"}")
assert all(torch.equal(v, tok.state_dict()[k]) for k, v in ref.items()), "weights differ"
root = cached_snapshot("lab/g1_udhm", "dataset")
assert str(root) == "{ds_snapshot}", root
ds = LeRobotDataset("lab/g1_udhm")  # no root: the pull linked it into $HF_LEROBOT_HOME
step = UniDexTokStateTokenizerStep.from_dataset(root, pretrained="lab/unidextok-tiny")
out = step.observation({{"observation.state": ds[0]["observation.state"]}})
frames = load_udhm_frames(repo_id="lab/g1_udhm")  # what unidextok-train / -eval --datasets=[repo id] use
print(len(ds), tuple(out["observation.hand_tokens"].shape), len(frames))
"""
    env = subprocess_env(HF_HUB_OFFLINE="1", HF_HOME=str(cache), HF_LEROBOT_HOME=str(cache / "lerobot"))
    r = subprocess.run([sys.executable, "-c", check], check=False, env=env, capture_output=True, text=True,
                       timeout=180)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    assert r.stdout.split()[-4:] == ["120", "(64,)", "240"]  # 3 x 40 frames; 2 hands x 4 tokens x 8; rows x 2

    # without the LeRobot-home link the readers fall back to the HF cache the pull filled
    (cache / "lerobot" / "lab" / "g1_udhm").unlink()
    check = 'from lerobot_unidextok.data.reader import load_udhm_frames; print(len(load_udhm_frames(repo_id="lab/g1_udhm")))'
    r = subprocess.run([sys.executable, "-c", check], check=False, env=env, capture_output=True, text=True, timeout=120)
    assert r.returncode == 0 and r.stdout.split()[-1] == "240", r.stderr[-2000:]


def test_push_keeps_our_card_and_adds_training_data(hub, tok_dir, tmp_path):
    folder = tmp_path / "run" / "best"  # a training run folder: best/ is pushed
    shutil.copytree(tok_dir, folder)
    (folder / "README.md").write_text(tokenizer_card(folder, "lab/tok") + "\nExtra figures kept.\n")
    r = run_cli(["unidextok-push", f"--local_dir={folder.parent}", "--repo_id=lab/tok-run", "--training_data=[lab/a]"],
                HF_ENDPOINT=hub.url, HF_TOKEN=TOKEN, HF_HUB_OFFLINE="0", HF_HOME=str(tmp_path / "hf"))  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    repo = hub.repos[("model", "lab/tok-run")]
    card = repo.commits[repo.branches["main"]]["README.md"].decode()
    assert "Extra figures kept." in card and "- `lab/a`" in card and "datasets:\n- lab/a" in card
    assert "config.json" in repo.commits[repo.branches["main"]]


def test_the_shipped_tokenizer_is_pushed_by_its_id_like_any_model(hub, tmp_path):
    from lerobot_unidextok.pretrained import DEFAULT_TOKENIZER, SHIPPED

    r = run_cli(["unidextok-push", f"--local_dir={DEFAULT_TOKENIZER}", "--repo_id=lab/universal-small"],
                HF_ENDPOINT=hub.url, HF_TOKEN=TOKEN, HF_HUB_OFFLINE="0", HF_HOME=str(tmp_path / "hf"))  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    repo = hub.repos[("model", "lab/universal-small")]
    uploaded = repo.commits[repo.branches["main"]]
    for name in ("config.json", "model.safetensors", "eval.json"):
        assert uploaded[name] == (SHIPPED[DEFAULT_TOKENIZER] / name).read_bytes(), name
    # the card is ours: named after the repo it is pushed to, its figures and the rest kept as they are
    shipped_card = (SHIPPED[DEFAULT_TOKENIZER] / "README.md").read_text()
    card = uploaded["README.md"].decode()
    assert "# lab/universal-small\n" in card and 'from_pretrained("lab/universal-small")' in card
    assert card.split("## Use")[0] == shipped_card.split("## Use")[0].replace(f"# {DEFAULT_TOKENIZER}\n",
                                                                               "# lab/universal-small\n")


def _pushed_card(hub, repo_id: str) -> str:
    repo = hub.repos[("model", repo_id)]
    return repo.commits[repo.branches["main"]]["README.md"].decode()


def test_run_card_reads_as_text_and_is_named_after_the_pushed_repo(hub, g1_like, tmp_path):
    """A unidextok-train card pushed as lab/unidextok-g1 was titled `# tok_small` (the run folder) and loaded
    `from_pretrained("tok_small")` / `unidextok-pull --repo_id=tok_small`; it said "not recorded" right above
    the dataset path; checkpoint selection was printed as a Python dict."""
    from lerobot_unidextok.training import TrainConfig
    from lerobot_unidextok.training.run import train_and_evaluate

    run = tmp_path / "tok_small"
    train_and_evaluate(TrainConfig(datasets=[str(g1_like["root"])], preset="tiny", steps=10, batch_size=16,
                                   warmup_steps=2, eval_every=5, progress=False, output_dir=str(run)))  # fmt: skip
    local = (run / "best" / "README.md").read_text()
    assert "not recorded" not in local and f"- `{g1_like['root']}`" in local.split("## Training data")[1]
    assert "{'rows'" not in local and "| preset | tiny |" in local
    assert "Checkpoint selection: the evaluation with the lowest joint MAE on 80 hand-rows" in local
    assert f"Scored: checkpoint `{run / 'best'}` on the test episodes below" in local
    assert f'from_pretrained("{run / "best"}")' in local and "Publish it with `unidextok-push" in local

    r = run_cli(["unidextok-push", f"--local_dir={run}", "--repo_id=lab/unidextok-g1"],
                HF_ENDPOINT=hub.url, HF_TOKEN=TOKEN, HF_HUB_OFFLINE="0", HF_HOME=str(tmp_path / "hf"))  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    card = _pushed_card(hub, "lab/unidextok-g1")
    assert card.split(CARD_MARKER)[1].lstrip().startswith("# lab/unidextok-g1\n")
    use = card.split("## Use")[1]
    assert 'from_pretrained("lab/unidextok-g1")' in use and "unidextok-pull --repo_id=lab/unidextok-g1" in use
    assert "tok_small" not in use and "Publish it" not in card
    assert card.split("## Use")[0] == local.split("## Use")[0].replace(f"# UniDexTok tokenizer `{run / 'best'}`",
                                                                        "# lab/unidextok-g1")  # fmt: skip


def test_folder_without_readme_gets_a_generated_card(hub, tok_dir, tmp_path):
    folder = tmp_path / "ckpt"
    shutil.copytree(tok_dir, folder)
    (folder / "README.md").unlink()
    r = run_cli(["unidextok-push", f"--local_dir={folder}", "--repo_id=lab/no-readme"],
                HF_ENDPOINT=hub.url, HF_TOKEN=TOKEN, HF_HUB_OFFLINE="0", HF_HOME=str(tmp_path / "hf"))  # fmt: skip
    assert r.returncode == 0, r.stderr[-2000:]
    card = _pushed_card(hub, "lab/no-readme")
    assert CARD_MARKER in card and "# lab/no-readme\n" in card and 'from_pretrained("lab/no-readme")' in card
    assert not (folder / "README.md").exists()  # staged: the folder is left as it was


def test_policy_folder_gets_a_policy_card(tmp_path, g1_like):
    """Pushing a policy folder wrote a tokenizer card ('None tokens x None groups')."""
    folder = tmp_path / "pretrained_model"
    folder.mkdir()
    config = {"type": "diffusion_udt", "udt_hand_layout": [INSPIRE] * 2, "udt_sides": ["left", "right"],
              "udt_state_names": [f"s{i}" for i in range(58)], "udt_pretrained": "lab/unidextok-small",
              "udt_representation": "dequantized", "udt_native_layout": {"native_names": [f"n{i}" for i in range(26)]},
              "udt_native_state_layout": {"native_names": [f"n{i}" for i in range(26)]},
              "input_features": {"observation.state": {"type": "STATE", "shape": [58]}},
              "output_features": {"action": {"type": "ACTION", "shape": [58]}}}  # fmt: skip
    (folder / "config.json").write_text(json.dumps(config))
    (folder / "train_config.json").write_text(json.dumps({"dataset": {"repo_id": "lab/g1_udhm"}, "steps": 3}))
    card = model_card(folder, "lab/diffusion-g1")
    assert "None tokens" not in card and "LeRobot policy `diffusion_udt`" in card
    assert "14 passthrough (arms, grippers...) + 2 UDHM blocks" in card and "native 26-wide vector" in card
    assert "the robot's native 26-wide state is accepted too" in card
    assert "- `lab/g1_udhm`" in card and "--policy.discover_packages_path=lerobot_unidextok" in card
    assert "library_name: lerobot" in card


def test_card_lists_only_the_hands_trained(tmp_path):
    """A tokenizer trained on one hand had all 11 vocabulary hands listed as supported."""
    cfg = UniDexTokConfig.from_preset("tiny", trained_hands=[INSPIRE])
    (tmp_path / "config.json").write_text(json.dumps(dataclasses.asdict(cfg)))
    card = tokenizer_card(tmp_path, "a/b")
    hands = card.split("## Hands trained")[1].split("##")[0]
    assert hands.count("\n- `") == 1 and f"- `{INSPIRE}`" in hands
    assert "never trained (zero-shot only" in hands and "`shadow`" in hands


def test_wrong_token_is_rejected(hub, tok_dir, tmp_path):
    r = run_cli(["unidextok-push", f"--local_dir={tok_dir}", "--repo_id=lab/other"],
                HF_ENDPOINT=hub.url, HF_TOKEN="wrong", HF_HUB_OFFLINE="0", HF_HOME=str(tmp_path))  # fmt: skip
    assert r.returncode == 2 and r.stderr.startswith("error: the Hub refused the push to model lab/other (HTTP 401")
    assert "Traceback" not in r.stderr and ("model", "lab/other") not in hub.repos


def test_user_mistakes_are_one_line_errors(tmp_path, monkeypatch, capsys):
    """A missing folder or a bad repo id printed a Python traceback."""
    from lerobot_unidextok.scripts.hub import pull_main, push_main

    for main, argv, expected in [
        (
            push_main,
            [f"--local_dir={tmp_path / 'missing'}", "--repo_id=lab/x"],
            f"error: {tmp_path / 'missing'} is not",
        ),
        (pull_main, ["--repo_id=no-namespace"], "error: repo_id must look like 'namespace/name'"),
    ]:
        monkeypatch.setattr(sys, "argv", ["unidextok", *argv])
        with pytest.raises(SystemExit) as exit_info:
            main()
        err = capsys.readouterr().err
        assert exit_info.value.code == 2 and err.startswith(expected) and "Traceback" not in err


def test_offline_errors_name_the_fix(tmp_path, monkeypatch):
    monkeypatch.setenv("HF_HUB_OFFLINE", "1")
    with pytest.raises(RuntimeError, match="unset HF_HUB_OFFLINE"):
        pull("lab/unidextok-tiny")
    monkeypatch.setenv("HF_HUB_CACHE", str(tmp_path))
    with pytest.raises(FileNotFoundError, match=r"unidextok-pull --repo_id=lab/nothing-here --repo_type=dataset"):
        cached_snapshot("lab/nothing-here", "dataset")
    with pytest.raises(ValueError, match="namespace/name"):
        pull("no-namespace")


def test_loopback_hub_stops_when_the_block_ends():
    with LoopbackHub() as server:
        url = server.url
        with urllib.request.urlopen(f"{url}/api/whoami-v2", timeout=5) as resp:  # NO_PROXY covers 127.0.0.1
            assert json.load(resp)["name"] == "loopback"
    with pytest.raises((urllib.error.URLError, ConnectionError)):
        urllib.request.urlopen(f"{url}/api/whoami-v2", timeout=5)
    with pytest.raises(RuntimeError, match="not running"):
        _ = server.url


def test_card_helpers(tok_dir, tmp_path):
    cfg = json.loads((tok_dir / "config.json").read_text())
    assert infer_preset(cfg) == "tiny"
    assert infer_preset({**cfg, "hidden_dim": 96}) == "custom"
    assert eval_table({"mpjae_deg": 2.0}).splitlines()[-1] == "| all | 2 |"
    (tmp_path / "config.json").write_text(json.dumps({**cfg, "trained_hands": []}))
    card = tokenizer_card(tmp_path, "a/b")
    assert "No evaluation file" in card and "not recorded" in card and "library_name: lerobot-unidextok" in card
    assert "does not record which of these hands" in card
    with pytest.raises(FileNotFoundError, match="no config.json"):
        tokenizer_card(tmp_path / "empty", "a/b")


def test_proxy_blocks_non_loopback_traffic():
    assert os.environ["NO_PROXY"] == "127.0.0.1,localhost"
    code = "import httpx; httpx.get('https://huggingface.co/api/whoami-v2', timeout=5)"
    r = subprocess.run([sys.executable, "-c", code], env=subprocess_env(), check=False, capture_output=True,
                       text=True, timeout=60)  # fmt: skip
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


def test_pull_fails_when_the_hub_refuses_even_with_a_warm_cache(hub, tok_dir, tmp_path):
    """A rejected token with the tokenizer already cached printed "pulled" and exited 0 with the stale
    snapshot (snapshot_download falls back to the cache on any HTTP error). Now: exit 2, the refusal named,
    the cache left as it was; an unreachable Hub falls back to the cache and says so."""
    env = dict(HF_ENDPOINT=hub.url, HF_HUB_OFFLINE="0", HF_HOME=str(tmp_path / "hf"))
    assert run_cli(["unidextok-push", f"--local_dir={tok_dir}", "--repo_id=lab/warm"], HF_TOKEN=TOKEN, **env).returncode == 0
    warm = run_cli(["unidextok-pull", "--repo_id=lab/warm"], HF_TOKEN=TOKEN, **env)
    assert warm.returncode == 0, warm.stderr[-2000:]
    refused = run_cli(["unidextok-pull", "--repo_id=lab/warm"], HF_TOKEN="wrong", **env)
    assert refused.returncode == 2, refused.stderr[-2000:]
    assert refused.stderr.startswith("error: the Hub refused model lab/warm (HTTP 401") and "Traceback" not in refused.stderr
    assert "the cached snapshot" in refused.stderr and "left as it was" in refused.stderr
    assert "pulled" not in refused.stdout + refused.stderr.replace("nothing was pulled", "")
    unreachable = run_cli(["unidextok-pull", "--repo_id=lab/warm"], HF_TOKEN=TOKEN,
                          **{**env, "HF_ENDPOINT": "http://127.0.0.1:9"})  # fmt: skip
    assert unreachable.returncode == 0, unreachable.stderr[-2000:]
    assert "cannot be reached" in unreachable.stderr and "may be older than the Hub's" in unreachable.stderr
    missing = run_cli(["unidextok-pull", "--repo_id=lab/never-pushed"], HF_TOKEN=TOKEN, **env)
    assert missing.returncode == 2 and missing.stderr.startswith("error: the Hub has no model lab/never-pushed")


def test_push_refuses_a_damaged_checkpoint_before_uploading(hub, tok_dir, tmp_path, monkeypatch, capsys):
    folder = tmp_path / "ckpt"
    shutil.copytree(tok_dir, folder)
    weights = folder / "model.safetensors"
    weights.write_bytes(weights.read_bytes()[:-64])
    code, err = _push_in_process(hub, monkeypatch, capsys, folder, "lab/damaged")
    assert code == 2 and err.startswith(f"error: {weights} cannot be read"), err[-2000:]
    assert "nothing was pushed" in err and ("model", "lab/damaged") not in hub.repos


def test_push_refuses_a_tokenizer_with_a_nan_weight_naming_it(hub, tok_dir, tmp_path, monkeypatch, capsys):
    """A tokenizer whose weights hold NaN loads (nothing in its load checks values) and was published (issue 54)."""
    from safetensors.torch import load_file, save_file

    folder = tmp_path / "nan_tok"
    shutil.copytree(tok_dir, folder)
    weights = load_file(folder / "model.safetensors")
    name = sorted(k for k, v in weights.items() if v.is_floating_point() and v.numel() > 3)[0]
    weights[name].view(-1)[3] = float("inf")
    save_file(weights, folder / "model.safetensors", metadata={"format": "pt"})
    code, err = _push_in_process(hub, monkeypatch, capsys, folder, "lab/nan-tok")
    assert code == 2 and err.startswith(f"error: {folder / 'model.safetensors'}: tensor {name} holds 1 NaN/inf"), err
    assert "nothing was pushed" in err.splitlines()[0] and ("model", "lab/nan-tok") not in hub.repos


@pytest.mark.parametrize("edit", ["unknown_key", "hidden_dim"])
def test_push_refuses_a_checkpoint_that_reads_but_does_not_load(hub, tok_dir, tmp_path, edit, monkeypatch, capsys):
    """Every file reads, but the config does not build the model the weights are: a key this version does not
    know, or a hidden_dim the weights do not have. Both used to be published with rc 0."""
    folder = tmp_path / "ckpt"
    shutil.copytree(tok_dir, folder)
    config = json.loads((folder / "config.json").read_text())
    config |= {"hiden_dim": 64} if edit == "unknown_key" else {"hidden_dim": config["hidden_dim"] * 2}
    (folder / "config.json").write_text(json.dumps(config))
    code, err = _push_in_process(hub, monkeypatch, capsys, folder, "lab/edited")
    why = "keys this version does not know" if edit == "unknown_key" else "does not fit the config.json beside it"
    assert code == 2 and err.startswith(f"error: {folder} does not load, so nothing was pushed"), err
    assert why in err and ("model", "lab/edited") not in hub.repos


def test_a_whole_policy_checkpoint_is_pushed(hub, tmp_path):
    """The strict load lets a checkpoint as LeRobot saved it through (the defects below are refused)."""
    from tiny_policy import write_tiny_act

    folder = write_tiny_act(tmp_path / "pretrained_model")
    r = run_cli(["unidextok-push", f"--local_dir={folder}", "--repo_id=lab/tiny-act"], HF_ENDPOINT=hub.url,
                HF_TOKEN=TOKEN, HF_HUB_OFFLINE="0", HF_HOME=str(tmp_path / "hf"))  # fmt: skip
    assert r.returncode == 0 and ("model", "lab/tiny-act") in hub.repos, r.stderr[-2000:]
    assert "Missing key" not in r.stderr and "Unexpected key" not in r.stderr


def _push_in_process(hub, monkeypatch, capsys, folder: Path, repo_id: str) -> tuple[int, str]:
    """`unidextok-push --local_dir=folder --repo_id=repo_id` to the loopback Hub, in this process: (status,
    stderr). Only for refusals: huggingface_hub read HF_HUB_OFFLINE=1 (tests/conftest.py) when it was imported."""
    from lerobot_unidextok.scripts.hub import push_main

    for name, value in (("HF_ENDPOINT", hub.url), ("HF_TOKEN", TOKEN), ("HF_HUB_OFFLINE", "0")):
        monkeypatch.setenv(name, value)
    return run_main(push_main, "unidextok-push", [f"--local_dir={folder}", f"--repo_id={repo_id}"], monkeypatch, capsys)


@pytest.mark.parametrize("edit", ["missing_tensor", "extra_tensor", "other_type", "unknown_step", "nan_weight",
                                  "nan_stats"])  # fmt: skip
def test_push_refuses_a_policy_that_does_not_load_strictly(hub, tmp_path, monkeypatch, capsys, edit):
    """A policy missing a tensor was pushed with a "Missing key(s)" warning (an extra one silently); a config of
    another policy type and an unknown processor step were tracebacks; a NaN weight or a NaN std in the saved
    normaliser was published (issue 54). Each is one line naming the tensor; nothing is pushed."""
    from tiny_policy import edited_copy, write_tiny_act

    bad = edited_copy(write_tiny_act(tmp_path / "ok"), tmp_path / "bad", edit)
    code, err = _push_in_process(hub, monkeypatch, capsys, bad, f"lab/{edit.replace('_', '-')}")
    what = {"missing_tensor": "(missing model.action_head.bias)", "extra_tensor": "(extra model.spare.weight)",
            "other_type": "config.json says type 'diffusion'", "unknown_step": "'unidextok.no_such_step'",
            "nan_weight": "model.safetensors: tensor model.action_head.weight holds 1 NaN/inf",
            "nan_stats": "normalizer_processor.safetensors: tensor action.std holds 1 NaN/inf"}[edit]  # fmt: skip
    assert code == 2 and err.startswith(f"error: {bad} does not load, so nothing was pushed:"), err
    assert what in err.splitlines()[0] and "Traceback" not in err
    assert ("model", f"lab/{edit.replace('_', '-')}") not in hub.repos


def test_push_refuses_a_dataset_that_fails_validation(hub, g1_like_hands, tmp_path, monkeypatch, capsys):
    """A dataset `unidextok-convert --validate=true` calls INVALID was pushed with rc 0 and no note."""
    bad = tmp_path / "ds"
    shutil.copytree(g1_like_hands["root"], bad)
    info = json.loads((bad / "meta" / "info.json").read_text())
    info["total_frames"] += 7  # every file still reads; the counts no longer agree
    (bad / "meta" / "info.json").write_text(json.dumps(info, indent=4))
    code, err = _push_in_process(hub, monkeypatch, capsys, bad, "lab/invalid")
    frames = info["total_frames"] - 7
    assert code == 2 and err.startswith(
        f"error: {bad} fails validation (total_frames: {frames} rows, info says {frames + 7}), so nothing was pushed: "
        f"`unidextok-convert --validate=true --root={bad}` shows every check"
    ), err
    assert ("dataset", "lab/invalid") not in hub.repos
