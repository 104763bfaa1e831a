"""Shared test set-up: offline Hugging Face caches in a temp dir, and the real-data fixture.

The HF variables are set here, before any test module imports lerobot or huggingface_hub,
because both read them at import time.
"""

from __future__ import annotations

import json
import logging
import os
import sys
import tempfile
from pathlib import Path

import pytest

_HF_TMP = Path(tempfile.mkdtemp(prefix="unidextok-tests-hf-"))
os.environ.setdefault("HF_HOME", str(_HF_TMP / "hf"))
os.environ.setdefault("HF_LEROBOT_HOME", str(_HF_TMP / "hf" / "lerobot"))
os.environ.setdefault("HF_DATASETS_CACHE", str(_HF_TMP / "hf" / "datasets"))
os.environ.setdefault("HF_HUB_OFFLINE", "1")
os.environ.setdefault("MPLBACKEND", "Agg")
# Any request that escapes loopback fails fast instead of hanging.
os.environ.setdefault("HTTPS_PROXY", "http://127.0.0.1:9")
os.environ.setdefault("HTTP_PROXY", "http://127.0.0.1:9")
os.environ.setdefault("NO_PROXY", "127.0.0.1,localhost")

from lerobot_unidextok.utils.shared_data import real_data_dir  # noqa: E402  (after the HF variables)

REPO_ROOT = Path(__file__).resolve().parents[1]


def _kept_root_logging():
    """Around each test phase: the root logger's handlers and level as they were. A CLI's `main()` run in a test's
    process sets up logging (`logging.basicConfig`) on that test's captured stderr, which is closed once the test
    ends; a later test in the same worker then logged "--- Logging error ---" tracebacks into its own stderr."""
    root = logging.getLogger()
    handlers, level = root.handlers[:], root.level
    try:
        return (yield)
    finally:
        root.handlers[:] = handlers
        root.setLevel(level)


@pytest.hookimpl(wrapper=True)
def pytest_runtest_setup(item):
    return (yield from _kept_root_logging())


@pytest.hookimpl(wrapper=True)
def pytest_runtest_call(item):
    return (yield from _kept_root_logging())


@pytest.hookimpl(wrapper=True)
def pytest_runtest_teardown(item, nextitem):
    return (yield from _kept_root_logging())


def pytest_collection_modifyitems(config, items):
    """Test files longest first, by their times in tests/durations.json (`tools/test_durations.py` writes it); a
    file not listed goes last, and each file's tests keep their order. `make test` hands whole files to its
    workers in this order (`--dist loadfile --no-loadscope-reorder`), so the run does not end on one worker
    finishing a long file while the other idles (xdist's own order, by number of tests, left 40-80 s of that)."""
    listed = REPO_ROOT / "tests" / "durations.json"  # absent (a copy of this conftest elsewhere): collection order
    durations = json.loads(listed.read_text()) if listed.is_file() else {}

    def seconds(item) -> float:
        path = item.path
        return durations.get(path.relative_to(REPO_ROOT).as_posix(), 0.0) if path.is_relative_to(REPO_ROOT) else 0.0

    items.sort(key=lambda item: -seconds(item))


REAL_DATA_DIR = real_data_dir(REPO_ROOT)


@pytest.fixture(scope="session")
def real_data_dir() -> Path:
    """The real recordings kept beside the checkout (../shared/data/real): skips when the folder is absent,
    fails when it is present but incomplete."""
    if not REAL_DATA_DIR.is_dir():
        pytest.skip(
            f"real hand recordings not found at {REAL_DATA_DIR}; "
            "set UNIDEXTOK_REAL_DATA to a copy of shared/data/real to run these tests"
        )
    from real_data import missing_real_data  # tests/fixtures/real_data.py

    missing = missing_real_data(REAL_DATA_DIR)
    if missing:
        pytest.fail(
            f"{REAL_DATA_DIR} is present but incomplete, missing {missing}: copy the whole shared/data/real "
            "folder (or point UNIDEXTOK_REAL_DATA at a complete copy, or at a path that does not exist to skip)",
            pytrace=False,
        )
    return REAL_DATA_DIR


# Real LinkerHand L10 vendor presets as UDHM (tests/fixtures/linkerhand_udhm.py), shared by the
# processor, hub and policy tests.
sys.path.insert(0, str(Path(__file__).resolve().parent / "fixtures"))


@pytest.fixture(scope="session")
def l10_states(real_data_dir):
    """(P, 44) float32 UDHM radians of real two-hand L10 preset poses."""
    from linkerhand_udhm import l10_preset_states

    return l10_preset_states(real_data_dir)


@pytest.fixture(scope="session")
def l10_dataset(real_data_dir, tmp_path_factory) -> Path:
    """A LeRobotDataset v3.0 folder following the converted-dataset contract."""
    from linkerhand_udhm import write_l10_dataset

    return write_l10_dataset(tmp_path_factory.mktemp("l10") / "ds", real_data_dir)


@pytest.fixture(scope="session")
def g1_like(tmp_path_factory) -> dict:
    """A synthetic whole-robot dataset in the converted contract: 14 G1 arm joints + 2 Inspire UDHM blocks,
    with `native_layout` (tests/fixtures/robot_udhm.py); {"root", "native_state", "native_action"}."""
    from robot_udhm import write_g1_like_dataset

    return write_g1_like_dataset(tmp_path_factory.mktemp("g1_like") / "ds")


@pytest.fixture(scope="session")
def g1_like_hands(tmp_path_factory) -> dict:
    """The hands-only variant of `g1_like`: state and action are the two Inspire UDHM blocks (44 wide)."""
    from robot_udhm import write_g1_like_dataset

    return write_g1_like_dataset(tmp_path_factory.mktemp("g1_like_hands") / "ds", arms=False)


@pytest.fixture(scope="session")
def l10_robot(tmp_path_factory) -> Path:
    """A robot with one LinkerHand L10 on the right (synthetic motion in SDK units), recorded as a plain LeRobot
    v3.0 dataset and converted by the project's converter (tests/fixtures/l10_robot.py)."""
    from l10_robot import convert_l10_robot, write_l10_robot

    base = tmp_path_factory.mktemp("l10_robot")
    return convert_l10_robot(write_l10_robot(base / "raw", episodes=5), base / "udhm")


@pytest.fixture(scope="session")
def g1_l10_mix(g1_like, l10_robot, tmp_path_factory) -> Path:
    """The synthetic G1-like robot (two Inspire hands, arms) mixed with the right-only L10 robot (unidextok-mix)."""
    from lerobot_unidextok.conversion.mix import MixOptions, mix

    root = tmp_path_factory.mktemp("mix") / "g1_l10"
    mix(MixOptions(inputs=[str(g1_like["root"]), str(l10_robot)], root=str(root), repo_id="test/g1_l10_mix",
                   progress=False))  # fmt: skip
    return root


@pytest.fixture(scope="module")
def tok_dir(tmp_path_factory):
    """A tiny untrained tokenizer knowing the human hand, the L10 and the Inspire (the mixes of the pooling,
    hand-head and mixed-step tests; a test module may define its own)."""
    import torch
    from l10_robot import HAND as L10
    from robot_udhm import INSPIRE

    from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

    torch.manual_seed(2)
    path = tmp_path_factory.mktemp("tok") / "unidextok-tiny"
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["human", L10, INSPIRE])).save_pretrained(path)
    return path
