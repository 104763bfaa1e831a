"""`unidextok-push` / `unidextok-pull`: share tokenizer checkpoints and converted datasets.

    unidextok-push --local_dir=outputs/tok --repo_id=me/unidextok-small --training_data='[me/dexycb_udhm]'
    unidextok-push --local_dir=outputs/train/act_udt --repo_id=me/act-udt-g1   # policy run: policy card
    unidextok-push --local_dir=unidextok/universal-small --repo_id=me/universal-small   # the shipped tokenizer
    unidextok-pull --repo_id=me/unidextok-small            # then HF_HUB_OFFLINE=1 works
    unidextok-pull --repo_id=me/dexycb_udhm --repo_type=dataset   # also linked at $HF_LEROBOT_HOME/<repo_id>

HF_ENDPOINT, HF_TOKEN, HF_HOME / HF_HUB_CACHE are honoured.
"""

import logging
from dataclasses import dataclass, field

from lerobot_unidextok.errors import ConfigError
from lerobot_unidextok.hub import pull, push
from lerobot_unidextok.utils.cli import run_cli
from lerobot_unidextok.utils.draccus_cli import wrap


@dataclass
class PushConfig:
    # tokenizer or policy checkpoint (config.json + model.safetensors; it must load whole), a training run folder
    # (its best/ or checkpoints/last/pretrained_model/ is pushed), a converted or mixed dataset (LeRobot v3.0,
    # valid as unidextok-convert --validate=true checks it), or a tokenizer shipped in the package by its id
    # (unidextok/universal-small)
    local_dir: str = ""
    repo_id: str = ""  # namespace/name on the Hub
    repo_type: str | None = None  # "model" | "dataset"; detected from the folder when omitted
    private: bool = False
    training_data: list[str] = field(default_factory=list)  # dataset repo ids named in the model card


@dataclass
class PullConfig:
    repo_id: str = ""  # namespace/name on the Hub
    repo_type: str = "model"  # "model" | "dataset"
    revision: str | None = None  # branch, tag or commit; datasets default to the v3.0 tag


def _require(value: str, flag: str) -> None:
    if not value:
        raise ConfigError(f"{flag} is required, e.g. {flag}=namespace/name")


@wrap()
def push_cli(cfg: PushConfig) -> None:
    _require(cfg.local_dir, "--local_dir")
    _require(cfg.repo_id, "--repo_id")
    commit = push(
        cfg.local_dir,
        cfg.repo_id,
        cfg.repo_type,
        private=cfg.private,
        training_data=cfg.training_data,
    )
    print(f"pushed {cfg.local_dir} -> {cfg.repo_id} @ {commit}")


@wrap()
def pull_cli(cfg: PullConfig) -> None:
    _require(cfg.repo_id, "--repo_id")
    path = pull(cfg.repo_id, cfg.repo_type, cfg.revision)
    print(path)


def _setup_logging() -> None:
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    logging.getLogger("httpx").setLevel(logging.WARNING)


def push_main() -> None:
    _setup_logging()
    run_cli(push_cli)


def pull_main() -> None:
    _setup_logging()
    run_cli(pull_cli)
