"""The grasp-centre frame end to end: the simulator's recorder writes each hand's grasp centre, unidextok-convert
and unidextok-mix carry it, a `<type>_udt` policy puts `unidextok.wrist_frame` into its processors, and
unidextok-deploy binds it to the target robot's own centre (a hand of the mix, and zero-shot another hand, and a
single-robot checkpoint). Real LeRobot datasets recorded by the simulator, written and reloaded."""

import json

import numpy as np
import pytest
import torch

from lerobot_unidextok.constants import ACTION, OBS_HAND_IDS, OBS_STATE
from lerobot_unidextok.data import UdhmDatasetMeta
from lerobot_unidextok.data.wrist_frame import WRIST_FRAME_PATH, WristFrameError
from lerobot_unidextok.policies import ACTUdtConfig
from lerobot_unidextok.processor import WristFrameStep
from lerobot_unidextok.processor.wrist_frame import rotation_rpy
from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

pytestmark = pytest.mark.slow
HANDS = ("inspire_rh56_unitree", "shadow", "allegro")  # the mix's two, and a zero-shot target
CHUNK = 4
TINY = dict(chunk_size=CHUNK, n_action_steps=CHUNK, dim_model=32, n_heads=2, dim_feedforward=64, n_encoder_layers=1,
            n_decoder_layers=1, use_vae=False)  # fmt: skip


@pytest.fixture(scope="module")
def sim(tmp_path_factory) -> dict:
    """Per hand: its recorded LeRobot dataset and its converted one; and the mix of the first two (--keep=all)."""
    from lerobot_env_unidextok.record import RecordConfig, record
    from lerobot_unidextok.conversion.mix import MixOptions, mix
    from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert

    work = tmp_path_factory.mktemp("frame")
    out = {}
    for hand in HANDS:
        record(RecordConfig(hand=hand, task="GraspLift-v0", episodes=2, episode_length=12, keep_failures=True,
                            root=str(work / f"{hand}_native")))  # fmt: skip
        convert(ConvertOptions(source="lerobot", input=str(work / f"{hand}_native"), root=str(work / f"{hand}_udhm"),
                               source_options={"hands": {"right": f"{hand}:right_"}}, test_fraction=0.0,
                               progress=False))  # fmt: skip
        out[hand] = {"native": work / f"{hand}_native", "udhm": work / f"{hand}_udhm"}
    mix(MixOptions(inputs=[str(out[h]["udhm"]) for h in HANDS[:2]], root=str(work / "mix"), repo_id="test/mix",
                   keep="all", progress=False))  # fmt: skip
    out["mix"] = work / "mix"
    torch.manual_seed(2)
    out["tok"] = work / "tok"
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["human", *HANDS[:2]])).save_pretrained(out["tok"])
    return out


def _config(sim, root, **kw):
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.datasets import LeRobotDatasetMetadata

    meta = LeRobotDatasetMetadata("test/frame", root=root)
    cfg = ACTUdtConfig(
        input_features={OBS_STATE: PolicyFeature(FeatureType.STATE, tuple(meta.features[OBS_STATE]["shape"]))},
        output_features={ACTION: PolicyFeature(FeatureType.ACTION, tuple(meta.features[ACTION]["shape"]))},
        udt_pretrained=str(sim["tok"]), device="cpu", **TINY, **kw,
    )  # fmt: skip
    cfg._runtime_dataset_meta = meta
    cfg.validate_features()
    return cfg, meta


def _batch(root, meta, frame: int = 5) -> dict:
    """Frame `frame` of every episode with its action chunk, collated as LeRobot's dataloader does."""
    from lerobot.datasets import LeRobotDataset

    ds = LeRobotDataset("test/frame", root=root, delta_timestamps={ACTION: [i / meta.fps for i in range(CHUNK)]})
    starts = [int(s) for s in ds.meta.episodes["dataset_from_index"]]
    items = [ds[s + frame] for s in starts]
    return torch.utils.data.default_collate([{k: v for k, v in it.items() if isinstance(v, torch.Tensor)}
                                             for it in items])  # fmt: skip


def _centre(sim, hand) -> list[float]:
    return json.loads((sim[hand]["native"] / WRIST_FRAME_PATH).read_text())["grasp_centre_in_wrist_m"][hand]


