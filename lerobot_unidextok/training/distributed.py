"""What multi-process training needs beyond DDP's gradient averaging (accelerate / torchrun, gloo on CPU).

DDP keeps replicas equal only for what the optimiser moves with all-reduced gradients. The quantiser also
changes its codebook outside the optimiser (dead-code re-seeding from the process's own last batch and
random draws), so after such a change the main process's state is broadcast to the others
(`broadcast_from_main`), and at every evaluation `check_replicas` compares a hash of every tensor of the
model's state dict (parameters and saved buffers) across processes and stops the run, naming the
tensors, if any replica drifted. Unsaved training statistics (the quantiser's code-usage EMA and last
batch features) are each process's own and are not compared.

    accelerate launch --multi_gpu --num_processes=2 -m lerobot_unidextok.scripts.train --device=cpu ...
    torchrun --nproc_per_node=2 -m lerobot_unidextok.scripts.train --device=cpu ...

Each process draws its own batches of `batch_size` rows (sampler seed + process index): the effective
batch is `batch_size x num_processes`.
"""

from __future__ import annotations

import atexit
import hashlib

import torch
from torch import nn

__all__ = ["broadcast_from_main", "check_replicas", "leave_at_exit", "leave_process_group", "state_digests"]


def _tensors(module: nn.Module):
    yield from module.named_parameters()
    yield from module.named_buffers()


@torch.no_grad()
def broadcast_from_main(module: nn.Module) -> None:
    """Copy every parameter and buffer of `module` from process 0 to the others (no-op in one process)."""
    import torch.distributed as dist

    if not (dist.is_available() and dist.is_initialized()) or dist.get_world_size() == 1:
        return
    for _, tensor in _tensors(module):
        dist.broadcast(tensor.data, src=0)


def state_digests(module: nn.Module) -> dict[str, str]:
    """sha1 of the bytes of every state-dict tensor (exact: equal digests = bit-identical tensors)."""
    return {
        name: hashlib.sha1(t.detach().cpu().contiguous().numpy().tobytes()).hexdigest()
        for name, t in module.state_dict().items()
    }


def check_replicas(module: nn.Module, step: int) -> None:
    """Raise when the processes' copies of `module` are not bit-identical (no-op in one process)."""
    import torch.distributed as dist

    if not (dist.is_available() and dist.is_initialized()) or dist.get_world_size() == 1:
        return
    mine = state_digests(module)
    everyone: list[dict[str, str] | None] = [None] * dist.get_world_size()
    dist.all_gather_object(everyone, mine)
    differ = sorted({n for other in everyone[1:] for n in mine if other.get(n) != everyone[0].get(n)})
    if differ:
        raise RuntimeError(
            f"step {step}: model replicas differ across the {len(everyone)} processes in {differ[:8]}"
            f"{' ...' if len(differ) > 8 else ''}: a state change outside the optimiser was not synchronised "
            "(see training/distributed.py)"
        )


def leave_at_exit() -> None:
    """Register `leave_process_group` to run when the interpreter exits (once, after the group exists: an
    exit handler registered by a process that never imported torch failed in interpreter shutdown)."""
    if not getattr(leave_at_exit, "registered", False):
        atexit.register(leave_process_group)
        leave_at_exit.registered = True


def leave_process_group() -> None:
    """Destroy this process's torch.distributed group, if any (run at exit, `leave_at_exit`): a process
    that exits with its gloo group alive can abort in interpreter shutdown ("terminate called without an active
    exception", exit code -6), which accelerate then reports as a failed run."""
    from datetime import timedelta

    import torch.distributed as dist

    if dist.is_available() and dist.is_initialized():
        try:  # every process reaches the end before any tears the group (and rank 0's store) down
            dist.monitored_barrier(timeout=timedelta(seconds=120))
        finally:
            dist.destroy_process_group()
