"""Fine-tuning the shipped universal tokenizer vs training from scratch, end to end at a tiny size on a converted
sample G1 dataset (no ../shared needed): what each row starts from, what it is scored on, and the run cache."""

import json
from pathlib import Path

import numpy as np
import pytest

from experiments import finetune
from lerobot_unidextok.configs import shipped_config
from lerobot_unidextok.pretrained import UNIVERSAL_SMALL
from lerobot_unidextok.tokenizer import NEAREST_CODES

TINY_RECIPE = shipped_config("train/tiny")
NO_STEP = 1e-12  # a fine-tune lr whose updates stay far below float32 resolution of the weights


def _argv(dataset: Path, out: Path, *extra: str) -> list[str]:
    return [f"--dataset={dataset}", f"--recipe={TINY_RECIPE}", "--steps=[2]", "--seeds=[0]",
            f"--finetune_lrs=[{NO_STEP},0.003]", f"--output_root={out}", *extra]  # fmt: skip


@pytest.fixture(scope="module")
def result(converted_g1, tmp_path_factory) -> tuple[dict, Path]:
    out = tmp_path_factory.mktemp("finetune")
    return finetune.run(finetune.parse(_argv(converted_g1, out))), out


def _scored(model, test, encoding) -> dict:
    from lerobot_unidextok.evaluation.report import evaluate_tokenizer

    model.with_encoding(encoding)
    return evaluate_tokenizer(model, test)["overall"]


def _row(result: dict, condition: str, lr: float | None = None) -> dict:
    rows = [r for r in result["runs"] if r["condition"] == condition and (lr is None or r["lr"] == lr)]
    assert len(rows) == 1, (condition, lr, [(r["condition"], r["lr"]) for r in result["runs"]])
    return rows[0]


def test_every_row_is_scored_on_the_test_split_only(result, converted_g1):
    from lerobot_unidextok.evaluation.report import evaluate_tokenizer
    from lerobot_unidextok.tokenizer import UniDexTok
    from lerobot_unidextok.training import load_hand_states

    res, _ = result
    test = load_hand_states([str(converted_g1)], split="test")
    train = load_hand_states([str(converted_g1)], split="train")
    test_eps = sorted(np.unique(test.episode_index).tolist())
    train_eps = sorted(np.unique(train.episode_index).tolist())
    assert len(test_eps) == 1 and len(train_eps) == 4 and res["test_episodes"] == test_eps
    assert [(r["condition"], r["steps"]) for r in res["runs"]] == [
        ("checkpoint as it is", 0), ("scratch", 2), ("fine-tuned", 2), ("fine-tuned", 2)]
    for r in res["runs"]:
        assert r["test_episodes"] == test_eps and r["test_rows"] == len(test)
        assert all(np.isfinite(v) and v > 0 for v in r["overall"].values()), r["overall"]
        if r["condition"] != "checkpoint as it is":  # trained on train episodes only, one held out for selection
            assert sorted(r["fit_episodes"] + r["select_episodes"]) == train_eps
            assert len(r["select_episodes"]) == 1 and not set(r["fit_episodes"]) & set(test_eps)
            assert r["best_step"] == 2 and r["train_cpu_s"] > 0
            # its figures are its kept checkpoint's on exactly the test rows, through the nearest codes and with
            # the code search (a fine-tuned model inherits the shipped config's search; the main columns do not use it)
            again = _scored(UniDexTok.from_pretrained(r["model_dir"]), test, NEAREST_CODES)
            assert r["overall"] == pytest.approx({k: again[k] for k in r["overall"]}, rel=1e-9)
            searched = _scored(UniDexTok.from_pretrained(r["model_dir"]), test, finetune.FinetuneConfig().searched)
            assert r["searched"]["mpjae_deg"] == pytest.approx(searched["mpjae_deg"], rel=1e-9)
            assert r["searched"]["mpjae_deg"] < r["overall"]["mpjae_deg"]
    # the checkpoint row is the shipped model evaluated on exactly these rows
    shipped = _scored(UniDexTok.from_pretrained(UNIVERSAL_SMALL), test, NEAREST_CODES)
    assert _row(res, "checkpoint as it is")["overall"]["mpjae_deg"] == pytest.approx(shipped["mpjae_deg"], rel=1e-9)
    assert res["summary"][0]["searched_mpjae_deg"] == pytest.approx(evaluate_tokenizer(
        UniDexTok.from_pretrained(UNIVERSAL_SMALL), test)["overall"]["mpjae_deg"], rel=1e-9)  # the shipped encoding


def test_finetuned_rows_start_from_the_checkpoint_and_scratch_does_not(result):
    from lerobot_unidextok.tokenizer import UniDexTok

    res, _ = result
    shipped = UniDexTok.from_pretrained(UNIVERSAL_SMALL)
    still = UniDexTok.from_pretrained(_row(res, "fine-tuned", NO_STEP)["model_dir"])
    assert still.config.num_tokens == shipped.config.num_tokens == 8  # the checkpoint's architecture, not tiny's
    ref = dict(shipped.named_parameters())
    for name, p in still.named_parameters():
        assert p.shape == ref[name].shape and np.allclose(p.detach(), ref[name].detach(), atol=1e-6), name
    # two optimiser steps that do not move the weights leave the checkpoint's test figures as they were
    assert _row(res, "fine-tuned", NO_STEP)["overall"]["mpjae_deg"] == pytest.approx(
        _row(res, "checkpoint as it is")["overall"]["mpjae_deg"], rel=1e-4)
    moved = UniDexTok.from_pretrained(_row(res, "fine-tuned", 0.003)["model_dir"])
    assert not np.allclose(moved.input_proj.weight.detach(), ref["input_proj.weight"].detach(), atol=1e-6)
    scratch = UniDexTok.from_pretrained(_row(res, "scratch")["model_dir"])
    assert scratch.config.num_tokens == 4  # the tiny recipe's own preset, trained from its random initialisation


