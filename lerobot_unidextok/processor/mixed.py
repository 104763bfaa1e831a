"""The tokenizer step for a dataset that mixes robots and people (`unidextok-mix`): hands per row.

A mixed dataset has one UDHM block per side any of its sources has, and its rows carry different hands: a G1's
two Inspire hands, a LinkerHand L10 on the right only, a person's hands. `observation.hand_ids` ((H,) int64
per frame) says which: an index into the record's `hand_vocabulary`, -1 where the block holds no hand. This
step tokenises each row's blocks with that row's hands (hand conditioning, active DoFs and ranges per row) and
tells the policy which embodiment it is looking at: a hand identity per block follows the token view in
`observation.environment_state` (all zero for an absent block). `identity` chooses it: `onehot` (the default) over
the vocabulary, which a hand the mix never had cannot fill (all zero); `morphology`, the hand's morphology vector
(`hands/morphology.py`: slot presence and UDHM ranges, 66 wide), which any registered hand fills the same way in
any dataset, so a zero-shot hand is described in the terms the trained ones were.

A checkpoint bound to one robot (`unidextok-deploy`) sets `fixed_hand_ids`: the robot's own state carries no
`observation.hand_ids`, so its hands come from there, and the policy sees the same identity it trained with.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from lerobot.configs.types import FeatureType, PipelineFeatureType, PolicyFeature
from lerobot.processor import ProcessorStepRegistry

from lerobot_unidextok import hands
from lerobot_unidextok.blocks import find_udhm_blocks
from lerobot_unidextok.constants import OBS_HAND_IDS, UDHM_DIM
from lerobot_unidextok.data.meta import UdhmDatasetMeta
from lerobot_unidextok.hands.morphology import MORPHOLOGY_WIDTH, morphology_vector
from lerobot_unidextok.processor.guards import check_batch, check_ranges, check_registry, layout_bounds
from lerobot_unidextok.processor.processor_unidextok import (
    STEP_NAME,
    UniDexTokStateTokenizerStep,
    tokenizer_output_dims,
)

MIXED_STEP_NAME = "unidextok.mixed_state_tokenizer"
ABSENT = -1  # `observation.hand_ids` of a block that holds no hand
IDENTITIES = ("onehot", "morphology")  # what tells the policy a row's hand (module docstring)


def identity_width(identity: str, vocabulary_size: int) -> int:
    """The columns per block the hand identity adds to the token view."""
    if identity not in IDENTITIES:
        raise ValueError(f"the hand identity must be one of {IDENTITIES}, got {identity!r}")
    return vocabulary_size if identity == "onehot" else MORPHOLOGY_WIDTH


@ProcessorStepRegistry.register(MIXED_STEP_NAME)
@dataclass
class UniDexTokMixedTokenizerStep(UniDexTokStateTokenizerStep):
    """`unidextok.state_tokenizer` with hands per row: each block of each row tokenised with its own hand
    (`hand_ids_key`, indices into `hand_vocabulary`, -1 = no hand: zero view, tokens -1), and a one-hot hand
    identity per block appended to the float view. `state_names` (required) locate the blocks; `hand_layout`
    is not used. Tokens are (H * N * K,) as in the fixed step; the view is H * (22 + V) wide (dequantized) or
    H * (N * codebook_dim + V) (embedding)."""

    hand_layout: list[str] = field(default_factory=list)  # not used: the hands come per row
    # the hands `hand_ids_key` indexes (the mixed dataset's record `hand_vocabulary`)
    hand_vocabulary: list[str] = field(default_factory=list)
    # per block, the hands of rows without `hand_ids_key` (a robot bound by unidextok-deploy; -1 = no hand);
    # [] = every observation must carry them
    fixed_hand_ids: list[int] = field(default_factory=list)
    # zero-shot hands of a bound robot the mix never had (unidextok-deploy --zero_shot=true): indices after the
    # vocabulary in fixed_hand_ids; tokenised by name, with an all-zero identity (the policy never saw them)
    extra_hands: list[str] = field(default_factory=list)
    hand_ids_key: str = OBS_HAND_IDS
    identity: str = "onehot"  # onehot over the vocabulary | morphology (module docstring)

    _vocab_tokenizer_ids: torch.Tensor | None = field(default=None, init=False, repr=False)  # (V,)
    _vocab_active: torch.Tensor | None = field(default=None, init=False, repr=False)  # (V, 22) bool
    _vocab_bounds: tuple[torch.Tensor, torch.Tensor] | None = field(default=None, init=False, repr=False)  # (H,V,22)
    _vocab_morphology: torch.Tensor | None = field(default=None, init=False, repr=False)  # (H, V+E, 66)

    def __post_init__(self, search_rounds: int | None = None) -> None:  # search_rounds: legacy (the base step's)
        self._check_settings()
        self.hand_vocabulary, self.state_names = list(self.hand_vocabulary), list(self.state_names)
        self.fixed_hand_ids, self.hand_layout = [int(i) for i in self.fixed_hand_ids], []
        self.extra_hands = list(self.extra_hands)
        identity_width(self.identity, len(self.hand_vocabulary))  # a known identity, before anything loads
        if not self.hand_vocabulary or not self.state_names:
            raise ValueError(
                f"{MIXED_STEP_NAME} needs the mixed dataset's hand_vocabulary and state_names; build it with "
                "UniDexTokMixedTokenizerStep.from_dataset(<dataset written by unidextok-mix>)"
            )
        names = self.hand_names
        check_registry(names)  # before any weights are loaded or anything is logged
        blocks = find_udhm_blocks(self.state_names)
        self._sides = [b.side for b in blocks]
        if self.fixed_hand_ids and (
            len(self.fixed_hand_ids) != len(blocks)
            or not all(ABSENT <= i < len(names) for i in self.fixed_hand_ids)
        ):
            raise ValueError(
                f"fixed_hand_ids {self.fixed_hand_ids} must give one index into hand_vocabulary + extra_hands "
                f"({len(names)} hands) or -1 per block ({len(blocks)} blocks: {self._sides})"
            )
        self._columns = torch.as_tensor(np.concatenate([np.arange(b.start, b.stop) for b in blocks]))
        self._load_tokenizer()
        self._upgrade_legacy_rounds(search_rounds)
        self._vocab_tokenizer_ids = torch.tensor(self._tokenizer_hand_ids(names))
        self._vocab_active = torch.as_tensor(np.stack([hands.get(h).active_mask for h in names]))
        per_side = [layout_bounds(names, [side] * len(names)) for side in self._sides]
        self._vocab_bounds = torch.stack([lo for lo, _ in per_side]), torch.stack([hi for _, hi in per_side])
        self._vocab_morphology = torch.as_tensor(
            np.stack([np.stack([morphology_vector(h, side) for h in names]) for side in self._sides])
        )

    @classmethod
    def from_dataset(cls, root: str | Path, **kwargs: Any) -> UniDexTokMixedTokenizerStep:
        """A step for a dataset written by `unidextok-mix`: its hand vocabulary and state columns."""
        meta = UdhmDatasetMeta(root)
        if meta.record is None or not meta.record.hand_vocabulary:
            raise ValueError(f"{root} is not a mixed dataset (no hand_vocabulary in its record); use the fixed step")
        return cls(hand_vocabulary=meta.record.hand_vocabulary, state_names=meta.names("observation.state"), **kwargs)

    @property
    def num_hands(self) -> int:
        return len(self._sides)

    @property
    def hand_names(self) -> list[str]:
        """The hands an id indexes: the vocabulary, then the zero-shot hands of a bound robot."""
        return [*self.hand_vocabulary, *self.extra_hands]

    # ----------------------------------------------------------------------------------------- core
    def _blocks(self, states: torch.Tensor) -> torch.Tensor:
        """(B, D) -> (B, H, 22) radians; width and NaN checked."""
        b, width = states.shape
        if width != len(self.state_names):
            raise ValueError(
                f"{self.input_key} has width {width}, but this step was set up for the {len(self.state_names)} "
                f"columns of the mixed dataset ({self.num_hands} UDHM blocks {self._sides}); feed that layout"
            )
        check_batch(states, self.state_names, self.input_key)
        if self._columns.device != states.device:
            self._columns = self._columns.to(states.device)
        return states.index_select(1, self._columns).float().reshape(b, self.num_hands, UDHM_DIM)

    def row_hand_ids(self, observation: dict[str, Any], lead: tuple[int, ...], device) -> torch.Tensor:
        """(prod(lead), H) int64 vocabulary index of each row's blocks: the observation's, else `fixed_hand_ids`."""
        ids = observation.get(self.hand_ids_key)
        if ids is None:
            if not self.fixed_hand_ids:
                raise KeyError(
                    f"{MIXED_STEP_NAME} needs '{self.hand_ids_key}' (each block's hand) in the observation: this "
                    "policy was trained on a mix of hands. Bind it to your robot with `unidextok-deploy "
                    "--checkpoint=... --robot=<its converted dataset> --output=...`"
                )
            ids = torch.tensor(self.fixed_hand_ids, device=device).expand(*lead, self.num_hands)
        ids = torch.as_tensor(ids, device=device).long()
        if ids.ndim == len(lead) and self.num_hands == 1 and tuple(ids.shape) == tuple(lead):
            ids = ids.unsqueeze(-1)  # one block: LeRobot's dataset returns a (1,) feature as a scalar per row
        elif ids.ndim == len(lead):  # one frame of hand ids beside a batched state (LeRobot batches only its keys)
            ids = ids.unsqueeze(0).expand(*lead, self.num_hands)
        if tuple(ids.shape) != (*lead, self.num_hands):
            raise ValueError(f"{self.hand_ids_key} has shape {tuple(ids.shape)}, expected {(*lead, self.num_hands)}")
        ids = ids.reshape(-1, self.num_hands)
        if bool(((ids < ABSENT) | (ids >= len(self.hand_names))).any()):
            raise ValueError(
                f"{self.hand_ids_key} holds {sorted(set(ids.unique().tolist()))}, outside -1 .. "
                f"{len(self.hand_vocabulary) - 1} (the hand_vocabulary {self.hand_vocabulary})"
            )
        return ids

    @torch.no_grad()
    def tokenize_rows(self, states: torch.Tensor, vocab_ids: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """(B, D) states, (B, H) vocabulary ids -> ((B, H*N*K) int64 tokens, (B, F) float32 view)."""
        rows = self._blocks(states)  # (B, H, 22)
        b, h = rows.shape[:2]
        tok, device = self.tokenizer, rows.device
        if tok.enc_pos.device != device:
            tok.to(device)
        for name in ("_vocab_tokenizer_ids", "_vocab_active"):
            if getattr(self, name).device != device:
                setattr(self, name, getattr(self, name).to(device))
        vocab_ids = vocab_ids.to(device)
        present = vocab_ids >= 0  # (B, H)
        v = vocab_ids[present]  # (P,)
        picked = rows[present]  # (P, 22)
        if self.range_check != "off":
            lo, hi = self._vocab_bounds
            if lo.device != device:
                self._vocab_bounds = lo, hi = lo.to(device), hi.to(device)
            block = torch.arange(h, device=device).expand(b, h)[present]  # (P,)
            names = [[self.hand_names[i]] for i in v.tolist()]
            check_ranges(picked[:, None], lo[block, v][:, None], hi[block, v][:, None], names, self.input_key,
                         self.range_check)  # fmt: skip
        cfg = tok.config
        codes = torch.full((b, h, cfg.num_tokens, cfg.num_groups * cfg.num_stages), ABSENT, dtype=torch.long,
                           device=device)  # fmt: skip
        active = self._vocab_active[v]  # (P, 22)
        encode = bool(len(v)) and self.encode  # not encoded: codes stay ABSENT, the view zero
        if encode:
            ids = self._vocab_tokenizer_ids[v]  # (P,)
            found, decoded = tok.encode_decode(picked, ids, mask=active if self.searches else None, encoding=self.encoding)
            codes[present] = found  # (P, N, K)
        if self.representation == "dequantized":
            view = torch.zeros(b, h, UDHM_DIM, device=device)
            if encode:
                view[present] = decoded * active  # (P, 22), slots a hand lacks set to zero
        else:
            view = torch.zeros(b, h, cfg.num_tokens * cfg.codebook_dim * cfg.num_stages, device=device)
            if encode:
                view[present] = tok.code_vectors(found).flatten(1)  # (P, N*K*S*d)
        identity = self._identity(vocab_ids, present, device)  # (B, H, V) or (B, H, 66)
        view = torch.cat([view.reshape(b, -1), identity.reshape(b, -1)], dim=1)  # (B, H*(F+V))
        return codes.reshape(b, -1), view.float()

    def _identity(self, vocab_ids: torch.Tensor, present: torch.Tensor, device) -> torch.Tensor:
        """(B, H, width) each block's hand identity: one-hot over the vocabulary (a zero-shot hand: all zero, no
        identity the policy knows) or the hand's morphology vector; all zero where the block holds no hand."""
        b, h = vocab_ids.shape
        v = vocab_ids[present]  # (P,)
        if self.identity == "onehot":
            identity = torch.zeros(b, h, len(self.hand_names), device=device)
            identity[present] = torch.nn.functional.one_hot(v, len(self.hand_names)).float()  # (P, V + E)
            return identity[..., : len(self.hand_vocabulary)]
        if self._vocab_morphology.device != device:
            self._vocab_morphology = self._vocab_morphology.to(device)
        identity = torch.zeros(b, h, MORPHOLOGY_WIDTH, device=device)
        block = torch.arange(h, device=device).expand(b, h)[present]  # (P,)
        identity[present] = self._vocab_morphology[block, v]  # (P, 66)
        return identity

    def observation(self, observation: dict[str, Any]) -> dict[str, Any]:
        if self.input_key not in observation:
            raise KeyError(f"{STEP_NAME} needs '{self.input_key}' in the observation, got {sorted(observation)}")
        state = torch.as_tensor(observation[self.input_key])
        if state.ndim == 0:
            raise ValueError(f"{self.input_key} must be (D,), (B, D) or (B, T, D), got a scalar")
        lead = tuple(state.shape[:-1])  # () | (B,) | (B, T): kept on both outputs
        vocab_ids = self.row_hand_ids(observation, lead, state.device)  # (prod(lead), H)
        tokens, view = self.tokenize_rows(state.reshape(-1, state.shape[-1]), vocab_ids)
        observation[self.token_key] = tokens.reshape(*lead, tokens.shape[-1])
        observation[self.features_key] = view.reshape(*lead, view.shape[-1])
        return observation

    # ----------------------------------------------------------------------------------------- contract
    def transform_features(
        self, features: dict[PipelineFeatureType, dict[str, PolicyFeature]]
    ) -> dict[PipelineFeatureType, dict[str, PolicyFeature]]:
        n_tokens, width = tokenizer_output_dims(
            self.tokenizer.config, self.num_hands, self.representation,
            identity_width(self.identity, len(self.hand_vocabulary)),
        )  # fmt: skip
        obs = dict(features.get(PipelineFeatureType.OBSERVATION, {}))
        obs[self.token_key] = PolicyFeature(type=FeatureType.STATE, shape=(n_tokens,))
        obs[self.features_key] = PolicyFeature(type=FeatureType.ENV, shape=(width,))
        return {**features, PipelineFeatureType.OBSERVATION: obs}

    def get_config(self) -> dict[str, Any]:
        config = super().get_config()
        config.pop("hand_layout")
        return {
            **config,
            "hand_vocabulary": list(self.hand_vocabulary),
            "fixed_hand_ids": list(self.fixed_hand_ids),
            "extra_hands": list(self.extra_hands),
            "hand_ids_key": self.hand_ids_key,
            "identity": self.identity,
        }


__all__ = ["ABSENT", "IDENTITIES", "MIXED_STEP_NAME", "UniDexTokMixedTokenizerStep", "identity_width"]
