"""`Skeleton`: the rigid palm (5 base offsets) and 15 bone lengths that UDHM FK needs besides angles."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from lerobot_unidextok.udhm.frames import BASE_INDICES, palm_frame, to_canonical

# ---------------------------------------------------------------------------------------------
# Canonical adult default (metres, right-hand canonical frame, see frames.py).
# Lengths: medians of keypoint-to-keypoint distances on real MediaPipe-tracked hands
# (../shared/notes/hand-specs.md, "Canonical adult lengths", MediaPipe column, mid-range of the
# two clips). Directions of the palm offsets: median over the 621 frames of dexsuite/dex-retargeting
# `human_joint_right.pkl` in the clip's own frame (+z = wrist -> middle MCP), rescaled to those lengths;
# `default()` re-expresses them in the knuckle-row palm frame of `frames.py` (a 5.4 deg turn about x).
# ---------------------------------------------------------------------------------------------
_DEFAULT_PALM_OFFSETS_M = (
    np.array(
        [
            [14.0, 27.7, 26.7],  # thumb CMC   |41.0 mm|
            [1.7, 26.2, 97.0],  # index MCP   |100.5 mm|
            [-3.3, 0.0, 98.9],  # middle MCP  |99.0 mm| (y = 0 in the clip's frame)
            [2.0, -22.2, 92.4],  # ring MCP    |95.0 mm|
            [7.7, -38.3, 75.5],  # pinky MCP   |85.0 mm|
        ]
    )
    * 1e-3
)
_DEFAULT_BONE_LENGTHS_M = (
    np.array(
        [
            [34.5, 36.5, 33.0],  # thumb  CMC->MCP, MCP->IP, IP->tip
            [29.0, 19.0, 28.0],  # index  MCP->PIP, PIP->DIP, DIP->tip
            [39.0, 27.0, 25.0],  # middle
            [32.5, 25.0, 24.0],  # ring
            [23.0, 22.0, 19.0],  # pinky
        ]
    )
    * 1e-3
)

MIN_BONE_LENGTH_M = 1e-6  # shorter bones are treated as zero-length (invalid)


@dataclass
class Skeleton:
    """Rigid palm plus finger bone lengths, in the right-hand canonical frame (see `frames.py`).

    palm_offsets_m:  (..., 5, 3) thumb CMC, index, middle, ring, pinky MCP relative to the wrist.
    bone_lengths_m:  (..., 5, 3) per finger, in keypoint order: thumb CMC->MCP, MCP->IP, IP->tip;
                     fingers MCP->PIP, PIP->DIP, DIP->tip.
    Leading dims (one skeleton per frame, per sequence, ...) broadcast against the angles in FK.
    Arrays may be numpy (converted to float64) or torch tensors (kept, e.g. for learnable skeletons).
    Left hands use the skeleton of their mirror-image right hand.
    """

    palm_offsets_m: np.ndarray | torch.Tensor
    bone_lengths_m: np.ndarray | torch.Tensor

    def __post_init__(self) -> None:
        if not isinstance(self.palm_offsets_m, torch.Tensor):
            self.palm_offsets_m = np.asarray(self.palm_offsets_m, dtype=np.float64)
        if not isinstance(self.bone_lengths_m, torch.Tensor):
            self.bone_lengths_m = np.asarray(self.bone_lengths_m, dtype=np.float64)
        for name in ("palm_offsets_m", "bone_lengths_m"):
            shape = tuple(getattr(self, name).shape)
            if shape[-2:] != (5, 3):
                raise ValueError(f"Skeleton.{name} must have shape (..., 5, 3), got {shape}")
        offsets = _as_numpy(self.palm_offsets_m)
        bones = _as_numpy(self.bone_lengths_m)
        if not (np.isfinite(offsets).all() and np.isfinite(bones).all()):
            raise ValueError("Skeleton contains NaN/inf; build it from finite keypoints (mask missing frames)")
        bad = bones <= MIN_BONE_LENGTH_M
        if bad.any():
            where = [tuple(int(i) for i in ix) for ix in np.argwhere(bad)[:5]]
            raise ValueError(
                f"Skeleton has zero or negative bone lengths at (..., finger, segment) {where}: "
                "every bone must be longer than 1e-6 m; check for duplicated keypoints or wrong units"
            )
        pinky = np.linalg.norm(offsets[..., 4, :], axis=-1)
        if (pinky <= MIN_BONE_LENGTH_M).any():
            raise ValueError("Skeleton pinky MCP offset is zero; it defines the pinky twist axis and must be > 1e-6 m")

    # ----------------------------------------------------------------------------------------- #
    @classmethod
    def default(cls) -> Skeleton:
        """Canonical adult right hand (tracked-hand medians, wrist -> middle MCP = 99 mm)."""
        return cls(_DEFAULT_PALM_OFFSETS_M.copy(), _DEFAULT_BONE_LENGTHS_M.copy()).canonicalized()

    def canonicalized(self) -> Skeleton:
        """The same hand with its palm offsets re-expressed in its own fitted palm frame.

        IK measures angles in the palm frame fitted to the keypoints, so FK -> IK -> FK recovers the
        angles exactly only for canonical skeletons (those from `from_keypoints` and `default` are).
        """
        offsets = _as_numpy(self.palm_offsets_m)
        kp = np.zeros((*offsets.shape[:-2], 21, 3))
        kp[..., BASE_INDICES, :] = offsets
        rot = palm_frame(kp)  # (..., 3, 3)
        return Skeleton(offsets @ rot, _as_numpy(self.bone_lengths_m).copy())

    @classmethod
    def from_keypoints(cls, keypoints_m: np.ndarray, per_frame: bool = True, side: str = "right") -> Skeleton:
        """Skeleton measured on keypoints (..., 21, 3) m: one per frame, or the median over all frames."""
        kp = np.asarray(keypoints_m, dtype=np.float64)
        if kp.shape[-2:] != (21, 3):
            raise ValueError(f"keypoints_m must have shape (..., 21, 3), got {kp.shape}")
        if not np.isfinite(kp).all():
            raise ValueError("keypoints_m contains NaN/inf; drop or mask missing frames before measuring a skeleton")
        local = to_canonical(kp, palm_frame(kp, side), side)  # (..., 21, 3)
        offsets = local[..., BASE_INDICES, :]  # (..., 5, 3)
        chains = local[..., 1:, :].reshape(*local.shape[:-2], 5, 4, 3)
        bones = np.linalg.norm(np.diff(chains, axis=-2), axis=-1)  # (..., 5, 3)
        if not per_frame:
            offsets = np.median(offsets.reshape(-1, 5, 3), axis=0)
            bones = np.median(bones.reshape(-1, 5, 3), axis=0)
        return cls(offsets, bones)

    def scaled(self, factor: float) -> Skeleton:
        """Uniformly scaled copy (factor > 0)."""
        if not factor > 0:
            raise ValueError(f"scale factor must be > 0, got {factor}")
        return Skeleton(self.palm_offsets_m * factor, self.bone_lengths_m * factor)

    @property
    def batch_shape(self) -> tuple[int, ...]:
        return tuple(self.bone_lengths_m.shape[:-2])

    def hand_length_m(self) -> np.ndarray:
        """Wrist -> middle fingertip along the straight middle finger, (...)."""
        return np.linalg.norm(_as_numpy(self.palm_offsets_m)[..., 2, :], axis=-1) + _as_numpy(self.bone_lengths_m)[
            ..., 2, :
        ].sum(-1)


def _as_numpy(x: np.ndarray | torch.Tensor) -> np.ndarray:
    return x.detach().cpu().numpy() if isinstance(x, torch.Tensor) else np.asarray(x)