def _shift(pose: torch.Tensor, centre) -> torch.Tensor:
    """R(rpy) @ centre for (..., 6) wrist poses."""
    return (rotation_rpy(pose[..., 3:6].double()) @ torch.tensor(centre, dtype=torch.float64)).float()


def test_the_grasp_centre_travels_from_the_recorder_through_convert_and_mix(sim):
    from lerobot_env_unidextok.grasp_centre import wrist_frame_of

    centres = {h: _centre(sim, h) for h in HANDS}
    for hand in HANDS:
        assert centres[hand] == wrist_frame_of(hand).grasp_centre_in_wrist_m[hand]
        frame = UdhmDatasetMeta(sim[hand]["udhm"]).record.wrist_frame
        assert frame["grasp_centre_in_wrist_m"] == {hand: centres[hand]}
        assert frame["columns"] == ["wrist_x", "wrist_y", "wrist_z", "wrist_roll", "wrist_pitch", "wrist_yaw"]
        assert frame["rotation"] == "Rz(yaw) Ry(pitch) Rx(roll)"
    assert np.linalg.norm(np.subtract(centres["shadow"], centres["inspire_rh56_unitree"])) > 0.02  # they differ
    mixed = UdhmDatasetMeta(sim["mix"]).record.wrist_frame
    assert mixed["grasp_centre_in_wrist_m"] == {h: centres[h] for h in HANDS[:2]}


def test_a_mix_policy_moves_each_rows_wrist_to_its_hands_centre_and_restores_the_action(sim):
    """The pre-processor's wrist step gives each row its own hand's grasp centre (state and action); the
    post-processor, after the unnormalisers, gives the recorded wrist action back. (The simulator's state has
    task columns between the wrist and the hand, so relative actions do not apply to it: the relative pair is
    checked in tests/processor/test_wrist_frame.py.)"""
    from lerobot.policies.factory import make_pre_post_processors

    cfg, meta = _config(sim, sim["mix"], udt_relative_actions=False, udt_copy_start=False)
    assert cfg.udt_grasp_centres_m == {h: _centre(sim, h) for h in HANDS[:2]}
    pre, post = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    names = [type(s).__name__ for s in pre.steps]
    assert names.index("WristFrameStep") == names.index("UniDexTokMixedTokenizerStep") + 1
    assert names.index("WristFrameStep") < names.index("NormalizerProcessorStep")
    assert [type(s).__name__ for s in post.steps][-1] == "WristFrameStep"
    batch = _batch(sim["mix"], meta)
    raw_state, raw_action = batch[OBS_STATE].clone(), batch[ACTION].clone()
    step = next(s for s in pre.steps if isinstance(s, WristFrameStep))
    from lerobot.lerobot_types import TransitionKey

    moved = step(_as_transition(batch))
    moved = {"observation": moved[TransitionKey.OBSERVATION], "action": moved[TransitionKey.ACTION]}
    ids = batch[OBS_HAND_IDS].reshape(len(raw_state), -1)[:, 0].tolist()
    assert sorted(set(ids)) == [0, 1]  # both hands in the batch
    for row, hand_id in enumerate(ids):
        centre = cfg.udt_grasp_centres_m[cfg.udt_hand_vocabulary[hand_id]]
        torch.testing.assert_close(moved["observation"][OBS_STATE][row, :3],
                                   raw_state[row, :3] + _shift(raw_state[row, :6], centre), rtol=0, atol=1e-6)
        torch.testing.assert_close(moved["action"][row, :, :3],
                                   raw_action[row, :, :3] + _shift(raw_action[row, :, :6], centre), rtol=0, atol=1e-6)
    out = pre(dict(batch))
    restored = post(out[ACTION][:, 0])  # the normalised first action of each chunk, back through the post steps
    torch.testing.assert_close(restored[:, :6], raw_action[:, 0, :6], rtol=0, atol=2e-5)


def _as_transition(batch: dict) -> dict:
    from lerobot.lerobot_types import TransitionKey

    obs = {k: v for k, v in batch.items() if k.startswith("observation.")}
    return {TransitionKey.OBSERVATION: obs, TransitionKey.ACTION: batch[ACTION]}


