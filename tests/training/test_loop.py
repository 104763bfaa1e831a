"""The training loop: learning, checkpoint selection, resume, few-shot and zero-shot protocols."""

import json
import re
import time
from pathlib import Path

import numpy as np
import pytest
import torch

from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig
from lerobot_unidextok.training import TrainConfig, build_model, evaluate_mae_deg, subsample_episodes, train_tokenizer
from lerobot_unidextok.training.loop import joint_ranges_rad


def _cfg(tmp_path, **kw) -> TrainConfig:
    base = dict(preset="tiny", steps=200, batch_size=64, lr=3e-3, warmup_steps=20, eval_every=100,
                output_dir=str(tmp_path / "run"), progress=False, save_last_every=100, num_threads=1)  # fmt: skip
    base.update(kw)
    return TrainConfig(**base)


def test_training_tiny_reduces_mae_far_below_untrained(mixture, tmp_path):
    train, test = mixture
    cfg = _cfg(tmp_path)
    torch.manual_seed(cfg.seed)
    untrained, _ = evaluate_mae_deg(build_model(cfg, train), test, 10_000, 0)
    result = train_tokenizer(cfg, train, test)
    assert result.best_mae_deg < 0.4 * untrained, (result.best_mae_deg, untrained)
    assert result.best_mae_deg < 12.0
    assert [h["step"] for h in result.history] == [100, 200]
    # the kept checkpoint is the one with the lowest held-out MAE, and reloads to that number
    assert result.best_mae_deg == min(h["eval_mae_deg"] for h in result.history)
    best = UniDexTok.from_pretrained(result.best_dir)
    again, usage = evaluate_mae_deg(best, test, 10_000, 0)
    assert again == pytest.approx(result.best_mae_deg, abs=1e-9)
    assert 0 < usage["usage"] <= 1
    assert json.loads((result.best_dir / "training_state.json").read_text())["step"] == result.best_step


def test_progress_bar_off_a_terminal_writes_the_start_and_the_end(mixture, tmp_path, capsys, monkeypatch):
    """Training wrote 213 bar updates into a log in 3 minutes, the step counter frozen at 0/2000 while the
    loss postfix changed every 10 steps. Off a terminal the bar refreshes every 30 s, counter and postfix together."""
    monkeypatch.delenv("TQDM_MININTERVAL", raising=False)
    train, test = mixture
    t0 = time.perf_counter()
    train_tokenizer(_cfg(tmp_path, steps=60, eval_every=60, progress=True), train, test)
    elapsed = time.perf_counter() - t0
    refreshes = re.findall(r"(\d+)/60 \[([^\]]*)\]", capsys.readouterr().err)  # stderr is captured: not a tty
    assert 2 <= len(refreshes) <= 2 + elapsed // 30, (elapsed, refreshes)  # start, end, one per 30 s between
    assert refreshes[0][0] == "0" and refreshes[-1][0] == "60"
    assert "loss=" in refreshes[-1][1] and "mae_deg=" in refreshes[-1][1]


def test_resume_continues_from_last_checkpoint(mixture, tmp_path):
    train, test = mixture
    kw = dict(eval_every=10, save_last_every=10, warmup_steps=2, batch_size=16)
    first = train_tokenizer(_cfg(tmp_path, steps=20, **kw), train, test)
    state = json.loads((tmp_path / "run" / "last" / "training_state.json").read_text())
    assert state["step"] == 20 and len(state["history"]) == 2
    resumed = train_tokenizer(_cfg(tmp_path, steps=30, resume=True, **kw), train, test)
    assert [h["step"] for h in resumed.history] == [10, 20, 30]
    assert resumed.history[:2] == first.history
    assert json.loads((tmp_path / "run" / "last" / "training_state.json").read_text())["step"] == 30


class _Interrupt(Exception):
    """Stands in for a crash or a kill right after a checkpoint was written."""


def _run_interrupted(cfg: TrainConfig, train, test, stop_at: int, monkeypatch, model=None) -> None:
    """Train with `cfg`, stopping as if killed right after `last/` was saved at step `stop_at`."""
    from lerobot_unidextok.training import loop

    original = loop.save_checkpoint

    def save_then_stop(model, directory, optimizer=None, state=None, *rest):
        out = original(model, directory, optimizer, state, *rest)
        if optimizer is not None and state["step"] == stop_at:
            raise _Interrupt
        return out

    monkeypatch.setattr(loop, "save_checkpoint", save_then_stop)
    with pytest.raises(_Interrupt):
        train_tokenizer(cfg, train, test, model)
    monkeypatch.setattr(loop, "save_checkpoint", original)


