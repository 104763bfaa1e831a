"""UDHM IK throughput: batched Levenberg-Marquardt vs per-frame scipy.optimize.least_squares.

Both solve the same objective in the same process: per-frame skeleton and palm frame, 21-keypoint
residual in metres plus the soft joint-limit residual (weight 1 m/rad), from the same analytic
initialisation. The reference runs on a subset (per-frame rate), the batched solver on all frames.

    .venv/bin/python benchmarks/bench_ik.py                 # 100k frames: real clip tiled + 0.5 mm noise
    .venv/bin/python benchmarks/bench_ik.py --source fk     # FK-generated random poses instead
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares
from tqdm import tqdm

from lerobot_unidextok import udhm
from lerobot_unidextok.udhm.fk import slots_to_angles
from lerobot_unidextok.udhm.frames import palm_frame, to_canonical
from lerobot_unidextok.udhm.ik import _initial_slots
from lerobot_unidextok.udhm.joints import JOINT_LIMITS_RAD
from lerobot_unidextok.utils.shared_data import real_data_dir

CLIP = real_data_dir(Path(__file__).resolve().parents[1]) / "dex-retargeting" / "human_joint_right.npy"
LIMIT_WEIGHT_M_PER_RAD = 1.0


def make_frames(source: str, n: int, noise_m: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    if source == "real":
        clip = np.load(CLIP)  # (621, 21, 3)
        kp = np.tile(clip, (int(np.ceil(n / len(clip))), 1, 1))[:n]
    else:
        kp = udhm.forward_kinematics(udhm.sample_angles(rng, (n,)))
    return kp + rng.normal(scale=noise_m, size=kp.shape)


def reference_ik(kp: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per-frame scipy least_squares ('trf', 2-point Jacobian) on the batched solver's objective."""
    rot = palm_frame(kp)
    local = to_canonical(kp, rot)  # (N, 21, 3)
    angles = np.empty((len(kp), 22))
    errors = np.empty(len(kp))
    lo, hi = JOINT_LIMITS_RAD[:, 0], JOINT_LIMITS_RAD[:, 1]
    for i in tqdm(range(len(kp)), desc="scipy reference", unit="frame"):
        sk = udhm.Skeleton.from_keypoints(local[i])
        target = local[i]
        x0 = slots_to_angles(
            _initial_slots(
                target[None, 1:].reshape(1, 5, 4, 3)[:, :, 1:],
                sk.palm_offsets_m[None],
                sk.bone_lengths_m[None],
                LIMIT_WEIGHT_M_PER_RAD,
            )
        )[0]

        def residual(q: np.ndarray, sk=sk, target=target) -> np.ndarray:
            fit = udhm.forward_kinematics(q, sk)
            excess = np.minimum(q - lo, 0.0) + np.maximum(q - hi, 0.0)
            return np.concatenate([(fit - target).ravel(), LIMIT_WEIGHT_M_PER_RAD * excess])

        sol = least_squares(residual, x0, method="trf")
        angles[i] = sol.x
        errors[i] = np.linalg.norm(udhm.forward_kinematics(sol.x, sk) - target, axis=-1).mean()
    return angles, errors


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--source", choices=["real", "fk"], default="real")
    parser.add_argument("--frames", type=int, default=100_000)
    parser.add_argument("--reference-frames", type=int, default=300)
    parser.add_argument("--noise-mm", type=float, default=0.5)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()

    kp = make_frames(args.source, args.frames, args.noise_mm * 1e-3, args.seed)
    sub = kp[: args.reference_frames]

    # CPU time (process_time) is the primary clock: the 2 cores are shared, so wall time depends on
    # other jobs; both clocks are printed.
    w0, c0 = time.perf_counter(), time.process_time()
    ref_angles, ref_err = reference_ik(sub)
    wall_ref, cpu_ref = time.perf_counter() - w0, time.process_time() - c0

    udhm.inverse_kinematics(kp[:1000])  # warm-up (imports, allocator)
    w0, c0 = time.perf_counter(), time.process_time()
    res = udhm.inverse_kinematics(kp)
    wall_ours, cpu_ours = time.perf_counter() - w0, time.process_time() - c0
    ours_sub = res.residual_m[: args.reference_frames]

    fps_ref, fps_ours = len(sub) / cpu_ref, len(kp) / cpu_ours
    print(f"source={args.source} frames={len(kp)} noise={args.noise_mm} mm reference_frames={len(sub)}")
    print(f"{'solver':<34}{'frames':>9}{'cpu s':>9}{'wall s':>9}{'frames/cpu-s':>14}{'mean err mm':>13}")
    print(
        f"{'scipy least_squares (per frame)':<34}{len(sub):>9}{cpu_ref:>9.2f}{wall_ref:>9.2f}{fps_ref:>14.1f}{ref_err.mean() * 1e3:>13.4f}"
    )
    print(f"{'udhm batched LM (same subset)':<34}{len(sub):>9}{'':>9}{'':>9}{'':>14}{ours_sub.mean() * 1e3:>13.4f}")
    print(
        f"{'udhm batched LM (all frames)':<34}{len(kp):>9}{cpu_ours:>9.2f}{wall_ours:>9.2f}{fps_ours:>14.1f}{res.residual_m.mean() * 1e3:>13.4f}"
    )
    print(
        f"speed ratio (cpu): {fps_ours / fps_ref:.0f}x   (wall: {len(kp) / wall_ours / (len(sub) / wall_ref):.0f}x)   "
        "max |angle diff| vs reference on subset: "
        f"{np.degrees(np.abs(res.angles_rad[: len(sub)] - ref_angles).max()):.3f} deg   "
        f"limit violations: {int(res.limit_violations.sum())}"
    )


if __name__ == "__main__":
    main()