def test_the_robot_frame_is_the_old_pipeline(sim):
    from lerobot.policies.factory import make_pre_post_processors

    cfg, meta = _config(sim, sim["mix"], udt_wrist_frame="robot")
    on, _ = _config(sim, sim["mix"])
    assert cfg.udt_grasp_centres_m == {} and not cfg.uses_wrist_frame
    pre, post = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    pre_on, post_on = make_pre_post_processors(on, dataset_stats=meta.stats)
    assert not any(isinstance(s, WristFrameStep) for s in [*pre.steps, *post.steps])
    assert [type(s) for s in pre.steps] == [type(s) for s in pre_on.steps if not isinstance(s, WristFrameStep)]
    batch = _batch(sim["mix"], meta)
    a, b = pre(dict(batch)), pre_on(dict(batch))
    assert torch.equal(a[OBS_STATE][:, 6:], b[OBS_STATE][:, 6:]) and not torch.equal(a[OBS_STATE], b[OBS_STATE])


def _save(cfg, meta, out):
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    pre, post = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    torch.manual_seed(0)
    get_policy_class(cfg.type)(cfg).save_pretrained(out)
    pre.save_pretrained(out, config_filename="policy_preprocessor.json")
    post.save_pretrained(out, config_filename="policy_postprocessor.json")
    return out


def _bound_post_shift(bound, sim, robot_hand):
    """The bound checkpoint's post-processor on one predicted action, with and without its wrist step: the
    difference is -R(rpy) @ the robot's own grasp centre, and it acts through LeRobot's factory."""
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.datasets import LeRobotDataset
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    import lerobot_policy_unidextok  # noqa: F401

    cfg = PreTrainedConfig.from_pretrained(bound)
    pre, post = make_pre_post_processors(cfg, pretrained_path=str(bound))
    frames = [s for s in [*pre.steps, *post.steps] if isinstance(s, WristFrameStep)]
    assert len(frames) == 2 and all(f.grasp_centres_m[robot_hand] == _centre(sim, robot_hand) for f in frames)
    assert all(f.hand_vocabulary[f.fixed_hand_ids[0]] == robot_hand for f in frames)
    policy = get_policy_class(cfg.type).from_pretrained(bound).eval()
    state = LeRobotDataset("test/robot", root=sim[robot_hand]["udhm"])[5][OBS_STATE]  # its converted state
    action = post(policy.select_action(pre({OBS_STATE: state[None]})))
    native_width = len(UdhmDatasetMeta(sim[robot_hand]["udhm"]).native_layout(ACTION).native_names)
    assert action.shape == (1, native_width) and torch.isfinite(action).all()
    from lerobot.lerobot_types import TransitionKey

    predicted = torch.randn(1, len(cfg.udt_action_names))
    moved = frames[1]({TransitionKey.OBSERVATION: {}, TransitionKey.ACTION: predicted})[TransitionKey.ACTION]
    torch.testing.assert_close(moved[0, :3], predicted[0, :3] - _shift(predicted[0, :6], _centre(sim, robot_hand)),
                               rtol=0, atol=1e-6)  # fmt: skip


