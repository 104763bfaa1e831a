"""A policy checkpoint loaded whole, as LeRobot's stock factory will load it, before a command ships it.

`unidextok-deploy` and `unidextok-push` call `check_policy_checkpoint` on what they are about to write or
upload: the config, the weights against it and both processor pipelines. A damaged file (a truncated
`model.safetensors`, a JSON file cut short) or an inconsistent folder is then one clear error, and nothing
is reported as bound or pushed. The check is stricter than LeRobot's own load where LeRobot only warns:

- `PreTrainedPolicy.from_pretrained` loads the weights with `strict=False`, so a tensor missing from
  `model.safetensors` (left at its random initialisation) or one the policy does not have is one "Missing
  key(s)" / "Unexpected key(s)" log line. Here the file's tensors must be the state dict of the policy its
  `config.json` builds, exactly; the weights are loaded once, by the loader LeRobot uses (safetensors'
  `load_model`, which accounts for tensors saved once for several names).
- a tensor holding NaN or inf, in `model.safetensors` or in a processor step's saved statistics, is named (LeRobot
  loads it without a word; the policy then acts on NaN or never moves a hand).
- a `config.json` value its config class refuses (a NaN std in a `<type>_udt`'s `udt_hand_stats`) is that
  refusal, naming the file.
- a `config.json` whose `type` is not a registered policy, or whose fields are another policy's (draccus'
  `DecodingError`), and a processor step that is neither registered nor importable (LeRobot's `ImportError`)
  are named with what is known.
"""

from __future__ import annotations

import functools
import importlib
import json
import logging
import re
from pathlib import Path

from lerobot_unidextok.errors import InvalidInputError, UserError
from lerobot_unidextok.utils.number_checks import nonfinite_tensors, nonfinite_text

PREPROCESSOR = "policy_preprocessor.json"
POSTPROCESSOR = "policy_postprocessor.json"
WEIGHTS = "model.safetensors"
NAMED = 4  # tensors / types named in a message; the rest are counted


class PolicyCheckpointError(InvalidInputError):
    """A policy checkpoint folder that does not load; the message names the file and the fix."""


def check_policy_checkpoint(folder: str | Path) -> None:
    """Load `folder` (config.json, model.safetensors, the two processor pipelines) the way `lerobot-eval` /
    `lerobot-rollout` will, but strictly (module docstring); raise `PolicyCheckpointError` naming the file
    that does not load and why."""
    folder = Path(folder)
    for name in ("config.json", WEIGHTS, PREPROCESSOR, POSTPROCESSOR):
        if not (folder / name).is_file():
            raise PolicyCheckpointError(
                f"{folder} has no {name}: a LeRobot policy checkpoint holds config.json, {WEIGHTS} and "
                f"{PREPROCESSOR} / {POSTPROCESSOR} (the pretrained_model folder of a lerobot-train run)"
            )
    _register_plugins()
    config = _load_config(folder / "config.json")
    _check_weights(folder / WEIGHTS, config)
    for path in sorted(folder.glob("*.safetensors")):  # the weights and the processors' saved statistics
        check_finite(path)
    for name in (PREPROCESSOR, POSTPROCESSOR):
        _check_pipeline(folder / name)


@functools.cache
def _register_plugins() -> None:
    """What LeRobot's CLIs do first: import the installed plugin packages (lerobot_policy_*: policy types and
    processor steps, ours too), without their one INFO line per plugin. Once a process: LeRobot reads every
    installed distribution's metadata to find them (about half a second), and a deploy checks two checkpoints."""
    from lerobot.utils.import_utils import register_third_party_plugins

    previous = logging.root.manager.disable
    logging.disable(logging.INFO)  # a plugin that fails to import is still logged (an ERROR)
    try:
        register_third_party_plugins()
    finally:
        logging.disable(previous)


# what LeRobot's loaders raise for a damaged or inconsistent file: JSON / draccus decoding (ValueError,
# KeyError, TypeError), a truncated safetensors file, torch's state-dict load (RuntimeError: shapes)
def _damaged() -> tuple[type[BaseException], ...]:
    from safetensors import SafetensorError

    return (OSError, ValueError, KeyError, TypeError, RuntimeError, SafetensorError)


def _load_config(path: Path):
    """The checkpoint's policy config; its `type` must be a registered policy whose fields the file holds."""
    from draccus.utils import DecodingError, ParsingError
    from lerobot.configs.policies import PreTrainedConfig

    try:
        found = json.loads(path.read_text()).get("type")
    except (OSError, ValueError, AttributeError) as e:  # AttributeError: JSON that is not an object
        raise _error(path, e) from e
    known = sorted(PreTrainedConfig.get_known_choices())
    if found not in known:
        what = f"names the policy type {found!r}, which is not registered here" if found else "names no policy type"
        raise PolicyCheckpointError(
            f"{path} {what} (known: {', '.join(known)}): install the package that registers it (a plugin policy: "
            "its lerobot_policy_* package), or use the config.json lerobot-train wrote beside these weights"
        )
    try:
        return PreTrainedConfig.from_pretrained(path.parent)
    except ParsingError as e:  # a DecodingError, or the config's own refusal of a value (its __post_init__)
        refusal = _refusal_in(e)
        if refusal is not None:  # e.g. a NaN std in udt_hand_stats: the message names the field and the fix
            raise PolicyCheckpointError(f"{path}: {refusal}") from e
        if not isinstance(e, DecodingError):
            raise _error(path, e) from e
        raise PolicyCheckpointError(
            f"{path} says type {found!r} but does not decode as one ({_decoding_reason(e)}): its type was changed, "
            f"or it is another policy's config (known types: {', '.join(known)}); use the config.json "
            "lerobot-train wrote beside these weights"
        ) from e
    except _damaged() as e:
        raise _error(path, e) from e


