"""Names shared by every layer: UDHM joints, MANO-21 keypoints, LeRobot feature keys and dataset files.

Layer 0: imports nothing from this package.
"""

from __future__ import annotations

import math
from typing import Literal

# ---------------------------------------------------------------------------------------------
# UDHM: the 22-DoF Unified Dexterous Hand Model state, in this fixed order.
# Signs: flexion positive toward the palm; abduction positive toward the thumb side of a right
# hand (left hands are mirrored into the right-hand frame before IK). Zero = flat hand, fingers
# together.
# ---------------------------------------------------------------------------------------------
UDHM_JOINT_NAMES: tuple[str, ...] = (
    "thumb_cmc_flex",
    "thumb_cmc_spread",
    "thumb_mcp_flex",
    "thumb_mcp_abd",
    "thumb_ip_flex",
    "index_mcp_abd",
    "index_mcp_flex",
    "index_pip_flex",
    "index_dip_flex",
    "middle_mcp_abd",
    "middle_mcp_flex",
    "middle_pip_flex",
    "middle_dip_flex",
    "ring_mcp_abd",
    "ring_mcp_flex",
    "ring_pip_flex",
    "ring_dip_flex",
    "pinky_metacarpal_twist",
    "pinky_mcp_abd",
    "pinky_mcp_flex",
    "pinky_pip_flex",
    "pinky_dip_flex",
)
UDHM_DIM = len(UDHM_JOINT_NAMES)  # 22
UDHM_INDEX: dict[str, int] = {name: i for i, name in enumerate(UDHM_JOINT_NAMES)}

# Fixed normaliser of the tokenizer: x_normalised = angles_rad / ANGLE_SCALE_RAD (no dataset stats).
ANGLE_SCALE_RAD = math.pi

# ---------------------------------------------------------------------------------------------
# MANO-21 keypoints (= OpenPose = MediaPipe = DexYCB joint_3d order).
# ---------------------------------------------------------------------------------------------
FINGERS: tuple[str, ...] = ("thumb", "index", "middle", "ring", "pinky")
KEYPOINT_NAMES: tuple[str, ...] = (
    "wrist",
    "thumb_cmc", "thumb_mcp", "thumb_ip", "thumb_tip",
    "index_mcp", "index_pip", "index_dip", "index_tip",
    "middle_mcp", "middle_pip", "middle_dip", "middle_tip",
    "ring_mcp", "ring_pip", "ring_dip", "ring_tip",
    "pinky_mcp", "pinky_pip", "pinky_dip", "pinky_tip",
)  # fmt: skip
NUM_KEYPOINTS = len(KEYPOINT_NAMES)  # 21
KEYPOINT_PARENTS: tuple[int, ...] = (-1, 0, 1, 2, 3, 0, 5, 6, 7, 0, 9, 10, 11, 0, 13, 14, 15, 0, 17, 18, 19)
FINGERTIP_INDICES: tuple[int, ...] = (4, 8, 12, 16, 20)

# ---------------------------------------------------------------------------------------------
# LeRobot feature keys written by the converters and read by training and the processor step.
# ---------------------------------------------------------------------------------------------
OBS_STATE = "observation.state"
ACTION = "action"
HAND_TYPE_KEY = "hand_type"  # string feature: hand spec name(s) of the frame, e.g. "inspire_rh56"
UDHM_MASK_KEY = "udhm_mask"  # bool feature: which UDHM slots are real DoFs of the source hand
OBS_HAND_TOKENS = "observation.hand_tokens"  # int64 codes added by the processor step
OBS_HAND_TOKEN_FEATURES = "observation.environment_state"  # float view of the tokens for policies
# int64 (H,) per frame of a mixed dataset (unidextok-mix): each block's hand as an index into the record's
# `hand_vocabulary`, -1 where the block holds no hand; the tokenizer step reads it and the policy never does
OBS_HAND_IDS = "observation.hand_ids"
# A robot or simulator may say its observation.state is its native layout (1.0): the native step then never takes
# it for the converted layout, even when both are as wide (a Shadow hand's 22 joints), and refuses any other width.
OBS_STATE_IS_NATIVE = "observation.state_is_native"
PASSTHROUGH_MASK_KEY = "passthrough_mask"  # bool feature of a mix with --keep=all: which common columns are real

SIDES: tuple[str, ...] = ("right", "left")

# How a hand's native joints fill the 22 UDHM slots: by meaning ("semantic", the paper's mapping) or in
# native order with zeros after ("append_pad", the ablation).
UdhmMapping = Literal["semantic", "append_pad"]
MAPPINGS: tuple[UdhmMapping, ...] = ("semantic", "append_pad")

# ---------------------------------------------------------------------------------------------
# Files of a LeRobotDataset v3.0 folder (paths relative to its root) and the record this package adds.
# ---------------------------------------------------------------------------------------------
INFO_PATH = "meta/info.json"
EPISODES_META_GLOB = "meta/episodes/chunk-*/file-*.parquet"  # per-episode metadata: lengths, stats
DATA_GLOB = "data/chunk-*/file-*.parquet"
# settings of the conversion, its test episodes, per-episode records and the native layout
CONVERSION_PATH = "meta/unidextok_conversion.json"
# beside the raw files of a synthetic sample (`samples`): per-frame gesture labels and
# `"synthetic": true`, which marks the converted dataset synthetic
SAMPLE_LABELS_FILE = "gestures.json"
