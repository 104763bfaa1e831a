"""UniDexTok: shared encoder -> factorised cosine VQ -> decoder, conditioned on the hand type.

No `from __future__ import annotations` here: the Hub mixin reads the real `UniDexTokConfig`
annotation of `__init__` to rebuild the config from config.json.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
import dataclasses
import logging
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from huggingface_hub import PyTorchModelHubMixin, hf_hub_download
from huggingface_hub import constants as hf_constants
from safetensors import SafetensorError
from torch import nn

from lerobot_unidextok.constants import ANGLE_SCALE_RAD
from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.pretrained import hub_errors, resolve
from lerobot_unidextok.tokenizer.configuration_unidextok import EncodingConfig, UniDexTokConfig
from lerobot_unidextok.tokenizer.layers import AdaLNBlock, AdaLNFinalNorm, HandEmbedder
from lerobot_unidextok.tokenizer.quantizer import FactorizedCosineVQ
from lerobot_unidextok.tokenizer.search import greedy_codes, search_codes

HandArg = str | Sequence[str] | torch.Tensor
logger = logging.getLogger(__name__)


@dataclass
class UniDexTokOutput:
    """What `UniDexTok.forward` returns."""

    states_rad: torch.Tensor  # (B, 22) reconstruction in radians
    indices: torch.Tensor  # (B, N, K * stages) int64 codes, stage 1 first
    loss: torch.Tensor  # total = recon_loss + vq_loss
    recon_loss: torch.Tensor  # masked MSE in normalised angle space (+ optional SmoothL1)
    vq_loss: torch.Tensor  # commitment * beta + codebook (+ entropy)


class UniDexTok(
    nn.Module,
    PyTorchModelHubMixin,
    library_name="lerobot-unidextok",
    tags=["robotics", "dexterous-hands", "tokenizer", "lerobot", "unidextok"],
    license="apache-2.0",
):
    """Tokenise 22-DoF UDHM hand states of any hand into (N, K) discrete codes and back."""

    def __init__(self, config: UniDexTokConfig) -> None:
        super().__init__()
        self.config = config
        c, n = config.hidden_dim, config.num_tokens
        self._hand_index = {name: i for i, name in enumerate(config.hand_names)}
        self._search_skipped: set[str] = set()  # hands the code search could not search (logged once each)

        # hand-type embedding c_h; last row = "unknown hand"
        self.hand_embed = HandEmbedder(len(config.hand_names), c)
        # encoder
        self.input_proj = nn.Linear(config.state_dim * (1 + 2 * config.fourier_octaves), n * c)
        self.enc_pos = nn.Parameter(torch.zeros(1, n, c))
        self.encoder = nn.ModuleList(
            AdaLNBlock(c, config.num_heads, config.mlp_ratio, config.dropout) for _ in range(config.encoder_depth)
        )
        self.enc_norm = AdaLNFinalNorm(c)
        # quantiser: the paper's stage, then the residual stages (none by default: old checkpoints keep their layout)
        self.quantizer = FactorizedCosineVQ(config)
        self.residual_quantizers = nn.ModuleList(FactorizedCosineVQ(config) for _ in range(config.residual_stages))
        # decoder (mirrors the encoder) and flatten head
        self.dec_pos = nn.Parameter(torch.zeros(1, n, c))
        self.decoder = nn.ModuleList(
            AdaLNBlock(c, config.num_heads, config.mlp_ratio, config.dropout) for _ in range(config.decoder_depth)
        )
        self.dec_norm = AdaLNFinalNorm(c)
        self.head = nn.Linear(n * c, config.state_dim)
        # angle normalisation (derived from the config, not saved): x_normalised = (x_rad - center) / scale
        center, scale = normalisation(config)
        self.register_buffer("norm_center", center, persistent=False)  # (22,)
        self.register_buffer("norm_scale", scale, persistent=False)  # (22,)
        self.initialize_weights()

    # -----------------------------------------------------------------------------------------
    # init (after DiT's initialize_weights)
    # -----------------------------------------------------------------------------------------
    def initialize_weights(self) -> None:
        def _basic(m: nn.Module) -> None:
            if isinstance(m, nn.Linear):
                nn.init.xavier_uniform_(m.weight)
                nn.init.zeros_(m.bias)

        self.apply(_basic)
        nn.init.normal_(self.enc_pos, std=0.02)
        nn.init.normal_(self.dec_pos, std=0.02)
        nn.init.normal_(self.hand_embed.weight, std=0.02)
        for vq in self.quantizers:
            nn.init.normal_(vq.codebooks)
        # adaLN-Zero: every block starts as the identity, final norms as plain LayerNorm
        for block in [*self.encoder, *self.decoder, self.enc_norm, self.dec_norm]:
            nn.init.zeros_(block.adaLN_modulation[-1].weight)
            nn.init.zeros_(block.adaLN_modulation[-1].bias)
        # departure from DiT: the head is not zeroed (a zero head + zero gates stalls the first steps)

    # -----------------------------------------------------------------------------------------
    # input checks
    # -----------------------------------------------------------------------------------------
    @property
    def unknown_hand_id(self) -> int:
        """Id of the "unknown hand" embedding row (hands outside `config.hand_names`, zero-shot)."""
        return self.hand_embed.unknown_id

    def hand_ids(self, hand: HandArg, batch_size: int, allow_unknown: bool = False) -> torch.Tensor:
        """Hand name, one name per row, or a LongTensor of ids -> (B,) ids."""
        device = self.enc_pos.device
        if isinstance(hand, torch.Tensor):
            ids = hand.to(device=device, dtype=torch.long).reshape(-1)
            if ids.numel() == 1:
                ids = ids.expand(batch_size)
            if ids.numel() and (int(ids.min()) < 0 or int(ids.max()) > self.unknown_hand_id):
                raise ValueError(f"hand ids must lie in [0, {self.unknown_hand_id}] (last = unknown hand)")
        else:
            names = [hand] if isinstance(hand, str) else list(hand)
            if len(names) == 1:
                names = names * batch_size
            ids = torch.tensor([self.hand_id(nm, allow_unknown) for nm in names], device=device)
        if ids.shape[0] != batch_size:
            raise ValueError(f"got {ids.shape[0]} hands for a batch of {batch_size}; pass one name or one per row")
        return ids  # (B,)

    def hand_id(self, name: str, allow_unknown: bool = False) -> int:
        """The embedding row of hand `name`; with `allow_unknown`, the unknown-hand row for other names."""
        if name in self._hand_index:
            return self._hand_index[name]
        if allow_unknown:
            return self.unknown_hand_id
        raise ValueError(
            f"unknown hand {name!r}; this tokenizer knows {self.config.hand_names}. Pass allow_unknown=True "
            "to use the unknown-hand embedding (zero-shot), or fine-tune with the hand added to hand_names"
        )

    def _check_states(self, states_rad: torch.Tensor) -> torch.Tensor:
        states_rad = torch.as_tensor(states_rad, dtype=torch.float32, device=self.enc_pos.device)
        if states_rad.ndim != 2 or states_rad.shape[-1] != self.config.state_dim:
            raise ValueError(
                f"states must have shape (B, {self.config.state_dim}) in UDHM order (radians), got "
                f"{tuple(states_rad.shape)}; split two-hand states into one row per hand"
            )
        if not torch.isfinite(states_rad).all():
            raise ValueError("states contain NaN or inf; fill or drop those frames before tokenising")
        return states_rad

    # -----------------------------------------------------------------------------------------
    # encoder / decoder
    # -----------------------------------------------------------------------------------------
    def _encode_latent(self, x_rad: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        b = x_rad.shape[0]
        x = (x_rad - self.norm_center) / self.norm_scale  # (B, 22) normalised (fixed pi in the paper)
        if self.config.fourier_octaves:
            freqs = (math.pi / 2) * 2.0 ** torch.arange(self.config.fourier_octaves, device=x.device)  # (F,)
            phase = (x.unsqueeze(-1) * freqs).flatten(1)  # (B, 22 F)
            x = torch.cat([x, phase.sin(), phase.cos()], dim=-1)  # (B, 22 (1 + 2F))
        z = self.input_proj(x).view(b, self.config.num_tokens, self.config.hidden_dim)  # (B, N, C)
        z = z + self.enc_pos  # (B, N, C)
        for block in self.encoder:
            z = block(z, c)  # (B, N, C)
        return self.enc_norm(z, c)  # (B, N, C)

    def _decode_latent(self, zq: torch.Tensor, c: torch.Tensor) -> torch.Tensor:
        z = zq + self.dec_pos  # (B, N, C)
        for block in self.decoder:
            z = block(z, c)  # (B, N, C)
        z = self.dec_norm(z, c)  # (B, N, C)
        x_hat = self.head(z.flatten(1))  # (B, 22) normalised
        return x_hat * self.norm_scale + self.norm_center  # (B, 22) radians

    @property
    def quantizers(self) -> list[FactorizedCosineVQ]:
        """Every quantiser stage, the paper's first."""
        return [self.quantizer, *self.residual_quantizers]

    @staticmethod
    def _left_out(vq: FactorizedCosineVQ, z: torch.Tensor, indices: torch.Tensor) -> torch.Tensor:
        """(B, N, C) input of stage `vq` and its (B, N, K) codes -> (B, N, C) what the codes left out: the decoder
        input its unsnapped group vectors would give minus the one its codes give (the next stage's input)."""
        u = vq.unit_groups(z)  # (B, N, K, d)
        return F.linear((u - vq.indices_to_codes(indices)).flatten(-2), vq.project_out.weight)  # (B, N, C)

    def _nearest_codes(self, z: torch.Tensor, stages: int) -> torch.Tensor:
        """(B, N, C) encoder output -> (B, N, K * stages) nearest codes of the first `stages` stages."""
        codes = [self.quantizer.nearest_indices(z)]  # (B, N, K)
        vq, z_in = self.quantizer, z
        for rq in self.residual_quantizers[: stages - 1]:
            z_in = self._left_out(vq, z_in, codes[-1])  # (B, N, C)
            codes.append(rq.nearest_indices(z_in))
            vq = rq
        return torch.cat(codes, dim=-1)

    def _decoder_input(self, codes: torch.Tensor) -> torch.Tensor:
        """(B, N, K * s) codes of the first s stages -> (B, N, C) the decoder input (the sum of the stages')."""
        k = self.config.num_groups
        return sum(vq.get_output_from_indices(codes[..., i * k : (i + 1) * k])
                   for i, vq in enumerate(self.quantizers[: codes.shape[-1] // k]))  # fmt: skip

    def _stages(self, stages: int | None) -> int:
        if stages is None:
            return self.config.num_stages
        if not 1 <= stages <= self.config.num_stages:
            raise ValueError(f"stages must be in [1, {self.config.num_stages}] (this model's quantiser stages), "
                             f"got {stages}")  # fmt: skip
        return stages

    def forward(
        self,
        states_rad: torch.Tensor,
        hand: HandArg,
        mask: torch.Tensor | None = None,
        allow_unknown: bool = False,
        hand_drop_prob: float = 0.0,
        generator: torch.Generator | None = None,
    ) -> UniDexTokOutput:
        """Reconstruct states and compute losses; `mask` (B, 22) bool marks the active DoFs.

        In training mode a `hand_drop_prob` share of rows is conditioned on the unknown-hand embedding
        instead of their own (`HandEmbedder`; the draws come from `generator`)."""
        x_rad = self._check_states(states_rad)  # (B, 22)
        b = x_rad.shape[0]
        c = self.hand_embed(self.hand_ids(hand, b, allow_unknown), hand_drop_prob, generator)  # (B, C)
        z = self._encode_latent(x_rad, c)  # (B, N, C)
        zq, indices, vq_loss = self.quantizer(z)  # (B, N, C), (B, N, K), ()
        if self.residual_quantizers:
            zq, indices, vq_loss = self._residual_forward(z, zq, indices, vq_loss, generator)
        x_hat_rad = self._decode_latent(zq, c)  # (B, 22)
        recon_loss = self.reconstruction_loss(x_hat_rad / ANGLE_SCALE_RAD, x_rad / ANGLE_SCALE_RAD, mask)
        return UniDexTokOutput(
            states_rad=x_hat_rad,
            indices=indices,
            loss=recon_loss + vq_loss,
            recon_loss=recon_loss,
            vq_loss=vq_loss,
        )

    def _residual_forward(self, z, zq, indices, vq_loss, generator):
        """The residual stages on top of the first one's (zq, indices, vq_loss): ((B, N, C) summed decoder input,
        (B, N, K * stages) codes, summed VQ loss). In training a `residual_drop_prob` share of rows gets the first
        stage's input alone."""
        keep = torch.ones(z.shape[0], 1, 1, device=z.device)  # (B, 1, 1)
        if self.training and self.config.residual_drop_prob > 0:
            draw = torch.rand(z.shape[0], generator=generator, device=generator.device if generator else None)
            keep = (draw.to(z.device) >= self.config.residual_drop_prob).to(z.dtype).view(-1, 1, 1)
        codes, vq, z_in = [indices], self.quantizer, z
        for rq in self.residual_quantizers:
            z_in = self._left_out(vq, z_in, codes[-1])  # (B, N, C)
            zq_r, idx_r, loss_r = rq(z_in)
            zq, vq_loss = zq + keep * zq_r, vq_loss + loss_r
            codes.append(idx_r)
            vq = rq
        return zq, torch.cat(codes, dim=-1), vq_loss

    def reconstruction_loss(self, x_hat: torch.Tensor, x: torch.Tensor, mask: torch.Tensor | None) -> torch.Tensor:
        """MSE (+ SmoothL1, + L1) in angle / pi units over active DoFs only; padded slots are not targets."""
        if mask is None:
            w = torch.ones_like(x)  # (B, 22)
        else:
            mask = torch.as_tensor(mask, device=x.device)
            if mask.shape != x.shape:
                raise ValueError(f"mask must have the states' shape {tuple(x.shape)}, got {tuple(mask.shape)}")
            w = mask.to(x.dtype)  # (B, 22)
        denom = w.sum().clamp_min(1.0)
        cfg, diff = self.config, x_hat - x  # (B, 22)
        loss = x.new_zeros(())
        if cfg.mse_weight > 0:
            loss = loss + cfg.mse_weight * (diff**2 * w).sum() / denom
        if cfg.smooth_l1_weight > 0:
            sl1 = F.smooth_l1_loss(x_hat, x, reduction="none", beta=0.01)  # (B, 22)
            loss = loss + cfg.smooth_l1_weight * (sl1 * w).sum() / denom
        if cfg.l1_weight > 0:
            loss = loss + cfg.l1_weight * (diff.abs() * w).sum() / denom
        return loss

    # -----------------------------------------------------------------------------------------
    # public tokenizer API
    # -----------------------------------------------------------------------------------------
    @torch.no_grad()
    def encode(
        self,
        states_rad: torch.Tensor,
        hand: HandArg,
        allow_unknown: bool = False,
        mask: torch.Tensor | None = None,
        encoding: EncodingConfig | None = None,
        stages: int | None = None,
    ) -> torch.Tensor:
        """(B, 22) radians -> (B, N, K * stages) int64 codes, picked as `encoding` says (None = the config's own,
        `config.encoding`; `EncodingConfig(rounds=0)` = `NEAREST_CODES`).

        With `rounds` 0 each group vector takes its nearest code (the paper's encoding); with R > 0 those codes are
        refined by R rounds of the decoder-aware search (`tokenizer.search`) over the active DoFs: `mask` (B, 22)
        bool, or each registered hand's spec when None (one stage only). `stages` (None = all of the model's): the
        codes of the first stages, `stages=1` the paper's N x K token sequence; a residual model's stage 1 is its
        own sequence (decodable alone, `decode`)."""
        return self._encode(states_rad, hand, allow_unknown, mask, encoding, stages)[0]

    @torch.no_grad()
    def encode_decode(
        self,
        states_rad: torch.Tensor,
        hand: HandArg,
        allow_unknown: bool = False,
        mask: torch.Tensor | None = None,
        encoding: EncodingConfig | None = None,
        stages: int | None = None,
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """`encode` and `decode` of its codes: ((B, N, K) codes, (B, 22) radians). The greedy search decodes its
        codes as it checks them, so this saves the decoder pass a separate `decode` would repeat."""
        codes, decoded, ids = self._encode(states_rad, hand, allow_unknown, mask, encoding, stages)
        if decoded is None:
            decoded = self._decode_latent(self._decoder_input(codes), self.hand_embed(ids))  # (B, 22) radians
        return codes, decoded

    def _encode(self, states_rad, hand, allow_unknown, mask, encoding: EncodingConfig | None, stages: int | None = None):
        """((B, N, K) codes, (B, 22) their decoded states when the search computed them else None, (B,) hand ids)."""
        x_rad = self._check_states(states_rad)  # (B, 22)
        ids = self.hand_ids(hand, x_rad.shape[0], allow_unknown)  # (B,)
        c = self.hand_embed(ids)  # (B, C)
        z = self._encode_latent(x_rad, c)  # (B, N, C)
        stages = self._stages(stages)
        codes = self._nearest_codes(z, stages)  # (B, N, K * stages) int64
        enc = self.config.encoding if encoding is None else encoding
        if not isinstance(enc, EncodingConfig):
            raise TypeError(f"encoding must be an EncodingConfig or None (the config's own), got {enc!r}")
        if not enc.rounds:
            return codes, None, ids
        if stages > 1:
            raise ValueError(f"the code search picks one stage's codes; encode with stages=1, or with the nearest "
                             f"codes (encoding=NEAREST_CODES) for all {stages} stages")  # fmt: skip
        active = self.active_dofs(ids) if mask is None else torch.as_tensor(mask, device=x_rad.device)
        if active.shape != x_rad.shape:
            raise ValueError(f"mask must have the states' shape {tuple(x_rad.shape)}, got {tuple(active.shape)}")
        if enc.method == "sweeps":
            return search_codes(self, x_rad, codes, c, active, enc.rounds, enc.sweeps), None, ids
        found = greedy_codes(self, x_rad, codes, c, active, enc.rounds, enc.changes, math.radians(enc.tolerance_deg))
        return *found, ids

    def active_dofs(self, ids: torch.Tensor) -> torch.Tensor:
        """(B,) hand ids -> (B, 22) bool active DoFs of each row's hand, from the registered hand specs. Rows of
        a hand without a registered spec (the unknown-hand row, a custom vocabulary name) get no active DoF, so
        the code search leaves them at their nearest codes (logged once per hand)."""
        from lerobot_unidextok import hands

        unique, row_of = ids.unique(return_inverse=True)  # (U,), (B,)
        masks, skipped = [], []
        for i in unique.tolist():
            name = self.config.hand_names[i] if i < self.unknown_hand_id else None
            if name is not None and name in hands.names():
                masks.append(torch.as_tensor(hands.get(name).active_mask, device=ids.device))
            else:
                masks.append(torch.zeros(self.config.state_dim, dtype=torch.bool, device=ids.device))
                skipped.append(name or "the unknown-hand row")
        new = [s for s in skipped if s not in self._search_skipped]
        if new:
            self._search_skipped.update(new)
            logger.warning(
                "code search skipped for %s (no registered hand spec tells the active DoFs): those rows get their "
                "nearest codes; pass mask=(B, 22) bool to encode() to search them",
                ", ".join(new),
            )
        return torch.stack(masks)[row_of]  # (B, 22)

    @torch.no_grad()
    def embed(self, states_rad: torch.Tensor, hand: HandArg, allow_unknown: bool = False) -> torch.Tensor:
        """(B, 22) radians -> (B, N, C) continuous encoder output before quantisation (features for probes)."""
        x_rad = self._check_states(states_rad)  # (B, 22)
        c = self.hand_embed(self.hand_ids(hand, x_rad.shape[0], allow_unknown))  # (B, C)
        return self._encode_latent(x_rad, c)  # (B, N, C)

    @torch.no_grad()
    def decode(self, codes: torch.Tensor, hand: HandArg, allow_unknown: bool = False) -> torch.Tensor:
        """(B, N, K * s) int codes of the first s stages (s = 1: the paper's (B, N, K)) -> (B, 22) radians."""
        codes = torch.as_tensor(codes, device=self.enc_pos.device)
        n, k, stages = self.config.num_tokens, self.config.num_groups, self.config.num_stages
        widths = [k * s for s in range(1, stages + 1)]
        if codes.ndim != 3 or codes.shape[1] != n or codes.shape[2] not in widths:
            shapes = " or ".join(f"(B, {n}, {w})" for w in widths)
            raise ValueError(f"codes must have shape {shapes} (stage 1 first), got {tuple(codes.shape)}")
        for i in range(codes.shape[2] // k):
            self.quantizers[i].check_indices(codes[..., i * k : (i + 1) * k])
        codes = codes.long()
        c = self.hand_embed(self.hand_ids(hand, codes.shape[0], allow_unknown))  # (B, C)
        return self._decode_latent(self._decoder_input(codes), c)  # (B, 22) radians

    def code_vectors(self, codes: torch.Tensor) -> torch.Tensor:
        """(B, N, K * s) codes -> (B, N, K * s, d) their unit-norm code vectors (each stage's own codebooks)."""
        k = self.config.num_groups
        return torch.cat([self.quantizers[i].indices_to_codes(codes[..., i * k : (i + 1) * k])
                          for i in range(codes.shape[-1] // k)], dim=-2)  # fmt: skip

    @torch.no_grad()
    def reseed_dead_codes(self) -> int:
        """Re-seed every stage's rarely used codes (training); returns how many were replaced."""
        return sum(vq.reseed_dead_codes() for vq in self.quantizers)

    @torch.no_grad()
    def add_hands(self, names: Sequence[str]) -> list[str]:
        """Grow the hand vocabulary in place (few-shot adaptation); new rows start as the unknown embedding.

        Returns the names actually added (known names are skipped).
        """
        new = [n for n in dict.fromkeys(names) if n not in self._hand_index]
        if not new:
            return []
        self.hand_embed = self.hand_embed.with_new_hands(len(new))  # (H + new + 1, C)
        self.config.hand_names = [*self.config.hand_names, *new]
        self._hand_index = {name: i for i, name in enumerate(self.config.hand_names)}
        return new

    def knows_hand(self, name: str) -> bool:
        return name in self._hand_index

    @property
    def num_codes_per_state(self) -> int:
        """Codes per hand state with every stage (`config.symbols_per_hand`)."""
        return self.config.symbols_per_hand()

    # -----------------------------------------------------------------------------------------
    # Hub loading: format check, safetensors only, strict
    # -----------------------------------------------------------------------------------------
    @classmethod
    def from_pretrained(
        cls,
        pretrained_model_name_or_path,
        *args,
        encoding: EncodingConfig | None = None,
        **kwargs,
    ) -> "UniDexTok":
        """The one door to a trained tokenizer: a checkpoint folder, a `unidextok-train` run folder (its
        `best/`), a tokenizer shipped in the package by its id (e.g. "unidextok/universal-small"; no network,
        no HF cache), or a Hub repo id (the HF cache serves it offline; an explicit `revision` always means the
        Hub). A name found nowhere is a `CheckpointNotFoundError` saying how to fix it (`pretrained.resolve`).

        `encoding`: how the loaded model encodes instead of the checkpoint's own (None keeps it; `NEAREST_CODES` =
        the nearest codes); it replaces the checkpoint's whole `EncodingConfig`."""
        name = str(pretrained_model_name_or_path)
        if kwargs.get("revision") is None:
            name = resolve(name, checkpoint=True)
        with hub_errors(str(pretrained_model_name_or_path)):
            model = super().from_pretrained(name, *args, **kwargs)
        return model.with_encoding(encoding)

    def with_encoding(self, encoding: EncodingConfig | None) -> "UniDexTok":
        """Make `encoding` this model's own (`config.encoding`, saved with it); None keeps the current one.
        Returns self."""
        if encoding is not None:
            self.config = dataclasses.replace(self.config, encoding=EncodingConfig.from_dict(encoding))
        return self

    @classmethod
    def _decode_arg(cls, expected_type, value):
        """huggingface_hub passes config.json's dict here to build the config; a file without `format_version`
        is read as `format_version=None` (refused by `UniDexTokConfig`), not as the current version."""
        if expected_type is UniDexTokConfig and isinstance(value, dict):
            return UniDexTokConfig.from_dict(value)
        return super()._decode_arg(expected_type, value)

    @classmethod
    def _from_pretrained(
        cls,
        *,
        model_id: str,
        revision: str | None,
        cache_dir,
        force_download: bool,
        local_files_only: bool,
        token,
        map_location: str = "cpu",
        strict: bool = True,
        **model_kwargs,
    ) -> "UniDexTok":
        def _fetch(filename: str) -> str:
            if os.path.isdir(model_id):
                path = os.path.join(model_id, filename)
                if not os.path.isfile(path):
                    raise FileNotFoundError(
                        f"{path} not found: a UniDexTok checkpoint folder holds config.json + model.safetensors"
                    )
                return path
            return hf_hub_download(
                repo_id=model_id, filename=filename, revision=revision, cache_dir=cache_dir,
                force_download=force_download, token=token, local_files_only=local_files_only,
            )  # fmt: skip

        if "config" not in model_kwargs:  # huggingface_hub found no config.json (it only logs that)
            _fetch(hf_constants.CONFIG_NAME)  # raises the error that says where it looked
            raise FileNotFoundError(f"{model_id}: config.json could not be read")
        model = cls(**model_kwargs)
        weights = _fetch(hf_constants.SAFETENSORS_SINGLE_FILE)
        try:
            model = cls._load_as_safetensor(model, weights, map_location, strict)
        except SafetensorError as e:  # cut short by a kill or a full disk, or not a safetensors file
            raise InvalidInputError(
                f"{weights} is damaged ({e}): load another checkpoint, or re-train / re-download this one"
            ) from e
        except RuntimeError as e:  # torch's strict load: missing, unexpected or other-shaped tensors
            reason = " ".join(str(e).split())[:400]
            raise InvalidInputError(
                f"{weights} does not fit the config.json beside it ({reason}): the folder holds files of two "
                "checkpoints, or config.json was edited; restore the checkpoint's own config.json or re-train"
            ) from e
        model.eval()
        return model


def normalisation(config: UniDexTokConfig) -> tuple[torch.Tensor, torch.Tensor]:
    """(center, scale), each (22,): x_normalised = (x_rad - center) / scale.

    "pi": center 0, scale pi (paper). "range": each joint's [lo, hi] onto [-1, 1]; joints with an empty
    range (no training hand moves them), and every joint before training fills the ranges, keep center 0 and
    scale pi.
    """
    center = torch.zeros(config.state_dim)
    scale = torch.full((config.state_dim,), ANGLE_SCALE_RAD)
    if config.input_norm == "range" and config.joint_range_rad is not None:
        rng = torch.tensor(config.joint_range_rad, dtype=torch.float32)  # (22, 2)
        half = (rng[:, 1] - rng[:, 0]) / 2
        moving = half > 1e-6
        center = torch.where(moving, rng.mean(1), center)
        scale = torch.where(moving, half, scale)
    return center, scale


def count_parameters(model: nn.Module) -> int:
    return sum(p.numel() for p in model.parameters())


__all__ = ["UniDexTok", "UniDexTokOutput", "count_parameters"]
