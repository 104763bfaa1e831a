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
    unidextok-convert --source=egodex --input=raw/egodex --root=out/egodex_udhm \\
        --executor.type=local --executor.tasks=8 --executor.workers=2
    # Slurm: an array job of 64 shard tasks and a merge job after it (configs/convert/slurm.yaml)
    unidextok-convert --config_path=convert/slurm --input=/data/egodex --root=/scratch/egodex_udhm

--push_to_hub=true uploads the result (HF_ENDPOINT / HF_TOKEN honoured) and tags it v3.0.
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
import json
import logging
import sys
from dataclasses import dataclass, field, fields
from pathlib import Path

import yaml

from lerobot_unidextok.conversion.pipeline import ConvertOptions
from lerobot_unidextok.conversion.sharded import ExecutorOptions
from lerobot_unidextok.errors import ConfigError
from lerobot_unidextok.utils.cli import EXIT_USER_ERROR, run_cli
from lerobot_unidextok.utils.draccus_cli import load_flag_value, parse_config


@dataclass
class ConvertConfig(ConvertOptions):
    """The conversion (every `ConvertOptions` field is a flag), where it runs (`--executor.*`), and the modes."""

    # -- what and where: given for a conversion, optional for --validate / --list_sources ---------------------
    source: str = ""  # registered source name (see --list_sources=true)
    input: str = ""  # raw dataset folder (or file) of the source
    root: str = ""  # output folder; default $HF_LEROBOT_HOME/<repo_id>
    # -- past one machine: shards on datatrove (pip install 'lerobot_policy_unidextok[datatrove]') --------------------
    executor: ExecutorOptions = field(default_factory=ExecutorOptions)
    """Where the conversion runs: this process (pool), or datatrove shards and a merge (--executor.type=local|slurm)."""
    # -- modes -------------------------------------------------------------------------------------------
    validate: bool = False  # validate the dataset at --root instead of converting
    push_to_hub: bool = False  # upload the dataset to --repo_id after converting (or validating)
    private: bool = False  # create the Hub repo private
    list_sources: bool = False  # print the registered sources and exit

    def __post_init__(self) -> None:
        if isinstance(self.source_options, str):  # a JSON object given as text (Python callers, quoted in YAML)
            self.source_options = _source_options(self.source_options)
        super().__post_init__()

    def conversion(self) -> ConvertOptions:
        """The library options of this run (`root` resolved)."""
        options = {f.name: getattr(self, f.name) for f in fields(ConvertOptions)}
        return ConvertOptions(**options | {"root": _root(self)})


def _root(cfg: ConvertConfig) -> Path:
    from lerobot_unidextok.utils.hf_cache import lerobot_home

    return Path(cfg.root).expanduser() if cfg.root else lerobot_home() / cfg.repo_id


def _source_options(text: str) -> dict:
    """The --source_options object given as text: JSON, read as YAML (a superset; its flow syntax also
    reads the repr of a Python dict)."""
    if not text:
        return {}
    try:
        value = load_flag_value(text)  # a key given twice is an error, not the last one kept
    except yaml.YAMLError as exc:
        problem = " ".join(str(getattr(exc, "problem", None) or exc).split())
        raise ConfigError(f"--source_options must be a JSON object with each key once: {problem}") from None
    if not isinstance(value, dict):
        raise ConfigError(f"--source_options must be a JSON object, got {type(value).__name__}")
    return value


def run(cfg: ConvertConfig) -> int:
    """Run the CLI config; returns the process exit code (2: the dataset is INVALID); user mistakes raise."""
    from lerobot_unidextok.conversion import pipeline, registry

    if cfg.list_sources:
        for name in registry.available_sources():
            cls = registry.get_source(name)
            print(f"{name:12s} {getattr(cls, 'description', '')}  [license: {getattr(cls, 'license', '?')}]")
        return 0
    root = _root(cfg)
    if not cfg.validate:
        if not cfg.source or not cfg.input:
            raise ConfigError("--source and --input are required (or --validate=true / --list_sources=true)")
        if cfg.executor.type != "pool":
            return _run_executor(cfg)
        report = pipeline.convert(cfg.conversion())
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
    if not validation.ok:
        return EXIT_USER_ERROR  # no training hint for a dataset that fails its checks
    _print_train_episodes(root)
    if cfg.push_to_hub:
        from lerobot_unidextok.hub import push

        commit = push(str(root), cfg.repo_id, "dataset", private=cfg.private)
        print(f"pushed {root} -> {cfg.repo_id} (tag v3.0) @ {commit}")
    return 0


def _run_executor(cfg: ConvertConfig) -> int:
    """--executor.type=local|slurm: shards on datatrove, then the merge (local) or both jobs submitted (slurm)."""
    from lerobot_unidextok.conversion.sharded import convert_with_executor

    if cfg.shard_index != 0 or cfg.num_shards != 1:
        raise ConfigError("--executor.type chooses the shards (--executor.tasks); drop --shard_index/--num_shards")
    root = convert_with_executor(cfg.conversion(), cfg.executor)
    if cfg.executor.type == "slurm":
        print(f"submitted the shard tasks and the merge into {root} (squeue lists them)")
        return 0
    info = json.loads((root / "meta" / "info.json").read_text())
    print(f"wrote {root}: {info['total_episodes']} episodes, {info['total_frames']} frames (datatrove local executor)")
    return _after_conversion(cfg, root)


def _print_train_episodes(root: Path) -> None:
    """How to keep the recorded test episodes out of `lerobot-train` (which ignores info.json splits)."""
    from lerobot_unidextok.conversion.card import lerobot_train_episodes_flag
    from lerobot_unidextok.data.record import load_record

    record = load_record(root)
    if record is not None and record.test_episodes and record.num_episodes <= 2000:
        flag = lerobot_train_episodes_flag(record.num_episodes, record.test_episodes)
        print(f"lerobot-train without the {len(record.test_episodes)} test episodes: {flag}")


# Flags renamed when the executor options became a group (--executor.*), accepted for one release.
RENAMED_FLAGS = {"--executor": "--executor.type", "--tasks": "--executor.tasks", "--workers": "--executor.workers"}


def renamed_flags(args: list[str]) -> list[str]:
    """`args` with the old spellings of renamed flags rewritten, one note on stderr for each."""
    out = []
    for arg in args:
        name, sep, value = arg.partition("=")
        new = RENAMED_FLAGS.get(name)
        if new is not None and sep and not value.lstrip().startswith(("{", "include ")):
            print(f"note: {name} is now {new} ({name}={value} read as {new}={value}); the old spelling goes in the "
                  "next release", file=sys.stderr)  # fmt: skip
            arg = f"{new}={value}"
        out.append(arg)
    return out


def main() -> None:
    # force: importing lerobot already gave the root logger a WARNING handler (a module-level logging.debug
    # call in lerobot.utils.import_utils), which would make this a no-op and hide our INFO lines
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s", force=True)
    for noisy in ("httpx", "lerobot.datasets.utils"):
        logging.getLogger(noisy).setLevel(logging.WARNING)
    run_cli(lambda: run(parse_config(ConvertConfig, renamed_flags(sys.argv[1:]))))


if __name__ == "__main__":
    main()
