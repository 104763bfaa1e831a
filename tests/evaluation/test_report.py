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
    from lerobot_unidextok.conversion.sample_motion import gesture_track

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


@pytest.fixture(scope="module")
def udhm_dataset(tmp_path_factory):
    """A converted-contract dataset written by LeRobot: 5 episodes (4 train, 1 test), human right hand."""
    from lerobot.datasets import LeRobotDataset

    from lerobot_unidextok.conversion.sample_motion import gesture_track

    root = tmp_path_factory.mktemp("cli") / "udhm_ds"
    features = {
        "observation.state": {"dtype": "float32", "shape": (22,), "names": NAMES},
        "hand_type": {"dtype": "string", "shape": (1,), "names": None},
        "udhm_mask": {"dtype": "bool", "shape": (22,), "names": NAMES},
    }
    ds = LeRobotDataset.create("test/udhm_cli", fps=30, features=features, root=root, use_videos=False)
    rng = np.random.default_rng(0)
    for _ in range(5):
        q = gesture_track(rng, 60, 30.0).angles_rad.astype(np.float32)
        for t in range(len(q)):
            ds.add_frame({"observation.state": q[t], "hand_type": "human", "udhm_mask": np.ones(22, bool), "task": "g"})
        ds.save_episode()
    ds.finalize()
    info_path = root / "meta" / "info.json"
    info = json.loads(info_path.read_text())
    info["splits"] = {"train": "0:4", "test": "4:5"}
    info_path.write_text(json.dumps(info))
    return root


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
    assert report["training"]["train_rows"] == 240 and report["training"]["test_rows"] == 60
    assert (out / "best" / "model.safetensors").is_file() and (out / "eval.md").is_file()

    ecfg = eval_script.EvalConfig(
        checkpoint=str(out / "best"), datasets=[str(udhm_dataset)], output=str(tmp_path / "e")
    )
    ereport = eval_script.run(ecfg)
    assert ereport["overall"]["rows"] == 60
    assert ereport["overall"]["mpjae_deg"] == pytest.approx(report["overall"]["mpjae_deg"])
    assert "| human | 60 | 22 |" in capsys.readouterr().out
