"""evaluate_tokenizer + write_report, and the train/eval CLIs on a real LeRobot-written dataset."""

import json

import numpy as np
import pytest
import torch

from lerobot_unidextok.constants import UDHM_JOINT_NAMES
from lerobot_unidextok.evaluation import evaluate_tokenizer, write_report
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig
from lerobot_unidextok.training import HandStates

NAMES = [f"right_{j}" for j in UDHM_JOINT_NAMES]


def _rows(n: int, hand: str, seed: int) -> HandStates:
    from lerobot_unidextok.samples.motion import gesture_track

    q = gesture_track(np.random.default_rng(seed), n, 30.0).angles_rad.astype(np.float32)
    return HandStates(q, np.full(n, hand), np.ones((n, 22), bool))


def test_report_flags_zero_shot_hands_and_writes_files(tmp_path):
    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["human"])).eval()
    data = HandStates.concat([_rows(40, "human", 0), _rows(30, "leap", 1)])
    report = evaluate_tokenizer(model, data)
    assert report["per_hand"]["human"]["zero_shot"] is False
    assert report["per_hand"]["leap"]["zero_shot"] is True
    assert report["per_hand"]["leap"]["rows"] == 30
    assert 0 < report["overall"]["codebook"]["usage"] <= 1
    md = write_report(report, tmp_path / "eval")
    saved = json.loads((tmp_path / "eval.json").read_text())
    assert saved["overall"]["mpjae_deg"] == pytest.approx(report["overall"]["mpjae_deg"])
    assert (tmp_path / "eval.md").read_text().strip() == md.strip()
    assert "| leap | 30 | 22 |" in md and "| yes |" in md and "index_pip_flex" in md


def write_udhm_dataset(root, hand: str, episodes: int, test_episodes: int, frames: int, seed: int):
    """A converted-contract dataset of one right `hand` written by LeRobot (hand mask from the registry)."""
    from lerobot.datasets import LeRobotDataset

    from lerobot_unidextok import hands
    from lerobot_unidextok.samples.motion import gesture_track

    features = {
        "observation.state": {"dtype": "float32", "shape": (22,), "names": NAMES},
        "hand_type": {"dtype": "string", "shape": (1,), "names": None},
        "udhm_mask": {"dtype": "bool", "shape": (22,), "names": NAMES},
    }
    mask = hands.get(hand).active_mask
    ds = LeRobotDataset.create(f"test/{root.name}", fps=30, features=features, root=root, use_videos=False)
    rng = np.random.default_rng(seed)
    for _ in range(episodes):
        q = (gesture_track(rng, frames, 30.0).angles_rad * mask).astype(np.float32)
        for t in range(len(q)):
            ds.add_frame({"observation.state": q[t], "hand_type": hand, "udhm_mask": mask, "task": "g"})
        ds.save_episode()
    ds.finalize()
    info_path = root / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    n_train = episodes - test_episodes
    info["splits"] = {"train": f"0:{n_train}", "test": f"{n_train}:{episodes}"}
    info_path.write_text(json.dumps(info))
    return root


@pytest.fixture(scope="module")
def udhm_dataset(tmp_path_factory):
    """A converted-contract dataset written by LeRobot: 5 episodes (4 train, 1 test), human right hand."""
    return write_udhm_dataset(tmp_path_factory.mktemp("cli") / "udhm_ds", "human", 5, 1, 60, 0)


def test_train_then_eval_cli_on_a_lerobot_dataset(udhm_dataset, tmp_path, capsys):
    from lerobot_unidextok.scripts import eval as eval_script
    from lerobot_unidextok.scripts import train as train_script

    out = tmp_path / "run"
    cfg_file = tmp_path / "train.yaml"
    cfg_file.write_text(f"preset: tiny\nsteps: 30\nbatch_size: 32\nwarmup_steps: 3\neval_every: 15\nprogress: false\n"
                        f"output_dir: {out}\ndatasets: [{udhm_dataset}]\n")  # fmt: skip
    import draccus

    cfg = draccus.parse(train_script.TrainConfig, config_path=cfg_file, args=["--steps=20"])
    assert cfg.steps == 20 and cfg.preset == "tiny"
    report = train_script.run(cfg)
    # 4 training episodes: 1 held out (whole) to choose the checkpoint, 3 trained on; the test episode scores
    assert report["training"]["train_rows"] == 180 and report["training"]["select_rows"] == 60
    assert report["training"]["test_rows"] == 60
    assert (out / "best" / "model.safetensors").is_file() and (out / "eval.md").is_file()
    printed = capsys.readouterr().out
    assert f"{out / 'best'}  <- use this one" in printed and f"{out / 'last'}  <- resume" in printed

    # a run folder is accepted: unidextok-eval picks its best/
    ecfg = eval_script.EvalConfig(checkpoint=str(out), datasets=[str(udhm_dataset)], output=str(tmp_path / "e"))
    ereport = eval_script.run(ecfg)
    assert ereport["checkpoint"] == str(out / "best")
    assert ereport["overall"]["rows"] == 60
    assert ereport["overall"]["mpjae_deg"] == pytest.approx(report["overall"]["mpjae_deg"])
    printed = capsys.readouterr().out
    assert "| human | 60 | 22 |" in printed
    # both say what they scored: the checkpoint folder, the test episode (4) of the dataset, hand-rows
    for rep, name in ((report, "eval.json"), (ereport, "e.json")):
        scored = json.loads(((out if name == "eval.json" else tmp_path) / name).read_text())["scored"]
        assert scored == rep["scored"] and scored["checkpoint"] == str(out / "best") and scored["split"] == "test"
        assert scored["datasets"] == [{"dataset": str(udhm_dataset), "episodes": [4], "hand_rows": 60,
                                       "hand_rows_per_hand": {"human": 60}}]  # fmt: skip
    assert f"Scored: checkpoint `{out / 'best'}` on the test episodes below. Rows are hand-rows" in printed
    assert f"| {udhm_dataset} | 4 (1) | 60 |" in printed