def _checkpoint(folder) -> dict:
    from safetensors.torch import load_file

    return {"model": load_file(folder / "model.safetensors"), "optim": load_file(folder / "optimizer.safetensors"),
            "state": json.loads((folder / "training_state.json").read_text())}  # fmt: skip


def test_resume_equals_an_uninterrupted_run(mixture, tmp_path, monkeypatch):
    """A run killed after its step-20 checkpoint and resumed ends bit-identical to the same run uninterrupted:
    weights, optimiser state, history, best step (same seed, dead-code re-seeding and hand dropout on).

    Catches: a resume that starts a step late or early, ignores the saved weights or optimiser state,
    restarts the LR schedule, or draws other batches / dropout / re-seeds than the uninterrupted run."""
    train, test = mixture
    kw = dict(steps=30, eval_every=10, save_last_every=10, warmup_steps=2, batch_size=16, reseed_every=5,
              unknown_hand_prob=0.2)  # fmt: skip

    def fresh_model() -> UniDexTok:  # a high dead-code threshold, so re-seeding (and its statistics) matter
        torch.manual_seed(0)
        return UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=train.hand_names(), dead_code_threshold=0.9))

    full = train_tokenizer(_cfg(tmp_path, output_dir=str(tmp_path / "full"), **kw), train, test, fresh_model())
    _run_interrupted(_cfg(tmp_path, output_dir=str(tmp_path / "cut"), **kw), train, test, 20, monkeypatch,
                     fresh_model())  # fmt: skip
    assert _checkpoint(tmp_path / "cut" / "last")["state"]["step"] == 20
    resumed = train_tokenizer(_cfg(tmp_path, output_dir=str(tmp_path / "cut"), resume=True, **kw), train, test)
    assert resumed.history == full.history and [h["step"] for h in resumed.history] == [10, 20, 30]
    assert (resumed.best_step, resumed.best_mae_deg) == (full.best_step, full.best_mae_deg)
    a, b = _checkpoint(tmp_path / "full" / "last"), _checkpoint(tmp_path / "cut" / "last")
    assert a["state"] == b["state"]
    for part in ("model", "optim"):
        assert a[part].keys() == b[part].keys()
        changed = [k for k in a[part] if not torch.equal(a[part][k], b[part][k])]
        assert not changed, (part, changed[:5])


def test_resume_from_a_checkpoint_without_random_streams_is_deterministic(mixture, tmp_path, monkeypatch, caplog):
    """A checkpoint without saved random streams (written before exact resume, or by several processes)
    resumes with fresh streams seeded from (seed, step, process): it says so, and two resumes of the same
    checkpoint end identical (weights, history). Catches a broken seed formula on that path (a float or
    negative seed fails to build the generators) and a fallback that is not reproducible."""
    import logging
    import shutil

    train, test = mixture
    kw = dict(steps=30, eval_every=10, save_last_every=10, warmup_steps=2, batch_size=16, unknown_hand_prob=0.2)
    _run_interrupted(_cfg(tmp_path, output_dir=str(tmp_path / "a"), **kw), train, test, 20, monkeypatch)
    (tmp_path / "a" / "last" / "resume_state.safetensors").unlink()
    state_path = tmp_path / "a" / "last" / "training_state.json"  # written before file hashes were kept, too
    state_path.write_text(json.dumps({k: v for k, v in json.loads(state_path.read_text()).items() if k != "files"}))
    shutil.copytree(tmp_path / "a", tmp_path / "b")
    results = []
    for name in ("a", "b"):
        with caplog.at_level(logging.WARNING, logger="lerobot_unidextok.training.loop"):
            caplog.clear()
            results.append(train_tokenizer(_cfg(tmp_path, output_dir=str(tmp_path / name), resume=True, **kw), train,
                                           test))  # fmt: skip
        assert any("fresh random streams" in r.getMessage() for r in caplog.records)
    assert results[0].history == results[1].history and [h["step"] for h in results[0].history] == [10, 20, 30]
    a, b = _checkpoint(tmp_path / "a" / "last"), _checkpoint(tmp_path / "b" / "last")
    assert a["state"]["step"] == 30 and all(torch.equal(a["model"][k], b["model"][k]) for k in a["model"])


