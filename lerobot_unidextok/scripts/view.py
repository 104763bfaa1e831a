"""`unidextok-view`: look at a converted episode: each hand in 3D (the robot with its coupled joints, or its
URDF) next to its native values and, with a tokenizer, the tokens and the decoded hand. Writes an .mp4 /
.gif, or a rerun recording (.rrd).

    unidextok-view --dataset=data/g1_udhm --episode=0 --output=outputs/view/g1_ep0.mp4
    unidextok-view --dataset=lab/g1_udhm --tokenizer=lab/unidextok-small --output=outputs/view/ep0.gif --stride=3
    unidextok-view --dataset=data/g1_udhm --urdf=../shared/data/urdf --output=outputs/view/g1_ep0.mp4
    unidextok-view --dataset=data/g1_udhm --output=outputs/view/ep0.rrd   # rerun-sdk: pip install 'lerobot[viz]'
        then: rerun outputs/view/ep0.rrd
"""

# Package modules used by only some functions are imported inside them, so importing this module stays
# light for the commands' start-up (tests/test_light_imports.py, benchmarks/bench_startup.py).
import logging
from dataclasses import dataclass
from pathlib import Path

from lerobot_unidextok.errors import InvalidInputError
from lerobot_unidextok.utils.cli import run_cli
from lerobot_unidextok.utils.draccus_cli import wrap


@dataclass
class ViewConfig:
    dataset: str = ""  # converted dataset folder, or a repo id pulled to this machine
    episode: int = 0  # episode_index to show
    tokenizer: str | None = None  # UniDexTok folder or repo id: adds tokens and the decoded hand
    output: str = "outputs/view/episode.mp4"  # .mp4 | .gif | .rrd (rerun recording)
    stride: int = 1  # show every stride-th frame (the video plays at fps / stride)
    max_frames: int = 300  # at most this many frames after the stride
    camera: str = "oblique"  # 3D view: side | oblique | palm (a left hand is seen by the mirrored camera)
    urdf: str | None = None  # draw robot hands by their URDF: a .urdf file, or a folder holding each hand's urdf.file


@wrap()
def view_cli(cfg: ViewConfig) -> None:
    from lerobot_unidextok.viz.episode import VIDEO_SUFFIXES, load_episode, write_rerun, write_video

    if not cfg.dataset:
        raise InvalidInputError("--dataset is required: a converted dataset folder or a pulled repo id")
    suffix = Path(cfg.output).suffix.lower()
    if suffix not in (*VIDEO_SUFFIXES, ".rrd"):
        raise InvalidInputError(f"--output must end in .mp4, .gif or .rrd, got {cfg.output!r}")
    from lerobot_unidextok.data.destination import claim_files

    # a dataset's own videos live inside it: never written over; an earlier view (same suffix) is replaced
    claim_files([Path(cfg.output)], is_ours=lambda p: p.suffix.lower() == suffix)
    view = load_episode(cfg.dataset, cfg.episode, cfg.tokenizer, cfg.stride, cfg.max_frames, cfg.urdf)
    path = write_rerun(view, cfg.output) if suffix == ".rrd" else write_video(view, cfg.output, cfg.camera)
    print(f"wrote {path} ({view.num_frames} frames, hands {view.hands}, sides {view.sides})")


def main() -> None:
    logging.basicConfig(level=logging.INFO, format="%(levelname)s %(name)s: %(message)s")
    run_cli(view_cli)


if __name__ == "__main__":
    main()
