"""Screening the universal recipe at a tiny size on the converted synthetic G1 sample (no ../shared needed):
variants train and are scored on the selection episodes and in-range states, runs are cached, and a finished
run folder scores the same as the variant that wrote it."""

import json
from pathlib import Path

import pytest

from experiments import universal_screen
from lerobot_unidextok import hands


@pytest.fixture(scope="module")
def recipe(converted_g1, tmp_path_factory) -> Path:
    path = tmp_path_factory.mktemp("cfg") / "recipe.yaml"
    path.write_text(f"preset: tiny\ndatasets: [{converted_g1}]\nrange_hands: [linkerhand_l6]\nbatch_size: 16\n"
                    "warmup_steps: 1\neval_every: 2\nselect_fraction: 0.25\nnum_threads: 1\n")  # fmt: skip
    return path


def test_variants_are_scored_on_selection_episodes_and_cached(recipe, tmp_path):
    argv = [f"--recipe={recipe}", "--variants=[shipped,anneal]", "--steps=2", "--range_rows=20",
            f"--output_root={tmp_path}"]  # fmt: skip
    result = universal_screen.run(universal_screen.parse(argv))
    runs = {r["variant"]: r for r in result["runs"]}
    assert set(runs) == {"shipped", "anneal"}
    for r in runs.values():
        assert r["steps"] == 2 and r["select_rows"] > 0
        assert set(r["select_deg"]) == {"inspire_rh56_unitree"}  # the recorded hand; range hands have no episodes
        assert set(r["in_range_deg"]) == set(hands.names())  # every registered hand on its in-range states
        assert r["in_range_max"] == max(r["in_range_deg"].values())
    assert runs["anneal"]["resolved"]["train"]["reseed_until"] == 0.7
    cache = tmp_path / "universal_screen" / "runs.jsonl"
    lines = cache.read_text().splitlines()
    again = universal_screen.run(universal_screen.parse(argv))  # cached: nothing trains again
    assert cache.read_text().splitlines() == lines
    assert again["runs"] == json.loads(json.dumps(result["runs"]))

    # a finished run folder is scored the same way: the shipped variant's own folder gives its figures
    folder = tmp_path / "universal_screen" / "models" / "shipped"
    scored = universal_screen.run(universal_screen.parse([f"--recipe={recipe}", f"--runs=[{folder}]",
                                                          "--range_rows=20", f"--output_root={tmp_path}"]))  # fmt: skip
    (row,) = scored["runs"]
    assert row["select_deg"] == pytest.approx(runs["shipped"]["select_deg"])
    assert row["in_range_deg"] == pytest.approx(runs["shipped"]["in_range_deg"])
    assert "finished run folders" in universal_screen.markdown(scored)

    # ... and once per code search setting: the nearest codes first, then each method's rounds x sweeps or
    # rounds x changes pairs
    searched = universal_screen.run(universal_screen.parse([f"--recipe={recipe}", f"--runs=[{folder}]",
                                                            "--range_rows=20", "--rounds=[0,1]",
                                                            "--methods=[sweeps,greedy]", "--changes=[8]",
                                                            "--sweeps=[1,2]", f"--output_root={tmp_path}"]))  # fmt: skip
    assert [r["search"] for r in searched["runs"]] == ["nearest codes", "sweeps 1 x 1", "sweeps 1 x 2", "greedy 1 x 8"]
    assert searched["runs"][0]["in_range_deg"] == pytest.approx(row["in_range_deg"])
    for r in searched["runs"][1:]:  # the search never worsens a row's squared error: the mean drops
        assert r["in_range_mean"] < searched["runs"][0]["in_range_mean"]
    assert "(sweeps 1 x 2)" in (tmp_path / "universal_screen" / "runs_scored.md").read_text()


def test_search_settings_and_their_labels():
    cfg = universal_screen.ScreenConfig(rounds=[0, 1, 2], methods=["greedy", "sweeps"],
                                        changes=[8], sweeps=[2], tolerances_deg=[0.0, 0.1])  # fmt: skip
    labels = [universal_screen.search_label(s) for s in universal_screen.search_settings(cfg)]
    # a tolerance only matters from the second round on: one-round settings are scored once
    assert labels == ["nearest codes", "greedy 1 x 8", "greedy 2 x 8", "greedy 2 x 8, stop at 0.1 deg",
                      "sweeps 1 x 2", "sweeps 2 x 2"]  # fmt: skip


def test_unknown_variants_and_missing_runs_fail_clearly(recipe, tmp_path):
    with pytest.raises(ValueError, match="unknown variants \\['nope'\\]"):
        universal_screen.run(universal_screen.parse([f"--recipe={recipe}", "--variants=[nope]",
                                                     f"--output_root={tmp_path}"]))  # fmt: skip
    with pytest.raises(FileNotFoundError, match="best not found"):
        universal_screen.run(universal_screen.parse([f"--recipe={recipe}", f"--runs=[{tmp_path / 'none'}]",
                                                     f"--output_root={tmp_path}"]))  # fmt: skip
