"""Each input's share of the training frames, by sampling instead of copies (`unidextok-mix --weights`).

A mix of 10 target demonstrations and 100 of other hands gives the target 9 % of the frames LeRobot samples.
`--weights` asks for another share (e.g. half), and two mechanisms give it without writing the target's episodes
several times:

- `ShareSampler`: a sampler over the dataset's frames that draws each frame's input with probability `shares[k]`,
  then a frame of that input uniformly. Same contract as LeRobot 0.6.1's `EpisodeAwareSampler` (episode bounds,
  `episode_indices_to_use`, a permutation that is a pure function of `(seed, epoch)`, `state_dict` /
  `load_state_dict` to resume): for a training loop that can be given a sampler.
- `share_loss_weights`: per row, `share[k] / (rows of input k / rows)` of its input, the rows counted over every
  batch seen so far (`ShareWeightStep` keeps the count), so a row weighs 1 on average. `lerobot-train` 0.6.1
  cannot be given a sampler (it builds `EpisodeAwareSampler` itself, `lerobot/scripts/lerobot_train.py`, and its
  `sample_weighting` knows only `rabc` and `uniform`), so the `<type>_udt` policies weight each row's loss
  instead (`unidextok.share_weights`): the expected gradient is the one the sampler gives (sum over inputs of
  share x that input's mean loss), with the variance of weighting rather than resampling. Frame fractions counted
  from the batches, not fixed from the frame counts of the mix, keep the shares whatever subset of episodes a run
  trains on (`--dataset.episodes`: 10 of a target's 50 demonstrations got a fifth of its share with weights fixed
  by the mix's frame counts), and unlike fractions of each batch alone they are not biased by the batches that
  miss a small input (a batch of 32 from an input of 5 % of the frames misses it 19 % of the time).

The shares come from the mix's record (`MixedSource.share`: the share rule's by default, frames^0.43, or the
normalised `--weights`; 0 = no share, `--share_rule=frames`), the
episodes' inputs from `EpisodeRecord.origin["mix_source"]`. `episode_map_key` names the dataset a map was made
for, so a checkpoint trained further on another dataset (fine-tuning a pooled policy on one robot's data) gets the
map of that dataset instead of weighting its rows by the old one (`policies/udt_config.py`).
"""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import torch

from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.data.record import ConversionRecord
from lerobot_unidextok.utils.files import fingerprint


class ShareSampler(torch.utils.data.Sampler[int]):
    """Dataset frame indices, `num_samples` per epoch, each input making `shares[k]` of them in expectation."""

    def __init__(
        self,
        dataset_from_indices: list[int],
        dataset_to_indices: list[int],
        episode_groups: list[int],
        shares: list[float],
        episode_indices_to_use: list[int] | None = None,
        num_samples: int | None = None,
        seed: int = 0,
        absolute_to_relative_idx: dict[int, int] | None = None,
    ):
        starts, stops = np.asarray(dataset_from_indices, np.int64), np.asarray(dataset_to_indices, np.int64)
        groups = np.asarray(episode_groups, np.int64)
        if not (len(starts) == len(stops) == len(groups)):
            raise ValueError(f"episode bounds ({len(starts)}, {len(stops)}) and groups ({len(groups)}) differ in length")
        shares = np.asarray(shares, np.float64)
        if len(shares) <= groups.max(initial=-1) or not (np.isfinite(shares).all() and (shares >= 0).all()):
            raise ValueError(f"shares {shares.tolist()} must give one finite share >= 0 per group {sorted(set(groups))}")
        used = np.zeros(len(starts), bool)
        used[np.asarray(episode_indices_to_use if episode_indices_to_use is not None else range(len(starts)))] = True
        self.frames: list[np.ndarray] = []  # per group, its frames' dataset indices
        for k in range(len(shares)):
            picked = [np.arange(a, b) for a, b, g, u in zip(starts, stops, groups, used, strict=True) if u and g == k]
            frames = np.concatenate(picked) if picked else np.zeros(0, np.int64)
            if absolute_to_relative_idx is not None:
                frames = np.asarray([absolute_to_relative_idx[int(i)] for i in frames], np.int64)
            self.frames.append(frames)
        present = np.asarray([len(f) > 0 for f in self.frames])
        if not (shares * present).sum() > 0:
            raise ValueError("no group with a share > 0 has frames among the episodes used")
        self.shares = shares * present / (shares * present).sum()
        self.num_samples = int(num_samples or sum(len(f) for f in self.frames))
        self.seed, self.epoch, self.start_index = int(seed), 0, 0

    def _order(self, epoch: int) -> np.ndarray:
        rng = np.random.default_rng([self.seed, epoch])
        group = rng.choice(len(self.shares), size=self.num_samples, p=self.shares)
        out = np.empty(self.num_samples, np.int64)
        for k, frames in enumerate(self.frames):
            at = np.flatnonzero(group == k)
            if len(at):
                out[at] = frames[rng.integers(0, len(frames), size=len(at))]
        return out

    def __iter__(self) -> Iterator[int]:
        order, start = self._order(self.epoch), self.start_index
        self.epoch, self.start_index = self.epoch + 1, 0
        yield from (int(i) for i in order[start:])

    def __len__(self) -> int:
        return self.num_samples

    def set_epoch(self, epoch: int) -> None:
        self.epoch, self.start_index = int(epoch), 0

    def state_dict(self) -> dict[str, int]:
        return {"epoch": self.epoch, "start_index": self.start_index}

    def load_state_dict(self, state: dict[str, int]) -> None:
        self.epoch, self.start_index = int(state["epoch"]), int(state["start_index"])