def test_zero_turns_reseeding_and_the_thread_setting_off(mixture, tmp_path):
    """`reseed_every=0` disables dead-code re-seeding and `num_threads=0` keeps torch's thread count, as the
    config documents; the thread count is the caller's again afterwards. Catches `> 0` tested as `>= 0` on
    either (a modulo by zero, or torch.set_num_threads(0), which raises)."""
    train, test = mixture
    before = torch.get_num_threads()
    result = train_tokenizer(_cfg(tmp_path, steps=3, eval_every=3, reseed_every=0, num_threads=0), train, test)
    assert result.steps == 3 and [h["step"] for h in result.history] == [3]
    assert torch.get_num_threads() == before


@pytest.mark.parametrize(
    ("adapt", "every", "until", "calls"),
    [("all", 5, 1.0, [5, 10]), ("all", 1, 1.0, list(range(1, 13))), ("hand_embedding", 5, 1.0, []),
     ("all", 1, 0.5, [1, 2, 3, 4, 5, 6]), ("all", 5, 0.0, [])],
)
def test_dead_codes_are_reseeded_every_n_steps_only_when_training_everything(
    mixture, tmp_path, adapt, every, until, calls
):
    """With `reseed_every=5` over 12 steps the quantiser re-seeds after optimiser steps 5 and 10 (with 1,
    after every step), and never when only the hand embedding adapts (the shared codebook stays as it is);
    `reseed_until=0.5` stops after the first 6 of 12 steps, 0 never re-seeds. Observed by counting the
    optimiser steps taken before each call. Catches the period off by one step (`step - 1`), re-seeding at
    every step but the period (`!= 0`), a period of 1 read as "off" (`> 0` -> `> 1`), re-seeding while
    adapting the embedding only (`and` -> `or`), and the stop off by one step (`<` -> `<=`)."""
    train, test = mixture
    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=train.hand_names()))
    seen: list[int] = []
    original = model.quantizer.reseed_dead_codes
    calls_before = []

    def counting() -> int:
        calls_before.append(len(seen))
        return original()

    model.quantizer.reseed_dead_codes = counting
    model.register_forward_hook(lambda *_: seen.append(1) if model.training else None)
    cfg = _cfg(tmp_path, steps=12, eval_every=12, reseed_every=every, reseed_until=until, adapt=adapt,
               warmup_steps=1)  # fmt: skip
    train_tokenizer(cfg, train, test, model)
    assert calls_before == calls


def test_evaluation_and_last_checkpoint_at_the_period_and_at_the_end(mixture, tmp_path, monkeypatch):
    """7 steps with eval_every=5 and save_last_every=5: held-out evaluations after steps 5 and 7, `last/`
    written after steps 5 and 7 (the end counts even off the period). Catches the final evaluation or save
    tested against the wrong step, a period shifted by one, and the run's duration computed as a sum of
    clock readings."""
    from lerobot_unidextok.training import loop

    train, test = mixture
    saved: list[tuple[str, int]] = []
    original = loop.save_checkpoint

    def recording(model, directory, optimizer=None, state=None, *rest):
        saved.append((directory.name, state["step"]))
        return original(model, directory, optimizer, state, *rest)

    monkeypatch.setattr(loop, "save_checkpoint", recording)
    t0 = time.perf_counter()
    result = train_tokenizer(_cfg(tmp_path, steps=7, eval_every=5, save_last_every=5, warmup_steps=1), train, test)
    assert 0 < result.seconds <= time.perf_counter() - t0  # the reported duration is of this run
    assert [h["step"] for h in result.history] == [5, 7]
    assert [step for name, step in saved if name == "last"] == [5, 7]
    assert all(step in (5, 7) for name, step in saved if name == "best")


def test_resume_without_checkpoint_is_a_clear_error(mixture, tmp_path):
    train, test = mixture
    with pytest.raises(FileNotFoundError, match="run once without --resume"):
        train_tokenizer(_cfg(tmp_path, steps=5, resume=True), train, test)


