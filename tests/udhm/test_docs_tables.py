"""docs/udhm.md states the joint limits and the default skeleton; the code must hold the same numbers.

The tables are data with a cited source (AAOS, Hume et al., real MediaPipe hands), so no behaviour test
pins a limit moved by a degree or a bone by a millimetre. Users read the limits and the skeleton from the
docs, so a number changed in one place and not the other is a bug this test catches.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from lerobot_unidextok.constants import FINGERS, UDHM_JOINT_NAMES
from lerobot_unidextok.udhm import Skeleton
from lerobot_unidextok.udhm.joints import JOINT_LIMITS_RAD

DOC = Path(__file__).resolve().parents[2] / "docs" / "udhm.md"


def _rows(section: str) -> list[list[str]]:
    """Cells of the Markdown table under the `## <section>` heading (header and rule skipped)."""
    text = DOC.read_text(encoding="utf-8").split(f"## {section}\n", 1)[1].split("\n## ", 1)[0]
    lines = [ln for ln in text.splitlines() if ln.startswith("|")]
    return [[c.strip().strip("`") for c in ln.strip("|").split("|")] for ln in lines[2:]]


def test_joint_limit_table_matches_the_code():
    rows = _rows("Joints and limits")
    assert [r[1] for r in rows] == list(UDHM_JOINT_NAMES)
    assert [int(r[0]) for r in rows] == list(range(22))
    limits_deg = np.array([[float(r[2]), float(r[3])] for r in rows])
    np.testing.assert_allclose(np.rad2deg(JOINT_LIMITS_RAD), limits_deg, atol=1e-9)


def test_default_skeleton_table_matches_the_code():
    rows = _rows("Default adult skeleton")
    assert [r[0] for r in rows] == list(FINGERS)
    numbers = [[float(v) for v in re.split(r",\s*", cell)] for r in rows for cell in r[1:3]]
    offsets_mm, bones_mm = np.array(numbers[0::2]), np.array(numbers[1::2])
    sk = Skeleton.default()
    np.testing.assert_allclose(np.asarray(sk.palm_offsets_m) * 1e3, offsets_mm, atol=0.006)  # 2 decimals
    np.testing.assert_allclose(np.asarray(sk.bone_lengths_m) * 1e3, bones_mm, atol=1e-9)
