"""Latency of the UniDexTok processor step (CPU), batch 1 and batch 256, small and paper presets.

Measured in the same run against a reference: the bare tokenizer `encode` + `decode` on the same
rows, so the figure for the step = tokenizer cost + LeRobot pipeline/step overhead (block gather by
name, range guard, reshapes). Inputs are synthetic G1-like frames from tests/fixtures/robot_udhm.py
(two Inspire hands in UDHM; `--layout robot` adds the 14 arm joints in front: a 58-wide whole-robot
state), tiled to the batch size. Weights are untrained (latency does not depend on them).
Target: <= 1 ms per single state (one hand), small preset.

`--native` also times `unidextok.native_to_udhm` (the robot's native state -> the converted layout: arm
columns copied, 6 Inspire values per hand through the hand spec into its UDHM block) on the same frames in
their native form: the step alone in a pipeline, and native state -> tokens (both steps) against the
tokenizer step on the converted state.

    .venv/bin/python benchmarks/bench_processor.py
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --repeats_large 3
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --num_hands 1 --presets small --batches 1
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --layout robot --presets small --batches 1
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --layout robot --presets small --native
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --presets small --encoding_rounds 2   # code search

`--encodings` compares the encodings of a trained tokenizer (`--pretrained`, default unidextok/universal-small) in one
run:
the nearest codes, the code search as shipped before (sweeps, 2 rounds x 2), and the checkpoint's own encoding
(the default of `encode` and of the step), each an `EncodingConfig` override of the step: the step's CPU ms per two-hand frame at batch 1 and per hand-row at
batch 256 (ratios to the nearest codes), and MPJAE (deg) of each on `--error_rows` states uniform inside each of
`--error_hands`' registered ranges (seed `--error_seed`; the card's in-range figures use seed 0), and on the test
episodes of each `--error_datasets` root (converted datasets, e.g. the card's G1 recording
outputs/universal_data/g1_inspire). `--candidates` adds other tokenizers (folders, ids), each with its own encoding
(e.g. a residual model's nearest codes of both stages), to the same table and the same ratios.

`--select_action` runs a robot's loop: every tick the pre-processor, `select_action` and the post-processor of a
LeRobot ACT (`--act_config`'s sizes, re-predicting every tick) on one G1-like frame (14 arm joints + two Inspire
hands), for the stock ACT on the state alone (the bare policy) and for `act_udt` with each encoding and with each
`--candidates` tokenizer (its own encoding); p50 / p99 of the tick and of the tokenizer step inside it (CPU and
wall ms), and the tick over the bare policy's.

    .venv/bin/python benchmarks/bench_processor.py --threads 1 --encodings
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --encodings \
        --candidates unidextok/universal-small-residual --error_datasets outputs/universal_data/g1_inspire
    .venv/bin/python benchmarks/bench_processor.py --threads 1 --select_action --ticks 1000 \
        --candidates unidextok/universal-small-residual
"""

from __future__ import annotations

import argparse
import os
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch
from lerobot.processor import PolicyProcessorPipeline

from lerobot_unidextok.constants import ACTION, OBS_HAND_TOKEN_FEATURES, OBS_STATE
from lerobot_unidextok.pretrained import UNIVERSAL_SMALL
from lerobot_unidextok.processor import NativeLayout, NativeToUDHMStateStep, UniDexTokStateTokenizerStep
from lerobot_unidextok.tokenizer import NEAREST_CODES, EncodingConfig

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "tests" / "fixtures"))
from robot_udhm import ARM_NAMES, INSPIRE, STATE_NAMES, native_motion, to_converted