def test_few_shot_adds_the_hand_and_adapts(mixture, tmp_path):
    train, test = mixture
    base_cfg = _cfg(tmp_path, steps=100, eval_every=100, output_dir=str(tmp_path / "base"), hand_names=["human"])
    base = train_tokenizer(base_cfg, train.without("inspire_rh56"), test.only("human"))
    model = UniDexTok.from_pretrained(base.best_dir)
    assert not model.knows_hand("inspire_rh56") and model.knows_hand("human")
    assert model.config.trained_hands == ["human"]
    # zero-shot: the unseen hand goes through the unknown-hand embedding
    zero_shot, _ = evaluate_mae_deg(model, test.only("inspire_rh56"), 10_000, 0)

    few = subsample_episodes(train.only("inspire_rh56"), 0.1, seed=0)
    assert len(few) == round(0.1 * len(train.only("inspire_rh56")))
    cfg = _cfg(tmp_path, init_from=str(base.best_dir), epochs=4, batch_size=32, warmup_steps=2, eval_every=10,
               lr=1e-3, output_dir=str(tmp_path / "few"))  # fmt: skip
    result = train_tokenizer(cfg, few, test.only("inspire_rh56"))
    assert result.steps == int(np.ceil(4 * len(few) / 32))
    adapted = UniDexTok.from_pretrained(result.best_dir)
    assert adapted.knows_hand("inspire_rh56")
    assert adapted.config.trained_hands == ["human", "inspire_rh56"]  # the base's hands plus the adapted one
    assert result.best_mae_deg < zero_shot


def test_add_hands_starts_from_unknown_embedding():
    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["human"]))
    unknown = model.hand_embed.weight[-1].detach().clone()
    x = torch.rand(4, 22)
    before = model.encode(x, "new_hand", allow_unknown=True)
    assert model.add_hands(["new_hand", "human"]) == ["new_hand"]
    assert model.config.hand_names == ["human", "new_hand"]
    assert torch.equal(model.hand_embed.weight[1], unknown) and torch.equal(model.hand_embed.weight[2], unknown)
    assert torch.equal(model.encode(x, "new_hand"), before)


def test_hand_dropout_trains_the_zero_shot_path(mixture, tmp_path):
    """Without hand-embedding dropout the 'unknown hand' row is never trained, so an unseen hand's
    zero-shot reconstruction is arbitrary; with it, the unknown path learns the shared mapping."""
    train, test = mixture
    zero_shot = {}
    for prob in (0.0, 0.2):
        cfg = _cfg(tmp_path, unknown_hand_prob=prob, output_dir=str(tmp_path / f"p{prob}"), hand_names=["human"])
        result = train_tokenizer(cfg, train.without("inspire_rh56"), test.only("human"))
        model = UniDexTok.from_pretrained(result.best_dir)
        assert not model.knows_hand("inspire_rh56")
        zero_shot[prob], _ = evaluate_mae_deg(model, test.only("inspire_rh56"), 10_000, 0)
    assert zero_shot[0.2] < 0.5 * zero_shot[0.0], zero_shot
    with pytest.raises(ValueError, match="unknown_hand_prob"):
        _cfg(tmp_path, unknown_hand_prob=1.0)


def test_hand_embedding_adaptation_changes_only_that_row(mixture, tmp_path):
    """adapt='hand_embedding' leaves the shared encoder, codebook and decoder bit-identical."""
    train, test = mixture
    base = train_tokenizer(_cfg(tmp_path, steps=20, eval_every=20, output_dir=str(tmp_path / "base"), hand_names=["human"]),
                           train.without("inspire_rh56"), test.only("human"))  # fmt: skip
    few = subsample_episodes(train.only("inspire_rh56"), 0.1, seed=0)
    cfg = _cfg(tmp_path, init_from=str(base.best_dir), epochs=2, batch_size=32, warmup_steps=1, eval_every=1, lr=1e-2,
               adapt="hand_embedding", unknown_hand_prob=0.0, reseed_every=1, output_dir=str(tmp_path / "few"))  # fmt: skip
    result = train_tokenizer(cfg, few, few)
    before = UniDexTok.from_pretrained(base.best_dir).state_dict()
    after = UniDexTok.from_pretrained(result.best_dir).state_dict()
    changed = sorted(k for k in after if k not in before or not torch.equal(before[k], after[k]))
    assert changed == ["hand_embed.weight"], changed
    row = UniDexTok.from_pretrained(result.best_dir).hand_id("inspire_rh56")
    assert not torch.equal(after["hand_embed.weight"][row], before["hand_embed.weight"][-1])  # the new row moved
    torch.testing.assert_close(after["hand_embed.weight"][:row], before["hand_embed.weight"][:row], rtol=0, atol=0)
    with pytest.raises(ValueError, match="adapt must be"):
        _cfg(tmp_path, adapt="encoder")


