"""Build `benchmarks/RESULTS.md` from the experiments' JSON files (never typed by hand).

Copies the PNGs the page shows into `benchmarks/results/` (skipping any over 300 KB) and links them.
"""

import json
import logging
import shutil
from dataclasses import dataclass, field
from pathlib import Path

import draccus

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import (
    EXPERIMENTS,
    ablation_human,
    ablation_mapping,
    closed_loop,
    cross_embodiment,
    main_table,
    mix_lerobot_train,
    policy_tokens,
    probe,
    rate_distortion,
    transfer,
)
from experiments.common import shown_command

logger = logging.getLogger(__name__)
MARKDOWN = {"main_table": main_table.markdown, "ablation_human": ablation_human.markdown,
            "ablation_mapping": ablation_mapping.markdown, "transfer": transfer.markdown, "probe": probe.markdown,
            "policy_tokens": policy_tokens.markdown, "rate_distortion": rate_distortion.markdown,
            "cross_embodiment": cross_embodiment.markdown,
            "mix_lerobot_train": mix_lerobot_train.markdown, "closed_loop": closed_loop.markdown}  # fmt: skip
COMMANDS = {name: f"python experiments/{name}.py" for name in EXPERIMENTS}
MAX_PNG_BYTES = 300_000


def load_results(results_dir: Path) -> dict[str, dict]:
    found = {}
    for name in EXPERIMENTS:
        path = results_dir / name / f"{name}.json"
        if path.is_file():
            found[name] = json.loads(path.read_text())
        else:
            logger.warning("no %s: run `%s` first", path, COMMANDS[name])
    return found


def _copy_figures(name: str, figures: dict, image_dir: Path, page: Path) -> list[str]:
    lines = []
    for key, src in figures.items():
        src = Path(src)
        if not src.is_file():
            continue
        if src.stat().st_size > MAX_PNG_BYTES:
            logger.warning(
                "%s is %d bytes (> %d): not copied",
                src,
                src.stat().st_size,
                MAX_PNG_BYTES,
            )
            continue
        dst = image_dir / f"{name}_{src.name}"
        dst.parent.mkdir(parents=True, exist_ok=True)
        shutil.copyfile(src, dst)
        lines.append(f"![{name} {key}]({dst.relative_to(page.parent).as_posix()})")
    return lines


def _remove_stale_figures(image_dir: Path, lines: list[str]) -> None:
    """Delete `<experiment>_*.png` figures of an earlier page that this page no longer links."""
    linked = {line.split("](")[1].rstrip(")").rsplit("/", 1)[-1] for line in lines if line.startswith("![")}
    for png in image_dir.glob("*.png"):
        if png.name not in linked and any(png.name.startswith(f"{name}_") for name in EXPERIMENTS):
            png.unlink()
            logger.info("removed stale figure %s", png)


DATA_LABELS = {
    "real": "REAL recordings (../shared/data/real)",
    "sample": "SYNTHETIC sample data",
    "datasets": "user datasets",
    "sim": "SIMULATED expert demonstrations (lerobot_env_unidextok)",
}


def data_label(result: dict) -> str:
    d = result["provenance"]["data"]
    source = d.get("source", "sample" if d["synthetic_sample"] else "datasets")
    return DATA_LABELS[source]


def _provenance_line(result: dict) -> str:
    p = result["provenance"]
    data = f"{data_label(result)}: " + ", ".join(p["data"]["datasets"])
    if "checkpoint" in p:  # scores a trained checkpoint, trains nothing
        c = p["checkpoint"]
        trained = f"{c['steps']} training steps, checkpoint of step {c['best_step']}" if c.get("steps") else "untrained"
        return (f"_Data: {data} ({p['data']['test_rows']} test rows, hands {', '.join(p['data']['hands'])}); "
                f"tokenizer `{c['checkpoint']}` ({trained}), seed {p['seed']}, commit `{p['git_commit'][:12]}`, "
                f"{p['date_utc']}, wall time {p['wall_seconds']} s._")  # fmt: skip
    steps = p["config"]["train"]["steps"] if "train" in p["config"] else p["config"]["steps"]  # flat in older files
    return (f"_Data: {data} ({p['data']['train_rows']} train / {p['data']['test_rows']} held-out rows, hands "
            f"{', '.join(p['data']['hands'])}); preset `{p['preset']}`, {steps} steps, seed {p['seed']}, "
            f"commit `{p['git_commit'][:12]}`, {p['date_utc']}, wall time {p['wall_seconds']} s._")  # fmt: skip


