"""Data of the policy experiments: a converted whole-robot dataset as arrays, the hand inputs a policy can be
given (native values, UDHM state, tokens dequantized or embedded, 8-bit bins), action chunks and their
open-loop errors.

The arm (passthrough) columns are the same in every input; only the hand part changes. Actions are always
the converted action (arms + the UDHM slots each hand has), so every input is scored on the same targets.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from lerobot_unidextok.constants import ACTION, INFO_PATH, OBS_STATE

# Hand inputs a policy can be given, with what each is.
HAND_INPUTS: dict[str, str] = {
    "native": "the robot's native hand values (Inspire: 6 per hand in [0, 1])",
    "udhm": "the converted UDHM hand blocks (radians), no tokens",
    "tokens_dequantized": "UniDexTok codes decoded back to UDHM radians",
    "tokens_embedding": "UniDexTok code vectors (unit norm)",
    "binned_8bit": "UDHM hand blocks through per-joint 256-bin uniform binning over each hand's range",
}
TOKEN_INPUTS = ("tokens_dequantized", "tokens_embedding")


@dataclass
class RobotFrames:
    """Every frame of a converted dataset: converted state and action, episode of each row, and the layouts."""

    root: Path
    state: np.ndarray  # (N, D) converted observation.state in the action's layout: passthrough (rad) + UDHM blocks
    action: np.ndarray  # (N, D) converted action
    episode: np.ndarray  # (N,) episode index
    names: list[str]  # the D action names (and of `state`)
    hands: list[str]  # hand spec per UDHM block
    sides: list[str]
    # (N, S) the whole observation.state, what a policy reads: `state` plus the columns no action has (a simulator
    # task's object and goal columns); None = the same as `state`
    policy_state: np.ndarray | None = None

    @property
    def policy_input(self) -> np.ndarray:
        return self.state if self.policy_state is None else self.policy_state

    @property
    def passthrough_columns(self) -> np.ndarray:
        from lerobot_unidextok.blocks import passthrough_indices

        return np.asarray(passthrough_indices(self.names), dtype=np.int64)

    @property
    def block_columns(self) -> np.ndarray:
        """(22 * H,) the columns of the UDHM blocks, block after block."""
        from lerobot_unidextok.layout import HandLayout

        return HandLayout(self.hands, state_names=self.names).block_columns

    @property
    def active_block_columns(self) -> np.ndarray:
        """The UDHM columns each hand has (its active DoFs), block after block."""
        from lerobot_unidextok import hands

        mask = np.concatenate([hands.get(h).active_mask for h in self.hands])
        return self.block_columns[mask]

    @property
    def action_columns(self) -> np.ndarray:
        """What a policy predicts: the passthrough columns, then the active UDHM columns."""
        return np.concatenate([self.passthrough_columns, self.active_block_columns])

    def native_layout(self, key: str = ACTION):
        from lerobot_unidextok.data import UdhmDatasetMeta

        layout = UdhmDatasetMeta(self.root).native_layout(key)
        if layout is None:
            raise ValueError(f"{self.root}: its hands have no native joints, so it has no native layout")
        return layout

    def native_hand_columns(self, key: str = ACTION) -> np.ndarray:
        """Columns of the native vector that hold hand values (the rest are the passthrough columns)."""
        layout = self.native_layout(key)
        index = {n: i for i, n in enumerate(layout.native_names)}
        return np.array([index[c] for h in layout.hands for c in h["columns"]], dtype=np.int64)


def load_frames(root: str | Path) -> RobotFrames:
    """A converted robot dataset (passthrough columns, none for a hands-only one, + UDHM blocks; hands with
    native joints)."""
    import pandas as pd
    import pyarrow.parquet as pq

    from lerobot_unidextok.data import UdhmDatasetMeta
    from lerobot_unidextok.data.reader import data_files

    root = Path(root)
    if not (root / INFO_PATH).is_file():
        raise FileNotFoundError(f"{root / INFO_PATH} not found: pass the root of a dataset written by unidextok-convert")
    meta = UdhmDatasetMeta(root)
    layout = meta.hand_layout()
    columns = [OBS_STATE, ACTION, "episode_index", "index"]
    tables = [pq.read_table(f, columns=columns).to_pandas() for f in data_files(root)]
    df = pd.concat(tables, ignore_index=True).sort_values("index")
    state = np.stack(df[OBS_STATE].to_numpy()).astype(np.float64)
    action = np.stack(df[ACTION].to_numpy()).astype(np.float64)
    names, policy_state = list(layout.state_names), None
    action_names = list(meta.names(ACTION) or names)
    if action_names != names:  # the state holds columns no action has (a simulator task's): align it to the action
        missing = [n for n in action_names if n not in names]
        if missing:
            raise ValueError(f"{root}: action columns {missing[:4]} are not in {OBS_STATE}; no state to copy them from")
        policy_state, state = state, state[:, [names.index(n) for n in action_names]]
        names = action_names
    frames = RobotFrames(root, state, action, df["episode_index"].to_numpy(np.int64), names, layout.hands,
                         layout.sides, policy_state)  # fmt: skip
    frames.native_layout(ACTION)  # fails early for hands without native joints
    return frames


def recorded_test_episodes(root: str | Path) -> list[int]:
    """The held-out episodes the converter recorded (`meta/unidextok_conversion.json`), [] when none, or when
    the record no longer describes the dataset (edited after conversion)."""
    from lerobot_unidextok.data import UdhmDatasetMeta

    meta = UdhmDatasetMeta(root)
    return [] if meta.record_problem else list(meta.record.test_episodes)


# ---------------------------------------------------------------------------------------------
# hand inputs
# ---------------------------------------------------------------------------------------------
def hand_input(kind: str, frames: RobotFrames, tokenizer: str | Path | None = None) -> np.ndarray:
    """(N, F) float32 hand part of the policy input for every frame (the arms are added by the caller)."""
    if kind not in HAND_INPUTS:
        raise ValueError(f"unknown hand input {kind!r}; choose from {sorted(HAND_INPUTS)}")
    if kind == "native":
        layout = frames.native_layout(OBS_STATE)
        native = layout.to_native(frames.state)
        return native[:, frames.native_hand_columns(OBS_STATE)].astype(np.float32)
    blocks = frames.state[:, frames.block_columns]  # (N, 22 * H)
    if kind == "udhm":
        return blocks.astype(np.float32)
    if kind == "binned_8bit":
        return binned_blocks(blocks, frames.hands).astype(np.float32)
    if tokenizer is None:
        raise ValueError(f"hand input {kind!r} needs a tokenizer (folder or Hub repo id)")
    return token_view(frames, tokenizer, "dequantized" if kind == "tokens_dequantized" else "embedding")


def token_view(frames: RobotFrames, tokenizer: str | Path, representation: str, batch: int = 4096) -> np.ndarray:
    """(N, F) the float view the `unidextok.state_tokenizer` step adds for the whole converted state."""
    import torch

    from lerobot_unidextok.processor import UniDexTokStateTokenizerStep

    step = UniDexTokStateTokenizerStep(hand_layout=frames.hands, state_names=frames.names, pretrained=str(tokenizer),
                                       representation=representation)  # fmt: skip
    state = torch.as_tensor(frames.state, dtype=torch.float32)
    return torch.cat([step.tokenize(state[i : i + batch])[1] for i in range(0, len(state), batch)]).numpy()


def binned_blocks(blocks_rad: np.ndarray, hand_names: list[str]) -> np.ndarray:
    """(N, 22 * H) UDHM blocks -> decode(encode(x)) of 8-bit per-joint binning (experiments' reference)."""
    from experiments.unseen_data import binning_reconstruction
    from lerobot_unidextok import hands
    from lerobot_unidextok.training import HandStates

    n, h = len(blocks_rad), len(hand_names)
    rows = blocks_rad.reshape(n * h, 22)
    hands_col = np.tile(np.asarray(hand_names), n)
    masks = np.stack([hands.get(name).active_mask for name in hands_col])
    out = binning_reconstruction(HandStates(rows, hands_col, masks))
    return out.reshape(n, h * 22)


# ---------------------------------------------------------------------------------------------
# action chunks and open-loop errors
# ---------------------------------------------------------------------------------------------
def chunk_index(episode: np.ndarray, chunk: int) -> tuple[np.ndarray, np.ndarray]:
    """((N, chunk) row of the k-th future action of every row, (N, chunk) bool padded): past an episode's end
    the index repeats its last frame and is marked padded (as LeRobot's `delta_timestamps` do)."""
    n = len(episode)
    rows = np.arange(n)[:, None] + np.arange(chunk)[None, :]
    last = np.empty(n, dtype=np.int64)
    for e in np.unique(episode):
        idx = np.flatnonzero(episode == e)
        last[idx] = idx.max()
    pad = rows > last[:, None]
    return np.minimum(rows, last[:, None]), pad


def open_loop_errors(
    pred: np.ndarray, frames: RobotFrames, rows: np.ndarray, chunk: int, predicted: np.ndarray | None = None
) -> dict[str, float]:
    """Mean absolute error of (R, chunk, D) predicted converted actions for `rows`, first action and over the
    chunk (padded steps excluded): arms (deg), hands in UDHM (deg, the slots each hand has) and native units.
    `predicted`: the action columns the prediction covers (a policy of a hands-only mix predicts no arms); the
    arms' figures are left out when it covers none (a hands-only dataset or policy)."""
    index, pad = chunk_index(frames.episode, chunk)
    index, valid = index[rows], ~pad[rows]  # (R, chunk)
    target = frames.action[index]  # (R, chunk, D)
    covered = np.ones(target.shape[-1], bool) if predicted is None else predicted
    pred = np.where(covered, pred, target)  # uncovered columns are not scored (the native decode needs them)
    arms = frames.passthrough_columns[covered[frames.passthrough_columns]]
    hand_udhm = frames.active_block_columns
    layout = frames.native_layout(ACTION)
    native_hands = frames.native_hand_columns(ACTION)
    err = np.abs(pred - target)
    native_err = np.abs(layout.to_native(pred)[..., native_hands] - layout.to_native(target)[..., native_hands])
    out = {}
    for name, window in (("first", np.s_[:, :1]), ("chunk", np.s_[:, :])):
        v = valid[window]
        if len(arms):
            out[f"arms_deg_{name}"] = float(np.degrees(err[window][..., arms][v].mean()))
        out[f"hands_udhm_deg_{name}"] = float(np.degrees(err[window][..., hand_udhm][v].mean()))
        out[f"hands_native_{name}"] = float(native_err[window][v].mean())
    return out


def copy_state_prediction(frames: RobotFrames, rows: np.ndarray, chunk: int) -> np.ndarray:
    """(R, chunk, D) the reference: every future action = the current converted state."""
    return np.repeat(frames.state[rows][:, None, :], chunk, axis=1)
