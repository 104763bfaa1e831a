"""Retarget source: human hand motion -> a robot-hand dataset, with dex-retargeting on the user's URDF.

    unidextok-convert --source=retarget --input=<human UDHM dataset | keypoints .npy | folder of .npy> \
        --root=out/l10 --source_options='{"hand": "linkerhand_l10", "urdf": "<folder or file>"}'

Input, either:
1. A converted human dataset (this project's UDHM LeRobotDataset; `hand_type` "human"): each human block
   becomes MANO-21 keypoints by forward kinematics with the human spec's skeleton
   (`hands.get("human").from_udhm(state, side)`), episode by episode, side by side; with `side` given, only
   that side (only its URDF is needed; episodes without that hand are skipped).
2. MANO-21 keypoints in metres, one `(T, 21, 3)` `.npy` per episode (any frame: the retargeter aligns palm
   frames), of the `side` hand (option, default right); `fps` option (default 30).
Each keypoint sequence goes through `lerobot_unidextok.retarget.HandRetargeter` (module docstring there) and
comes out as the robot hand's native values, which the shared mapping turns into UDHM like any robot source.
Options: `hand` (a hand with a retarget spec: `lerobot_unidextok.retarget.retarget_hands()`), `urdf` (file or
folder; required), `side`, `fps`, `scaling`, `low_pass_alpha`. Needs the `retarget` extra.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
from __future__ import annotations

from functools import lru_cache
from pathlib import Path

import numpy as np

from lerobot_unidextok.constants import INFO_PATH
from lerobot_unidextok.conversion.episode import HandStream, RawEpisode
from lerobot_unidextok.conversion.registry import SetupError, register_source

HUMAN = "human"


class RetargetInputError(SetupError):
    """The retarget input is not a converted human dataset or keypoint files; the message names the path."""


@lru_cache(maxsize=2)
def _human_frames(root: str):
    from lerobot_unidextok.data import load_udhm_frames

    return load_udhm_frames(root, split=None, drop_absent=False)


@register_source("retarget")
class RetargetSource:
    license = "as the input human data's; kinematics from the user's URDF (its own license)"
    description = "human keypoint motion retargeted onto a robot hand with dex-retargeting (robot)"

    def __init__(
        self,
        hand: str | None = None,
        urdf: str | None = None,
        side: str | None = None,
        fps: float = 30.0,
        scaling: float | None = None,
        low_pass_alpha: float = 1.0,
    ) -> None:
        from lerobot_unidextok.retarget import RetargetConfig, get_retarget_spec, require_dex_retargeting

        if hand is None or urdf is None:
            raise ValueError(
                "the retarget source needs the target hand and its URDF: "
                '--source_options=\'{"hand": "linkerhand_l10", "urdf": "<URDF file or folder>"}\''
            )
        require_dex_retargeting()
        if side not in (None, "left", "right"):
            raise ValueError(f"side must be 'left' or 'right', got {side!r}")
        get_retarget_spec(hand, side or "right")  # raises listing the hands that have a URDF map
        if not Path(urdf).exists():
            raise FileNotFoundError(f"URDF {urdf} does not exist; pass the robot hand's URDF file or its folder")
        self.hand, self.urdf, self.side, self.fps = hand, str(urdf), side, float(fps)
        self.config = RetargetConfig(scaling=scaling, low_pass_alpha=low_pass_alpha)
        self._retargeters: dict = {}

    def _retargeter(self, side: str):
        from lerobot_unidextok.retarget import HandRetargeter

        if side not in self._retargeters:
            self._retargeters[side] = HandRetargeter(self.hand, self.urdf, side, self.config)
        return self._retargeters[side]

    # ----------------------------------------------------------------------------------------- #
    def list_episodes(self, input_path: str | Path) -> list:
        root = Path(input_path)
        if not root.exists():
            raise FileNotFoundError(f"retarget input {root} does not exist")
        if (root / INFO_PATH).is_file():
            frames = _human_frames(str(root))
            human = frames.hands == HUMAN
            if not human.any():
                raise RetargetInputError(
                    f"{root}: no human hand blocks (hand_type 'human'); retarget a converted human dataset "
                    f"(its hands: {sorted(set(frames.hands.tolist()))})"
                )
            if self.side is not None:
                human &= (frames.side == self.side) & frames.masks.any(axis=1)
                if not human.any():
                    raise RetargetInputError(f"{root}: no {self.side} human hand in any frame; pick the other side")
            return [f"{root}#episode={int(e)}" for e in np.unique(frames.episode_index[human])]
        files = [root] if root.is_file() else sorted(root.rglob("*.npy"))
        if not files or any(f.suffix != ".npy" for f in files):
            raise RetargetInputError(
                f"{root}: expected a converted human dataset (meta/info.json) or (T, 21, 3) keypoint .npy files"
            )
        return [str(f) for f in files]

    def read_episode(self, ref) -> RawEpisode:
        text = str(ref)
        if "#episode=" in text:
            return self._read_dataset_episode(*text.split("#episode="))
        kp = np.load(text)
        if kp.ndim != 3 or kp.shape[1:] != (21, 3):
            raise RetargetInputError(f"{text}: expected (T, 21, 3) MANO-21 keypoints in metres, got {kp.shape}")
        side = self.side or "right"
        res = self._retargeter(side).retarget(kp)
        return RawEpisode(text, self.fps, [HandStream(side, self.hand, res.native)],
                          task=f"retargeted human motion ({Path(text).stem})",
                          extra={"retarget": self._extra(res)})  # fmt: skip

    def _read_dataset_episode(self, root: str, episode: str) -> RawEpisode:
        from lerobot_unidextok import hands

        frames = _human_frames(root)
        rows = (frames.episode_index == int(episode)) & (frames.hands == HUMAN)
        streams, extra = [], {}
        sides = sorted(set(frames.side[rows].tolist()), key=["right", "left"].index)
        for side in [s for s in sides if self.side in (None, s)]:
            r = rows & (frames.side == side)
            order = np.argsort(frames.frame_index[r], kind="stable")
            state = frames.states_rad[r][order].astype(np.float64)  # (T, 22) rad
            valid = frames.masks[r][order].any(axis=1)
            keypoints = np.asarray(hands.get(HUMAN).from_udhm(state, side))  # (T, 21, 3) m
            res = self._retargeter(side).retarget(keypoints)
            streams.append(HandStream(side, self.hand, res.native, valid=valid))
            extra[side] = self._extra(res)
        return RawEpisode(f"{root}#episode={episode}", frames.fps or self.fps, streams,
                          task=f"retargeted human motion (episode {episode})", extra={"retarget": extra})  # fmt: skip

    @staticmethod
    def _extra(res) -> dict:
        return {"scaling": round(res.scaling, 4), "mean_target_error_mm": round(res.mean_target_error_mm, 2)}
