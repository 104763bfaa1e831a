"""`unidextok-convert`: raw source dataset -> UDHM LeRobotDataset v3.0 (or validate / push one).

    unidextok-convert --source=linkerhand --input=raw/linkerhand --repo_id=me/linkerhand_udhm \\
        --root=out/linkerhand_udhm --num_workers=2 --on_error=skip
    unidextok-convert --source=dexycb --input=raw/dexycb --sides=right,left --root=out/dexycb_udhm
    unidextok-convert --source=lerobot --input=raw/g1 --source_options='{"hands": {...}}' --root=...
    unidextok-convert --source=let --input=raw/let_bags --fps=30 --root=...   # bags resampled onto 30 fps
    unidextok-convert --validate=true --root=out/linkerhand_udhm
    unidextok-convert --config_path=convert.yaml          # same fields in a YAML/JSON file
    unidextok-convert --list_sources=true
    # datatrove: 8 shards, 2 at a time on this machine, then one merge (pip install 'lerobot_policy_unidextok[datatrove]')
    unidextok-convert --source=egodex --input=raw/egodex --root=out/egodex_udhm --executor=local --tasks=8 --workers=2
    # Slurm: an array job of 64 shard tasks and a merge job after it (configs/convert/slurm.yaml)
    unidextok-convert --config_path=configs/convert/slurm.yaml --input=/data/egodex --root=/scratch/egodex_udhm

--push_to_hub=true uploads the result (HF_ENDPOINT / HF_TOKEN honoured) and tags it v3.0.
"""

import json
import logging
import os
import sys
from dataclasses import dataclass, field
from pathlib import Path

import draccus
import yaml

from lerobot_unidextok.conversion.sharded import EXECUTORS, SlurmOptions
from lerobot_unidextok.utils.cli import UserError, configure_output


@dataclass
class ConvertConfig:
    # -- what ---------------------------------------------------------------------------------------
    source: str = ""  # registered source name (see --list_sources=true)
    input: str = ""  # raw dataset folder (or file) of the source
    source_options: str = ""  # JSON object of source reader options, e.g. '{"hands": {...}}'
    # -- where --------------------------------------------------------------------------------------
    repo_id: str = "local/udhm"  # dataset id (namespace/name), used for the card and the Hub
    root: str = ""  # output folder; default $HF_LEROBOT_HOME/<repo_id>
    overwrite: bool = False  # replace an existing dataset at --root (atomically, at the end)
    # -- how ----------------------------------------------------------------------------------------
    mapping: str = "semantic"  # "semantic" (joint -> named UDHM slot) | "append_pad" (ablation)
    sides: str = ""  # block layout, e.g. "right,left" for sources whose episodes are left or right hands
    fps: int | None = None  # frame grid for time-stamped sources (ROS bags, keypoint files); None = source default
    keep: str = "all"  # "all": the whole robot (arms, other features, videos) | "hands": UDHM blocks only
    num_workers: int = 1  # processes reading + mapping episodes
    on_error: str = "raise"  # "raise": stop at the first bad episode | "skip": skip, report at the end
    test_fraction: float = 0.2  # share of episodes in the deterministic test split
    max_episodes: int | None = None  # convert only the first N episodes (quick looks)
    shard_index: int = 0  # convert one contiguous shard of the episode list (multi-machine runs by hand)
    num_shards: int = 1
    # -- past one machine: datatrove (pip install 'lerobot_policy_unidextok[datatrove]') -------------------------
    # "pool": this process, --num_workers reader processes | "local" / "slurm": datatrove's Local/Slurm
    # PipelineExecutor, --tasks shard conversions (each with --num_workers processes), then one merge
    executor: str = "pool"
    tasks: int = 2  # shards = datatrove tasks (capped at the number of episodes)
    workers: int = -1  # datatrove tasks running at the same time (-1: all)
    logging_dir: str = ""  # datatrove run folder (logs, completions, shards); default <root>.datatrove
    keep_shards: bool = False  # keep the shard datasets after the merge
    slurm: SlurmOptions = field(default_factory=SlurmOptions)  # --slurm.partition=... --slurm.time=...
    # -- modes --------------------------------------------------------------------------------------
    validate: bool = False  # validate the dataset at --root instead of converting
    push_to_hub: bool = False  # upload the dataset to --repo_id after converting (or validating)
    private: bool = False
    list_sources: bool = False  # print the registered sources and exit


def _root(cfg: ConvertConfig) -> Path:
    if cfg.root:
        return Path(cfg.root).expanduser()
    home = os.environ.get("HF_LEROBOT_HOME") or str(Path(os.environ.get("HF_HOME", "~/.cache/huggingface")) / "lerobot")
    return Path(home).expanduser() / cfg.repo_id


def _source_options(text: str) -> dict:
    """The --source_options object. Parsed as YAML, a superset of JSON: draccus hands a flag that looks
    like a mapping over as the Python repr of the dict it parsed, which YAML's flow syntax also reads."""
    if not text:
        return {}
    try:
        value = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise SystemExit(f"error: --source_options must be a JSON object: {exc}") from exc
    if not isinstance(value, dict):
        raise SystemExit(f"error: --source_options must be a JSON object, got {type(value).__name__}")
    return value


