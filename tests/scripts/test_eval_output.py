"""`unidextok-eval --output`: one rule for where the report goes, and the paths written are printed (issue 45 Q1:
`--output=evalout/` wrote `evalout.json` beside the folder and printed no path)."""

import json
import sys
from pathlib import Path

import pytest

from lerobot_unidextok.scripts.eval import main, report_stem


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory) -> Path:
    from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

    folder = tmp_path_factory.mktemp("tok") / "tiny"
    UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["inspire_rh56_unitree"])).save_pretrained(folder)
    return folder


def _eval(checkpoint: Path, dataset: Path, output: str, monkeypatch, capsys) -> tuple[int, str, str]:
    monkeypatch.setattr(sys, "argv", ["unidextok-eval", f"--checkpoint={checkpoint}", f"--datasets=[{dataset}]",
                                      "--split=all", f"--output={output}"])  # fmt: skip
    try:
        main()
        code = 0
    except SystemExit as exit_info:
        code = exit_info.code
    out = capsys.readouterr()
    return code, out.out, out.err


def test_the_output_rule(tmp_path):
    (tmp_path / "there").mkdir()
    assert report_stem(f"{tmp_path}/evalout/") == tmp_path / "evalout" / "eval"  # a trailing slash: a folder
    assert report_stem(str(tmp_path / "there")) == tmp_path / "there" / "eval"  # an existing folder
    assert report_stem(str(tmp_path / "r.json")) == report_stem(str(tmp_path / "r.md")) == tmp_path / "r"
    assert report_stem(str(tmp_path / "run.v2")) == tmp_path / "run.v2"  # not run.json


@pytest.mark.parametrize("output, written", [("evalout/", "evalout/eval"), ("there", "there/eval"),
                                             ("run.v2", "run.v2"), ("r.json", "r")])  # fmt: skip
def test_eval_writes_where_the_rule_says_and_prints_the_paths(checkpoint, g1_like, tmp_path, monkeypatch, capsys,
                                                              output, written):  # fmt: skip
    (tmp_path / "there").mkdir()
    code, out, _ = _eval(checkpoint, g1_like["root"], f"{tmp_path}/{output}", monkeypatch, capsys)
    stem = tmp_path / written
    assert code == 0
    assert json.loads(Path(f"{stem}.json").read_text())["per_hand"] and Path(f"{stem}.md").is_file()
    assert out.strip().splitlines()[-1] == f"wrote {stem}.json and {stem}.md"
    assert not (tmp_path / "evalout.json").exists()


def test_an_output_inside_the_dataset_is_one_error_line(checkpoint, g1_like, monkeypatch, capsys):
    root = g1_like["root"]
    code, _, err = _eval(checkpoint, root, f"{root}/meta/", monkeypatch, capsys)
    assert code == 2 and err.splitlines()[0].startswith(f"error: --output {root}/meta/eval.json") and "inside" in err
    assert not (root / "meta" / "eval.json").exists()