def median_ms(fns, repeats: int) -> list[tuple[float, float]]:
    """Median (CPU ms, wall ms) per call of each function, calls interleaved (f0, f1, f0, f1, ...) so every
    function sees the same load on shared cores; CPU time is the clock that survives them best."""
    for fn in fns:  # warm-up
        fn()
        fn()
    cpu, wall = [[] for _ in fns], [[] for _ in fns]
    for _ in range(repeats):
        for i, fn in enumerate(fns):
            c0, t0 = time.process_time(), time.perf_counter()
            fn()
            cpu[i].append(time.process_time() - c0)
            wall[i].append(time.perf_counter() - t0)
    return [(1e3 * statistics.median(c), 1e3 * statistics.median(w)) for c, w in zip(cpu, wall, strict=True)]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--presets", nargs="+", default=["small", "paper"])
    parser.add_argument("--batches", nargs="+", type=int, default=[1, 256])
    parser.add_argument("--repeats", type=int, default=100, help="timed calls at batch 1")
    parser.add_argument("--repeats_large", type=int, default=5, help="timed calls at batch > 1")
    parser.add_argument("--num_hands", type=int, choices=(1, 2), default=2, help="UDHM blocks per frame")
    parser.add_argument("--layout", choices=("hands", "robot"), default="hands", help="robot: 14 arm joints first")
    parser.add_argument("--threads", type=int, default=0, help="torch threads (0 = torch default)")
    parser.add_argument("--native", action="store_true", help="also time unidextok.native_to_udhm (native input)")
    parser.add_argument("--encoding_rounds", type=int, default=0,
                        help="the step's encoding: EncodingConfig(rounds=this) (0 = nearest codes)")  # fmt: skip
    parser.add_argument("--encodings", action="store_true", help="compare a trained tokenizer's encodings")
    parser.add_argument("--select_action", action="store_true", help="a robot's loop around select_action")
    parser.add_argument("--pretrained", default=UNIVERSAL_SMALL,
                        help="tokenizer of --encodings / --select_action, one that the code search can encode with")
    parser.add_argument("--candidates", nargs="*", default=[], help="more tokenizers, each with its own encoding")
    parser.add_argument("--error_datasets", nargs="*", default=[],
                        help="--encodings: MPJAE on these converted datasets' test episodes too")
    parser.add_argument("--error_hands", nargs="+", default=["inspire_rh56_unitree", "human"])
    parser.add_argument("--error_rows", type=int, default=1000, help="in-range states per hand for the MPJAE")
    parser.add_argument("--error_seed", type=int, default=1, help="their seed (not 0, the card's)")
    parser.add_argument("--ticks", type=int, default=500, help="--select_action: timed ticks per policy")
    parser.add_argument("--act_config", default="lerobot/act_udt_cpu", help="--select_action: ACT sizes from it")
    args = parser.parse_args()
    if args.threads:
        torch.set_num_threads(args.threads)
    torch.manual_seed(0)
    if args.encodings:
        compare_encodings(args)
        return
    if args.select_action:
        select_action_loop(args)
        return
    hands = [INSPIRE] * args.num_hands
    names = STATE_NAMES[14 : 14 + 22 * args.num_hands]
    g1 = native_motion(64, seed=0).astype(np.float32)  # (P, 26): 14 arm rad, left and right Inspire in [0, 1]
    start = 0 if args.layout == "robot" else 14  # robot: the 14 arm joints first
    native = torch.from_numpy(g1[:, start : 14 + 6 * args.num_hands])  # (P, [14 +] 6*H)
    poses = torch.from_numpy(to_converted(g1)[:, start : 14 + 22 * args.num_hands]).float()  # (P, [14 +] 22*H) rad
    if args.layout == "robot":
        names = ARM_NAMES + names
    native_layout = NativeLayout.from_hands(hands, ["left", "right"][: args.num_hands], names)
    print(
        f"torch {torch.__version__}, {torch.get_num_threads()} threads, CPU, load average "
        f"{os.getloadavg()[0]:.1f} on {os.cpu_count()} cores; median of {args.repeats} (batch 1) / "
        f"{args.repeats_large} (larger) calls; state layout {args.layout} ({len(names)} columns); code search "
        f"rounds {args.encoding_rounds}"
    )
    print(
        f"{'preset':<7} {'batch':>5} {'states':>6} | {'step CPU ms':>11} {'CPU ms/state':>12} {'wall ms':>9} | "
        f"{'bare tok CPU ms':>15} {'step overhead CPU ms':>20}"
    )
    native_rows = []
    for preset in args.presets:
        encoding = EncodingConfig(rounds=args.encoding_rounds)
        step = UniDexTokStateTokenizerStep(hand_layout=hands, state_names=names, preset=preset, encoding=encoding)
        pipe = PolicyProcessorPipeline(steps=[step], name="policy_preprocessor")
        to_udhm = NativeToUDHMStateStep.from_layout(native_layout)
        native_pipe = PolicyProcessorPipeline(steps=[to_udhm], name="policy_preprocessor")
        native_tok_pipe = PolicyProcessorPipeline(steps=[to_udhm, step], name="policy_preprocessor")
        tok = step.tokenizer
        for batch in args.batches:
            x = poses[np.arange(batch) % len(poses)]  # (B, D)
            xn = native[np.arange(batch) % len(native)]  # (B, D_native) the same frames, native
            if batch == 1:
                x, xn = x[0], xn[0]  # one unbatched frame, as at inference
            rows = x.reshape(-1, x.shape[-1])[:, -22 * args.num_hands :].reshape(-1, 22)  # (B*H, 22) the blocks
            row_hands = hands * (rows.shape[0] // args.num_hands)

            def run_step(x=x, pipe=pipe):
                pipe({OBS_STATE: x})

            def run_bare(rows=rows, row_hands=row_hands, tok=tok, encoding=encoding):
                tok.decode(tok.encode(rows, row_hands, encoding=encoding), row_hands)

            def run_native(xn=xn, native_pipe=native_pipe):
                native_pipe({OBS_STATE: xn})

            def run_native_tok(xn=xn, native_tok_pipe=native_tok_pipe):
                native_tok_pipe({OBS_STATE: xn})

            repeats = args.repeats if batch == 1 else args.repeats_large
            fns = [run_step, run_bare] + ([run_native, run_native_tok] if args.native else [])
            with torch.inference_mode():
                timed = median_ms(fns, repeats)
            (step_cpu, step_wall), (bare_cpu, _) = timed[:2]
            n_states = batch * args.num_hands
            print(f"{preset:<7} {batch:>5} {n_states:>6} | {step_cpu:>11.3f} {step_cpu / n_states:>12.4f} "
                  f"{step_wall:>9.3f} | {bare_cpu:>15.3f} {step_cpu - bare_cpu:>20.3f}")  # fmt: skip
            if args.native:
                (native_cpu, native_wall), (both_cpu, _) = timed[2:]
                native_rows.append((preset, batch, native_cpu, native_wall, both_cpu, both_cpu - step_cpu))
    if native_rows:
        print(f"\nunidextok.native_to_udhm, native state ({native_layout.native_dim} columns) -> converted "
              f"({native_layout.converted_dim})")  # fmt: skip
        print(f"{'preset':<7} {'batch':>5} | {'native step CPU ms':>18} {'CPU ms/frame':>12} {'wall ms':>9} | "
              f"{'native -> tokens CPU ms':>23} {'vs converted -> tokens':>22}")  # fmt: skip
        for preset, batch, native_cpu, native_wall, both_cpu, extra in native_rows:
            print(f"{preset:<7} {batch:>5} | {native_cpu:>18.3f} {native_cpu / batch:>12.4f} {native_wall:>9.3f} | "
                  f"{both_cpu:>23.3f} {extra:>+22.3f}")  # fmt: skip


# ---------------------------------------------------------------------------------------------
# a trained tokenizer's encodings, and the step inside a robot's loop
# ---------------------------------------------------------------------------------------------
ENCODINGS: dict[str, EncodingConfig | None] = {  # label -> the step's override (None = the checkpoint's own)
    "nearest codes": NEAREST_CODES,
    "code search as shipped before (sweeps, 2 x 2)": EncodingConfig(rounds=2, method="sweeps", sweeps=2),
    "default (the checkpoint's encoding)": None,
    "one round of the greedy search": EncodingConfig(rounds=1),
}


def g1_frames(frames: int) -> tuple[torch.Tensor, list[str]]:
    """(frames, 58) G1-like converted states (14 arm joints, two Inspire UDHM blocks) and their column names."""
    converted = to_converted(native_motion(frames, seed=0).astype(np.float32))
    return torch.from_numpy(converted).float(), list(ARM_NAMES + STATE_NAMES[14:])


def encoding_step(pretrained: str, names: list[str], encoding: EncodingConfig | None) -> UniDexTokStateTokenizerStep:
    """The tokenizer step on two Inspire blocks of `pretrained`, encoding with `encoding` (None: the tokenizer's)."""
    return UniDexTokStateTokenizerStep(hand_layout=[INSPIRE, INSPIRE], state_names=names, pretrained=pretrained,
                                       encoding=encoding)  # fmt: skip


def describe(step: UniDexTokStateTokenizerStep) -> str:
    cfg = step.tokenizer.config
    words = (step.encoding or cfg.encoding).describe()
    return f"{words} of all {cfg.num_stages} stages" if cfg.num_stages > 1 else words


def held_out_rows(roots: list[str]) -> dict[str, tuple[str, np.ndarray, np.ndarray]]:
    """{f"{dataset name}: {hand}": (hand, states_rad, masks)} of each converted dataset's test episodes."""
    from lerobot_unidextok.training import load_hand_states

    out = {}
    for root in roots:
        data = load_hand_states([root], split="test")
        for hand in np.unique(data.hands):
            rows = data.hands == hand
            out[f"{Path(root).name} test episodes: {hand}"] = (str(hand), data.states_rad[rows], data.masks[rows])
    return out


def compare_encodings(args) -> None:
    from lerobot_unidextok.evaluation import mpjae_deg
    from lerobot_unidextok.training.coverage import range_states

    frames, names = g1_frames(256)
    steps = {label: encoding_step(args.pretrained, names, enc) for label, enc in ENCODINGS.items()}
    steps |= {f"candidate {path}": encoding_step(path, names, None) for path in args.candidates}
    sets = {hand: (hand, s.states_rad, s.masks) for hand, s in
            ((h, range_states(h, args.error_rows, args.error_seed)) for h in args.error_hands)}  # fmt: skip
    sets |= held_out_rows(args.error_datasets)
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} cores; tokenizer {args.pretrained}; the step on G1-like frames (two Inspire hands); "
          f"MPJAE on {args.error_rows} in-range states per hand, seed {args.error_seed}")  # fmt: skip
    cost = {}
    for batch, repeats in ((1, args.repeats), (256, args.repeats_large)):
        x = frames[0] if batch == 1 else frames[:batch]
        pipes = [PolicyProcessorPipeline(steps=[st], name="policy_preprocessor") for st in steps.values()]
        with torch.inference_mode():
            timed = median_ms([lambda p=p, x=x: p({OBS_STATE: x}) for p in pipes], repeats)
        cost[batch] = [cpu / (2 * batch) if batch > 1 else cpu for cpu, _ in timed]  # per frame / per hand-row
    err = {label: {} for label in steps}
    with torch.inference_mode():
        for label, st in steps.items():
            tok = st.tokenizer
            for name, (hand, states, masks) in sets.items():
                x, m = torch.tensor(states), torch.tensor(masks)
                back = tok.decode(tok.encode(x, hand, mask=m, encoding=st.encoding), hand)
                err[label][name] = mpjae_deg(back.numpy(), states, masks)
    head = " | ".join(f"MPJAE {name} (deg)" for name in sets)
    print(f"\n| encoding | {head} | symbols per hand | CPU ms per frame, batch 1 | x nearest | CPU ms per hand-row, "
          "batch 256 | x nearest |")  # fmt: skip
    print("|" + "---|" * (6 + len(sets)))
    for i, (label, st) in enumerate(steps.items()):
        errs = " | ".join(f"{err[label][name]:.3f}" for name in sets)
        print(f"| {label}: {describe(st)} | {errs} | {st.tokenizer.config.symbols_per_hand()} | {cost[1][i]:.2f} | {cost[1][i] / cost[1][0]:.1f} | "
              f"{cost[256][i]:.3f} | {cost[256][i] / cost[256][0]:.1f} |")  # fmt: skip


