"""Where each hand's scripted expert holds an object when it lifts it, in the grasp-centre frame the policies learn.

A mix teaches a hand what the other hands did: with wrist actions in the grasp-centre frame (docs/pooling.md "The
grasp-centre frame"), where their grasp centres went relative to the object. This measures that point per hand on
the GraspLift-v0 or PinchLift-v0 recordings `experiments/closed_loop.py` made (its `--cache_dir`), so a hand whose
own point lies far from the others' can be told apart from one the policy simply fails on.

Per recorded episode: the lift frame is the first whose object centre is `lift_m` above where it rested; there the
grasp centre c_h (the recording's `meta/unidextok_wrist_frame.json`) in world is wrist xyz + R(roll, pitch, yaw) c_h,
and its offset from the object centre is turned into the object's frame by the object's yaw (the drawn yaw of a box;
a cylinder's is 0; PinchLift's cylinder has no yaw column). The grasp kind follows the object on GraspLift
(`lerobot_env_unidextok.tasks.SHAPES`: power for the two larger shapes, pinch for the two small ones) and the named
finger on PinchLift (`index`, `middle`: the thumb's partner). Per hand and kind: the mean offset (cm), its spread, the wrist pitch
(rad), and the distance from the hand's mean offset to the mean of the other hands' (what a policy pooled without
this hand is taught).

On PinchLift also the posture each hand's expert holds the cylinder with (`pinch_holds`): its thumb-finger pinch
(`lerobot_env_unidextok.pinch_place.pinch_of`, fitted per hand by forward kinematics) closed on a cylinder of the
task's middle width, in UDHM degrees, and per hand the mean distance of its thumb's slots (and the pinching
finger's curl) from the other hands' mean over the slots both move: what a policy pooled without this hand
commands its thumb to do.

    python experiments/grasp_points.py --cache_dir=outputs/experiments/_sim [--frame=wrist]
    python experiments/grasp_points.py --task=PinchLift-v0 --cache_dir=outputs/pinchlift/_sim \
        --hands='[inspire_rh56_unitree,shadow,leap,xhand1,linkerhand_l10]' 
"""

from __future__ import annotations

import logging
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.closed_loop import HANDS
from experiments.common import git_commit, md_table, write_result

logger = logging.getLogger(__name__)
NAME = "grasp_points"
TASKS = {"GraspLift-v0": ("power", "pinch"), "PinchLift-v0": ("index", "middle")}  # task -> its grasp kinds
FRAMES = ("grasp_centre", "wrist")
PINCH_HALF_M = 0.02  # SHAPES: the power shapes' half widths are >= 0.022 m, the pinch shapes' <= 0.017 m


@dataclass
class GraspPointsConfig:
    task: str = "GraspLift-v0"  # or PinchLift-v0
    cache_dir: str = "outputs/experiments/_sim"  # closed_loop.py's: <cache_dir>/<task>/seed0/<hand>/native_<pool>
    hands: list[str] = field(default_factory=lambda: list(HANDS))
    pool: int = 50
    lift_m: float = 0.01  # the object counts as lifted this far above its resting height
    # the point measured: the hand's grasp centre (what the policies learn with `udt_wrist_frame=grasp_centre`) or
    # the wrist itself (what they learn in the robot's wrist frame, `closed_loop.py`'s `no_frame` arms)
    frame: str = "grasp_centre"
    output_root: str = "outputs/experiments"

    def __post_init__(self) -> None:
        if self.frame not in FRAMES:
            raise ValueError(f"frame must be one of {FRAMES}, got {self.frame!r}")
        if self.task not in TASKS:
            raise ValueError(f"task must be one of {tuple(TASKS)}, got {self.task!r}")


def rotation_rpy(rpy: np.ndarray) -> np.ndarray:
    """(3,) roll, pitch, yaw (rad) -> (3, 3), the recordings' convention (the wrist-frame step's own rotation)."""
    import torch

    from lerobot_unidextok.processor.wrist_frame import rotation_rpy as rotation

    return rotation(torch.as_tensor(rpy, dtype=torch.float64)).numpy()


