"""The kept-statistics ablation's table: gains over the hand alone per pool, for each fine-tune, from its runs."""

import pytest

from experiments import kept_state_stats as kss


def _run(hand: str, seed: int, kept: int, swapped: int, alone: int, pool: int = 2) -> dict:
    return {"task": "T", "hand": hand, "seed": seed, "arm": f"mix_ft_default_10_pool{pool}", "pool": pool,
            "kept": kept, "swapped": swapped, "alone": alone, "episodes": 50, "cpu_s": 30.0}  # fmt: skip


def test_the_table_gives_each_fine_tunes_mean_gain_and_the_targets_within_3_points():
    runs = [_run("a", 0, 20, 10, 10), _run("a", 1, 20, 10, 10),  # a: kept +20, swapped 0
            _run("b", 0, 5, 10, 10), _run("b", 1, 5, 10, 10),  # b: kept -10, swapped 0
            _run("c", 0, 9, 9, 9, pool=3)]  # fmt: skip
    text = kss.markdown({"runs": runs})
    assert "| T | 2 | +5.0 (1 of 2) | +0.0 (2 of 2) | a +20, b -10 | 2.0 |" in text
    assert "| T | 3 | +0.0 (1 of 1) | +0.0 (1 of 1) | c +0 | 0.5 |" in text


def test_a_missing_closed_loop_run_is_named_with_the_command_that_makes_it(tmp_path):
    cfg = kss.KeptStatsConfig(tasks=["GraspLift-v0"], hands=["shadow", "leap"], seeds=[0],
                              output_root=str(tmp_path), cache_dir=str(tmp_path / "sim"))  # fmt: skip
    with pytest.raises(FileNotFoundError, match=r"run closed_loop.py with --arms='\[alone,mix_ft_default\]'"):
        kss.run(cfg)