def act_policy(names: list[str], frames: torch.Tensor, act_config: str, pretrained: str | None,
               encoding: EncodingConfig | None, hand_input: str = "both"):  # fmt: skip
    """(policy, pre, post, step): LeRobot's ACT with `act_config`'s sizes on the G1-like state, re-predicting every
    tick; `pretrained` None = the stock ACT on the state alone (step None), else `act_udt` with that tokenizer and
    `hand_input` (`state`: the step does not encode)."""
    import yaml
    from lerobot.configs.types import FeatureType, PolicyFeature
    from lerobot.policies.act.configuration_act import ACTConfig
    from lerobot.policies.act.modeling_act import ACTPolicy
    from lerobot.policies.act.processor_act import make_act_pre_post_processors

    from lerobot_unidextok.configs import resolve_config_path
    from lerobot_unidextok.policies.act_udt import ACTUdtConfig, make_act_udt_pre_post_processors

    sizes = yaml.safe_load(Path(resolve_config_path(act_config, "lerobot")).read_text())["policy"]
    sizes = {k: v for k, v in sizes.items() if k in ACTConfig.__dataclass_fields__ and k not in ("type", "device",
                                                                                                 "push_to_hub")}
    width = frames.shape[1]
    features = dict(input_features={OBS_STATE: PolicyFeature(type=FeatureType.STATE, shape=(width,))},
                    output_features={ACTION: PolicyFeature(type=FeatureType.ACTION, shape=(width,))})  # fmt: skip
    stats = {key: {"mean": frames.mean(0), "std": frames.std(0) + 1e-3, "min": frames.min(0).values,
                   "max": frames.max(0).values} for key in (OBS_STATE, ACTION)}  # fmt: skip
    if pretrained is None:  # the same network reading the raw hand blocks where act_udt reads their decoded tokens
        features["input_features"][OBS_HAND_TOKEN_FEATURES] = PolicyFeature(type=FeatureType.ENV, shape=(width - 14,))
        cfg = ACTConfig(device="cpu", **features, **sizes)
        return ACTPolicy(cfg).eval(), *make_act_pre_post_processors(cfg, dataset_stats=stats), None
    cfg = ACTUdtConfig(device="cpu", **features, **sizes, udt_pretrained=pretrained, udt_hand_layout=[INSPIRE, INSPIRE],
                       udt_state_names=names, udt_native_action=False, udt_native_state=False, udt_encoding=encoding,
                       udt_hand_input=hand_input)  # fmt: skip
    cfg.validate_features()
    from lerobot_unidextok.policies.act_udt import ACTUdtPolicy

    pre, post = make_act_udt_pre_post_processors(cfg, dataset_stats=stats)
    step = next(s for s in pre.steps if isinstance(s, UniDexTokStateTokenizerStep))
    return ACTUdtPolicy(cfg).eval(), pre, post, step


