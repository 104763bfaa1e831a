"""experiments/user_path.py: the cell it runs is the table's, as the stock command lines closed_loop renders."""

import pytest

from experiments import closed_loop as cl
from experiments import user_path as up


def test_the_cell_is_one_job_of_the_table_and_its_commands_are_the_rendered_ones(tmp_path):
    cfg = up.UserPathConfig(hand="shadow", pool=3, seed=1, output_root=str(tmp_path / "u"))
    user = up.closed_loop_config(cfg, cfg.output_root)
    job = up.cell_job(user)
    assert (job["hand"], job["kind"], job["pool"], job["seed"], job["demos"]) == ("shadow", "mix", 3, 1, 10)
    table = up.closed_loop_config(cfg, cfg.table_root)
    assert up.cell_job(table)["arm"] == job["arm"]  # the kept run it is compared with is the same cell's
    lines = cl.user_commands(user, job)
    assert [line.split()[0] for line in lines] == ["unidextok-sim-record", "unidextok-convert"] * 3 + [
        "unidextok-mix", "lerobot-train", "unidextok-deploy", "lerobot-eval"]
    assert all(str(tmp_path / "u") in line for line in lines if not line.startswith("lerobot-train"))
    with pytest.raises(ValueError, match="one-training arms"):
        up.UserPathConfig(arm="mix_ft")


def test_the_report_sets_the_users_success_beside_the_tables():
    result = {"job": {"task": "GraspLift-v0", "hand": "shadow", "arm": "mix_10_pool2", "seed": 0},
              "commands": ["a"] * 7, "cpu_s": 120.0, "wall_s": 90.0,
              "user": {"successes": 33, "episodes": 50, "interval": (0.52, 0.77)},
              "table": {"successes": 33, "episodes": 50, "interval": (0.52, 0.77), "recipe_equal": True},
              "same_weights": True}  # fmt: skip
    text = up.markdown(result)
    assert "- the user's path: 33/50 (52-77 %)" in text and "- the table's run: 33/50 (52-77 %)" in text
    assert "- the same model.safetensors: yes" in text
    assert "none kept" in up.markdown({**result, "table": None})
