"""Datasets found by repo id in LeRobot's home, the HF hub cache (tag v3.0 before main) and LeRobot's cache."""

import pytest

from lerobot_unidextok.utils.hf_cache import cached_repo_snapshot, dataset_root, find_dataset


def _snapshot(cache, repo_id: str, ref: str, commit: str):
    repo = cache / f"datasets--{repo_id.replace('/', '--')}"
    (repo / "refs").mkdir(parents=True, exist_ok=True)
    (repo / "refs" / ref).write_text(commit)
    snap = repo / "snapshots" / commit
    (snap / "meta").mkdir(parents=True)
    (snap / "meta" / "info.json").write_text("{}")
    return snap


@pytest.fixture
def homes(tmp_path, monkeypatch):
    monkeypatch.setenv("HF_HOME", str(tmp_path / "hf"))
    monkeypatch.delenv("HF_HUB_CACHE", raising=False)
    monkeypatch.setenv("HF_LEROBOT_HOME", str(tmp_path / "lerobot"))
    return tmp_path


def test_hub_cache_snapshot_at_tag_v3_is_found(homes):
    """unidextok-train/-eval --datasets=<repo id> only looked in $HF_HOME/lerobot, not where the pull put it."""
    snap = _snapshot(homes / "hf" / "hub", "lab/ds", "v3.0", "abc123")
    assert find_dataset("lab/ds") == snap
    assert cached_repo_snapshot(homes / "hf" / "hub", "lab/ds", "dataset", ("main",)) is None
    main = _snapshot(homes / "hf" / "hub", "lab/ds", "main", "def456")
    assert find_dataset("lab/ds") == snap  # the codebase tag wins over main
    assert cached_repo_snapshot(homes / "hf" / "hub", "lab/ds", "dataset", ("main",)) == main


def test_lookup_order_and_error(homes):
    lerobot_snap = _snapshot(homes / "lerobot" / "hub", "lab/ds", "v3.0", "111")
    assert find_dataset("lab/ds") == lerobot_snap  # LeRobot's own download cache
    local = homes / "lerobot" / "lab" / "ds"
    (local / "meta").mkdir(parents=True)
    (local / "meta" / "info.json").write_text("{}")
    assert find_dataset("lab/ds") == local  # $HF_LEROBOT_HOME/<repo_id> first, as LeRobotDataset does
    with pytest.raises(
        FileNotFoundError, match=r"(?s)'lab/other' is not on this machine.*unidextok-pull --repo_id=lab/other"
    ):
        dataset_root("lab/other")
