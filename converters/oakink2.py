"""OakInk-v2 reader: `anno_preview/<seq>.pkl` MANO parameters -> 21 keypoints (m) per hand, both hands.

Follows oakink/OakInk2-PreviewTool: the annotation layout of `README.md` and
`src/oakink2_toolkit/dataset.py` (`_collect_mano`: `raw_mano[fid]` per `mocap_frame_id_list` id),
joints as `src/oakink2_preview/launch/viz/seg_3d.py` computes them (manotorch `ManoLayer(rot_mode="quat",
center_idx=0, use_pca=False, flat_hand_mean=True)`, `joints + tsl`), and the frame rate of the mocap ids,
`FPS_MOCAP = 120` (`src/oakink2_toolkit/meta.py`, `dataset/stream_preview.py`; images are 30 fps).

`raw_mano[fid]` has `{rh,lh}__pose_coeffs` [1,16,4] quaternions (wxyz), `{rh,lh}__tsl` [1,3] and
`{rh,lh}__betas` [1,10]. Episodes are at 120 fps, or 120 / `subsample` (`subsample=4`: 30 fps); a mocap
id missing inside the sequence is a frame without hands (`valid=False`). Joints need the user's licensed
MANO model files, never shipped here: pass `mano_assets=<dir with models/MANO_{RIGHT,LEFT}.pkl>`
(`--source_options='{"mano_assets": "..."}'`) and install `manotorch`. `mano_layer="module:factory"`
replaces manotorch by another layer with the same call (tests use a stand-in):
`factory(side, mano_assets, device)(pose_coeffs (T,16,4), betas (T,10)) -> joints (T,21,3)` in metres.
"""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np

from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.registry import register_source
from lerobot_unidextok.errors import SourceFormatError, UnavailableError

MANO_HELP = (
    "install the mano extra (pip install manotorch) and point --mano_assets to your licensed MANO files "
    "(a folder with models/MANO_RIGHT.pkl and models/MANO_LEFT.pkl from https://mano.is.tue.mpg.de)"
)
FPS_MOCAP = 120  # OakInk2-PreviewTool src/oakink2_toolkit/meta.py
_PREFIX = {"right": "rh", "left": "lh"}


class OakInk2FormatError(SourceFormatError):
    """An OakInk-v2 annotation is missing, truncated or lacks a field; the message names both."""


class MissingManoError(UnavailableError):
    """OakInk-v2 needs the licensed MANO model and manotorch."""


