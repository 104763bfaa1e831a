"""Multi-process training for real: `accelerate launch` starts 2 CPU processes (gloo) running unidextok-train
on a converted dataset read through the memory-mapped row store; a probe (tests/training/ddp_probe.py)
records what each process did."""

from __future__ import annotations

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import pytest

from lerobot_unidextok.conversion.pipeline import ConvertOptions, convert
from lerobot_unidextok.samples import write_samples

PROBE = Path(__file__).with_name("ddp_probe.py")


@pytest.fixture(scope="module")
def converted(tmp_path_factory) -> Path:
    raw = write_samples(tmp_path_factory.mktemp("raw"), sources=["linkerhand"], episodes_per_source=6,
                        frames_per_episode=60)["linkerhand"]  # fmt: skip
    root = tmp_path_factory.mktemp("conv") / "linker"
    convert(ConvertOptions(source="linkerhand", input=raw, root=root, progress=False))
    return root


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _launch(probe_dir: Path, *flags: str) -> tuple[dict, dict, str]:
    cmd = [
        str(Path(sys.executable).parent / "accelerate"), "launch", "--multi_gpu", "--num_processes=2",
        "--num_machines=1", "--mixed_precision=no", "--dynamo_backend=no", f"--main_process_port={_free_port()}",
        str(PROBE), *flags,
    ]  # fmt: skip
    env = dict(os.environ, UNIDEXTOK_PROBE_DIR=str(probe_dir), OMP_NUM_THREADS="1", CUDA_VISIBLE_DEVICES="")
    done = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=900)
    assert done.returncode == 0, done.stderr[-4000:]
    ranks = [json.loads((probe_dir / f"rank{k}.json").read_text()) for k in range(2)]
    return ranks[0], ranks[1], done.stderr


# Known, not yet understood: in 2 of 2 fresh-clone runs of the whole suite (2026-12-05, never when this file ran on
# its own, 0 of 12) process 0 aborted about 0.15 s after its last training step with gloo's "terminate called
# without an active exception" (exit -6), the abort `training.distributed.leave_at_exit` exists to prevent at
# interpreter exit. Rerun on that message only; any other failure fails at once.
@pytest.mark.flaky(reruns=2, only_rerun=["terminate called without an active exception"])
@pytest.mark.slow
def test_two_cpu_processes_train_one_model_and_resume(converted, tmp_path):
    """Catches dead-code re-seeding (each process re-seeds from its own batch) leaving the processes with
    different codebooks: the start checkpoint's fast usage decay makes codes go dead within a few steps."""
    from lerobot_unidextok.tokenizer import UniDexTok, UniDexTokConfig

    init = tmp_path / "init"
    UniDexTok(UniDexTokConfig.from_preset("tiny", usage_decay=0.5, dead_code_threshold=0.5)).save_pretrained(init)
    out = tmp_path / "run"
    flags = [f"--datasets=[{converted}]", f"--init_from={init}", "--batch_size=32", "--warmup_steps=2", "--eval_every=10",
             "--save_last_every=10", "--reseed_every=3", "--device=cpu", "--progress=false", "--streaming=true",
             f"--output_dir={out}"]  # fmt: skip
    r0, r1, log = _launch(tmp_path / "probe1", *flags, "--steps=20")

    assert (r0["process_index"], r0["num_processes"], r1["process_index"]) == (0, 2, 1)
    assert "batch 32 x 2 processes = 64" in log
    # each process drew its own batches: 20 steps each, none shared
    assert len(r0["batches"]) == len(r1["batches"]) == 20
    assert not set(r0["batches"]) & set(r1["batches"])
    # one model: every state-dict tensor bit-identical across processes after the steps (with dead-code
    # re-seeding every 3 steps from each process's own batch), and a drifted copy is caught
    assert r0["final_state"] and r0["final_state"] == r1["final_state"]
    assert r0["drift_detected"] and r1["drift_detected"]
    # only the main process evaluates and writes checkpoints and the report
    assert r0["evaluations"] >= 2 and r1["evaluations"] == 0  # steps 10, 20 (+ the final report's)
    assert {"best", "last"} <= set(r0["checkpoints"]) and r1["checkpoints"] == []
    assert (r0["reports"], r1["reports"]) == (1, 0) and (out / "eval.json").is_file()
    state = json.loads((out / "last" / "training_state.json").read_text())
    assert state["step"] == 20 and [h["step"] for h in state["history"]] == [10, 20]
    assert (out / "row_store" / "train" / "index.json").is_file()  # built once, by the main process

    # resume: both processes continue from output_dir/last
    r0, r1, log = _launch(tmp_path / "probe2", *flags, "--steps=30", "--resume=true")
    assert len(r0["batches"]) == len(r1["batches"]) == 10  # steps 20..29 only
    assert r0["final_state"] == r1["final_state"]
    resumed = json.loads((out / "last" / "training_state.json").read_text())
    assert resumed["step"] == 30 and resumed["history"][:2] == state["history"]
    assert [h["step"] for h in resumed["history"]] == [10, 20, 30]

    # overwrite: both processes train into the one temp folder the main process chose (the row store in it too),
    # which replaces the run only at the end
    r0, r1, log = _launch(tmp_path / "probe3", *flags, "--steps=10", "--overwrite=true")
    assert r0["final_state"] == r1["final_state"]
    replaced = json.loads((out / "last" / "training_state.json").read_text())
    assert replaced["step"] == 10 and [h["step"] for h in replaced["history"]] == [10]
    assert (out / "row_store" / "train" / "index.json").is_file()
    assert sorted(p.name for p in out.parent.iterdir() if p.name.startswith(".")) == []