def test_joint_ranges_are_measured_only_for_range_normalisation(mixture):
    """input_norm "pi" (the paper's fixed normaliser) keeps no ranges; "range" measures them from the training
    hands unless given. Catches the condition joined with `or` (ranges written into every config)."""
    train, _ = mixture
    cfg = TrainConfig(preset="tiny", output_dir="unused")
    assert UniDexTokConfig.from_preset("tiny").input_norm == "pi"
    assert build_model(cfg, train).config.joint_range_rad is None
    measured = build_model(cfg, train, input_norm="range").config.joint_range_rad
    assert measured == joint_ranges_rad(train)
    given = [[-1.0, 1.0]] * 22
    assert build_model(cfg, train, input_norm="range", joint_range_rad=given).config.joint_range_rad == given


def test_the_encoding_goes_into_the_saved_checkpoint_but_not_into_selection(mixture, tmp_path):
    """`encoding` is how the saved checkpoint encodes at use; checkpoint selection still scores the nearest
    codes, so a run with and without it keeps the same step and the same selection figure."""
    from lerobot_unidextok.tokenizer import EncodingConfig

    train, test = mixture
    results = {}
    for rounds in (None, 1):
        encoding = None if rounds is None else EncodingConfig(rounds=rounds, tolerance_deg=0.1)
        cfg = _cfg(tmp_path / str(rounds), steps=20, eval_every=10, encoding=encoding)
        torch.manual_seed(cfg.seed)
        assert build_model(cfg, train).config.encoding == (encoding or EncodingConfig())
        torch.manual_seed(cfg.seed)
        results[rounds] = train_tokenizer(cfg, train, test)
    assert results[1].best_mae_deg == pytest.approx(results[None].best_mae_deg, abs=1e-9)
    assert results[1].best_step == results[None].best_step
    assert UniDexTok.from_pretrained(results[1].best_dir).config.encoding == EncodingConfig(rounds=1, tolerance_deg=0.1)
    assert UniDexTok.from_pretrained(results[None].best_dir).config.encoding.rounds == 0
    with pytest.raises(ValueError, match="encoding.rounds must be >= 0"):
        TrainConfig(encoding=EncodingConfig(rounds=-1))


def test_ema_codebook_is_moved_by_the_ema_and_everything_else_by_the_optimiser(mixture, tmp_path):
    """codebook_update="ema": the codebook is frozen for the optimiser (its EMA update moves it) while the
    encoder, decoder and hand embeddings train. Catches the freeze applied to every other parameter instead
    (`name == "quantizer.codebooks"` -> `!=`), which trains nothing but the codebook."""
    train, test = mixture
    cfg = _cfg(tmp_path, steps=20, eval_every=20, reseed_every=0)
    torch.manual_seed(cfg.seed)
    model = build_model(cfg, train, codebook_update="ema")
    before = {k: v.clone() for k, v in model.state_dict().items()}
    train_tokenizer(cfg, train, test, model=model)
    after = UniDexTok.from_pretrained(Path(cfg.output_dir) / "last").state_dict()
    for name, param in model.named_parameters():
        assert param.requires_grad == (name != "quantizer.codebooks"), name
    moved = {k for k in before if k in after and not torch.equal(before[k], after[k])}
    assert "quantizer.codebooks" in moved  # by the EMA
    assert {"enc_pos", "hand_embed.weight"} <= moved
    assert any(k.startswith("encoder.") for k in moved) and any(k.startswith("decoder.") for k in moved)