def _refusal_in(err: BaseException) -> UserError | None:
    """The config's own refusal of a value (a `UserError` its `__post_init__` raised) that draccus wrapped."""
    seen: set[int] = set()
    while err is not None and id(err) not in seen:
        if isinstance(err, UserError):
            return err
        seen.add(id(err))
        err = err.__cause__ or err.__context__
    return None


def _check_weights(path: Path, config) -> None:
    """`model.safetensors` must hold exactly the tensors of the policy `config` builds."""
    from lerobot.policies.factory import get_policy_class
    from safetensors.torch import load_model

    try:
        policy = get_policy_class(config.type)(config)
    except _damaged() as e:
        raise _error(path.parent / "config.json", e) from e
    try:
        missing, extra = load_model(policy, path, strict=False, device="cpu")  # LeRobot's loader, once
    except _damaged() as e:
        raise _error(path, e) from e
    if missing or extra:
        what = [f"missing {_few(missing)}" if missing else "", f"extra {_few(extra)}" if extra else ""]
        raise PolicyCheckpointError(
            f"{path} does not hold the tensors of the {config.type} policy its config.json builds "
            f"({'; '.join(w for w in what if w)}): LeRobot would load it anyway, with "
            + ("the missing ones left random" if missing else "the extra ones ignored")
            + "; the file was edited or comes from another checkpoint: use the model.safetensors lerobot-train "
            "saved with this config.json (one pretrained_model folder), or train again"
        )


def check_finite(path: Path) -> None:
    """Every tensor of the safetensors file at `path` finite: a NaN weight or statistic makes a policy that
    crashes on its own output or never moves a hand, and nothing in LeRobot's load notices it."""
    try:
        found = nonfinite_tensors(path)
    except _damaged() as e:
        raise _error(path, e) from e
    if found:
        raise PolicyCheckpointError(
            f"{path}: {nonfinite_text(found)}: a policy with them acts on NaN; the training diverged or the file "
            "was edited: use an earlier checkpoint of the run (checkpoints/<step>/pretrained_model), or train again"
        )


def _check_pipeline(path: Path) -> None:
    """A processor pipeline file whose steps are all known here, and that loads."""
    from lerobot.processor import PolicyProcessorPipeline

    unknown = _unknown_step(path)
    if unknown is not None:
        raise PolicyCheckpointError(
            f"{path} has the processor step {unknown}, which is not known here: steps come from LeRobot's "
            "registry (ProcessorStepRegistry: LeRobot's own and those the installed plugin packages register, "
            "lerobot_policy_unidextok the unidextok.* ones) or a 'class' importable as module.Class; install "
            "the package that defines it, or use the processor files lerobot-train wrote"
        )
    try:
        PolicyProcessorPipeline.from_pretrained(path.parent, config_filename=path.name)
    except (*_damaged(), ImportError) as e:  # ImportError: a step's own module failing to import
        raise _error(path, e) from e


def _unknown_step(path: Path) -> str | None:
    """'<i> (<registry name or class>)' of the first step of the pipeline file that resolves to no class, or
    None (also for a file that does not parse: the load then says why)."""
    from lerobot.processor import ProcessorStepRegistry

    try:
        steps = json.loads(path.read_text()).get("steps") or []
        entries = [(i, s) for i, s in enumerate(steps) if isinstance(s, dict)]
    except (OSError, ValueError, AttributeError):
        return None
    registered = set(ProcessorStepRegistry.list())
    for i, step in entries:
        if "registry_name" in step:
            if step["registry_name"] not in registered:
                return f"{i} {step['registry_name']!r}"
        elif "class" in step:
            module, _, name = str(step["class"]).rpartition(".")
            try:
                getattr(importlib.import_module(module), name)
            except (ImportError, AttributeError, ValueError):  # ValueError: an empty module name
                return f"{i} {step['class']!r}"
    return None


def _decoding_reason(e: Exception) -> str:
    """draccus' reason, with a long list of fields of another policy shortened to a few."""
    fields = re.findall(r"`([^`]+)`", str(e))
    invalid = re.search(r"not valid for (\w+)", str(e))
    if fields and invalid:
        return f"the fields {_few(fields, sort=False)} are not valid for {invalid.group(1)}"
    return _reason(e, 240)


def _few(names, sort: bool = True) -> str:
    names = sorted(names) if sort else list(names)
    more = f" and {len(names) - NAMED} more" if len(names) > NAMED else ""
    return ", ".join(names[:NAMED]) + more


def _reason(e: BaseException, limit: int = 400) -> str:
    return " ".join(f"{type(e).__name__}: {e}".split())[:limit]


def _error(path: Path, e: BaseException) -> PolicyCheckpointError:
    return PolicyCheckpointError(
        f"{path} does not load ({_reason(e)}): the checkpoint is damaged (a copy cut short, an edited file) or "
        "mixes two checkpoints' files; use the pretrained_model folder lerobot-train wrote, or train again"
    )


__all__ = [
    "POSTPROCESSOR",
    "PREPROCESSOR",
    "WEIGHTS",
    "PolicyCheckpointError",
    "check_finite",
    "check_policy_checkpoint",
]
