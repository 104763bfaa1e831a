"""Training checkpoints: Hub-format model folder + optimiser state in safetensors (no pickle)."""

import json
import logging
from pathlib import Path

import torch
from safetensors.torch import load_file, save_file

TRAINING_STATE = "training_state.json"
OPTIMIZER_STATE = "optimizer.safetensors"
RESUME_STATE = "resume_state.safetensors"  # random generators and quantiser statistics, for an exact resume

logger = logging.getLogger(__name__)


def save_checkpoint(
    model,
    directory: Path,
    optimizer: torch.optim.Optimizer | None = None,
    state: dict | None = None,
    resume_tensors: dict[str, torch.Tensor] | None = None,
) -> Path:
    """Write config.json + model.safetensors (+ optimiser tensors, a JSON training state and the tensors
    an exact resume needs beyond the weights: random generator states, non-persistent statistics)."""
    directory = Path(directory)
    directory.mkdir(parents=True, exist_ok=True)
    model.save_pretrained(directory)
    if optimizer is not None:
        tensors: dict[str, torch.Tensor] = {}
        params = [p for g in optimizer.param_groups for p in g["params"]]
        for i, p in enumerate(params):
            for key, value in optimizer.state.get(p, {}).items():
                t = value if isinstance(value, torch.Tensor) else torch.tensor(value)
                tensors[f"{i}.{key}"] = t.detach().cpu().contiguous()
        save_file(tensors, directory / OPTIMIZER_STATE)
    if resume_tensors is not None:
        save_file({k: v.detach().cpu().contiguous() for k, v in resume_tensors.items()}, directory / RESUME_STATE)
    if state is not None:
        (directory / TRAINING_STATE).write_text(json.dumps(state, indent=2))
    return directory


def load_resume_tensors(directory: Path) -> dict[str, torch.Tensor]:
    """The `resume_tensors` of `save_checkpoint`; empty for checkpoints written before they were saved."""
    path = Path(directory) / RESUME_STATE
    return load_file(path) if path.is_file() else {}


def load_optimizer_state(optimizer: torch.optim.Optimizer, directory: Path) -> None:
    """Restore optimiser tensors written by `save_checkpoint` (same parameter order)."""
    path = Path(directory) / OPTIMIZER_STATE
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found; cannot resume the optimiser (start without --resume)")
    tensors = load_file(path)
    params = [p for g in optimizer.param_groups for p in g["params"]]
    for name, t in tensors.items():
        i, key = name.split(".", 1)
        p = params[int(i)]
        optimizer.state[p][key] = t.to(p.device) if key != "step" else t
    if tensors and len({n.split(".")[0] for n in tensors}) > len(params):
        raise ValueError(f"{path} has state for more parameters than the model; the architecture changed")


def load_training_state(directory: Path) -> dict:
    path = Path(directory) / TRAINING_STATE
    if not path.is_file():
        raise FileNotFoundError(f"{path} not found; nothing to resume")
    return json.loads(path.read_text())
