"""Success rates and their Wilson intervals, from what lerobot-eval writes."""

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from lerobot_env_unidextok.errors import SimInputError
from lerobot_env_unidextok.success import describe, from_eval_info, wilson_interval


def test_wilson_interval_matches_published_values():
    # Wilson score interval, 95 %: 0/10 -> [0, 0.2775], 5/10 -> [0.2366, 0.7634] (Newcombe 1998, table I)
    assert wilson_interval(0, 10) == pytest.approx((0.0, 0.2775), abs=1e-4)
    assert wilson_interval(5, 10) == pytest.approx((0.2366, 0.7634), abs=1e-4)
    assert wilson_interval(10, 10)[1] == pytest.approx(1.0) and wilson_interval(10, 10)[0] == pytest.approx(0.7225, abs=1e-4)


def test_reads_lerobot_evals_output(tmp_path):
    (tmp_path / "eval_info.json").write_text(json.dumps({"overall": {"pc_success": 62.0, "n_episodes": 50}}))
    assert from_eval_info(tmp_path) == (31, 50)
    assert describe(31, 50) == "success 31/50 = 62.0 % (95 % Wilson interval 48.2-74.1 %)"
    with pytest.raises(SimInputError, match="lerobot-eval's --output_dir"):
        from_eval_info(tmp_path / "missing")


@pytest.mark.parametrize(("content", "said"), [
    ('{"overall": {"pc_success": 62.0, ', "is not JSON (Expecting"),
    ('[1, 2]', "has no 'overall' section"),
    ('{"per_task": []}', "has no 'overall' section"),
    ('{"overall": {"n_episodes": 50}}', "'overall' has no 'pc_success'"),
    ('{"overall": {"pc_success": "lots", "n_episodes": 50}}', "'overall.pc_success' is 'lots', not a number"),
    ('{"overall": {"pc_success": 150, "n_episodes": 50}}', "'overall.pc_success' is 150, outside 0-100 %"),
    ('{"overall": {"pc_success": -5, "n_episodes": 50}}', "'overall.pc_success' is -5, outside 0-100 %"),
    ('{"overall": {"pc_success": 50.0, "n_episodes": 2.5}}', "'overall.n_episodes' is 2.5, not a whole number"),
    ('{"overall": {"pc_success": 0.0, "n_episodes": 0}}', "no episodes: 'overall.n_episodes' is 0"),
    ('{"overall": {"pc_success": NaN, "n_episodes": 0}}', "no episodes: 'overall.n_episodes' is 0"),
    ('{"overall": {"pc_success": 33.0, "n_episodes": 2}}', "33.0 % of 2 episodes is not a whole number of episodes"),
    ('{"overall": {"pc_success": 50.0, "n_episodes": 1e20}}', "'overall.n_episodes' is 1e+20, more than any"),
    ('{"overall": {"pc_success": 50.0, "n_episodes": 100000000000000000000}}', "more than any lerobot-eval run"),
])  # fmt: skip
def test_a_malformed_or_impossible_eval_info_is_one_clear_error(tmp_path, content, said):
    """Before: tracebacks on malformed JSON, a missing 'overall' and a pc_success of 150, and 0 of 0 episodes
    reported as 'success 0/0 = 0.0 %'."""
    (tmp_path / "eval_info.json").write_text(content)
    with pytest.raises(SimInputError, match=re.escape(said)) as err:
        from_eval_info(tmp_path)
    assert str(tmp_path / "eval_info.json") in str(err.value)


@pytest.mark.parametrize("given", ["output_dir", "file"])
def test_an_eval_info_that_is_a_folder_is_said_to_be_one(tmp_path, given):
    """Before: reported as "not there" (it is there, as a folder)."""
    (tmp_path / "eval_info.json").mkdir()
    with pytest.raises(SimInputError, match=r"eval_info.json is a folder, not the file lerobot-eval writes"):
        from_eval_info(tmp_path if given == "output_dir" else tmp_path / "eval_info.json")


def test_the_cli_says_no_episodes_in_one_line(tmp_path):
    (tmp_path / "eval_info.json").write_text(json.dumps({"overall": {"pc_success": 0.0, "n_episodes": 0}}))
    r = subprocess.run([str(Path(sys.executable).parent / "unidextok-sim-success"), f"--eval={tmp_path}"],
                       capture_output=True, text=True, timeout=120)  # fmt: skip
    assert r.returncode == 2 and r.stdout == "" and "0.0 %" not in r.stderr
    assert [line for line in r.stderr.splitlines() if line.startswith("error:")] == [
        f"error: {tmp_path / 'eval_info.json'}: no episodes: 'overall.n_episodes' is 0, so there is no success rate "
        "(run lerobot-eval with --eval.n_episodes >= 1)"
    ], r.stderr
