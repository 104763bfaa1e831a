"""Open-hand MCP abductions per hand-tracking source: does one hand give one UDHM reading whatever the tracker?

    .venv/bin/python experiments/tracker_abduction.py                  # this checkout
    git worktree add --detach ../before f6eb1f7                        # the code before the knuckle-row frame
    PYTHONPATH=../before .venv/bin/python experiments/tracker_abduction.py

Prints one Markdown table of MCP abductions (deg, > 0 toward the thumb) of index / middle / ring / pinky, the
median over a source's open-hand frames, and the number of frames. It uses only `udhm.inverse_kinematics`, so
the same script measures the older code through PYTHONPATH (`docs/conversion.md`, "Human keypoints").
Real rows read ../shared/data/real beside the checkout (UNIDEXTOK_REAL_DATA elsewhere) and are left out when
it is absent:
- `dex-retargeting` clip (621 MediaPipe frames of one right hand): open-hand frames are those where every
  finger's MCP + PIP + DIP flexion is below 45 deg.
- MediaPipe's reference landmarks of two open left hands (`expected_left_{up,down}_hand_landmarks`, image
  landmarks on a 720 x 382 px grid, no depth): lifted to z = 0, so the palm is the image plane and each
  abduction is the angle seen in the photo (pixels scaled to a 97 mm wrist -> middle MCP).
- MediaPipe gesture world landmarks (3D): the extended fingers only, index of `pointing_up`, index and middle
  of `victory`.
Synthetic rows: `tests/fixtures/tracker_layouts.py`, one open hand with the fingers together (its four MCP
abductions are 0 by construction), the wrist point where each tracker's skeleton definition puts it, with the
hand straight on the forearm and turned 15 deg toward the little finger (the resting posture).
"""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests" / "fixtures"))

from tracker_layouts import LAYOUTS, mano21_keypoints_m  # noqa: E402  (tests/fixtures, added above)

from lerobot_unidextok import udhm  # noqa: E402
from lerobot_unidextok.udhm.joints import joint_index  # noqa: E402
from lerobot_unidextok.utils.shared_data import real_data_dir  # noqa: E402

FINGERS = ("index", "middle", "ring", "pinky")
OPEN_FLEX_DEG = 45.0  # MCP + PIP + DIP flexion of an extended finger (tests/udhm/test_ik_real.py EXTENDED_RAD)
PALM_M = 0.097  # wrist -> middle MCP used to scale the 2D landmarks (MediaPipe world-landmark median)
REAL = real_data_dir(ROOT)


def abductions_deg(angles_rad: np.ndarray) -> np.ndarray:
    """(..., 4) MCP abductions of index, middle, ring, pinky in degrees."""
    return np.degrees(angles_rad[..., [joint_index(f"{f}_mcp_abd") for f in FINGERS]])


def open_hand(angles_rad: np.ndarray) -> np.ndarray:
    """Bool (...): every finger's MCP + PIP + DIP flexion below OPEN_FLEX_DEG."""
    flex = [sum(angles_rad[..., joint_index(f"{f}_{j}_flex")] for j in ("mcp", "pip", "dip")) for f in FINGERS]
    return (np.degrees(np.stack(flex, -1)) < OPEN_FLEX_DEG).all(-1)


def real_rows() -> list[tuple[str, list[float | None], int]]:
    rows: list[tuple[str, list[float | None], int]] = []
    clip_path = REAL / "dex-retargeting" / "human_joint_right.npy"
    if clip_path.is_file():
        angles = udhm.inverse_kinematics(np.load(clip_path)).angles_rad
        keep = open_hand(angles)
        rows.append(
            (
                "real: dex-retargeting MediaPipe clip, open frames",
                list(np.median(abductions_deg(angles[keep]), 0)),
                int(keep.sum()),
            )
        )
    fixtures_path = REAL / "mediapipe" / "mediapipe_hand_fixtures.json"
    if fixtures_path.is_file():
        fixtures = json.loads(fixtures_path.read_text())
        for view in ("up", "down"):
            px = np.asarray(fixtures[f"expected_left_{view}_hand_landmarks.prototxt"]["landmarks_2d_normalized"]) * (
                720,
                382,
            )
            kp = np.concatenate([px, np.zeros((21, 1))], axis=1)
            kp *= PALM_M / np.linalg.norm(kp[9] - kp[0])
            rows.append(
                (
                    f"real: MediaPipe open left hand pointing {view} (2D photo)",
                    list(abductions_deg(udhm.inverse_kinematics(kp, side="left").angles_rad)),
                    1,
                )
            )
        for gesture, extended in (("pointing_up", ("index",)), ("victory", ("index", "middle"))):
            kp = np.asarray(fixtures[f"{gesture}_landmarks.pbtxt"]["world_landmarks_m"])
            abd = abductions_deg(udhm.inverse_kinematics(kp).angles_rad)
            rows.append((f"real: MediaPipe `{gesture}` (3D), extended fingers", [float(a) if f in extended else None for f, a in zip(FINGERS, abd, strict=True)], 1))  # fmt: skip
    return rows


def synthetic_rows() -> list[tuple[str, list[float | None], int]]:
    label = {"mano": "MANO (DexYCB, OakInk-v2)", "mediapipe": "MediaPipe", "webxr": "WebXR / OpenXR (Quest)",
             "arkit": "ARKit / EgoDex, laid out as OpenXR"}  # fmt: skip
    rows = []
    for deviation in (0.0, 15.0):
        for layout in LAYOUTS:
            angles = udhm.inverse_kinematics(mano21_keypoints_m(layout, deviation_deg=deviation)).angles_rad
            rows.append(
                (f"synthetic: {label[layout]}, wrist deviation {deviation:.0f} deg", list(abductions_deg(angles)), 1)
            )
    return rows


def main() -> None:
    print("| source | index | middle | ring | pinky | frames |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, values, frames in real_rows() + synthetic_rows():
        cells = " | ".join("-" if v is None else f"{v:+.1f}" for v in values)
        print(f"| {name} | {cells} | {frames} |")


if __name__ == "__main__":
    main()
