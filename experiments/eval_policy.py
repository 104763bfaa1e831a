"""Open-loop errors of a `lerobot-train` checkpoint of a `<type>_udt` policy on episodes of a converted
dataset, next to copying the current state and to the mean action of the other episodes (no state at all):
the figures of docs/lerobot.md's CPU recipe.

    python experiments/eval_policy.py --checkpoint=outputs/act_udt_cpu/checkpoints/last/pretrained_model \
        --dataset=data/g1_udhm --episodes='[1,5]'

The checkpoint is reloaded as docs/lerobot.md shows (LeRobot's stock factory, its saved processors); each
frame's converted `observation.state` goes through the saved pre-processor, `predict_action_chunk` and the
saved post-processor, whose last step returns the robot's native action (checked against the converted
prediction decoded with the dataset's native layout). A policy trained on a mix of robots (`unidextok-mix`) is
scored once bound to the dataset's robot (`unidextok-deploy`): its predictions are in the mix's layout, taken
into the robot's columns by name, and only the columns it predicts are scored (a hands-only mix: the hands).
"""

from __future__ import annotations

import json
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.common import md_table


@dataclass
class EvalPolicyConfig:
    checkpoint: str = ""  # a `pretrained_model` folder written by lerobot-train
    dataset: str = ""  # the converted dataset root
    episodes: list[int] = field(default_factory=list)  # episodes scored; empty = the converter's test episodes
    output: str = ""  # optional JSON file for the figures

    def __post_init__(self) -> None:
        if not self.checkpoint or not self.dataset:
            raise ValueError("give --checkpoint=<pretrained_model folder> and --dataset=<converted dataset root>")


def checkpoint_chunks(checkpoint: str | Path, state: np.ndarray, batch: int = 256) -> tuple[np.ndarray, np.ndarray]:
    """((R, chunk, D) converted, (R, chunk, native D) native) action chunks of a reloaded checkpoint."""
    import torch
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import get_policy_class, make_pre_post_processors
    from lerobot.processor import TransitionKey

    import lerobot_policy_unidextok  # noqa: F401  registers the _udt types and the steps

    cfg = PreTrainedConfig.from_pretrained(checkpoint)
    policy = get_policy_class(cfg.type).from_pretrained(checkpoint).eval()
    pre, post = make_pre_post_processors(cfg, pretrained_path=str(checkpoint))
    converted, native = [], []
    with torch.no_grad():
        for i in range(0, len(state), batch):
            obs = pre({"observation.state": torch.as_tensor(state[i : i + batch], dtype=torch.float32)})
            chunk = policy.predict_action_chunk(obs)
            steps = list(post.step_through(chunk))
            converted.append(steps[-2][TransitionKey.ACTION].numpy())
            native.append(steps[-1][TransitionKey.ACTION].numpy())
    return np.concatenate(converted).astype(np.float64), np.concatenate(native).astype(np.float64)


def prediction_columns(policy_cfg, names: list[str]) -> tuple[np.ndarray, np.ndarray]:
    """(the dataset's action columns, the checkpoint's) of what the checkpoint predicts, matched by name: all of
    them for a policy of this dataset; the hands (and shared columns) for one of a mix bound to its robot."""
    own = list(getattr(policy_cfg, "udt_action_names", None) or names)
    index = {n: i for i, n in enumerate(own)}
    pairs = [(i, index[n]) for i, n in enumerate(names) if n in index]
    if not pairs:
        raise ValueError(f"the checkpoint predicts none of the dataset's action columns ({names[:3]}...)")
    return np.array([d for d, _ in pairs]), np.array([s for _, s in pairs])


def mean_action_prediction(frames, rows: np.ndarray, chunk: int) -> np.ndarray:
    """(R, chunk, D) the no-state reference: the mean action of the episodes not scored, at every step."""
    mean = frames.action[~np.isin(np.arange(len(frames.action)), rows)].mean(0)
    return np.broadcast_to(mean, (len(rows), chunk, mean.size)).copy()


def run(cfg: EvalPolicyConfig) -> dict:
    from lerobot.configs.policies import PreTrainedConfig

    from experiments.policy_data import (
        copy_state_prediction,
        load_frames,
        open_loop_errors,
        recorded_test_episodes,
    )

    frames = load_frames(cfg.dataset)
    episodes = cfg.episodes or recorded_test_episodes(cfg.dataset)
    if not episodes:
        raise ValueError(f"{cfg.dataset} records no test episodes; pass --episodes='[...]'")
    rows = np.flatnonzero(np.isin(frames.episode, episodes))
    import lerobot_policy_unidextok  # noqa: F401  registers the _udt config types before the config is read

    policy_cfg = PreTrainedConfig.from_pretrained(cfg.checkpoint)
    chunk = policy_cfg.chunk_size
    if getattr(policy_cfg, "udt_hand_vocabulary", None) and not policy_cfg.udt_fixed_hand_ids:
        raise ValueError(
            f"{cfg.checkpoint} was trained on a mix of robots: bind it to {cfg.dataset}'s robot first "
            f"(unidextok-deploy --checkpoint={cfg.checkpoint} --robot={cfg.dataset} --output=...)"
        )
    t0 = time.process_time()
    own, native = checkpoint_chunks(cfg.checkpoint, frames.policy_input[rows])
    cpu = time.process_time() - t0
    dataset_cols, own_cols = prediction_columns(policy_cfg, frames.names)
    converted = np.zeros((*own.shape[:2], len(frames.names)))  # the prediction in the dataset's action columns
    converted[..., dataset_cols] = own[..., own_cols]
    covered = np.isin(np.arange(len(frames.names)), dataset_cols)
    layout = frames.native_layout()
    returned = (getattr(policy_cfg, "udt_native_layout", None) or {}).get("native_names") or layout.native_names
    decoded = layout.to_native(converted)[..., [layout.native_names.index(n) for n in returned]]
    gap = float(np.abs(decoded - native).max()) if native.shape == decoded.shape else float("inf")
    if gap > 1e-4:
        raise RuntimeError(f"the post-processor's native action differs from the decoded prediction (max {gap})")
    result = {
        "checkpoint": str(cfg.checkpoint), "dataset": str(cfg.dataset), "episodes": list(episodes), "rows": len(rows),
        "chunk_size": chunk, "native_width": int(native.shape[-1]), "inference_cpu_ms_per_frame": 1000 * cpu / len(rows),
        "policy": open_loop_errors(converted, frames, rows, chunk, covered),
        "copy_state": open_loop_errors(copy_state_prediction(frames, rows, chunk), frames, rows, chunk, covered),
        "mean_action": open_loop_errors(mean_action_prediction(frames, rows, chunk), frames, rows, chunk, covered),
    }  # fmt: skip
    if cfg.output:
        Path(cfg.output).write_text(json.dumps(result, indent=2))
    return result


def markdown(result: dict) -> str:
    metrics = list(result["policy"])
    rows = [[name, *[f"{result[name][m]:.4f}" if "native" in m else f"{result[name][m]:.2f}" for m in metrics]]
            for name in ("policy", "copy_state", "mean_action")]  # fmt: skip
    return "\n".join([
        f"Open-loop MAE on episodes {result['episodes']} ({result['rows']} frames, chunk {result['chunk_size']}, "
        f"native action width {result['native_width']}): arms deg, hands UDHM deg and native units.", "",
        md_table(["prediction", *metrics], rows),
    ])  # fmt: skip


def main(argv: list[str] | None = None) -> None:
    runtime.cli(EvalPolicyConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
