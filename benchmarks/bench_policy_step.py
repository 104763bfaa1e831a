"""CPU cost of one `lerobot-train` update of a policy config, and the size of the checkpoint it writes.

Runs the real `lerobot-train` (its `main()`, in this process) with the given flags and times every call of its
`update_policy` (forward, backward, optimiser step) with `time.process_time()`; data loading is outside it.
Prints the CPU seconds of each update and the size of the saved checkpoint (model + processors + optimiser state).

    OMP_NUM_THREADS=1 python benchmarks/bench_policy_step.py --config_path=lerobot/act_udt \
        --dataset.repo_id=lab/g1_udhm --dataset.root=data/g1_udhm --policy.udt_pretrained=<tokenizer> \
        --batch_size=8 --steps=4 --save_freq=4 --num_workers=0 --output_dir=outputs/bench_act_udt

Every argument is lerobot-train's. The first update includes one-off set-up; the figure is the mean of the others.
"""

import sys
import time
from pathlib import Path


def folder_bytes(path: Path) -> int:
    return sum(f.stat().st_size for f in path.rglob("*") if f.is_file())


def main() -> None:
    from lerobot.scripts import lerobot_train

    cpu_s: list[float] = []
    update = lerobot_train.update_policy

    def timed(*args, **kwargs):
        t0 = time.process_time()
        out = update(*args, **kwargs)
        cpu_s.append(time.process_time() - t0)
        return out

    lerobot_train.update_policy = timed
    sys.argv = ["lerobot-train", *sys.argv[1:]]
    lerobot_train.main()
    out = next(a.split("=", 1)[1] for a in sys.argv if a.startswith("--output_dir="))
    ckpt = Path(out) / "checkpoints" / "last"
    steady = cpu_s[1:] or cpu_s
    print(f"updates: {len(cpu_s)}; CPU s per update: {[round(c, 2) for c in cpu_s]}; "
          f"mean after the first: {sum(steady) / len(steady):.2f} s")
    if ckpt.exists():
        model = folder_bytes(ckpt.resolve() / "pretrained_model")
        total = folder_bytes(ckpt.resolve())
        print(f"checkpoint: {total / 1e6:.1f} MB ({model / 1e6:.1f} MB pretrained_model, "
              f"{(total - model) / 1e6:.1f} MB training_state)")


if __name__ == "__main__":
    main()