def grasp_point(state: np.ndarray, names: list[str], centre_m: np.ndarray, lift_m: float) -> dict | None:
    """One episode's (T, D) state -> {"kind", "offset_m" (3,), "pitch_rad"} at its lift frame (None: never lifted)."""
    col = {n: i for i, n in enumerate(names)}
    z = state[:, col["object_z"]]
    lifted = np.flatnonzero(z > z[0] + lift_m)
    if not len(lifted):
        return None
    row = state[lifted[0]]
    wrist = row[[col[n] for n in ("wrist_x", "wrist_y", "wrist_z")]]
    rpy = row[[col[n] for n in ("wrist_roll", "wrist_pitch", "wrist_yaw")]]
    obj = row[[col[n] for n in ("object_x", "object_y", "object_z")]]
    world = wrist + rotation_rpy(rpy) @ centre_m - obj  # grasp centre from the object centre, world axes
    yaw = row[col["object_yaw"]] if "object_yaw" in col else 0.0  # PinchLift's upright cylinder: no yaw
    in_object = rotation_rpy(np.array([0.0, 0.0, -yaw])) @ world
    if "pinch_index" in col:  # PinchLift: the finger the thumb pinches with
        kind = "index" if row[col["pinch_index"]] > 0.5 else "middle"
    else:
        kind = "pinch" if row[col["object_half_x"]] < PINCH_HALF_M else "power"
    return {"kind": kind, "offset_m": in_object, "pitch_rad": float(rpy[1])}


def hand_points(cfg: GraspPointsConfig, hand: str) -> tuple[list[dict], np.ndarray]:
    """Every recorded episode's grasp point of one hand, and its grasp centre in the wrist frame (m)."""
    import json

    import pandas as pd

    from lerobot_unidextok.constants import INFO_PATH
    from lerobot_unidextok.data.reader import data_files
    from lerobot_unidextok.data.wrist_frame import read_recorded

    root = Path(cfg.cache_dir) / cfg.task / "seed0" / hand / f"native_{cfg.pool}"  # seed 0's recording
    frame = read_recorded(root)
    if frame is None or hand not in frame.grasp_centre_in_wrist_m:
        raise FileNotFoundError(f"{root}: no recorded {cfg.task} dataset with a grasp centre for {hand}; record it "
                                f"with experiments/closed_loop.py --tasks='[{cfg.task}]' --cache_dir={cfg.cache_dir} "
                                f"--hands='[{hand}]'")  # fmt: skip
    names = json.loads((root / INFO_PATH).read_text())["features"]["observation.state"]["names"]
    table = pd.concat([pd.read_parquet(p) for p in data_files(root)])
    grasp_centre = np.asarray(frame.grasp_centre_in_wrist_m[hand])
    centre = grasp_centre if cfg.frame == "grasp_centre" else np.zeros(3)
    points = []
    for _, episode in table.groupby("episode_index"):
        state = np.stack(episode.sort_values("frame_index")["observation.state"].to_numpy())
        point = grasp_point(state, names, centre, cfg.lift_m)
        points.append(point or {"kind": "never lifted"})
    return points, grasp_centre


def run(cfg: GraspPointsConfig) -> dict:
    t0 = time.time()
    measured = {hand: hand_points(cfg, hand) for hand in cfg.hands}
    points = {hand: ps for hand, (ps, _) in measured.items()}
    rows = []
    for kind in TASKS[cfg.task]:
        means = {h: np.mean([p["offset_m"] for p in ps if p["kind"] == kind], axis=0) for h, ps in points.items()}
        for hand, ps in points.items():
            own = [p for p in ps if p["kind"] == kind]
            offsets = np.array([p["offset_m"] for p in own])
            others = np.mean([m for h, m in means.items() if h != hand], axis=0)
            rows.append({"hand": hand, "kind": kind, "episodes": len(own),
                         "offset_cm": (100 * offsets.mean(0)).round(1).tolist(),
                         "spread_cm": round(float(100 * np.linalg.norm(offsets.std(0))), 1),
                         "pitch_rad": round(float(np.mean([p["pitch_rad"] for p in own])), 2),
                         "from_others_cm": round(float(100 * np.linalg.norm(means[hand] - others)), 1),
                         "centre_from_wrist_cm": round(float(100 * np.linalg.norm(measured[hand][1])), 1)})  # fmt: skip
    never = {h: sum(p["kind"] == "never lifted" for p in ps) for h, ps in points.items()}
    holds = pinch_holds(cfg.hands) if cfg.task == "PinchLift-v0" else []
    return {"config": vars(cfg), "rows": rows, "never_lifted": never, "holds": holds, "git_commit": git_commit(),
            "wall_seconds": round(time.time() - t0, 1)}  # fmt: skip


def from_others_deg(postures: dict[str, np.ndarray]) -> dict[str, float]:
    """Per hand: the mean |own - the other hands' mean| (deg) over the slots it and at least one other hand move
    (NaN in a posture: a slot the hand lacks)."""
    out = {}
    for hand, own in postures.items():
        others = np.array([p for h, p in postures.items() if h != hand])
        moved = ~np.isnan(others).all(0)
        mean = np.full(own.shape, np.nan)
        mean[moved] = np.nanmean(others[:, moved], axis=0)
        both = ~np.isnan(own) & ~np.isnan(mean)
        out[hand] = float(np.mean(np.abs(own[both] - mean[both]))) if both.any() else float("nan")
    return out