def test_the_checkpoint_records_its_selection_and_without_held_out_rows_best_is_the_final_model(mixture, tmp_path):
    """With held-out rows `best/` is the evaluated checkpoint (its state names the rows that chose it); with
    none, or an empty set, `best/` is the final model, saved at the last step. Catches the final-model save
    run when held-out rows exist (`eval_data is None` -> `is not None`, or `and` -> `or`), which overwrote the
    selected checkpoint, an empty held-out set treated as a selection set (`and` -> `or` on the emptiness
    test), and a selection record written for the wrong case."""
    train, test = mixture
    cfg = _cfg(tmp_path, steps=6, eval_every=3, output_dir=str(tmp_path / "held_out"))
    result = train_tokenizer(cfg, train, test)
    state = json.loads((result.best_dir / "training_state.json").read_text())
    assert state["eval_mae_deg"] == pytest.approx(result.best_mae_deg, abs=1e-12)
    assert state["selection"] == {"rows": len(test), "hands": test.hand_names()}

    for name, held_out in (("none", None), ("empty", test.select(np.zeros(0, dtype=np.int64)))):
        cfg = _cfg(tmp_path, steps=6, eval_every=3, output_dir=str(tmp_path / name))
        result = train_tokenizer(cfg, train, held_out)
        assert result.best_step == 6 and result.history == [] and np.isnan(result.best_mae_deg), name
        state = json.loads((result.best_dir / "training_state.json").read_text())
        assert state["step"] == 6 and state["eval_mae_deg"] is None, name
        assert state["selection"] == "none: best = the final model", name
        best = UniDexTok.from_pretrained(result.best_dir).state_dict()
        last = UniDexTok.from_pretrained(Path(cfg.output_dir) / "last").state_dict()
        assert all(torch.equal(best[k], last[k]) for k in best), name


def test_num_threads_is_set_for_the_run_and_restored(mixture, tmp_path, monkeypatch):
    """`num_threads=1` runs the training on one torch thread and gives the caller's count back afterwards.
    Catches the setting skipped for 1 (`> 0` -> `> 1`). Observed through the calls to torch.set_num_threads,
    which still do their work."""
    train, test = mixture
    before = torch.get_num_threads()
    calls: list[int] = []
    real = torch.set_num_threads

    def recording(n: int) -> None:
        calls.append(n)
        real(n)

    monkeypatch.setattr(torch, "set_num_threads", recording)
    train_tokenizer(_cfg(tmp_path, steps=2, eval_every=2, num_threads=1), train, test)
    assert calls == [1, before] and torch.get_num_threads() == before


def test_resuming_a_finished_run_adds_nothing_but_a_missing_evaluation(mixture, tmp_path):
    """`--resume` on a run that already reached its steps trains no further. If it was evaluated, nothing
    changes; if it ran without held-out rows, resuming with them evaluates the final model once so `best/`
    is a selected checkpoint. Catches the extra evaluation on every resume (`not history` dropped, or `and`
    -> `or`) and none for a run that is exactly at its end (`>=` -> `>`)."""
    train, test = mixture
    kw = dict(steps=6, eval_every=3, save_last_every=3)
    first = train_tokenizer(_cfg(tmp_path, output_dir=str(tmp_path / "a"), **kw), train, test)
    again = train_tokenizer(_cfg(tmp_path, output_dir=str(tmp_path / "a"), resume=True, **kw), train, test)
    assert [h["step"] for h in first.history] == [3, 6] and again.history == first.history

    train_tokenizer(_cfg(tmp_path, output_dir=str(tmp_path / "b"), **kw), train, None)
    late = train_tokenizer(_cfg(tmp_path, output_dir=str(tmp_path / "b"), resume=True, **kw), train, test)
    assert [h["step"] for h in late.history] == [6] and late.best_step == 6
    state = json.loads((late.best_dir / "training_state.json").read_text())
    assert state["eval_mae_deg"] == pytest.approx(late.best_mae_deg, abs=1e-12)


def test_training_data_needs_one_row_and_a_given_model_learns_new_hands(mixture, tmp_path):
    """No rows is a clear error, one row is enough; a model passed in that lacks a training hand gets its
    embedding row added (and recorded as trained). Catches the emptiness test off by one (`== 0` -> `== 1`)
    and the known hands taken for the unknown ones (`not` dropped: the new hand has no row)."""
    train, test = mixture
    with pytest.raises(ValueError, match="need training rows"):
        train_tokenizer(_cfg(tmp_path, steps=1), train.select(np.zeros(0, dtype=np.int64)), None)
    one = train.only("inspire_rh56").select(np.array([0]))
    torch.manual_seed(0)
    model = UniDexTok(UniDexTokConfig.from_preset("tiny", hand_names=["human"]))
    result = train_tokenizer(_cfg(tmp_path, steps=2, eval_every=2, batch_size=4), one, None, model)
    assert result.steps == 2
    trained = UniDexTok.from_pretrained(result.best_dir)
    assert trained.knows_hand("inspire_rh56") and trained.knows_hand("human")
    assert trained.config.trained_hands == ["inspire_rh56"]
