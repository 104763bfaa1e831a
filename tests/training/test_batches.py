"""Training batches from a memory-mapped row store: the mixture sampler mixes hands with the same probabilities
as from in-memory rows (hand by share, then uniform inside the hand), coverage sources stay inside the hand's
ranges and masks, selection episodes never train, and training on a store learns like in memory."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
from lerobot_unidextok.data import open_row_store
from lerobot_unidextok.samples import write_samples
from lerobot_unidextok.training import TrainConfig, load_hand_states, train_tokenizer
from lerobot_unidextok.training.coverage import CoverageConfig, MixtureSampler
from lerobot_unidextok.training.splits import split_by_episode, split_store_by_episode


@pytest.fixture(scope="module")
def converted(tmp_path_factory):
    """LinkerHand bags (L10 and L20 hands, unequal row counts) converted to a UDHM dataset."""
    raw = write_samples(tmp_path_factory.mktemp("raw"), sources=["linkerhand"], episodes_per_source=6,
                        frames_per_episode=60)["linkerhand"]  # fmt: skip
    root = tmp_path_factory.mktemp("conv") / "linker"
    convert(ConvertOptions(source="linkerhand", input=raw, root=root, progress=False))
    return root


def test_store_batches_mix_hands_like_in_memory_rows(converted, tmp_path):
    """Same per-row probability share_h / n_h: hand shares and within-hand uniformity, over many draws."""
    store = open_row_store([converted], "train", tmp_path / "store")
    rows = load_hand_states([str(converted)], "train")
    counts = store.hand_counts()
    assert counts == {h: int((rows.hands == h).sum()) for h in rows.hand_names()}
    assert len(set(counts.values())) > 1  # unequal hands: balanced mixing is not proportional sampling
    weights = {"linkerhand_l10": 1.0, "linkerhand_l20": 3.0}
    recorded = CoverageConfig.recorded_only()
    streaming = MixtureSampler(store, weights, 1.0, recorded, seed=5)
    memory = MixtureSampler(rows, weights, 1.0, recorded, seed=5)
    assert streaming.hand_names == memory.hand_names == ["linkerhand_l10", "linkerhand_l20"]
    assert streaming.hand_p == pytest.approx(memory.hand_p) == [0.25, 0.75]
    draws = 400
    for source in (streaming, memory):
        seen = {h: [] for h in source.hand_names}
        for _ in range(draws):
            b = source.sample(256)
            for k, hand in enumerate(source.hand_names):
                seen[hand].append(b.states_rad[b.hands == k])
        total = draws * 256
        for hand, share in zip(source.hand_names, source.hand_p, strict=True):
            got = np.concatenate(seen[hand])
            assert abs(len(got) / total - share) < 4 * np.sqrt(share * (1 - share) / total), hand
            # uniform over the hand's rows: chi-square of how often each distinct row came up
            table = rows.states_rad[rows.hands == hand]
            _, ref_index = np.unique(table, axis=0, return_inverse=True)
            expected = np.bincount(ref_index.ravel()) / len(table) * len(got)
            keys, idx = np.unique(np.concatenate([table, got]), axis=0, return_inverse=True)
            observed = np.bincount(idx.ravel()[len(table) :], minlength=len(keys))
            assert len(keys) == len(expected)  # every drawn row is a row of that hand
            chi2 = ((observed - expected) ** 2 / expected).sum()
            dof = len(expected) - 1
            assert chi2 < dof + 6 * np.sqrt(2 * dof), (hand, chi2, dof)


def test_training_on_a_row_store_learns_like_in_memory(converted, tmp_path):
    import torch

    from lerobot_unidextok.training import build_model, evaluate_mae_deg

    store = open_row_store([converted], "train", tmp_path / "store")
    rows = load_hand_states([str(converted)], "train")
    held_out = load_hand_states([str(converted)], "test")
    cfg = dict(preset="tiny", steps=300, batch_size=64, lr=3e-3, warmup_steps=10, eval_every=150,
               save_last_every=300, progress=False)  # fmt: skip
    torch.manual_seed(0)
    untrained, _ = evaluate_mae_deg(build_model(TrainConfig(**cfg), rows), held_out, 10_000, 0)
    streamed = train_tokenizer(TrainConfig(**cfg, output_dir=str(tmp_path / "s")), store, held_out)
    in_memory = train_tokenizer(TrainConfig(**cfg, output_dir=str(tmp_path / "m")), rows, held_out)
    # untrained ~160 deg; after 300 steps both ~7-9 deg (two seeds measured: 7.8 vs 6.9, 7.7 vs 8.9)
    assert streamed.best_mae_deg < 0.1 * untrained and in_memory.best_mae_deg < 0.1 * untrained
    assert streamed.best_mae_deg < 1.5 * in_memory.best_mae_deg, (streamed.best_mae_deg, in_memory.best_mae_deg)
    assert (tmp_path / "s" / "best" / "model.safetensors").is_file()


def test_store_coverage_stays_inside_ranges_and_masks(converted, tmp_path):
    """Coverage sources drawn from a memory map: same per-hand bounds and masks as from in-memory rows."""
    store = open_row_store([converted], "train", tmp_path / "store")
    rows = load_hand_states([str(converted)], "train")
    streaming = MixtureSampler(store, seed=1)
    memory = MixtureSampler(rows, seed=1)
    for a, b in zip(streaming.hands, memory.hands, strict=True):
        np.testing.assert_array_equal(a.mask, b.mask)
        np.testing.assert_array_equal(a.lo, b.lo)
        np.testing.assert_array_equal(a.hi, b.hi)
    batch = streaming.sample(4096)
    assert set(np.unique(batch.sources)) >= {0, 1}  # recorded and uniform rows both drawn
    for k, hand in enumerate(streaming.hands):
        lo, hi = hand.box
        x, m = batch.states_rad[batch.hands == k], batch.masks[batch.hands == k]
        assert (x >= lo - 1e-6).all() and (x <= hi + 1e-6).all()
        assert not x[~m].any()  # inactive slots stay 0


def test_store_selection_episodes_never_train(converted, tmp_path):
    """The store's held-out selection episodes are the ones `split_by_episode` holds out from the same rows,
    and no kept row belongs to one of them."""
    store = open_row_store([converted], "train", tmp_path / "store")
    rows = load_hand_states([str(converted)], "train")
    kept, selection = split_store_by_episode(store, 0.3, max_rows=10**9, seed=2)
    ref_kept, ref_selection = split_by_episode(rows, 0.3, seed=2)
    assert len(kept) == len(ref_kept) and len(selection) == len(ref_selection) > 0
    assert set(selection.episode_keys().tolist()) == set(ref_selection.episode_keys().tolist())
    for hand in kept.hand_names():
        train_keys = store.episode_keys(hand)[kept.rows_of(hand)]
        assert not np.isin(train_keys, selection.episode_keys()).any()
    assert len(split_store_by_episode(store, 0.3, max_rows=50, seed=2)[1]) == 50