def test_deploy_binds_the_target_robots_own_centre_to_the_mix_and_zero_shot(sim, tmp_path, caplog):
    from lerobot_unidextok.policies.deploy import deploy
    from lerobot_unidextok.policies.deploy_frame import FrameBindError

    cfg, meta = _config(sim, sim["mix"], udt_relative_actions=False, udt_copy_start=False)
    checkpoint = _save(cfg, meta, tmp_path / "mix_act")
    shadow = deploy(checkpoint, sim["shadow"]["udhm"], tmp_path / "on_shadow")
    _bound_post_shift(shadow, sim, "shadow")
    allegro = deploy(checkpoint, sim["allegro"]["udhm"], tmp_path / "on_allegro", zero_shot=True)
    _bound_post_shift(allegro, sim, "allegro")
    written = json.loads((allegro / "unidextok_deploy.json").read_text())
    assert written["grasp_centres_m"] == {"allegro": _centre(sim, "allegro")}
    with caplog.at_level("WARNING", logger="lerobot_unidextok.policies.deploy_frame"):
        override = deploy(checkpoint, sim["allegro"]["udhm"], tmp_path / "override", zero_shot=True,
                          grasp_centre_m=[0.05, 0.0, -0.05])  # fmt: skip
    assert json.loads((override / "config.json").read_text())["udt_grasp_centres_m"]["allegro"] == [0.05, 0.0, -0.05]
    # the centre the robot's dataset records, which the flag overrides, is named in one note (issue 54)
    notes = [r.getMessage() for r in caplog.records if "overrides" in r.getMessage()]
    assert len(notes) == 1 and notes[0].startswith("note: --grasp_centre_m=[0.05, 0.0, -0.05] overrides the grasp "
                                                   f"centre {_centre(sim, 'allegro')} m of 'allegro' that")  # fmt: skip
    # a robot dataset recording another centre for a hand the checkpoint learned (another model of the hand): the
    # robot's is bound, and one note names both and the flag that keeps the checkpoint's
    shadow_record = sim["shadow"]["udhm"] / "meta" / "unidextok_conversion.json"
    saved = shadow_record.read_text()
    remodelled = json.loads(saved)
    remodelled["wrist_frame"]["grasp_centre_in_wrist_m"]["shadow"] = [0.11, 0.04, -0.07]
    try:
        shadow_record.write_text(json.dumps(remodelled))
        caplog.clear()
        with caplog.at_level("WARNING", logger="lerobot_unidextok.policies.deploy_frame"):
            other_model = deploy(checkpoint, sim["shadow"]["udhm"], tmp_path / "other_model")
    finally:
        shadow_record.write_text(saved)
    assert json.loads((other_model / "config.json").read_text())["udt_grasp_centres_m"]["shadow"] == [0.11, 0.04, -0.07]
    notes = [r.getMessage() for r in caplog.records if "the checkpoint learned" in r.getMessage()]
    assert len(notes) == 1 and f"the checkpoint learned {_centre(sim, 'shadow')} m" in notes[0], notes
    assert f"--grasp_centre_m={_centre(sim, 'shadow')}" in notes[0]
    for absurd in ([1e6, 0.0, 0.0], [-5.0, 3.0, 7.0]):  # metres typed as mm, or nonsense: refused before binding
        with pytest.raises(WristFrameError, match=r"--grasp_centre_m: .* m at ind.*beyond the plausible 0.3 m"):
            deploy(checkpoint, sim["allegro"]["udhm"], tmp_path / "absurd", zero_shot=True, grasp_centre_m=absurd)
    assert not (tmp_path / "absurd").exists()
    # a zero-shot hand whose dataset records no frame: refused, naming the flag; nothing written
    record_path = sim["allegro"]["udhm"] / "meta" / "unidextok_conversion.json"
    saved = record_path.read_text()
    try:
        record_path.write_text(json.dumps({**json.loads(saved), "wrist_frame": {}}))
        with pytest.raises(FrameBindError, match=r"--grasp_centre_m='\[x, y, z\]'") as err:
            deploy(checkpoint, sim["allegro"]["udhm"], tmp_path / "refused", zero_shot=True)
        assert "\n" not in str(err.value) and not (tmp_path / "refused").exists()
        other = {**json.loads(saved)["wrist_frame"], "columns": ["x", "y", "z", "roll", "pitch", "yaw"]}
        record_path.write_text(json.dumps({**json.loads(saved), "wrist_frame": other}))
        with pytest.raises(FrameBindError, match="records its wrist in columns"):
            deploy(checkpoint, sim["allegro"]["udhm"], tmp_path / "refused", zero_shot=True)
    finally:
        record_path.write_text(saved)
    plain_cfg, _ = _config(sim, sim["mix"], udt_wrist_frame="robot", udt_relative_actions=False, udt_copy_start=False)
    plain = _save(plain_cfg, meta, tmp_path / "plain")
    with pytest.raises(FrameBindError, match="leave the flag out"):
        deploy(plain, sim["shadow"]["udhm"], tmp_path / "refused", grasp_centre_m=[0.05, 0.0, -0.05])
    with pytest.raises(WristFrameError, match="must be 3 numbers in m"):
        deploy(checkpoint, sim["allegro"]["udhm"], tmp_path / "bad", zero_shot=True, grasp_centre_m=[0.1, 0.2])


