"""blocks: UDHM blocks found by name inside wider vectors (arms + hands)."""

import numpy as np
import pytest

from lerobot_unidextok.blocks import (
    feature_names,
    find_udhm_blocks,
    passthrough_indices,
    udhm_block_names,
    udhm_state_names,
)


def test_blocks_after_passthrough_columns():
    arms = [f"arm_{i}" for i in range(14)]
    names = arms + udhm_state_names(["left", "right"])
    blocks = find_udhm_blocks(names)
    assert [(b.side, b.start, b.stop) for b in blocks] == [("left", 14, 36), ("right", 36, 58)]
    np.testing.assert_array_equal(passthrough_indices(names), np.arange(14))


def test_hands_only_and_no_hands():
    assert [b.start for b in find_udhm_blocks(udhm_state_names(["right"]))] == [0]
    assert find_udhm_blocks(["a", "b"]) == []
    np.testing.assert_array_equal(passthrough_indices(["a", "b"]), [0, 1])


def test_block_between_passthrough_columns():
    names = ["gripper"] + udhm_block_names("right") + ["base_x"]
    (block,) = find_udhm_blocks(names)
    assert block.slice == slice(1, 23)
    np.testing.assert_array_equal(passthrough_indices(names), [0, 23])


def test_incomplete_or_shuffled_block_raises():
    names = udhm_block_names("right")
    with pytest.raises(ValueError, match="incomplete or out of order"):
        find_udhm_blocks(names[:10])
    shuffled = names[:]
    shuffled[3], shuffled[4] = shuffled[4], shuffled[3]
    with pytest.raises(ValueError, match="position 3"):
        find_udhm_blocks(shuffled)
    with pytest.raises(ValueError, match="one block per side"):
        find_udhm_blocks(names + names)


@pytest.mark.parametrize(
    ("names", "flat"),
    [
        (["a", "b"], ["a", "b"]),
        ([["a", "b"]], ["a", "b"]),  # one nested list, as some LeRobot datasets write it
        ({"axes": ["a", "b"]}, ["a", "b"]),
        (["ab"], ["ab"]),  # one name is not a nested list
        ({"motors": ["a"], "grippers": [["b"]]}, ["a", "b"]),  # every list of a dict, in order
        (None, []),
    ],
)
def test_feature_names_flattens_lerobot_spellings(names, flat):
    """Catches a plain name split into characters (a string taken for a nested list) and a nested list kept
    as one name."""
    assert feature_names({"dtype": "float32", "names": names}) == flat


def test_feature_names_of_another_type_raise():
    with pytest.raises(ValueError, match="feature names must be a list or dict of lists, got str"):
        feature_names({"names": "a,b"})
