"""Building and fitting the baseline tokenizers at the experiment's size."""

import logging

import numpy as np

from experiments.common import HUMAN, hand_masks, per_hand_states
from experiments.config import ExperimentConfig
from lerobot_unidextok.training import HandStates

logger = logging.getLogger(__name__)


def hand_range(hand: str, train: HandStates, mask: np.ndarray):
    """Binning limits of one hand: its spec's reachable UDHM range (human: UDHM joint limits), widened to
    the training rows where they go beyond it; unregistered hands use the training range."""
    from lerobot_unidextok import hands as registry
    from lerobot_unidextok import udhm
    from lerobot_unidextok.baselines import HandRange

    rows = train.states_rad[train.hands == hand].astype(np.float64)
    lo, hi = rows.min(0), rows.max(0)
    if hand == HUMAN:
        lo, hi = (
            np.minimum(lo, udhm.JOINT_LIMITS_RAD[:, 0]),
            np.maximum(hi, udhm.JOINT_LIMITS_RAD[:, 1]),
        )
    else:
        try:
            spec = registry.get(hand)
            for side in ("right", "left"):
                s_lo, s_hi = spec.udhm_limits_rad(side)
                lo, hi = np.minimum(lo, s_lo), np.maximum(hi, s_hi)
        except (
            KeyError,
            ValueError,
        ) as e:  # unregistered or keypoint-only hand: training range only
            logger.warning("binning range of %r from training rows only (%s)", hand, e)
    hi = np.where(mask & (hi <= lo), lo + 1e-3, hi)
    return HandRange(lo, hi, mask)


def binning(train: HandStates):
    from lerobot_unidextok.baselines import UniformBinning

    masks = hand_masks(train)
    return UniformBinning({h: hand_range(h, train, m) for h, m in masks.items()})


def unihm(cfg: ExperimentConfig, train: HandStates, paired: dict[str, np.ndarray] | None = None):
    """UniHM-style VQ-VAE on `train`; `paired[hand]` = the robot rows retargeted from `train`'s human rows
    (row for row), UniHM's own recipe. Without pairs, human rows reach the robot decoders by semantic insertion."""
    from lerobot_unidextok.baselines import UniHMConfig, UniHMTokenizer

    ucfg = UniHMConfig.from_preset(
        cfg.unihm_preset, teacher_steps=cfg.unihm_teacher_steps, rounds=cfg.unihm_rounds,
        distill_steps=cfg.unihm_round_steps, align_steps=cfg.unihm_round_steps,
        finetune_steps=cfg.unihm_finetune_steps, seed=cfg.seed, progress=cfg.progress,
        kmeans_first_step=min(100, max(1, cfg.unihm_teacher_steps // 4)),
        kmeans_every=max(1, cfg.unihm_teacher_steps // 3),
    )  # fmt: skip
    tok = UniHMTokenizer(ucfg)
    tok.fit(per_hand_states(train), hand_masks(train), paired=paired)
    return tok


UNIHM_RETARGETED, UNIHM_INSERTED = "UniHM (retargeted)", "UniHM-style (semantic insertion)"


def unihm_for(cfg: ExperimentConfig, fit: HandStates, pairs) -> tuple[object, str]:
    """(UniHM tokenizer, its label): trained per robot hand on retargeted human motion when `pairs`
    (`retargeted.RetargetedPairs`) exist, else on `fit` with semantic insertion as the stand-in."""
    if pairs is None:
        return unihm(cfg, fit), UNIHM_INSERTED
    train = HandStates.concat([pairs.human_train, pairs.train_states()])
    return unihm(cfg, train, paired={h: pairs.robot_train[h].states_rad for h in pairs.hands}), UNIHM_RETARGETED


def pca(cfg: ExperimentConfig, train: HandStates):
    """PCA of each hand's training states to `pca_components` coefficients, `pca_bits` bits each."""
    from lerobot_unidextok.baselines import PCAConfig, PCATokenizer

    tok = PCATokenizer(PCAConfig(num_components=cfg.pca_components, bits=cfg.pca_bits))
    tok.fit(per_hand_states(train), hand_masks(train))
    return tok


def quantized_ae(cfg: ExperimentConfig, train: HandStates, quantizer: str):
    """FSQ or RVQ at UniDexTok's budget (8 tokens x 8 codes x 5 bits); None when the library is missing."""
    from lerobot_unidextok.baselines import QuantizedAEConfig, QuantizedAETokenizer
    from lerobot_unidextok.baselines.quantized_ae import require_vector_quantize

    try:
        require_vector_quantize()
    except ImportError as err:
        logger.warning("%s: skipping %s", err, quantizer)
        return None
    qcfg = QuantizedAEConfig.from_preset(
        cfg.qae_preset,
        quantizer=quantizer,
        steps=cfg.qae_steps,
        seed=cfg.seed,
        progress=cfg.progress,
    )
    tok = QuantizedAETokenizer(qcfg)
    tok.fit(per_hand_states(train), hand_masks(train))
    return tok