def test_a_single_robot_checkpoint_binds_zero_shot_with_the_targets_centre(sim, tmp_path):
    from lerobot_unidextok.policies.deploy import deploy

    cfg, meta = _config(sim, sim["inspire_rh56_unitree"]["udhm"], udt_relative_actions=False, udt_copy_start=False)
    assert cfg.udt_grasp_centres_m == {"inspire_rh56_unitree": _centre(sim, "inspire_rh56_unitree")}
    checkpoint = _save(cfg, meta, tmp_path / "inspire_act")
    bound = deploy(checkpoint, sim["allegro"]["udhm"], tmp_path / "on_allegro", zero_shot=True)
    _bound_post_shift(bound, sim, "allegro")


def test_a_checkpoint_saved_before_the_frame_loads_and_acts_as_before(sim, tmp_path):
    """config.json without the frame's fields and processors without its step: reloaded through LeRobot's
    factory, the same steps and the same actions."""
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors

    import lerobot_policy_unidextok  # noqa: F401

    root = sim["inspire_rh56_unitree"]["udhm"]
    cfg, meta = _config(sim, root, udt_wrist_frame="robot", udt_relative_actions=False, udt_copy_start=False)
    checkpoint = _save(cfg, meta, tmp_path / "old")
    saved = json.loads((checkpoint / "config.json").read_text())
    for new in ("udt_wrist_frame", "udt_wrist_columns", "udt_grasp_centres_m"):
        saved.pop(new)
    (checkpoint / "config.json").write_text(json.dumps(saved))
    batch = _batch(root, meta)
    obs = {k: v for k, v in batch.items() if k.startswith("observation.")}

    def act(path):
        config = PreTrainedConfig.from_pretrained(path)
        pre, post = make_pre_post_processors(config, pretrained_path=str(path))
        policy = get_policy_class(config.type).from_pretrained(path).eval()
        return config, pre, post(policy.select_action(pre(dict(obs))))

    old_cfg, pre, old = act(checkpoint)
    assert old_cfg.udt_wrist_frame == "auto" and not old_cfg.uses_wrist_frame
    assert not any(isinstance(s, WristFrameStep) for s in pre.steps)
    torch.manual_seed(0)
    policy = get_policy_class(cfg.type)(cfg).eval()
    fresh_pre, fresh_post = make_pre_post_processors(cfg, dataset_stats=meta.stats)
    assert torch.equal(old, fresh_post(policy.select_action(fresh_pre(dict(obs)))))


def test_a_mix_without_the_wrist_columns_has_no_frame_and_grasp_centre_refuses_it(sim, tmp_path, caplog):
    """The default --keep=hands drops the inputs' wrist columns and with them their frame: said in one warning
    naming --keep=all (it was an info line, silent in most logs; issue 54)."""
    from lerobot_unidextok.conversion.mix import MixOptions, mix
    from lerobot_unidextok.errors import ConfigError

    root = tmp_path / "hands_only"
    with caplog.at_level("WARNING", logger="lerobot_unidextok.conversion.mix"):
        mix(MixOptions(inputs=[str(sim[h]["udhm"]) for h in HANDS[:2]], root=str(root), repo_id="test/hands",
                       keep="hands", progress=False))  # fmt: skip
    notes = [r.getMessage() for r in caplog.records if "wrist" in r.getMessage()]
    assert len(notes) == 1 and "--keep=hands drops their wrist columns" in notes[0] and "--keep=all keeps it" in notes[0]
    assert UdhmDatasetMeta(root).record.wrist_frame == {}
    cfg, _ = _config(sim, root)
    assert not cfg.uses_wrist_frame
    with pytest.raises(ConfigError, match="records no wrist frame.*--policy.udt_wrist_frame=robot") as err:
        _config(sim, root, udt_wrist_frame="grasp_centre")
    assert "\n" not in str(err.value)
    with pytest.raises(ConfigError, match="udt_wrist_frame must be one of"):
        _config(sim, root, udt_wrist_frame="centre")