def run(cfg: ConvertConfig) -> int:
    """Run the CLI config; returns the process exit code."""
    from lerobot_unidextok.conversion import pipeline, registry

    if cfg.list_sources:
        for name in registry.available_sources():
            cls = registry.get_source(name)
            print(f"{name:12s} {getattr(cls, 'description', '')}  [license: {getattr(cls, 'license', '?')}]")
        return 0
    root = _root(cfg)
    if not cfg.validate:
        if not cfg.source or not cfg.input:
            raise SystemExit("error: --source and --input are required (or --validate=true / --list_sources=true)")
        try:
            opts = pipeline.ConvertOptions(
                source=cfg.source,
                input=cfg.input,
                root=root,
                repo_id=cfg.repo_id,
                source_options=_source_options(cfg.source_options),
                mapping=cfg.mapping,
                on_error=cfg.on_error,
                num_workers=cfg.num_workers,
                overwrite=cfg.overwrite,
                test_fraction=cfg.test_fraction,
                max_episodes=cfg.max_episodes,
                shard_index=cfg.shard_index,
                num_shards=cfg.num_shards,
                sides=tuple(s.strip() for s in cfg.sides.split(",") if s.strip()) or None,
                fps=cfg.fps,
                keep=cfg.keep,
            )
            if cfg.executor != "pool":
                return _run_executor(cfg, opts)
            report = pipeline.convert(opts)
        except (
            pipeline.ConversionError,
            FileExistsError,
            FileNotFoundError,
            ValueError,
            UserError,
        ) as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 1
        print(
            f"wrote {report.root}: {report.num_episodes} episodes ({report.num_train} train / {report.num_test} test), "
            f"{report.num_frames} frames, hands {', '.join(report.hands)}, {report.seconds:.1f} s "
            f"({report.frames_per_second:,.0f} frames/s)"
        )
        if report.failures:
            print(f"skipped {len(report.failures)} episode(s):\n{pipeline.format_failures(report.failures)}")
    return _after_conversion(cfg, root)


def _after_conversion(cfg: ConvertConfig, root: Path) -> int:
    """Validate (table when asked or invalid), print the lerobot-train flag, push when asked."""
    from lerobot_unidextok.conversion.validate import validate_dataset

    validation = validate_dataset(root, repo_id=cfg.repo_id)
    if cfg.validate or not validation.ok:
        print(validation.table())
    _print_train_episodes(root)
    if not validation.ok:
        return 2
    if cfg.push_to_hub:
        from lerobot_unidextok.hub import push

        commit = push(str(root), cfg.repo_id, "dataset", private=cfg.private)
        print(f"pushed {root} -> {cfg.repo_id} (tag v3.0) @ {commit}")
    return 0


def _run_executor(cfg: ConvertConfig, opts) -> int:
    """--executor=local|slurm: shards on datatrove, then the merge (local) or both jobs submitted (slurm)."""
    from lerobot_unidextok.conversion.sharded import ExecutorOptions, convert_with_executor

    if cfg.executor not in EXECUTORS:
        raise ValueError(f"--executor must be pool, {' or '.join(EXECUTORS)}; got {cfg.executor!r}")
    if cfg.shard_index != 0 or cfg.num_shards != 1:
        raise ValueError("--executor chooses the shards (--tasks); drop --shard_index/--num_shards")
    ex = ExecutorOptions(
        executor=cfg.executor,
        tasks=cfg.tasks,
        workers=cfg.workers,
        logging_dir=cfg.logging_dir or None,
        keep_shards=cfg.keep_shards,
        slurm=cfg.slurm,
    )
    root = convert_with_executor(opts, ex)
    if cfg.executor == "slurm":
        print(f"submitted the shard tasks and the merge into {root} (squeue lists them)")
        return 0
    info = json.loads((root / "meta" / "info.json").read_text())
    print(f"wrote {root}: {info['total_episodes']} episodes, {info['total_frames']} frames (datatrove local executor)")
    return _after_conversion(cfg, root)


def _print_train_episodes(root: Path) -> None:
    """How to keep the recorded test episodes out of `lerobot-train` (which ignores info.json splits)."""
    from lerobot_unidextok.conversion.card import lerobot_train_episodes_flag
    from lerobot_unidextok.conversion.pipeline import read_settings

    settings = read_settings(root)
    if settings.get("test_episodes") and int(settings.get("num_episodes", 0)) <= 2000:
        flag = lerobot_train_episodes_flag(int(settings["num_episodes"]), settings["test_episodes"])
        print(f"lerobot-train without the {len(settings['test_episodes'])} test episodes: {flag}")


@draccus.wrap()
def convert_cli(cfg: ConvertConfig) -> int:
    return run(cfg)


def main() -> None:
    configure_output()
    # force: importing lerobot already gave the root logger a WARNING handler (a module-level logging.debug
    # call in lerobot.utils.import_utils), which would make this a no-op and hide our INFO lines
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", force=True)
    for noisy in ("httpx", "lerobot.datasets.utils"):
        logging.getLogger(noisy).setLevel(logging.WARNING)
    sys.exit(convert_cli())


if __name__ == "__main__":
    main()
