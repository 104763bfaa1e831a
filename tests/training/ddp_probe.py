"""Run by test_multiprocess.py under `accelerate launch`: unidextok-train's own entry point, with spies that
record per process what cannot be seen from outside (the spied functions still run unchanged):

- a fingerprint of every batch the process drew,
- how often it evaluated, which checkpoints it wrote, whether it wrote the evaluation report,
- digests of its final model state (at the loop's closing `wait_for_everyone`),
- then it perturbs process 1's copy and records whether `check_replicas` notices.

Writes <UNIDEXTOK_PROBE_DIR>/rank<k>.json. Arguments are unidextok-train flags.
"""

import hashlib
import json
import os
import sys
from pathlib import Path

import torch
from accelerate import Accelerator, PartialState

import lerobot_unidextok.evaluation.report as report_module
import lerobot_unidextok.scripts.train as train_script
from lerobot_unidextok.training import coverage, distributed, loop

record = {"batches": [], "evaluations": 0, "checkpoints": [], "reports": 0, "final_state": None}
models = []


def _spy_sample(original):
    def sample(self, batch_size):
        batch = original(self, batch_size)
        record["batches"].append(hashlib.sha1(batch.states_rad.tobytes() + batch.hands.tobytes()).hexdigest())
        return batch

    return sample


coverage.MixtureSampler.sample = _spy_sample(coverage.MixtureSampler.sample)

_evaluate, _save, _report, _wait = (
    loop.evaluate_mae_deg, loop.save_checkpoint, report_module.write_report, Accelerator.wait_for_everyone
)  # fmt: skip


def evaluate(*args, **kwargs):
    record["evaluations"] += 1
    return _evaluate(*args, **kwargs)


def save(model, directory, *args, **kwargs):
    record["checkpoints"].append(Path(directory).name)
    return _save(model, directory, *args, **kwargs)


def write_report(*args, **kwargs):
    record["reports"] += 1
    return _report(*args, **kwargs)


def wait_for_everyone(self):
    if self._models:
        models[:] = [self.unwrap_model(self._models[0])]
        record["final_state"] = distributed.state_digests(models[0])
    return _wait(self)


loop.evaluate_mae_deg, loop.save_checkpoint = evaluate, save
report_module.write_report = write_report
Accelerator.wait_for_everyone = wait_for_everyone

state = PartialState(cpu=True)
try:
    sys.argv = ["unidextok-train", *sys.argv[1:]]
    train_script.main()
    # a replica that drifts (here: process 1 nudges one weight) must be caught
    with torch.no_grad():
        if state.process_index == 1:
            next(models[0].parameters()).view(-1)[0] += 1e-3
    try:
        distributed.check_replicas(models[0], step=-1)
        record["drift_detected"] = False
    except RuntimeError as exc:
        record["drift_detected"] = "replicas differ" in str(exc)
finally:
    out = Path(os.environ["UNIDEXTOK_PROBE_DIR"])
    out.mkdir(parents=True, exist_ok=True)
    record["process_index"], record["num_processes"] = state.process_index, state.num_processes
    (out / f"rank{state.process_index}.json").write_text(json.dumps(record))
