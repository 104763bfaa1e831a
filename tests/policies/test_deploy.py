"""One policy, several robots: the real `lerobot-train` on a mix of two robots (unidextok-mix), then
`unidextok-deploy` binds the checkpoint to each; LeRobot's stock factory reloads each bound checkpoint in a fresh
process, takes that robot's native state and returns its native action."""

import json
import shutil
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
import torch
from cli_main import run_main
from l10_robot import HAND as L10
from linkerhand_udhm import subprocess_env
from robot_udhm import INSPIRE

from lerobot_unidextok.data import UdhmDatasetMeta
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

BIN = Path(sys.executable).parent
REPO = Path(__file__).resolve().parents[2]

RELOAD = """
import json, sys, numpy as np, torch
from lerobot.utils.import_utils import register_third_party_plugins
register_third_party_plugins()
from lerobot.configs.policies import PreTrainedConfig
from lerobot.policies.factory import get_policy_class, make_pre_post_processors
path, states = sys.argv[1], np.load(sys.argv[2])
cfg = PreTrainedConfig.from_pretrained(path)
policy = get_policy_class(cfg.type).from_pretrained(path).eval()
pre, post = make_pre_post_processors(cfg, pretrained_path=path)
out = [post(policy.select_action(pre({"observation.state": torch.from_numpy(s)}))).squeeze(0).tolist() for s in states]
print(json.dumps({"actions": out, "pre": [type(s).__name__ for s in pre.steps],
                  "post": [type(s).__name__ for s in post.steps]}))
"""


@pytest.fixture(scope="module")
def mixed_policy(g1_l10_mix, tmp_path_factory) -> Path:
    """act_udt trained 3 steps on the mix (a tiny tokenizer trained on neither hand: a wiring test)."""
    base = tmp_path_factory.mktemp("mixed_policy")
    torch.manual_seed(0)
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=[INSPIRE, L10])).save_pretrained(base / "tok")
    out = base / "act"
    r = subprocess.run([str(BIN / "lerobot-train"), "--policy.type=act_udt", "--dataset.repo_id=test/g1_l10_mix",
                        f"--dataset.root={g1_l10_mix}", f"--policy.udt_pretrained={base / 'tok'}",
                        "--policy.device=cpu", "--policy.push_to_hub=false", "--policy.dim_model=32",
                        "--policy.n_heads=2", "--policy.dim_feedforward=64", "--policy.chunk_size=5",
                        "--policy.n_action_steps=1", "--policy.udt_relative_actions=true", "--steps=3",
                        "--batch_size=4", "--num_workers=0", "--save_freq=3", f"--output_dir={out}"],
                       env=subprocess_env(HF_HOME=str(base / "hf")), capture_output=True, text=True,
                       timeout=600)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    return out / "checkpoints" / "last" / "pretrained_model"


def _deploy(checkpoint: Path, robot: Path, out: Path, *extra: str) -> subprocess.CompletedProcess:
    return subprocess.run([str(BIN / "unidextok-deploy"), f"--checkpoint={checkpoint}", f"--robot={robot}",
                           f"--output={out}", *extra], capture_output=True, text=True, timeout=300)  # fmt: skip


