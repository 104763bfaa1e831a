"""The universal recipe (configs/train/universal.yaml): registered hands without recordings train on in-range
states (`range_hands`), and the recipe itself rebuilds at a tiny size in seconds."""

from pathlib import Path

import draccus
import numpy as np
import pytest

from lerobot_unidextok import hands
from lerobot_unidextok.configs import shipped_config
from lerobot_unidextok.training import HandStates, TrainConfig
from lerobot_unidextok.training.coverage import CoverageConfig, MixtureSampler, range_states, resolve_range_hands

REPO = Path(__file__).resolve().parents[2]
INSPIRE = "inspire_rh56_unitree"


def _inspire_rows(n: int = 50) -> HandStates:
    return range_states(INSPIRE, n, seed=3)


def test_range_only_hands_draw_uniform_states_inside_each_sides_registered_range():
    sampler = MixtureSampler(_inspire_rows(), coverage=CoverageConfig(robot={"recorded": 1.0}), seed=0,
                             range_hands=[INSPIRE, "shadow", "linkerhand_l6"])  # fmt: skip
    assert sampler.hand_names == [INSPIRE, "shadow", "linkerhand_l6"]  # the recorded hand is not added twice
    described = sampler.describe()["hands"]
    assert described["shadow"]["range_only"] and described["shadow"]["sources"] == {"uniform": 1.0}
    assert described[INSPIRE]["sources"] == {"recorded": 1.0} and not described[INSPIRE]["range_only"]
    batch = sampler.sample(6000)
    for k, name in enumerate(sampler.hand_names[1:], start=1):
        spec, x, m = hands.get(name), batch.states_rad[batch.hands == k], batch.masks[batch.hands == k]
        assert len(x) > 1000 and (m == spec.mask("semantic")).all()
        bounds = [spec.udhm_limits_rad(side) for side in spec.sides]
        inside = [((x >= lo - 1e-6) & (x <= hi + 1e-6)).all(1) for lo, hi in bounds]
        assert np.logical_or.reduce(inside).all()  # each row inside the range of one side
        lo, hi = np.min([b[0] for b in bounds], 0), np.max([b[1] for b in bounds], 0)
        moving = m[0] & (hi > lo)
        assert (x[:, moving].min(0) < lo[moving] + 0.1 * (hi - lo)[moving]).all()  # the range is filled
        assert (x[:, moving].max(0) > hi[moving] - 0.1 * (hi - lo)[moving]).all()


def test_the_input_ranges_cover_the_range_only_hands():
    from lerobot_unidextok.training.loop import joint_ranges_rad

    rows = _inspire_rows()
    lo, hi = np.array(joint_ranges_rad(rows, range_hands=["shadow", "allegro"])).T
    for name in ("shadow", "allegro", INSPIRE):
        for side in hands.get(name).sides:
            a, b = hands.get(name).udhm_limits_rad(side)
            assert (lo <= a + 1e-6).all() and (hi >= b - 1e-6).all(), name
    shadow_lo = np.min([hands.get("shadow").udhm_limits_rad(s)[0] for s in hands.get("shadow").sides], 0)
    assert (np.array(joint_ranges_rad(rows))[:, 0] > shadow_lo + 1e-3).any()  # without them: narrower


def test_range_hands_all_is_every_registered_hand_minus_the_excluded_and_names_are_checked():
    assert resolve_range_hands(["all"], ["shadow"]) == [h for h in hands.names() if h != "shadow"]
    with pytest.raises(ValueError, match=r"range_hands \['no_such_hand'\] are not registered hands"):
        resolve_range_hands(["no_such_hand"])


def test_the_universal_recipe_rebuilds_at_a_tiny_size(g1_like_hands, tmp_path):
    """configs/train/universal.yaml with the tiny preset, 30 steps and the synthetic G1-like dataset: a model
    whose vocabulary and trained hands are every registered hand, scored on the dataset's test episodes."""
    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.training.run import train_and_evaluate

    cfg = draccus.parse(TrainConfig, config_path=shipped_config("train/universal"), args=[
        "--preset=tiny", "--steps=30", "--batch_size=64", "--warmup_steps=5", "--eval_every=15",
        "--save_last_every=30", f"--datasets=[{g1_like_hands['root']}]", f"--output_dir={tmp_path / 'run'}"])  # fmt: skip
    assert cfg.range_hands == ["all"] and cfg.hand_weights == {"human": 2.0, INSPIRE: 2.0}
    report, _ = train_and_evaluate(cfg)
    model = UniDexTok.from_pretrained(str(tmp_path / "run" / "best"))
    assert set(model.config.hand_names) == set(model.config.trained_hands) == set(hands.names())
    assert INSPIRE in report["per_hand"] and np.isfinite(report["per_hand"][INSPIRE]["mpjae_deg"])
