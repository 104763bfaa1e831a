"""Success rates and their Wilson intervals, from what lerobot-eval writes."""

import json

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
