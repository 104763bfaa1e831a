"""Protocol (b) data: human motion retargeted onto robot hands, paired frame for frame, train / held-out.

UniHM trains per robot hand on human motion retargeted to it (`baselines.unihm`, `paired=`); protocol (b)
scores every tokenizer on the retargeted held-out human motion. The human motion is the real clip when the
experiment runs on real data (its keypoints go straight to the retargeter), else the human rows of the
experiment's data (keypoints by forward kinematics of their UDHM states with the human spec's skeleton).
Retargeting runs once per (keypoints, hand, spec, URDF) and is cached under `data_dir/retargeted/`.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from experiments.config import ExperimentConfig
from lerobot_unidextok.training import HandStates
from lerobot_unidextok.utils.files import fingerprint

logger = logging.getLogger(__name__)
HUMAN = "human"


@dataclass
class RetargetedPairs:
    """Human rows and, per robot hand, the retargeted robot rows in the same order."""

    human_train: HandStates
    human_test: HandStates
    robot_train: dict[str, HandStates]  # hand -> rows aligned with human_train
    robot_test: dict[str, HandStates]  # hand -> rows aligned with human_test
    target_error_mm: dict[str, float]  # mean |robot - scaled human| wrist -> target vector error
    source: str  # where the human motion came from

    @property
    def hands(self) -> list[str]:
        return sorted(self.robot_train)

    def train_states(self) -> HandStates:
        return HandStates.concat([self.robot_train[h] for h in self.hands])

    def test_states(self) -> HandStates:
        return HandStates.concat([self.robot_test[h] for h in self.hands])


def retarget_cached(cfg: ExperimentConfig, keypoints_m: np.ndarray, hand: str) -> tuple[np.ndarray, float] | None:
    """(T, 22) UDHM of `keypoints_m` (right hand) retargeted onto `hand`, and the mean target error (mm).
    None (with a warning) when no URDF of the hand is under urdf_dir or dex-retargeting is not installed."""
    from lerobot_unidextok.hands import SPECS_DIR
    from lerobot_unidextok.retarget import HandRetargeter, URDFError

    try:
        retargeter = HandRetargeter(hand, cfg.urdf_root, "right")
    except (URDFError, ImportError) as e:
        logger.warning("%s not retargeted: %s", hand, e)
        return None
    key = fingerprint(np.ascontiguousarray(keypoints_m).tobytes(), (SPECS_DIR / f"{hand}.yaml").read_bytes(),
               retargeter.urdf_path.read_bytes(), Path(__file__).read_bytes())  # fmt: skip
    cache = Path(cfg.data_dir) / "retargeted" / f"{hand}_{key}.npz"
    if cache.is_file():
        z = np.load(cache)
        return z["udhm_rad"], float(z["error_mm"])
    res = retargeter.retarget(keypoints_m)
    cache.parent.mkdir(parents=True, exist_ok=True)
    np.savez(cache, udhm_rad=res.udhm_rad, error_mm=res.mean_target_error_mm, scaling=res.scaling)
    logger.info("retargeted %d frames onto %s: mean target error %.1f mm, scale %.3f",
                len(keypoints_m), hand, res.mean_target_error_mm, res.scaling)  # fmt: skip
    return res.udhm_rad, res.mean_target_error_mm


def _robot_rows(udhm_rad: np.ndarray, hand: str, episodes: np.ndarray | None) -> HandStates:
    from lerobot_unidextok import hands as registry

    n = len(udhm_rad)
    return HandStates(udhm_rad, np.full(n, hand), np.tile(registry.get(hand).active_mask, (n, 1)), episodes)


def retargeted_pairs(cfg: ExperimentConfig, data) -> RetargetedPairs | None:
    """Protocol (b) data for `data` (an `ExperimentData`), or None when nothing could be retargeted."""
    from lerobot_unidextok import hands as registry

    if data.clip is not None:  # real: the clip's own keypoints, split into segments
        clip = data.clip
        human_train, human_test = clip.human_states(test=False), clip.human_states(test=True)
        kp_train, kp_test = clip.keypoints_m[~clip.test], clip.keypoints_m[clip.test]
        source = "real human clip (dex-retargeting/human_joint_right.npy), held-out segments"
    else:
        if HUMAN not in data.train.hand_names() or HUMAN not in data.test.hand_names():
            logger.info("no human rows in the data: protocol (b) skipped")
            return None
        human_train, human_test = data.train.only(HUMAN), data.test.only(HUMAN)
        skel_fk = registry.get(HUMAN)
        kp_train = np.asarray(skel_fk.from_udhm(human_train.states_rad.astype(np.float64), "right"))
        kp_test = np.asarray(skel_fk.from_udhm(human_test.states_rad.astype(np.float64), "right"))
        source = "human rows of the experiment data (FK with the human skeleton), held-out split"
    robot_train, robot_test, errors = {}, {}, {}
    for hand in cfg.retarget_hands:
        both = [retarget_cached(cfg, kp, hand) for kp in (kp_train, kp_test)]
        if any(b is None for b in both):
            continue
        (tr, e_tr), (te, e_te) = both
        robot_train[hand] = _robot_rows(tr, hand, human_train.episode_index)
        robot_test[hand] = _robot_rows(te, hand, human_test.episode_index)
        errors[hand] = (e_tr * len(tr) + e_te * len(te)) / (len(tr) + len(te))
    if not robot_train:
        return None
    return RetargetedPairs(human_train, human_test, robot_train, robot_test, errors, source)
