"""udhm.joints: the limit helpers on (..., 22) angle arrays."""

from __future__ import annotations

import numpy as np
import pytest

from lerobot_unidextok.udhm import joints
from lerobot_unidextok.udhm.joints import JOINT_LIMITS_RAD, clip_to_limits, limit_violations, sample_angles


def test_limit_violations_flag_only_beyond_the_tolerance():
    """Default tolerance 1 mrad (0.06 deg): IK lands exactly on a limit up to rounding, and that is no
    violation; 2 mrad past it is. Catches a tolerance of ~1 rad (`1e-3` -> `1.001`), which flags nothing."""
    lo, hi = JOINT_LIMITS_RAD[:, 0], JOINT_LIMITS_RAD[:, 1]
    assert not limit_violations(np.stack([lo - 5e-4, hi + 5e-4, (lo + hi) / 2])).any()
    assert limit_violations(np.stack([lo - 2e-3, hi + 2e-3])).all()
    one = (lo + hi) / 2
    one[7] = hi[7] + 0.01
    assert np.flatnonzero(limit_violations(one)).tolist() == [7]
    assert not limit_violations(hi + 0.01, tol_rad=0.02).any()
    assert not limit_violations(np.full(22, np.nan)).any()  # untracked frames are not violations


def test_clip_and_sample_stay_inside_and_keep_nan(rng):
    lo, hi = JOINT_LIMITS_RAD[:, 0], JOINT_LIMITS_RAD[:, 1]
    wild = rng.normal(scale=3.0, size=(500, 22))
    wild[0, 3] = np.nan
    clipped = clip_to_limits(wild)
    assert np.isnan(clipped[0, 3]) and np.isnan(clipped).sum() == 1
    ok = ~np.isnan(clipped)
    assert ((clipped >= lo) & (clipped <= hi) | ~ok).all()
    inside = (wild >= lo) & (wild <= hi)
    np.testing.assert_array_equal(clipped[inside], wild[inside])  # values inside are untouched
    s = sample_angles(rng, (4000,), margin=0.1)
    pad = 0.1 * (hi - lo)
    assert s.shape == (4000, 22) and (s >= lo + pad).all() and (s <= hi - pad).all()
    assert (s.min(0) < lo + pad + 0.05 * (hi - lo)).all() and (s.max(0) > hi - pad - 0.05 * (hi - lo)).all()


def test_bad_names_and_shapes_name_the_fix():
    assert joints.joint_index("pinky_metacarpal_twist") == 17
    with pytest.raises(ValueError, match="unknown UDHM joint 'index_flex'; valid names: thumb_cmc_flex"):
        joints.joint_index("index_flex")
    with pytest.raises(ValueError, match=r"shape \(\.\.\., 22\), got \(3, 21\)"):
        limit_violations(np.zeros((3, 21)))
