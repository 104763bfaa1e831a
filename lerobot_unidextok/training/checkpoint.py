"""Training checkpoints: Hub-format model folder + optimiser state in safetensors (no pickle).

Every checkpoint is written into a hidden sibling folder and renamed into place (`utils/files.replace_folder`),
so a kill mid-save leaves the previous checkpoint whole (`utils/files.recover_folder` tidies what it left);
`training_state.json`, written last, records a hash of every file beside it, and `check_checkpoint` refuses a
folder whose files disagree with it. Ctrl-C or SIGTERM during a save (raised as an exception by the command
line, `utils/cli.run_cli`) removes the unfinished folder, and is held back while the finished one is renamed
into place, so an interrupted run leaves no temp folder and never a checkpoint set aside."""

import contextlib
import hashlib
import json
import logging
import shutil
import signal
import threading
from collections.abc import Iterator
from pathlib import Path

import torch
from safetensors.torch import load_file, save_file

from lerobot_unidextok.data.destination import DestinationError, enclosing_unit
from lerobot_unidextok.errors import InvalidInputError, MissingInputError
from lerobot_unidextok.utils.files import recover_folder, replace_folder, temp_sibling

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
    target = Path(directory)
    unit = enclosing_unit(target)
    if unit is not None:  # another command (a conversion, a mix) finished into the run folder while this run trained
        raise DestinationError(
            f"{unit[0]} is now {unit[1].value} (another command wrote there while this run trained): {target.name}/ is "
            "not written inside it; train again into another --output_dir"
        )
    target.parent.mkdir(parents=True, exist_ok=True)
    for note in recover_folder(target):
        logger.warning(note)
    directory = temp_sibling(target)
    try:
        directory.mkdir()
        _write(directory, model, optimizer, state, resume_tensors)
        with signals_deferred():  # the two renames of a replacement: never cut between them by Ctrl-C or SIGTERM
            replace_folder(directory, target)
    except BaseException:  # also KeyboardInterrupt and utils.cli.Terminated (SIGTERM): nothing half-written stays
        with signals_deferred():
            shutil.rmtree(directory, ignore_errors=True)
        raise
    return target


@contextlib.contextmanager
def signals_deferred() -> Iterator[None]:
    """Ctrl-C and SIGTERM held back while the block runs, and raised again when it ends, so the block is never cut
    by their handlers (KeyboardInterrupt, `utils.cli.Terminated`). Python runs signal handlers in the main thread
    only, whichever thread the signal reached (masking it with pthread_sigmask in the main thread is not enough:
    a signal sent to the process then reaches another of its threads); elsewhere there is nothing to hold back."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    previous = {sig: signal.signal(sig, lambda signum, _frame: caught.append(signum)) for sig in _HELD}
    try:
        yield
    finally:
        for sig, handler in previous.items():
            signal.signal(sig, signal.SIG_DFL if handler is None else handler)  # None: set outside Python
        if caught:
            signal.raise_signal(caught[0])  # now its own handler runs


_HELD = (signal.SIGINT, signal.SIGTERM)


def _write(directory: Path, model, optimizer: torch.optim.Optimizer | None, state: dict | None,
           resume_tensors: dict[str, torch.Tensor] | None) -> None:  # fmt: skip
    """The files of one checkpoint, into the (new, empty) folder `directory`."""
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
        files = {p.name: _sha1(p) for p in sorted(directory.iterdir()) if p.suffix == ".safetensors"}
        (directory / TRAINING_STATE).write_text(json.dumps({**state, "files": files}, indent=2))


def check_checkpoint(directory: Path) -> dict:
    """The training state of a checkpoint folder, after checking every file it lists has the recorded hash
    (a folder mixed from two saves, or a truncated file, is refused with the fix)."""
    state = load_training_state(directory)
    for name, digest in state.get("files", {}).items():  # absent in checkpoints written before hashes were kept
        path = Path(directory) / name
        if not path.is_file() or _sha1(path) != digest:
            raise InvalidInputError(
                f"{directory} is inconsistent: {name} is {'missing' if not path.is_file() else 'not the file'} "
                f"{TRAINING_STATE} recorded (a save was cut short or the folder was edited); resume from another "
                "checkpoint, or start again without --resume"
            )
    return state


def _sha1(path: Path) -> str:
    h = hashlib.sha1()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def load_resume_tensors(directory: Path) -> dict[str, torch.Tensor]:
    """The `resume_tensors` of `save_checkpoint`; empty for checkpoints written before they were saved."""
    path = Path(directory) / RESUME_STATE
    return load_file(path) if path.is_file() else {}


def load_optimizer_state(optimizer: torch.optim.Optimizer, directory: Path) -> None:
    """Restore optimiser tensors written by `save_checkpoint` (same parameter order)."""
    path = Path(directory) / OPTIMIZER_STATE
    if not path.is_file():
        raise MissingInputError(f"{path} not found; cannot resume the optimiser (start without --resume)")
    tensors = load_file(path)
    params = [p for g in optimizer.param_groups for p in g["params"]]
    for name, t in tensors.items():
        i, key = name.split(".", 1)
        p = params[int(i)]
        optimizer.state[p][key] = t.to(p.device) if key != "step" else t
    if tensors and len({n.split(".")[0] for n in tensors}) > len(params):
        raise InvalidInputError(f"{path} has state for more parameters than the model; the architecture changed")


def load_training_state(directory: Path) -> dict:
    path = Path(directory) / TRAINING_STATE
    if not path.is_file():
        raise MissingInputError(f"{path} not found; nothing to resume")
    return json.loads(path.read_text())
