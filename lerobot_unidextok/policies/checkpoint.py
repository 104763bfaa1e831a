"""A policy checkpoint loaded whole, as LeRobot's stock factory will load it, before a command ships it.

`unidextok-deploy` and `unidextok-push` call `check_policy_checkpoint` on what they are about to write or
upload: the config, the weights against it and both processor pipelines. A damaged file (a truncated
`model.safetensors`, a JSON file cut short) or an inconsistent folder is then one clear error, and nothing
is reported as bound or pushed.
"""

from __future__ import annotations

from pathlib import Path

from lerobot_unidextok.errors import InvalidInputError

PREPROCESSOR = "policy_preprocessor.json"
POSTPROCESSOR = "policy_postprocessor.json"


class PolicyCheckpointError(InvalidInputError):
    """A policy checkpoint folder that does not load; the message names the file and the fix."""


def check_policy_checkpoint(folder: str | Path) -> None:
    """Load `folder` (config.json, model.safetensors, the two processor pipelines) the way `lerobot-eval` /
    `lerobot-rollout` will; raise `PolicyCheckpointError` naming the file that does not load."""
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.policies.factory import get_policy_class
    from lerobot.processor import PolicyProcessorPipeline
    from safetensors import SafetensorError

    folder = Path(folder)
    for name in ("config.json", "model.safetensors", PREPROCESSOR, POSTPROCESSOR):
        if not (folder / name).is_file():
            raise PolicyCheckpointError(
                f"{folder} has no {name}: a LeRobot policy checkpoint holds config.json, model.safetensors and "
                f"{PREPROCESSOR} / {POSTPROCESSOR} (the pretrained_model folder of a lerobot-train run)"
            )
    # what LeRobot's loaders raise for a damaged or inconsistent file: JSON / draccus decoding (ValueError,
    # KeyError, TypeError), a truncated safetensors file, torch's strict state-dict load (RuntimeError)
    damaged = (OSError, ValueError, KeyError, TypeError, RuntimeError, SafetensorError)
    try:
        config = PreTrainedConfig.from_pretrained(folder)
    except damaged as e:
        raise _error(folder / "config.json", e) from e
    try:
        get_policy_class(config.type).from_pretrained(folder, config=config)
    except damaged as e:
        raise _error(folder / "model.safetensors", e) from e
    for name in (PREPROCESSOR, POSTPROCESSOR):
        try:
            PolicyProcessorPipeline.from_pretrained(folder, config_filename=name)
        except damaged as e:
            raise _error(folder / name, e) from e


def _error(path: Path, e: Exception) -> PolicyCheckpointError:
    reason = " ".join(f"{type(e).__name__}: {e}".split())[:400]
    return PolicyCheckpointError(
        f"{path} does not load ({reason}): the checkpoint is damaged (a copy cut short, an edited file) or mixes "
        "two checkpoints' files; use the pretrained_model folder lerobot-train wrote, or train again"
    )


__all__ = ["POSTPROCESSOR", "PREPROCESSOR", "PolicyCheckpointError", "check_policy_checkpoint"]