def reduced_size_note(result: dict) -> str | None:
    """A section's first line when its UniDexTok trained fewer steps than the shipped schedule
    (`configs/train/small.yaml` = `TrainConfig().steps`), else None. Only the experiments that train UniDexTok
    through `ExperimentConfig.train` (their provenance config has `train`) are concerned."""
    from experiments.config import ExperimentTraining
    from lerobot_unidextok.training import TrainConfig

    config = result.get("provenance", {}).get("config", {})
    if "train" not in config:
        return None
    steps, shipped = int(config["train"]["steps"]), TrainConfig().steps
    if steps >= shipped:
        return None
    return (f"**Reduced-size run: UniDexTok trained {steps} steps here** (`--train.steps`; the experiments' default "
            f"is {ExperimentTraining().steps}, `experiments/configs/default.yaml`), not the shipped schedules "
            f"(`configs/train/small.yaml`, {shipped} steps; `configs/train/universal.yaml`), which score far lower "
            "errors: the shipped figures are in `docs/tokenizer.md`, \"Measured on data the model never trained on\" "
            "and \"The shipped universal tokenizer\".")  # fmt: skip


def section_title(name: str, label: str = "") -> str:
    """`closed_loop`, or `closed_loop (PinchLift-v0)` for a second run of one experiment kept beside the first."""
    return f"{name} ({label})" if label else name


def section(name: str, r: dict | None, image_dir: Path, page: Path, label: str = "") -> list[str]:
    """The page's lines for one experiment (its figures copied next to the page, a labelled section's under
    `<name>_<label>_`, so that the unlabelled section's figures stay)."""
    title = section_title(name, label)
    if r is None:
        return [f"## {title}", "", f"Not run yet: `{COMMANDS[name]}`.", ""]
    body = MARKDOWN[name](r).split("\n")
    body = body[2:] if body and body[0].startswith("# ") else body  # drop the experiment's own title
    note = reduced_size_note(r)
    out = [f"## {title}", "", *([note, ""] if note else []), f"Command: `{shown_command(r.get('command', COMMANDS[name]))}`", "",
           _provenance_line(r), "", *body, ""]  # fmt: skip
    prefix = f"{name}_{label}" if label else name
    return out + _copy_figures(prefix, r.get("figures", {}), image_dir, page) + [""]


def _section_order(titles) -> list[str]:
    """The experiments' order, each labelled section right after its experiment's, then anything else."""
    titles = list(titles)
    order = []
    for name in EXPERIMENTS:
        order += [t for t in titles if t == name] + sorted(t for t in titles if t.startswith(f"{name} ("))
    return order + [t for t in titles if t not in order]


def update_sections(results_dir: str | Path, page: str | Path, names: list[str], image_dir: str | Path | None = None,
                    label: str = "") -> str:
    """Replace (or add, in the page's experiment order) only `names`' sections of an existing page, from their
    JSON files; the other sections stay as they are (for a checkout holding only some experiments' results).
    With a `label`, the sections are `<name> (<label>)`, kept beside the unlabelled ones (another run of the
    same experiment, e.g. `closed_loop` on a second task)."""
    results_dir, page = Path(results_dir), Path(page)
    image_dir = Path(image_dir) if image_dir else page.parent / "results"
    unknown = sorted(set(names) - set(EXPERIMENTS))
    if unknown:
        raise ValueError(f"unknown experiments {unknown}; choose from {list(EXPERIMENTS)}")
    if not page.is_file():
        raise FileNotFoundError(f"{page} does not exist; build the whole page first (without --only)")
    results = load_results(results_dir)
    missing = [n for n in names if n not in results]
    if missing:
        raise FileNotFoundError(f"no results for {missing} under {results_dir}; run `{COMMANDS[missing[0]]}` first")
    head, *chunks = page.read_text().split("\n## ")
    sections = {c.split("\n", 1)[0].strip(): "## " + c for c in chunks}  # untouched text kept byte for byte
    for name in names:
        sections[section_title(name, label)] = "\n".join(section(name, results[name], image_dir, page, label)).rstrip() + "\n"
    text = head + "".join("\n" + sections[n] for n in _section_order(sections))
    page.write_text(text)
    logger.info("updated %s in %s", names, page)
    return text