def test_eval_names_episodes_per_dataset_and_counts_hand_rows(g1_like, udhm_dataset, tmp_path, capsys):
    """eval.json held `"split": "test"` only. A two-hand dataset (3 episodes x 40 frames, test episode 2) gives
    80 hand-rows for its 40 test frames; each dataset lists its own episodes."""
    from lerobot_unidextok.scripts import eval as eval_script

    torch.manual_seed(0)
    cfg = UniDexTokConfig.from_preset("tiny", hand_names=["human", "inspire_rh56_unitree"])
    UniDexTok(cfg).save_pretrained(tmp_path / "run" / "best")
    datasets = [str(g1_like["root"]), str(udhm_dataset)]
    report = eval_script.run(eval_script.EvalConfig(checkpoint=str(tmp_path / "run"), datasets=datasets, split="all",
                                                    output=str(tmp_path / "e")))  # fmt: skip
    scored = json.loads((tmp_path / "e.json").read_text())["scored"]
    assert scored["checkpoint"] == str(tmp_path / "run" / "best") and scored["split"] == "all"
    assert "a two-hand frame gives two rows" in scored["rows"]
    g1, human = scored["datasets"]
    assert g1 == {"dataset": datasets[0], "episodes": [0, 1, 2], "hand_rows": 240,
                  "hand_rows_per_hand": {"inspire_rh56_unitree": 240}}  # fmt: skip
    assert human["episodes"] == [0, 1, 2, 3, 4] and human["hand_rows"] == 300
    assert report["overall"]["rows"] == 540
    md = (tmp_path / "e.md").read_text()
    assert md.startswith("Scored: checkpoint") and f"| {datasets[0]} | 0-2 (3) | 240 |" in md


def test_zero_shot_cli_with_default_settings(udhm_dataset, tmp_path, capsys):
    """Catches the zero-shot CLI bug: with the preset's default `hand_names`, `--exclude_hands` kept the
    excluded hand in the vocabulary, so unidextok-eval scored it with an untrained embedding row and did not
    flag it zero-shot. The vocabulary must be the training hands (plus explicitly requested ones)."""
    import subprocess
    import sys

    from lerobot_unidextok.scripts import eval as eval_script

    inspire = write_udhm_dataset(tmp_path / "inspire_ds", "inspire_rh56_unitree", 3, 1, 40, 1)
    out = tmp_path / "zs"
    cmd = [sys.executable, "-m", "lerobot_unidextok.scripts.train", "--preset=tiny", "--steps=20", "--batch_size=32",
           "--warmup_steps=2", "--eval_every=10", "--progress=false", f"--output_dir={out}",
           f"--datasets=[{udhm_dataset},{inspire}]", "--exclude_hands=[inspire_rh56_unitree]"]  # fmt: skip
    subprocess.run(cmd, check=True, capture_output=True, text=True, timeout=600)

    config = json.loads((out / "best" / "config.json").read_text())
    assert config["hand_names"] == ["human"]  # not the preset's 11 default names
    card = (out / "best" / "README.md").read_text()
    assert "- `human`" in card and "`inspire_rh56_unitree`" in card  # trained hand listed; excluded hand named
    assert "- `inspire_rh56_unitree`" not in card.split("## Training")[0]  # ... but not as a supported hand
    assert "Hands left out of training (zero-shot): `inspire_rh56_unitree`" in card
    state = json.loads((out / "best" / "training_state.json").read_text())
    assert list(state["mixture"]["hands"]) == ["human"] and state["excluded_hands"] == ["inspire_rh56_unitree"]

    report = eval_script.run(eval_script.EvalConfig(checkpoint=str(out), datasets=[str(udhm_dataset), str(inspire)],
                                                    output=str(tmp_path / "e")))  # fmt: skip
    assert report["per_hand"]["inspire_rh56_unitree"]["zero_shot"] is True
    assert report["per_hand"]["human"]["zero_shot"] is False
    assert "| inspire_rh56_unitree | 40 | 6 |" in capsys.readouterr().out


def test_requesting_an_excluded_hand_is_a_clear_error(udhm_dataset, tmp_path):
    from lerobot_unidextok.scripts import train as train_script

    cfg = train_script.TrainConfig(preset="tiny", steps=2, datasets=[str(udhm_dataset)], output_dir=str(tmp_path),
                                   hand_names=["inspire_rh56_unitree"], exclude_hands=["inspire_rh56_unitree"],
                                   progress=False)  # fmt: skip
    with pytest.raises(ValueError, match="both requested in hand_names and excluded"):
        train_script.run(cfg)
