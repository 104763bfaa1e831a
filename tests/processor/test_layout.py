"""processor.layout: the native layout's column checks."""

from __future__ import annotations

import pytest
from robot_udhm import HAND_NAMES, INSPIRE, NATIVE_NAMES, STATE_NAMES

from lerobot_unidextok.processor.layout import NativeLayout


def _hands(right_columns):
    return [{"side": "left", "hand": INSPIRE, "columns": HAND_NAMES["left"]},
            {"side": "right", "hand": INSPIRE, "columns": right_columns}]  # fmt: skip


def test_native_layout_names_missing_and_miscounted_columns():
    """Every hand column must be a native name, and a hand needs exactly its joint count. Catches the two
    checks joined with `and` (a misspelt column of the right count slipped through)."""
    NativeLayout(STATE_NAMES, NATIVE_NAMES, _hands(HAND_NAMES["right"]))  # the G1 layout is fine
    misspelt = [*HAND_NAMES["right"][:-1], "kRightHandThumbRot"]
    with pytest.raises(ValueError, match=r"must be 6 names of the native vector; missing: \['kRightHandThumbRot'\]"):
        NativeLayout(STATE_NAMES, NATIVE_NAMES, _hands(misspelt))
    with pytest.raises(ValueError, match=r"right inspire_rh56_unitree \(5\) must be 6"):
        NativeLayout(STATE_NAMES, NATIVE_NAMES, _hands(HAND_NAMES["right"][:5]))