@register_source("oakink2")
class OakInk2Source:
    license = "OakInk-v2 terms (research use); MANO model under its own licence"
    description = "OakInk-v2 bimanual manipulation: MANO parameters -> MANO-21 keypoints (human, needs MANO)"

    def __init__(
        self, mano_assets: str | None = None, subsample: int = 1, device: str = "cpu", mano_layer: str | None = None
    ) -> None:
        if int(subsample) != subsample or subsample < 1 or FPS_MOCAP % int(subsample):
            divisors = [k for k in range(1, FPS_MOCAP + 1) if FPS_MOCAP % k == 0]
            raise ValueError(
                f"subsample must divide the {FPS_MOCAP} Hz mocap rate so the frame rate stays an integer; "
                f"got {subsample!r}, use one of {divisors}"
            )
        self.mano_assets = mano_assets
        self.subsample = int(subsample)
        self.fps = FPS_MOCAP / self.subsample
        self.device = device
        self.mano_layer = mano_layer

    def list_episodes(self, input_path: str | Path) -> list[str]:
        root = Path(input_path)
        folder = root / "anno_preview" if (root / "anno_preview").is_dir() else root
        if root.is_file():
            return [str(root)]
        files = sorted(str(p) for p in folder.glob("*.pkl"))
        if not files:
            raise OakInk2FormatError(f"{root}: no anno_preview/*.pkl annotation files found")
        return files

    def _mano_layers(self) -> dict:
        if self.mano_layer:
            return _custom_layers(self.mano_layer, self.mano_assets, self.device)
        if not self.mano_assets:
            raise MissingManoError(f"OakInk-v2 stores MANO parameters only; no mano_assets given: {MANO_HELP}")
        assets = Path(self.mano_assets)
        missing = [f for f in ("MANO_RIGHT.pkl", "MANO_LEFT.pkl") if not (assets / "models" / f).is_file()]
        if missing:
            raise MissingManoError(f"MANO files {missing} not found under {assets / 'models'}: {MANO_HELP}")
        try:
            from manotorch.manolayer import ManoLayer
        except ImportError as exc:
            raise MissingManoError(f"manotorch is not installed: {MANO_HELP}") from exc
        layers = {
            side: ManoLayer(
                rot_mode="quat",
                side=side,
                center_idx=0,
                use_pca=False,
                flat_hand_mean=True,
                mano_assets_root=str(assets),
            ).to(self.device)
            for side in ("right", "left")
        }
        return {side: (lambda q, b, layer=layer: layer(q, b).joints) for side, layer in layers.items()}

    def read_episode(self, ref: str) -> RawEpisode:
        path = Path(ref)
        anno = _load_pickle(path)
        layers = self._mano_layers()
        import torch

        ids = [int(f) for f in anno["mocap_frame_id_list"]]
        if not ids:
            raise OakInk2FormatError(f"{path}: mocap_frame_id_list is empty")
        raw = anno["raw_mano"]
        first, last = min(ids), max(ids)
        frame_ids = list(range(first, last + 1, self.subsample))  # the 120 Hz clock, subsampled
        present = np.array([fid in raw for fid in frame_ids])
        if not present.any():
            raise OakInk2FormatError(f"{path}: raw_mano has no entry for the mocap frames {first}..{last}")
        hands = []
        for side, prefix in _PREFIX.items():
            quat, tsl, betas = [], [], []
            for fid in np.asarray(frame_ids)[present]:
                entry = raw[int(fid)]
                for key in (f"{prefix}__pose_coeffs", f"{prefix}__tsl", f"{prefix}__betas"):
                    if key not in entry:
                        raise OakInk2FormatError(f"{path}: raw_mano[{int(fid)}] missing field {key!r}")
                quat.append(_array(entry[f"{prefix}__pose_coeffs"]).reshape(16, 4))
                tsl.append(_array(entry[f"{prefix}__tsl"]).reshape(3))
                betas.append(_array(entry[f"{prefix}__betas"]).reshape(10))
            with torch.no_grad():
                joints = layers[side](
                    torch.from_numpy(np.stack(quat)).to(self.device), torch.from_numpy(np.stack(betas)).to(self.device)
                )
            keypoints = np.zeros((len(frame_ids), 21, 3))
            keypoints[present] = joints.cpu().numpy().astype(np.float64) + np.stack(tsl)[:, None, :]  # (T, 21, 3) m
            hands.append(HandStream(side=side, hand="human", state_native=keypoints, valid=present.copy()))
        return RawEpisode(
            source_file=str(path),
            fps=self.fps,
            hands=hands,
            extra={"sequence": path.stem},
            source_episode={"mocap_frames": [first, last], "subsample": self.subsample},
        )


def _array(value) -> np.ndarray:
    """A float32 array of a pickled value (torch tensors in the real annotations, arrays elsewhere)."""
    if hasattr(value, "detach"):
        value = value.detach().cpu().numpy()
    return np.asarray(value, dtype=np.float32)


def _custom_layers(target: str, mano_assets: str | None, device: str) -> dict:
    import importlib

    module, sep, name = target.partition(":")
    if not sep:
        raise MissingManoError(f"mano_layer must be 'module:factory', got {target!r}")
    try:
        factory = getattr(importlib.import_module(module), name)
    except (ImportError, AttributeError) as exc:
        raise MissingManoError(f"mano_layer {target!r} cannot be imported: {exc}") from exc
    return {side: factory(side, mano_assets, device) for side in ("right", "left")}


def _load_pickle(path: Path) -> dict:
    try:
        with open(path, "rb") as f:
            anno = pickle.load(f)  # noqa: S301 - the user's own downloaded annotation file
    except FileNotFoundError as exc:
        raise OakInk2FormatError(f"{path}: missing") from exc
    except (pickle.UnpicklingError, EOFError, AttributeError, ValueError) as exc:
        raise OakInk2FormatError(f"{path}: unreadable or truncated pickle ({exc})") from exc
    if not isinstance(anno, dict):
        raise OakInk2FormatError(f"{path}: expected a dict annotation, got {type(anno).__name__}")
    for key in ("mocap_frame_id_list", "raw_mano"):
        if key not in anno:
            raise OakInk2FormatError(f"{path}: missing field {key!r}")
    return anno