def _reload_and_act(bound: Path, native_states: np.ndarray, tmp_path: Path) -> dict:
    np.save(tmp_path / "states.npy", native_states.astype(np.float32))
    r = subprocess.run([sys.executable, "-c", RELOAD, str(bound), str(tmp_path / "states.npy")],
                       env=subprocess_env(HF_HOME=str(tmp_path / "hf")), capture_output=True, text=True,
                       timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


@pytest.mark.slow
def test_a_mixed_policy_bound_to_each_robot_takes_its_native_state_and_returns_its_native_action(
    mixed_policy, g1_like, l10_robot, g1_l10_mix, tmp_path
):
    config = json.loads((mixed_policy / "config.json").read_text())
    assert config["udt_hand_vocabulary"] == sorted([INSPIRE, L10]) and config["udt_native_layout"] == {}
    # relative actions on a mix: each hand's offsets scaled by its own statistics, between the relative pair
    delta = UdhmDatasetMeta(g1_l10_mix).record.hand_stats["action_delta"]
    assert config["udt_hand_stats"]["modes"] == {"action": "MEAN_STD"}  # the state: LeRobot's statistics (default)
    assert config["udt_hand_stats"]["action"]["right"][L10]["std"] == delta["right"][L10]["std"]
    pre_steps = [s["registry_name"] for s in json.loads((mixed_policy / "policy_preprocessor.json").read_text())["steps"]]
    post_steps = [s["registry_name"] for s in json.loads((mixed_policy / "policy_postprocessor.json").read_text())["steps"]]
    assert pre_steps.index("unidextok.hand_normalizer") == pre_steps.index("relative_actions_processor") + 1
    assert post_steps.index("unidextok.hand_normalizer") == post_steps.index("absolute_actions_processor") - 1
    # the G1-like robot: 26 native columns (14 arm angles, 2 x 6 Inspire values); the mix is hands-only
    r = _deploy(mixed_policy, g1_like["root"], tmp_path / "g1")
    assert r.returncode == 0, r.stderr[-2000:]
    g1 = _reload_and_act(tmp_path / "g1", g1_like["native_state"][:3], tmp_path)
    assert g1["pre"].index("NativeToUDHMStateStep") == g1["pre"].index("UniDexTokMixedTokenizerStep") - 1
    assert np.asarray(g1["actions"]).shape == (3, 12)  # its hand columns, in its own order
    bound = json.loads((tmp_path / "g1" / "config.json").read_text())
    g1_action = UdhmDatasetMeta(g1_like["root"]).native_layout("action")
    assert bound["udt_native_layout"]["native_names"] == g1_action.native_names[14:]
    assert bound["udt_native_layout"]["source_names"] == g1_action.native_names
    assert bound["udt_fixed_hand_ids"] == [0, 0]
    assert "HandNormalizerStep" in g1["post"]
    scale = [s for s in json.loads((tmp_path / "g1" / "policy_postprocessor.json").read_text())["steps"]
             if s["registry_name"] == "unidextok.hand_normalizer"]  # fmt: skip
    assert [s["config"]["fixed_hand_ids"] for s in scale] == [[0, 0]]
    # the right-only L10 robot: 10 native SDK values in, 10 out; its lacking left block is zero
    r = _deploy(mixed_policy, l10_robot, tmp_path / "l10")
    assert r.returncode == 0, r.stderr[-2000:]
    from l10_robot import l10_motion

    l10 = _reload_and_act(tmp_path / "l10", l10_motion(3, seed=5), tmp_path)
    assert np.asarray(l10["actions"]).shape == (3, 10)
    assert json.loads((tmp_path / "l10" / "config.json").read_text())["udt_fixed_hand_ids"] == [-1, 1]
    # each bound checkpoint is scored on its robot's own test episodes, next to copying the state; the G1 one
    # on its whole-robot dataset too (its robot's converted state: arms + hands; only the hands are scored)
    for bound, robot in ((tmp_path / "l10", l10_robot), (tmp_path / "g1", g1_like["root"])):
        out = tmp_path / f"{bound.name}.json"
        r = subprocess.run([sys.executable, str(REPO / "experiments" / "eval_policy.py"), f"--checkpoint={bound}",
                            f"--dataset={robot}", f"--output={out}"], env=subprocess_env(HF_HOME=str(tmp_path / "hf")),
                           capture_output=True, text=True, timeout=300)  # fmt: skip
        assert r.returncode == 0, r.stderr[-3000:]
        result = json.loads(out.read_text())
        assert set(result["policy"]) == {f"hands_{k}_{w}" for k in ("udhm_deg", "native") for w in ("first", "chunk")}
        assert result["episodes"] == UdhmDatasetMeta(robot).record.test_episodes


@pytest.mark.slow
def test_deploy_refuses_what_it_cannot_bind(mixed_policy, g1_like, tmp_path, monkeypatch, capsys):
    """In this process (the entry point runs as a subprocess in the test above): each refusal is exit 2 and one
    line, a zero-shot bind and a rebind with --overwrite=true succeed."""

    def deploy_cli(checkpoint: Path, robot: Path, out: Path, *extra: str) -> tuple[int, str]:
        return _deploy_in_process(monkeypatch, capsys, f"--checkpoint={checkpoint}", f"--robot={robot}",
                                  f"--output={out}", *extra)  # fmt: skip

    dexora = _dexora_robot(tmp_path)  # two XHand1 hands: never in the mix
    code, err = deploy_cli(mixed_policy, dexora, tmp_path / "x")
    assert code == 2 and err.startswith("error: ") and "never in the mix" in err
    assert not (tmp_path / "x").exists()
    code, err = deploy_cli(mixed_policy, dexora, tmp_path / "x", "--zero_shot=true")
    assert code == 0, err[-2000:]
    assert json.loads((tmp_path / "x" / "config.json").read_text())["udt_extra_hands"] == ["xhand1"]
    # its hands are normalised with the pooled statistics of the mix's hands (processor/hand_normalizer.py)
    normaliser = [s for s in json.loads((tmp_path / "x" / "policy_preprocessor.json").read_text())["steps"]
                  if s["registry_name"] == "unidextok.hand_normalizer"]  # fmt: skip
    assert [s["config"]["extra_hands"] for s in normaliser] == [["xhand1"]]
    # --zero_shot_slots=nearest on the mix: the XHand1 drives the slots it shares with the mix's hand nearest it
    code, err = deploy_cli(mixed_policy, dexora, tmp_path / "near", "--zero_shot=true", "--zero_shot_slots=nearest")
    assert code == 0, err[-2000:]
    from lerobot_unidextok import hands
    from lerobot_unidextok.hands.morphology import nearest_hand

    vocab = json.loads((tmp_path / "near" / "config.json").read_text())["udt_hand_vocabulary"]
    near = nearest_hand("xhand1", vocab)
    shared = [int(i) for i in np.flatnonzero(hands.get("xhand1").active_mask & hands.get(near).active_mask)]
    assert json.loads((tmp_path / "near" / "unidextok_deploy.json").read_text())["zero_shot_slots"] == {"xhand1": shared}
    # a mistaken flag is named before any path is looked up
    for flags, says in ((["--zero_shot_slots=nearest"], "pass it with --zero_shot=true"),
                        (["--zero_shot=true", "--zero_shot_slots=all"], "must be one of ('own', 'nearest')")):  # fmt: skip
        code, err = deploy_cli(tmp_path / "nowhere", tmp_path / "no_robot", tmp_path / "z", *flags)
        assert code == 2 and says in err and not (tmp_path / "z").exists(), err[-2000:]
    # binding again into it: refused with the flag that exists; with it, the bound checkpoint is replaced
    code, err = deploy_cli(mixed_policy, g1_like["root"], tmp_path / "x")
    assert code == 2 and "pass --overwrite=true to replace it" in err, err[-2000:]
    code, err = deploy_cli(mixed_policy, g1_like["root"], tmp_path / "x", "--overwrite=true")
    assert code == 0, err[-2000:]
    assert json.loads((tmp_path / "x" / "config.json").read_text())["udt_extra_hands"] == []
    assert json.loads((tmp_path / "x" / "unidextok_deploy.json").read_text())["robot"] == str(g1_like["root"])
    code, err = deploy_cli(tmp_path / "nowhere", g1_like["root"], tmp_path / "y")
    assert code == 2 and "is not a LeRobot policy checkpoint" in err
    # a mixed checkpoint not bound to a robot is not scored on it: eval_policy.py names the bind
    from experiments.eval_policy import EvalPolicyConfig, run

    with pytest.raises(ValueError, match="trained on a mix of robots: bind it to"):
        run(EvalPolicyConfig(checkpoint=str(mixed_policy), dataset=str(g1_like["root"])))


def _dexora_robot(tmp_path: Path) -> Path:
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.samples import write_samples

    raw = write_samples(tmp_path / "raw", sources=["dexora"], episodes_per_source=2, frames_per_episode=20)
    root = tmp_path / "dexora"
    convert(ConvertOptions(source="dexora", input=raw["dexora"], root=root, progress=False, keep="hands"))
    return root


@pytest.mark.slow
def test_deploy_loads_what_it_ships_and_writes_nowhere_it_must_not(mixed_policy, g1_like, tmp_path):
    """A truncated model.safetensors was reported "bound" and copied; a malformed policy_preprocessor.json was
    a traceback; --output inside the checkpoint wrote into it; a robot dataset whose episodes have different
    hands got a hint naming a flag deploy does not have. Each is now one clear error, and nothing is written."""
    import shutil

    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
    from lerobot_unidextok.data.destination import DestinationError
    from lerobot_unidextok.policies.checkpoint import PolicyCheckpointError
    from lerobot_unidextok.policies.deploy import DeployError, deploy
    from lerobot_unidextok.samples import write_samples

    truncated = tmp_path / "truncated"
    shutil.copytree(mixed_policy, truncated)
    weights = truncated / "model.safetensors"
    weights.write_bytes(weights.read_bytes()[: weights.stat().st_size // 2])
    r = _deploy(truncated, g1_like["root"], tmp_path / "a")
    assert r.returncode == 2 and r.stderr.startswith(f"error: {weights} does not load"), r.stderr[-2000:]
    assert not (tmp_path / "a").exists() and not list(tmp_path.glob(".a.*"))

    malformed = tmp_path / "malformed"
    shutil.copytree(mixed_policy, malformed)
    (malformed / "policy_preprocessor.json").write_text('{"name": "policy_preprocessor", "steps": [')
    with pytest.raises(PolicyCheckpointError, match="policy_preprocessor.json does not load"):
        deploy(malformed, g1_like["root"], tmp_path / "b")
    before = sorted(p.name for p in mixed_policy.iterdir())
    with pytest.raises(DestinationError, match="is, holds or sits inside the input"):
        deploy(mixed_policy, g1_like["root"], mixed_policy / "bound")
    assert sorted(p.name for p in mixed_policy.iterdir()) == before

    raw = write_samples(tmp_path / "raw", sources=["linkerhand"], episodes_per_source=4, frames_per_episode=20)
    lh = tmp_path / "lh"
    convert(ConvertOptions(source="linkerhand", input=raw["linkerhand"], root=lh, progress=False))
    with pytest.raises(DeployError, match=r"holds episodes of different hands .*episodes \[.*a robot has one set of hands"):
        deploy(mixed_policy, lh, tmp_path / "c")
    assert not any((tmp_path / n).exists() for n in "bc")


def _deploy_in_process(monkeypatch, capsys, *args: str) -> tuple[int, str]:
    """`unidextok-deploy args` in this process: (exit status, stderr)."""
    from lerobot_unidextok.scripts.deploy import main

    return run_main(main, "unidextok-deploy", list(args), monkeypatch, capsys)


@pytest.mark.parametrize("edit", ["missing_tensor", "extra_tensor", "other_type", "unknown_step", "nan_weight",
                                  "nan_stats"])  # fmt: skip
def test_deploy_refuses_a_checkpoint_that_does_not_load_strictly(edit, g1_like, tmp_path, monkeypatch, capsys):
    """A checkpoint missing a tensor was bound with a "Missing key(s)" warning (an extra one silently); a config
    of another policy type and an unknown processor step ended in tracebacks; a NaN weight or a NaN std in the
    saved normaliser was bound (issue 54). Each is one line naming the tensor, nothing written."""
    from tiny_policy import edited_copy, write_tiny_act

    bad = edited_copy(write_tiny_act(tmp_path / "ok"), tmp_path / "bad", edit)
    code, err = _deploy_in_process(monkeypatch, capsys, f"--checkpoint={bad}", f"--robot={g1_like['root']}",
                                   f"--output={tmp_path / 'bound'}")  # fmt: skip
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert code == 2 and len(lines) == 1 and err.startswith(f"error: {bad}"), err
    what = {"missing_tensor": "missing model.action_head.bias", "extra_tensor": "extra model.spare.weight",
            "other_type": "says type 'diffusion'", "unknown_step": "'unidextok.no_such_step'",
            "nan_weight": "model.safetensors: tensor model.action_head.weight holds 1 NaN/inf",
            "nan_stats": "normalizer_processor.safetensors: tensor action.std holds 1 NaN/inf"}[edit]  # fmt: skip
    assert what in lines[0] and "Traceback" not in err
    assert not (tmp_path / "bound").exists() and not list(tmp_path.glob(".bound*"))


def test_deploy_has_the_overwrite_flag_its_refusals_name(g1_like, tmp_path, monkeypatch, capsys):
    """Deploy's refusal of an existing --output said "pass --overwrite=true", a flag deploy did not have. It has
    it now, with the destination rule's meaning: it replaces a policy checkpoint only, after every check."""
    from tiny_policy import write_tiny_act

    checkpoint = write_tiny_act(tmp_path / "act")  # a stock single-robot policy: nothing to bind
    out = write_tiny_act(tmp_path / "earlier_bound", seed=1)
    before = {p.name: p.read_bytes() for p in out.iterdir()}
    args = [f"--checkpoint={checkpoint}", f"--robot={g1_like['root']}", f"--output={out}"]
    code, err = _deploy_in_process(monkeypatch, capsys, *args)
    assert code == 2 and "already holds a policy checkpoint: pass --overwrite=true to replace it" in err, err
    code, err = _deploy_in_process(monkeypatch, capsys, *args, "--overwrite=true")
    assert code == 2 and "not a <type>_udt one: there is nothing to bind" in err, err  # past the destination
    assert {p.name: p.read_bytes() for p in out.iterdir()} == before  # nothing replaced by a refused deploy
    code, err = _deploy_in_process(monkeypatch, capsys, f"--checkpoint={checkpoint}", f"--robot={g1_like['root']}",
                                   f"--output={g1_like['root'].parent}", "--overwrite=true")  # fmt: skip
    assert code == 2 and "is, holds or sits inside the input" in err, err


@pytest.mark.parametrize("edit", ["config_std", "normaliser_std"])
def test_deploy_refuses_a_mix_checkpoint_whose_hand_statistics_hold_nan(edit, mixed_policy, g1_like, tmp_path,
                                                                         monkeypatch, capsys):  # fmt: skip
    """Issue 54 cases 1-3: a NaN std in a checkpoint's udt_hand_stats (config.json) or in its saved per-hand
    normaliser was bound with exit 0 (the bound policy never moved that hand). One line naming the field or
    tensor; nothing written."""
    from safetensors.torch import load_file, save_file

    bad = tmp_path / "bad"
    shutil.copytree(mixed_policy, bad)
    if edit == "config_std":
        config = json.loads((bad / "config.json").read_text())
        side, per = next(iter(config["udt_hand_stats"]["action"].items()))
        hand = next(iter(per))
        per[hand]["std"][2] = float("nan")
        (bad / "config.json").write_text(json.dumps(config))
        what = f"config.json: udt_hand_stats['action']['{side}']['{hand}'].std holds NaN at index 2"
    else:
        path = next(bad.glob("policy_preprocessor_step_*_unidextok.hand_normalizer.safetensors"))
        tensors = load_file(path)
        tensors["action.std"].view(-1)[5] = float("nan")
        save_file(tensors, path)
        what = f"{path.name}: tensor action.std holds 1 NaN/inf"
    code, err = _deploy_in_process(monkeypatch, capsys, f"--checkpoint={bad}", f"--robot={g1_like['root']}",
                                   f"--output={tmp_path / 'bound'}")  # fmt: skip
    lines = [line for line in err.splitlines() if line.startswith("error:")]
    assert code == 2 and len(lines) == 1 and what in lines[0] and "Traceback" not in err, err
    assert not (tmp_path / "bound").exists() and not list(tmp_path.glob(".bound*"))


@pytest.mark.slow
def test_a_morphology_identity_is_trained_saved_and_given_to_a_zero_shot_hand(g1_l10_mix, tmp_path, monkeypatch,
                                                                             capsys):
    """`--policy.udt_hand_identity=morphology`: the policy reads each block's hand as its spec's morphology vector,
    so a hand the mix never had (the Dexora's XHand1s, bound with --zero_shot=true) gets its own vector where the
    one-hot identity gives it zeros; the bound checkpoint reloads and acts on that robot's native state. The bind
    and the reload run in this process (their own processes: the test above)."""
    from lerobot.processor import PolicyProcessorPipeline

    from lerobot_unidextok.constants import OBS_HAND_TOKEN_FEATURES, OBS_STATE, UDHM_DIM
    from lerobot_unidextok.hands.morphology import MORPHOLOGY_WIDTH, morphology_vector
    from lerobot_unidextok.processor import UniDexTokMixedTokenizerStep

    torch.manual_seed(0)
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=[INSPIRE, L10])).save_pretrained(tmp_path / "tok")
    out = tmp_path / "act"
    r = subprocess.run([str(BIN / "lerobot-train"), "--policy.type=act_udt", "--dataset.repo_id=test/g1_l10_mix",
                        f"--dataset.root={g1_l10_mix}", f"--policy.udt_pretrained={tmp_path / 'tok'}",
                        "--policy.udt_hand_identity=morphology", "--policy.device=cpu", "--policy.push_to_hub=false",
                        "--policy.dim_model=32", "--policy.n_heads=2", "--policy.dim_feedforward=64",
                        "--policy.chunk_size=5", "--policy.n_action_steps=1", "--steps=2", "--batch_size=4",
                        "--num_workers=0", "--save_freq=2", f"--output_dir={out}"],
                       env=subprocess_env(HF_HOME=str(tmp_path / "hf")), capture_output=True, text=True,
                       timeout=600)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    checkpoint = out / "checkpoints" / "last" / "pretrained_model"
    config = json.loads((checkpoint / "config.json").read_text())
    assert config["udt_hand_identity"] == "morphology"
    assert config["input_features"][OBS_HAND_TOKEN_FEATURES]["shape"] == [2 * (UDHM_DIM + MORPHOLOGY_WIDTH)]
    dexora = _dexora_robot(tmp_path)
    code, err = _deploy_in_process(monkeypatch, capsys, f"--checkpoint={checkpoint}", f"--robot={dexora}",
                                   f"--output={tmp_path / 'x'}", "--zero_shot=true")  # fmt: skip
    assert code == 0, err[-2000:]
    pipe = PolicyProcessorPipeline.from_pretrained(tmp_path / "x", config_filename="policy_preprocessor.json")
    (step,) = [s for s in pipe.steps if isinstance(s, UniDexTokMixedTokenizerStep)]
    assert step.identity == "morphology" and step.extra_hands == ["xhand1"]
    view = step.observation({OBS_STATE: torch.zeros(1, len(step.state_names))})[OBS_HAND_TOKEN_FEATURES]
    tail = view[0, 2 * UDHM_DIM :].reshape(2, MORPHOLOGY_WIDTH).numpy()
    for block, side in enumerate(step._sides):
        np.testing.assert_array_equal(tail[block], morphology_vector("xhand1", side))
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    from lerobot_unidextok.hands import get

    cfg = PreTrainedConfig.from_pretrained(tmp_path / "x")
    policy = get_policy_class(cfg.type).from_pretrained(tmp_path / "x").eval()
    pre, post = make_pre_post_processors(cfg, pretrained_path=str(tmp_path / "x"))
    with torch.inference_mode():
        action = post(policy.select_action(pre({OBS_STATE: torch.zeros(2 * get("xhand1").num_native)})))
    assert action.shape == (1, 2 * get("xhand1").num_native) and torch.isfinite(action).all()
