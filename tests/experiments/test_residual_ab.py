"""experiments/residual_ab.py on a tiny configuration: both arms trained by the recipe's loop, scored on the
card's in-range states next to the shipped tokenizer, with the symbols each reading emits."""

import json

from experiments import residual_ab


def test_both_arms_and_the_reference_are_scored_on_the_same_rows(tmp_path):
    argv = ["--hands=[inspire_rh56_unitree]", "--tiny=true", "--rows=24", "--train_rows=200",
            f"--output_root={tmp_path}"]  # fmt: skip
    result = residual_ab.run(residual_ab.parse(argv))
    rows = result["rows"]
    assert [r["symbols"] for r in rows] == [32, 64, 32, 64, 64]  # tiny: 4 x 8 a stage; shipped: 8 x 8
    assert [r["encoding"] for r in rows][:3] == ["nearest codes", "nearest codes, both stages",
                                                 "nearest codes, first stage alone"]  # fmt: skip
    for r in rows:
        assert set(r["mpjae_deg"]) == {"inspire_rh56_unitree"} and r["mpjae_deg"]["inspire_rh56_unitree"] > 0
    shipped_nearest, shipped_search = rows[3]["mpjae_deg"], rows[4]["mpjae_deg"]
    assert shipped_search["inspire_rh56_unitree"] < shipped_nearest["inspire_rh56_unitree"]
    assert rows[0]["cpu_s"] > 0 and rows[1]["cpu_s"] > 0
    folder = tmp_path / "residual_ab"
    assert json.loads((folder / "residual_ab.json").read_text())["rows"] == rows
    assert "| same + one residual stage | nearest codes, first stage alone | 32 |" in (folder / "residual_ab.md").read_text()