def pinch_holds(hands: list[str]) -> list[dict]:
    """Per pinching finger and hand: the expert's hold of a cylinder of PinchLift's middle width, in UDHM degrees
    (the thumb's slots, then the finger's MCP, PIP, DIP), and its distance from the other hands' mean."""
    from lerobot_env_unidextok import sim_hands
    from lerobot_env_unidextok.pinch_place import PINCH_FINGERS, RADIUS_M, THUMB_SLOTS, pinch_of
    from lerobot_unidextok.constants import UDHM_JOINT_NAMES

    width_m = 2 * float(np.mean(RADIUS_M))
    rows = []
    for finger in PINCH_FINGERS:
        slots = [*THUMB_SLOTS, *(f"{finger}_{j}_flex" for j in ("mcp", "pip", "dip"))]
        index = [UDHM_JOINT_NAMES.index(s) for s in slots]
        postures = {}
        for hand in hands:
            sim_hand = sim_hands.load(hand)
            hold = pinch_of(sim_hand, finger).hold(width_m)
            udhm_deg = np.degrees(np.asarray(sim_hand.spec.to_udhm(hold, sim_hand.side), dtype=np.float64))
            postures[hand] = np.where(np.asarray(sim_hand.spec.active_mask, dtype=bool), udhm_deg, np.nan)[index]
        n = len(THUMB_SLOTS)
        thumb = from_others_deg({h: p[:n] for h, p in postures.items()})
        curl = from_others_deg({h: p[n:] for h, p in postures.items()})
        rows += [{"hand": h, "finger": finger, "width_mm": round(1000 * width_m, 1), "slots": slots,
                  "hold_deg": [None if np.isnan(v) else round(float(v), 1) for v in p],
                  "thumb_from_others_deg": round(thumb[h], 1), "curl_from_others_deg": round(curl[h], 1)}
                 for h, p in postures.items()]  # fmt: skip
    return rows


def markdown(result: dict) -> str:
    head = ["hand", "grasp", "episodes", "offset x, y, z (cm)", "spread (cm)", "wrist pitch (rad)",
            "from the other hands' mean (cm)", "grasp centre from the wrist (cm)"]  # fmt: skip
    rows = [[r["hand"], r["kind"], r["episodes"], ", ".join(f"{v:+.1f}" for v in r["offset_cm"]), f"{r['spread_cm']:.1f}",
             f"{r['pitch_rad']:.2f}", f"{r['from_others_cm']:.1f}", f"{r['centre_from_wrist_cm']:.1f}"]
            for r in result["rows"]]  # fmt: skip
    text = md_table(head, rows)
    holds = result.get("holds") or []
    if holds:
        slots = [s.replace("_flex", "").replace("thumb_", "") for s in holds[0]["slots"][:5]]
        head = ["hand", "pinch", *(f"thumb {s} (deg)" for s in slots), "finger MCP, PIP, DIP (deg)",
                "thumb from the others' mean (deg)", "finger from the others' mean (deg)"]  # fmt: skip
        rows = [[h["hand"], h["finger"], *("-" if v is None else f"{v:.0f}" for v in h["hold_deg"][:5]),
                 ", ".join("-" if v is None else f"{v:.0f}" for v in h["hold_deg"][5:]),
                 f"{h['thumb_from_others_deg']:.0f}", f"{h['curl_from_others_deg']:.0f}"] for h in holds]  # fmt: skip
        text += (f"\n\nThe expert's hold of a {holds[0]['width_mm']:.0f} mm cylinder, in UDHM degrees ('-': a slot the "
                 "hand lacks):\n\n" + md_table(head, rows))  # fmt: skip
    return text


def run_and_write(cfg: GraspPointsConfig) -> dict:
    result = run(cfg)
    name = "_".join([NAME, *([cfg.frame] if cfg.frame != "grasp_centre" else []),
                     *(["pinchlift"] if cfg.task == "PinchLift-v0" else [])])  # fmt: skip
    folder = Path(cfg.output_root) / name
    folder.mkdir(parents=True, exist_ok=True)
    write_result(folder, name, result, f"# {name}\n\n{markdown(result)}")
    return result


def main(argv: list[str] | None = None) -> None:
    runtime.cli(GraspPointsConfig, run_and_write, markdown, argv)


if __name__ == "__main__":
    main()