def test_finished_runs_are_cached_and_only_new_budgets_train(result, converted_g1):
    res, out = result
    cache = out / "finetune" / "runs.jsonl"
    assert len(cache.read_text().splitlines()) == 3  # scratch + two fine-tune lrs; the checkpoint row trains nothing
    again = finetune.run(finetune.parse(_argv(converted_g1, out)))
    assert len(cache.read_text().splitlines()) == 3
    assert [r["overall"] for r in again["runs"]] == [r["overall"] for r in res["runs"]]
    more = finetune.run(finetune.parse(_argv(converted_g1, out, "--steps=[2,3]")))
    lines = [json.loads(line) for line in cache.read_text().splitlines()]
    assert len(lines) == 6 and {r["steps"] for r in lines[3:]} == {3}
    assert [s["steps"] for s in more["summary"]] == [0, 2, 2, 2, 3, 3, 3]
    md = (out / "finetune" / "finetune.md").read_text()
    assert "| fine-tuned | 3 | 0.003 | 1 |" in md and "| checkpoint as it is | 0 | - | - |" in md


def test_a_retrained_checkpoint_retrains_the_finetuned_rows_only(result, converted_g1, tmp_path):
    """The same checkpoint name with other weights (a retrained universal tokenizer; here the folder first holds
    the shipped model, then the scratch run's) retrains the fine-tuned rows; the scratch rows do not depend on
    it and are reused."""
    import shutil

    from lerobot_unidextok.pretrained import SHIPPED

    res, _ = result
    ckpt = tmp_path / "checkpoint"
    shutil.copytree(SHIPPED[UNIVERSAL_SMALL], ckpt)
    argv = _argv(converted_g1, tmp_path / "out", f"--finetune_lrs=[{NO_STEP}]", f"--checkpoint={ckpt}")
    first = finetune.run(finetune.parse(argv))
    cache = tmp_path / "out" / "finetune" / "runs.jsonl"
    assert len(cache.read_text().splitlines()) == 2
    shutil.rmtree(ckpt)
    shutil.copytree(_row(res, "scratch")["model_dir"], ckpt)
    second = finetune.run(finetune.parse(argv))
    lines = [json.loads(line) for line in cache.read_text().splitlines()]
    assert len(lines) == 3 and lines[2]["condition"] == "fine-tuned"
    assert first["checkpoint_fingerprint"] != second["checkpoint_fingerprint"]
    assert _row(second, "scratch") == _row(first, "scratch")
    # with NO_STEP a fine-tuned row keeps its checkpoint's figures: the shipped model's, then the other one's
    for r in (first, second):
        assert _row(r, "fine-tuned")["overall"]["mpjae_deg"] == pytest.approx(
            _row(r, "checkpoint as it is")["overall"]["mpjae_deg"], rel=1e-4)
    assert _row(second, "checkpoint as it is")["overall"] == pytest.approx(_row(res, "scratch")["overall"])


def test_bad_inputs_fail_with_one_clear_line(tmp_path):
    with pytest.raises(FileNotFoundError, match="dataset .*nowhere not found: convert one first"):
        finetune.run(finetune.parse([f"--dataset={tmp_path / 'nowhere'}", f"--recipe={TINY_RECIPE}",
                                     f"--output_root={tmp_path}"]))  # fmt: skip
    with pytest.raises(FileNotFoundError, match="recipe .* not found"):
        finetune.run(finetune.parse([f"--recipe={tmp_path / 'no.yaml'}", f"--output_root={tmp_path}"]))
    with pytest.raises(ValueError, match="steps must be a non-empty list of budgets >= 1"):
        finetune.FinetuneConfig(steps=[0])
    assert not (tmp_path / "finetune").exists()  # nothing written
    with pytest.raises(ValueError, match="only takes 'scratch' and 'fine-tuned'"):
        finetune.FinetuneConfig(only=["finetuned"])


def test_only_trains_the_named_condition():
    """`only=[scratch]` keeps the scratch trainings of every budget and seed and drops the fine-tuned ones
    (catches the filter inverted or ignored)."""
    cfg = finetune.FinetuneConfig(recipe=str(TINY_RECIPE), steps=[2, 3], seeds=[0, 1], finetune_lrs=[0.1, 0.2])
    assert len(finetune.conditions(cfg)) == 2 * 2 * 3
    only = finetune.conditions(finetune.FinetuneConfig(recipe=str(TINY_RECIPE), steps=[2, 3], seeds=[0, 1],
                                                       only=["scratch"]))  # fmt: skip
    assert [(c.name, c.steps, c.seed) for c in only] == [("scratch", s, d) for s in (2, 3) for d in (0, 1)]
