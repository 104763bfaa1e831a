"""Each input's share of the training frames by sampling (`ShareSampler`) and, under lerobot-train, by loss weights
(`ShareWeightStep`, `share_loss_weights`): the asked shares, within the statistical tolerance of many draws."""

import numpy as np
import pytest
import torch

from lerobot_unidextok.data.record import ConversionRecord, EpisodeRecord, MixedSource
from lerobot_unidextok.data.share_sampler import ShareSampler, episode_inputs, share_loss_weights
from lerobot_unidextok.processor import ShareWeightStep

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


def _record(shares: list[float]) -> ConversionRecord:
    episodes = [EpisodeRecord(i, f"x#{i}", "test" if i == 5 else "train", n, "", {"mix_source": g})
                for i, (n, g) in enumerate(zip(LENGTHS, GROUPS, strict=True))]  # fmt: skip
    sources = [MixedSource("a", None, "s", ["right"], ["h"], 2, [], share=shares[0]),
               MixedSource("b", None, "s", ["right"], ["h"], 4, [5], share=shares[1])]  # fmt: skip
    return ConversionRecord(source="mix", episodes=episodes, sources=sources)


def test_each_episodes_input_and_the_shares_come_from_the_mixs_record():
    assert episode_inputs(_record([0.7, 0.3])) == (GROUPS, [0.7, 0.3])
    assert episode_inputs(_record([0.0, 0.0])) == ([], [])  # no share asked (or a mix of copies): no weights


@pytest.mark.parametrize("episodes", [[0, 1, 2, 3, 4, 5], [0, 2, 3, 4, 5], [1, 5]])
def test_loss_weights_give_each_input_its_share_of_the_loss_on_any_subset_of_episodes(episodes):
    """Batches of 32 drawn uniformly from the frames of the episodes a run trains on (what lerobot-train does; here
    with one of the target's two episodes left out, as closed_loop.py trains 10 of a target's 50): the weight mass
    of each input's rows is its share, and a row weighs 1 on average. Weights fixed by the mix's frame counts gave
    the target half its share when half its episodes were left out; fractions of each batch alone, 0.59 of 0.7 in
    the [0, 2, 3, 4, 5] case (the target 40 of 840 frames, absent from a fifth of the batches)."""
    inputs, shares = episode_inputs(_record([0.7, 0.3]))
    step = ShareWeightStep(episode_inputs=inputs, shares=shares)
    frames = np.concatenate([np.full(LENGTHS[e], e) for e in episodes])
    rng = np.random.default_rng(0)
    mass, rows = np.zeros(2), 0
    for _ in range(400):
        batch = torch.as_tensor(rng.choice(frames, size=32))
        weight = step.weights(batch)
        own = torch.as_tensor(inputs)[batch]
        mass += [weight[own == k].sum().item() for k in range(2)]
        rows += len(batch)
    np.testing.assert_allclose(mass / mass.sum(), [0.7, 0.3], atol=0.02)
    assert mass.sum() / rows == pytest.approx(1.0, abs=0.03)
    step.reset()  # a new run counts afresh
    assert step._seen.sum() == 0


def test_rows_without_an_input_weigh_one_and_an_input_of_share_zero_nothing():
    weight = share_loss_weights(torch.tensor([-1, 0, 0, 1]), torch.tensor([0.5, 0.5]), torch.tensor([2, 1]))
    torch.testing.assert_close(weight, torch.tensor([1.0, 0.75, 0.75, 1.5]))
    torch.testing.assert_close(share_loss_weights(torch.tensor([0, 1, 1]), torch.tensor([1.0, 0.0]), torch.tensor([1, 2])),
                               torch.tensor([3.0, 0.0, 0.0]))  # fmt: skip
    torch.testing.assert_close(share_loss_weights(torch.tensor([-1, -1]), torch.tensor([1.0]), torch.tensor([0])),
                               torch.ones(2))  # fmt: skip


def test_a_checkpoint_saved_with_fixed_episode_weights_keeps_them():
    step = ShareWeightStep(episode_weights=[2.0, 0.5])
    torch.testing.assert_close(step.weights(torch.tensor([0, 1, 7])), torch.tensor([2.0, 0.5, 1.0]))
    assert step.get_config() == {"episode_weights": [2.0, 0.5]}
    with pytest.raises(ValueError, match="episode_inputs name inputs"):
        ShareWeightStep(episode_inputs=[0, 2], shares=[0.5, 0.5])