def select_action_loop(args) -> None:
    frames, names = g1_frames(args.ticks + 50)
    loops = {"bare ACT (state only)": act_policy(names, frames, args.act_config, None, None)}
    for label, enc in ENCODINGS.items():
        loops[f"act_udt, {label}"] = act_policy(names, frames, args.act_config, args.pretrained, enc)
    for path in args.candidates:  # each with its own encoding
        loops[f"act_udt, candidate {path}"] = act_policy(names, frames, args.act_config, path, None)
    # the state alone (`--policy.udt_hand_input=state`): the step converts and checks, and does not encode
    loops["act_udt, state input"] = act_policy(names, frames, args.act_config, args.pretrained, None, "state")
    tick: dict[str, tuple[list[float], list[float]]] = {k: ([], []) for k in loops}
    step_ms = {k: [] for k in loops}
    for label, (_, _, _, step) in loops.items():
        if step is not None:  # time the step inside the pipeline
            inner = step.observation

            def timed(observation, inner=inner, out=step_ms[label]):
                c0 = time.process_time()
                result = inner(observation)
                out.append(1e3 * (time.process_time() - c0))
                return result

            step.observation = timed
    with torch.inference_mode():
        for t in range(len(frames)):
            for label, (policy, pre, post, step) in loops.items():  # interleaved: every policy sees the same load
                c0, w0 = time.process_time(), time.perf_counter()
                obs = {OBS_STATE: frames[t]} if step is not None else {OBS_STATE: frames[t], OBS_HAND_TOKEN_FEATURES: frames[t, 14:]}
                post(policy.select_action(pre(obs)))
                if t >= 50:  # warm-up ticks
                    tick[label][0].append(1e3 * (time.process_time() - c0))
                    tick[label][1].append(1e3 * (time.perf_counter() - w0))
    bare = np.median(tick["bare ACT (state only)"][0])
    print(f"torch {torch.__version__}, {torch.get_num_threads()} threads, load average {os.getloadavg()[0]:.1f} on "
          f"{os.cpu_count()} cores; {args.ticks} ticks per policy (after 50 warm-up), interleaved; ACT sizes of "
          f"{args.act_config}; tokenizer {args.pretrained}")  # fmt: skip
    print("\n| policy | tick CPU ms p50 / p99 | tick wall ms p50 / p99 | tokenizer step CPU ms p50 / p99 | tick CPU over "
          "bare | tick CPU ms p50 minus bare's |")
    print("|---|---|---|---|---|---|")
    for label, (cpu, wall) in tick.items():
        st = step_ms[label][50:]
        steps = f"{np.median(st):.2f} / {np.percentile(st, 99):.2f}" if st else "-"
        print(f"| {label} | {np.median(cpu):.2f} / {np.percentile(cpu, 99):.2f} | {np.median(wall):.2f} / "
              f"{np.percentile(wall, 99):.2f} | {steps} | {np.median(cpu) / bare:.2f} | "
              f"{np.median(cpu) - bare:+.2f} |")  # fmt: skip


if __name__ == "__main__":
    main()
