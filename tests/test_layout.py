"""layout: the native layout's column checks."""

from __future__ import annotations

import pytest
from robot_udhm import HAND_NAMES, INSPIRE, NATIVE_NAMES, STATE_NAMES

from lerobot_unidextok.data import UdhmDatasetMeta
from lerobot_unidextok.layout import NativeLayout


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


def test_native_layout_rebuilds_the_converted_vector_from_the_recorded_layout(g1_like):
    """`to_converted` (numpy or torch) is the converter's map: the dataset's own native frames come back as its
    converted frames; the converter's mapping is read with the layout and saved in `to_dict`."""
    import numpy as np
    import torch
    from robot_udhm import to_converted

    layout = UdhmDatasetMeta(g1_like["root"]).native_layout("observation.state")
    assert layout.mapping == "semantic" and layout.invertible and NativeLayout(**layout.to_dict()) == layout
    native = g1_like["native_state"][:8]  # (8, 26) float32
    np.testing.assert_allclose(layout.to_converted(native), to_converted(native.astype(np.float64)), atol=1e-6)
    as_tensor = layout.to_converted(torch.from_numpy(native))
    assert as_tensor.dtype == torch.float32 and as_tensor.shape == (8, 58)
    with pytest.raises(ValueError, match=r"width 26 \(native layout\), got \(8, 58\)"):
        layout.to_converted(to_converted(native))
