"""OakInk-v2 reader: `anno_preview/<seq>.pkl` MANO parameters -> 21 keypoints (m) per hand, both hands.

The annotations hold no keypoints: `raw_mano[fid]` has `{rh,lh}__pose_coeffs` [1,16,4] quaternions (wxyz),
`{rh,lh}__tsl` [1,3] and `{rh,lh}__betas` [1,10]; joints come from a MANO layer (manotorch,
`rot_mode="quat"`, `center_idx=0`, `flat_hand_mean=True`) plus `tsl`. That needs the user's licensed
MANO model files, never shipped here: pass `mano_assets=<dir with models/MANO_{RIGHT,LEFT}.pkl>`
(`--source_options='{"mano_assets": "..."}'`) and install `manotorch`.
"""

from __future__ import annotations

import pickle
from pathlib import Path

import numpy as np

from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.registry import register_source

MANO_HELP = (
    "install the mano extra (pip install manotorch) and point --mano_assets to your licensed MANO files "
    "(a folder with models/MANO_RIGHT.pkl and models/MANO_LEFT.pkl from https://mano.is.tue.mpg.de)"
)
OAKINK2_FPS = 30.0  # unconfirmed upstream: frames are keyed by mocap frame id
_PREFIX = {"right": "rh", "left": "lh"}


class OakInk2FormatError(ValueError):
    """An OakInk-v2 annotation is missing, truncated or lacks a field; the message names both."""


class MissingManoError(RuntimeError):
    """OakInk-v2 needs the licensed MANO model and manotorch."""


@register_source("oakink2")
class OakInk2Source:
    license = "OakInk-v2 terms (research use); MANO model under its own licence"
    description = "OakInk-v2 bimanual manipulation: MANO parameters -> MANO-21 keypoints (human, needs MANO)"

    def __init__(self, mano_assets: str | None = None, fps: float = OAKINK2_FPS, device: str = "cpu") -> None:
        self.mano_assets = mano_assets
        self.fps = float(fps)
        self.device = device

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
        return {
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

    def read_episode(self, ref: str) -> RawEpisode:
        path = Path(ref)
        anno = _load_pickle(path)
        layers = self._mano_layers()
        import torch

        frame_ids = list(anno["mocap_frame_id_list"])
        raw = anno["raw_mano"]
        hands = []
        for side, prefix in _PREFIX.items():
            quat, tsl, betas = [], [], []
            for fid in frame_ids:
                if fid not in raw:
                    raise OakInk2FormatError(f"{path}: raw_mano has no entry for mocap frame {fid!r}")
                entry = raw[fid]
                for key in (f"{prefix}__pose_coeffs", f"{prefix}__tsl", f"{prefix}__betas"):
                    if key not in entry:
                        raise OakInk2FormatError(f"{path}: raw_mano[{fid!r}] missing field {key!r}")
                quat.append(np.asarray(entry[f"{prefix}__pose_coeffs"], dtype=np.float32).reshape(16, 4))
                tsl.append(np.asarray(entry[f"{prefix}__tsl"], dtype=np.float32).reshape(3))
                betas.append(np.asarray(entry[f"{prefix}__betas"], dtype=np.float32).reshape(10))
            with torch.no_grad():
                out = layers[side](
                    torch.from_numpy(np.stack(quat)).to(self.device), torch.from_numpy(np.stack(betas)).to(self.device)
                )
            joints = out.joints.cpu().numpy().astype(np.float64) + np.stack(tsl)[:, None, :]  # (T, 21, 3) m
            hands.append(HandStream(side=side, hand="human", state_native=joints))
        return RawEpisode(source_file=str(path), fps=self.fps, hands=hands, extra={"sequence": path.stem})


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
