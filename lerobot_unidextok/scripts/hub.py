"""`unidextok-push` / `unidextok-pull`: share tokenizer checkpoints and converted datasets.

    unidextok-push --local_dir=outputs/tok --repo_id=me/unidextok-small
    unidextok-pull --repo_id=me/unidextok-small            # then HF_HUB_OFFLINE=1 works
    unidextok-pull --repo_id=me/dexycb_udhm --repo_type=dataset

HF_ENDPOINT, HF_TOKEN, HF_HOME / HF_HUB_CACHE are honoured.
"""

import logging
from dataclasses import dataclass, field

import draccus

from lerobot_unidextok.hub import pull, push


@dataclass
class PushConfig:
    local_dir: str = ""  # checkpoint folder (config.json + model.safetensors) or LeRobotDataset v3.0 folder
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
        raise SystemExit(f"error: {flag} is required, e.g. {flag}=namespace/name")


@draccus.wrap()
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


@draccus.wrap()
def pull_cli(cfg: PullConfig) -> None:
    _require(cfg.repo_id, "--repo_id")
    path = pull(cfg.repo_id, cfg.repo_type, cfg.revision)
    print(path)


def push_main() -> None:
    logging.basicConfig(level=logging.INFO)
    logging.getLogger("httpx").setLevel(logging.WARNING)
    push_cli()


def pull_main() -> None:
    logging.basicConfig(level=logging.INFO)
    logging.getLogger("httpx").setLevel(logging.WARNING)
    pull_cli()
