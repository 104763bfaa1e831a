"""Each input's share of the training frames by sampling (`ShareSampler`) and, under lerobot-train, by loss weights
(`episode_loss_weights`): the asked shares, within the statistical tolerance of many draws."""

import numpy as np
import pytest

from lerobot_unidextok.data.record import ConversionRecord, EpisodeRecord, MixedSource
from lerobot_unidextok.data.share_sampler import ShareSampler, episode_loss_weights

# 6 episodes: the target's 2 short ones (input 0, 40 frames each), the others' 4 long ones (input 1, 200 each)
LENGTHS = [40, 40, 200, 200, 200, 200]
GROUPS = [0, 0, 1, 1, 1, 1]
STARTS = np.cumsum([0, *LENGTHS[:-1]]).tolist()
STOPS = np.cumsum(LENGTHS).tolist()


def _group_of(index: np.ndarray) -> np.ndarray:
    return np.asarray(GROUPS)[np.searchsorted(STOPS, index, side="right")]


@pytest.mark.parametrize("shares", [[0.5, 0.5], [0.85, 0.15], [1, 3]])
def test_the_sampler_gives_the_asked_shares(shares):
    sampler = ShareSampler(STARTS, STOPS, GROUPS, shares, num_samples=20000, seed=3)
    drawn = np.fromiter(iter(sampler), np.int64)
    assert len(drawn) == len(sampler) == 20000
    want = np.asarray(shares, float) / sum(shares)
    got = np.bincount(_group_of(drawn), minlength=2) / len(drawn)
    tolerance = 4 * np.sqrt(want * (1 - want) / len(drawn))  # 4 binomial standard deviations
    assert (np.abs(got - want) <= tolerance).all(), (got, want)
    # within an input, its frames uniformly: every target frame drawn, none far from its expected count
    target = drawn[_group_of(drawn) == 0]
    counts = np.bincount(target, minlength=80)[:80]
    assert counts.min() > 0 and counts.max() < 2 * len(target) / 80
    # without the sampler (every frame equally) the target would get 80 / 880 = 9 %
    assert want[0] > 0.2


def test_the_order_is_a_function_of_seed_and_epoch_and_resumes_where_it_stopped():
    a = ShareSampler(STARTS, STOPS, GROUPS, [0.5, 0.5], seed=1)
    first, second = list(a), list(a)  # two epochs
    assert first != second and len(first) == sum(LENGTHS)
    b = ShareSampler(STARTS, STOPS, GROUPS, [0.5, 0.5], seed=1)
    b.load_state_dict({"epoch": 1, "start_index": 100})
    assert list(b) == second[100:]
    assert list(ShareSampler(STARTS, STOPS, GROUPS, [0.5, 0.5], seed=2)) != first
    # only the episodes used: the second target episode left out
    c = ShareSampler(STARTS, STOPS, GROUPS, [0.5, 0.5], episode_indices_to_use=[0, 2, 3], seed=0)
    assert set(_group_of(np.asarray(list(c)))) == {0, 1}
    assert max(i for i in c._order(0) if i < 80) < 40


def test_bad_shares_are_named():
    with pytest.raises(ValueError, match="one finite share"):
        ShareSampler(STARTS, STOPS, GROUPS, [1.0])
    with pytest.raises(ValueError, match="no group with a share"):
        ShareSampler(STARTS, STOPS, GROUPS, [0.0, 1.0], episode_indices_to_use=[0, 1])


def test_loss_weights_give_each_input_its_share_of_the_weighted_frames():
    episodes = [EpisodeRecord(i, f"x#{i}", "test" if i == 5 else "train", n, "", {"mix_source": g})
                for i, (n, g) in enumerate(zip(LENGTHS, GROUPS, strict=True))]  # fmt: skip
    sources = [MixedSource("a", None, "s", ["right"], ["h"], 2, [], share=0.7),
               MixedSource("b", None, "s", ["right"], ["h"], 4, [5], share=0.3)]  # fmt: skip
    record = ConversionRecord(source="mix", episodes=episodes, sources=sources)
    weights = episode_loss_weights(record)
    assert sorted(weights) == [0, 1, 2, 3, 4]  # the test episode has none
    mass = np.zeros(2)
    for e, w in weights.items():
        mass[GROUPS[e]] += w * LENGTHS[e]
    np.testing.assert_allclose(mass / mass.sum(), [0.7, 0.3], rtol=1e-6)
    np.testing.assert_allclose(mass.sum(), sum(LENGTHS[:5]), rtol=1e-6)  # a frame weighs 1 on average
    for s in sources:
        s.share = 0.0
    assert episode_loss_weights(record) == {}  # no share asked (or a mix of copies): no weights