def mix_shares(record: ConversionRecord) -> tuple[dict[int, int], list[float]]:
    """({episode index: its input}, each input's share) of a mixed dataset's record; shares [] when none was recorded
    (`--share_rule=frames`, copies, or a mix written before shares, whose weights were honoured by copies)."""
    groups = {e.episode_index: int(e.origin.get("mix_source", 0)) for e in record.episodes}
    shares = [float(getattr(s, "share", 0.0)) for s in record.sources]
    return groups, (shares if any(shares) else [])


def episode_inputs(record: ConversionRecord) -> tuple[list[int], list[float]]:
    """(each episode's input by episode index, each input's share) of a mixed dataset's record; ([], []) when no
    share was recorded (a mix of copies, or `--share_rule=frames`)."""
    groups, shares = mix_shares(record)
    if not shares:
        return [], []
    inputs = [-1] * (max(groups, default=-1) + 1)
    for episode, k in groups.items():
        inputs[episode] = k
    return inputs, shares


def episode_map_key(meta: UdhmDatasetMeta) -> str:
    """Which dataset an episode map is for: `"<N> episodes <12 hex digits>"`, the digits a fingerprint of the
    episodes' lengths and (converted or mixed) sources. The same for a copy or a move of the dataset, another for a
    dataset with other episodes."""
    lengths = sorted((meta.episode_lengths or {}).items())
    sources = [e.source for e in meta.record.episodes] if meta.record is not None else []
    return f"{meta.total_episodes} episodes {fingerprint(lengths, sources)}"


def share_loss_weights(inputs: torch.Tensor, shares: torch.Tensor, seen: torch.Tensor) -> torch.Tensor:
    """(B,) loss weight of each row from its input `inputs` (B,) (-1: none, weight 1), the inputs' `shares` (K,)
    and `seen` (K,), the rows of each input counted so far (this batch's included): `share[k] / (seen[k] /
    seen.sum())`, the shares renormalised over the inputs seen, so that input k's rows carry `share[k]` of the
    weight in expectation and a row with an input weighs 1 on average."""
    inputs = inputs.long().reshape(-1)
    weight = torch.ones(len(inputs), dtype=torch.float32)
    known = inputs >= 0
    seen = seen.float()
    present = shares.float() * (seen > 0)
    if not known.any():
        return weight
    if not present.sum() > 0:  # only inputs with share 0 seen: nothing to weight them against
        weight[known] = 0.0
        return weight
    per_input = present / present.sum() * seen.sum() / seen.clamp(min=1)
    weight[known] = per_input[inputs[known]]
    return weight


__all__ = ["ShareSampler", "episode_inputs", "episode_map_key", "mix_shares", "share_loss_weights"]