def _split_sections(text: str) -> tuple[str, dict[str, str]]:
    """A page's text before its first `## ` section, and each section by title (ending in one newline)."""
    head, *chunks = text.split("\n## ")
    return head, {c.split("\n", 1)[0].strip(): "## " + c.rstrip() + "\n" for c in chunks}


def _labelled_sections(page: Path) -> dict[str, str]:
    """An existing page's labelled sections (`## <experiment> (<label>)`)."""
    if not page.is_file():
        return {}
    _, sections = _split_sections(page.read_text())
    return {t: text for t, text in sections.items() if t.split(" (", 1)[0] in EXPERIMENTS and t.endswith(")")}


def build_page(results_dir: str | Path, page: str | Path, image_dir: str | Path | None = None) -> str:
    """Write the results page from `<results_dir>/<experiment>/<experiment>.json`; returns its text."""
    results_dir, page = Path(results_dir), Path(page)
    image_dir = Path(image_dir) if image_dir else page.parent / "results"
    results = load_results(results_dir)
    if not results:
        raise FileNotFoundError(f"no experiment results under {results_dir}; run e.g. `{COMMANDS['main_table']}` first")
    sources = sorted({data_label(r) for r in results.values()})
    out = ["# Results", "", ("Generated by `python experiments/make_results.py` from the JSON files under "
           f"`{results_dir.as_posix()}/`; do not edit by hand. Every section names the command, data source, preset, "
           "seed and commit it came from. By default the experiments run on the REAL recordings in "
           "../shared/data/real when that folder is beside the checkout (G1 Inspire teleoperation, a real human "
           "MediaPipe clip and that clip retargeted onto robot hands with dex-retargeting), else on the built-in "
           "SYNTHETIC sample (generated gesture motion: it shows the pipeline works, not how methods compare on "
           "recordings). The real recordings are small (10 G1 episodes, one 21 s human clip), so these are small-data "
           "figures, not the paper's. Other data: `--datasets='[a,b]'`."), "",
           f"Data sources on this page: {', '.join(sources)}.", ""]  # fmt: skip
    for name in EXPERIMENTS:
        out += section(name, results.get(name), image_dir, page)
    kept = _labelled_sections(page)  # other runs' sections (`--label`): their JSON files are elsewhere
    text = "\n".join(out).rstrip() + "\n"
    if kept:
        head, sections = _split_sections(text)
        sections |= kept
        text = head + "".join("\n" + sections[n] for n in _section_order(sections))
        out = text.split("\n")
    _remove_stale_figures(image_dir, out)
    page.parent.mkdir(parents=True, exist_ok=True)
    page.write_text(text)
    logger.info("wrote %s", page)
    return text


@dataclass
class ResultsPageConfig:
    results_dir: str = "outputs/experiments"  # where the experiments wrote <name>/<name>.json
    page: str = "benchmarks/RESULTS.md"
    image_dir: str = ""  # figures copied here; empty = <page folder>/results
    # Replace only these experiments' sections of the existing page (the others' JSON files may be absent).
    only: list[str] = field(default_factory=list)
    # With --only: name the sections `<experiment> (<label>)`, kept beside the unlabelled ones, for another run of
    # the same experiment (e.g. --results_dir=outputs/pinchlift --only='[closed_loop]' --label=PinchLift-v0).
    label: str = ""

    def __post_init__(self):
        if self.label and not self.only:
            raise ValueError("--label names the sections --only writes; give --only='[<experiment>]' too")


def main(argv: list[str] | None = None) -> None:
    cfg = draccus.parse(ResultsPageConfig, args=argv)
    logging.basicConfig(level=logging.INFO)
    if cfg.only:
        update_sections(cfg.results_dir, cfg.page, cfg.only, cfg.image_dir or None, cfg.label)
    else:
        build_page(cfg.results_dir, cfg.page, cfg.image_dir or None)
    print(f"wrote {cfg.page}")


if __name__ == "__main__":
    main()
