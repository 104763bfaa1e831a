"""Per-episode outcomes in the simulator: a trained `<type>_udt` checkpoint, or the scripted expert, on seeded
episodes of one task and hand; how each episode ended as the task says it (success, `failure_reason`) and, for
FingerSequence-v0, PinchPlace-v0 and PinchLift-v0, what happened on the way (docs/tasks.md, "The new tasks in
closed loop").

    python experiments/sim_rollouts.py --task=PinchPlace-v0 --hand=shadow \
        --checkpoint=<out>/closed_loop/policies/PinchPlace-v0/shadow/alone_25_seed0/checkpoints/last/pretrained_model
    python experiments/sim_rollouts.py --checkpoint=expert --task=FingerSequence-v0 --hand=shadow --output=fs.json

Episodes: episode i is drawn from `eval_seed + i` (lerobot-eval's `--seed`, closed_loop.py's seed 0), the expert's
noise from `EXPERT_NOISE_SEED + i` (closed_loop.py's). A checkpoint runs as `closed_loop.evaluate` runs it: LeRobot's
factory with the checkpoint's saved processors and the env's, LeRobot's own `rollout` on sync envs in batches of
`batch_size` (seeds as `eval_policy` gives them), success counted with `eval_policy`'s mask. The expert runs
`expert_episode`'s loop (closed_loop.py's `expert_success`). Every env is wrapped in `EpisodeTrace`, which reads
after each step what the task's state says (nothing is patched), inside LeRobot's own `FreezeAfterEpisodeEnd`, so
a finished episode is replayed instead of auto-reset and the trace ends with the seeded episode; the trace's
success is checked equal to the rollout's.

Measured per episode (`summary`):
- every task: success, and `failure_reason` where it failed (a timeout included);
- FingerSequence-v0: the drawn order, the buttons down at the first step any button was down (`first_press`), how
  many of the three presses were done at the end;
- PinchPlace-v0: whether it was lifted (the task's own `lifted`: 15 mm at some step), released at the end (no
  finger on it), the distance from the target's centre at the last step a finger touched it (`let_go_mm`), the
  closest it came to the target while lifted (`closest_lifted_mm`), how far it was carried toward the target from
  its start to where it was let go (`carry_along_mm`, and off that line: `carry_across_mm`), the tilt at the end;
  and, per phase of the policy's action chunk (step k of the episode runs action (k - 1) mod `n_action_steps` of
  a chunk), the mean distance it came closer to the target on the steps it was held at least 5 mm up;
- PinchLift-v0: the highest the cylinder rose, whether it was lifted (15 mm), which fingers ever touched it, and
  how the pinch went (`pinch`): "none" (no finger touched it), "one finger" (only the thumb or only the named
  finger, never both at once), "both, not lifted" (both on it at once, never 15 mm up), "lifted".
"""

from __future__ import annotations

import json
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

import gymnasium as gym
import numpy as np

if __package__ in (None, ""):  # `python experiments/<name>.py`: the checkout on sys.path, for `experiments.*`
    import sys

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from experiments import runtime
from experiments.common import git_commit, md_table
from lerobot_env_unidextok.columns import TASK_COLUMNS
from lerobot_env_unidextok.columns import TASKS as SIM_TASK_IDS

NAME = "sim_rollouts"
EXPERT = "expert"  # --checkpoint=expert: the scripted expert
EXPERT_NOISE_SEED = 2_000_000  # the expert's noise on episode i: this + i (closed_loop.py's, for its seed 0)
HELD_UP_M = 0.005  # the carry per chunk phase counts the steps that start with the cylinder held this far up


@dataclass
class SimRolloutsConfig:
    # a `pretrained_model` folder of a <type>_udt policy (lerobot-train's, or a mix bound to the hand by
    # unidextok-deploy), or `expert` for the scripted expert
    checkpoint: str = ""
    task: str = "FingerSequence-v0"  # one of the simulator's tasks (lerobot_env_unidextok.columns.TASKS)
    hand: str = "shadow"  # a hand the simulator models (the policy's own, or the one it was bound to)
    episodes: int = 50
    eval_seed: int = 1000  # episode i is drawn from eval_seed + i (lerobot-eval's --seed)
    batch_size: int = 50  # envs stepped together (lerobot-eval's --eval.batch_size); no effect on the outcomes
    output: str = ""  # optional JSON file: the summary and every episode

    def __post_init__(self) -> None:
        if not self.checkpoint:
            raise ValueError(f"give --checkpoint=<pretrained_model folder> or --checkpoint={EXPERT}")
        if self.task not in SIM_TASK_IDS:
            raise ValueError(f"unknown task {self.task!r}; choose from {list(SIM_TASK_IDS)}")
        if self.episodes < 1 or self.batch_size < 1:
            raise ValueError(f"--episodes and --batch_size must be >= 1, got {self.episodes} and {self.batch_size}")
        if self.checkpoint != EXPERT and not (Path(self.checkpoint) / "config.json").is_file():
            raise ValueError(f"--checkpoint={self.checkpoint} holds no config.json: give a pretrained_model folder")


# ---------------------------------------------------------------------------------------------
# what the task's state says, step by step
# ---------------------------------------------------------------------------------------------
def task_state(env) -> dict:
    """What the task's state says now (`env`: the unwrapped UniDexTokEnv): FingerSequence-v0's, PinchPlace-v0's and
    PinchLift-v0's; nothing for the other tasks (their success and failure reasons only)."""
    task, data = env.task, env.data
    if env.task_name == "FingerSequence-v0":
        return {"order": list(task.order), "pressed": [f for f, down in task.pressed(data).items() if down],
                "done": task.done}  # fmt: skip
    if env.task_name == "PinchPlace-v0":
        pos = data.qpos[task.qpos : task.qpos + 3]
        return {"finger": task.finger, "target": task.target.tolist(), "xy": pos[:2].tolist(),
                "up_m": float(pos[2] - task.rest_z), "lifted": bool(task.lifted),
                "by": sorted(task.scene.fingers_touching(data, task.geom)),
                "tilt_deg": float(np.degrees(task.tilt_rad(data)))}  # fmt: skip
    if env.task_name == "PinchLift-v0":
        return {"finger": task.finger, "up_m": float(data.qpos[task.qpos + 2] - task.rest_z),
                "lifted": bool(task.lifted), "by": sorted(task.scene.fingers_touching(data, task.geom))}  # fmt: skip
    return {}


class EpisodeTrace(gym.Wrapper):
    """Records `task_state` at reset and after each step, and the episode's end as the task says it. A reset starts
    a new trace: wrap it in LeRobot's `FreezeAfterEpisodeEnd`, which absorbs the vector env's auto-reset."""

    def __init__(self, env: gym.Env) -> None:
        super().__init__(env)
        self.seed: int | None = None
        self.states: list[dict] = []
        self.end: dict | None = None

    def reset(self, *, seed=None, options=None):
        out = self.env.reset(seed=seed, options=options)
        self.seed, self.states, self.end = seed, [task_state(self.env.unwrapped)], None
        return out

    def step(self, action):
        obs, reward, terminated, truncated, info = self.env.step(action)
        env = self.env.unwrapped
        self.states.append(task_state(env))
        if (terminated or truncated) and self.end is None:
            success = bool(info.get("is_success", False))
            self.end = {"success": success, "reason": "" if success else env.task.failure_reason(bool(terminated)),
                        "steps": len(self.states) - 1}  # fmt: skip
        return obs, reward, terminated, truncated, info


def _mm(metres: float) -> float:
    return round(1000 * float(metres), 1) + 0.0  # + 0.0: no -0.0


def summary(task_name: str, trace: EpisodeTrace) -> dict:
    """One episode's outcome (module docstring) from its trace."""
    end, states = trace.end, trace.states
    if end is None:
        raise RuntimeError(f"episode of seed {trace.seed} did not end: the env has no time limit")
    out = {"seed": trace.seed, "success": end["success"], "reason": end["reason"], "steps": end["steps"]}
    if task_name == "FingerSequence-v0":
        first = next((s["pressed"] for s in states if s["pressed"]), [])
        out.update(order=states[-1]["order"], first_press=first, done=int(states[-1]["done"]))
    elif task_name == "PinchPlace-v0":
        from lerobot_env_unidextok.pinch_place import PinchPlace

        target = np.array(states[0]["target"])
        dist = [float(np.linalg.norm(np.array(s["xy"]) - target)) for s in states]
        held = [k for k, s in enumerate(states) if s["by"]]
        up = [k for k, s in enumerate(states) if s["up_m"] >= PinchPlace.LIFTED_M]
        start = np.array(states[0]["xy"])
        out.update(finger=states[-1]["finger"], lifted=states[-1]["lifted"], released=not states[-1]["by"],
                   start_mm=_mm(dist[0]), final_mm=_mm(dist[-1]), final_up_mm=_mm(states[-1]["up_m"]),
                   final_tilt_deg=round(states[-1]["tilt_deg"], 1),
                   let_go_mm=_mm(dist[held[-1]]) if held else None,
                   closest_lifted_mm=_mm(min(dist[k] for k in up)) if up else None)  # fmt: skip
        if held:
            line = (target - start) / np.linalg.norm(target - start)
            moved = np.array(states[held[-1]]["xy"]) - start
            across = abs(moved[0] * line[1] - moved[1] * line[0])
            out.update(carry_along_mm=_mm(moved @ line), carry_across_mm=_mm(across))
        # the progress toward the target of each step k (1..T) that starts held at least HELD_UP_M up
        out["held_up_progress_mm"] = [[k, _mm(dist[k - 1] - dist[k])] for k in range(1, len(states))
                                      if states[k - 1]["by"] and states[k - 1]["up_m"] >= HELD_UP_M]  # fmt: skip
    elif task_name == "PinchLift-v0":
        finger = states[-1]["finger"]
        both = any({"thumb", finger} <= set(s["by"]) for s in states)
        lifted = states[-1]["lifted"]
        pinch = ("lifted" if lifted else "both, not lifted" if both
                 else "one finger" if any(s["by"] for s in states) else "none")  # fmt: skip
        out.update(finger=finger, lifted=lifted, pinch=pinch, max_up_mm=_mm(max(s["up_m"] for s in states)),
                   touched_by=sorted({f for s in states for f in s["by"]}))  # fmt: skip
    return out


def _median(values: list) -> float | None:
    values = [v for v in values if v is not None]
    return round(float(np.median(values)), 1) if values else None


def aggregate(task_name: str, rows: list[dict], n_action_steps: int | None) -> dict:
    """The episodes' counts and medians (module docstring)."""
    out = {"episodes": len(rows), "successes": sum(r["success"] for r in rows),
           "failure_reasons": dict(Counter(r["reason"] for r in rows if not r["success"]).most_common())}  # fmt: skip
    if task_name == "FingerSequence-v0":
        first = Counter(
            "none" if not r["first_press"] else "due" if r["first_press"] == r["order"][:1]
            else "another of the three" if set(r["first_press"]) <= set(r["order"]) else "not in the order"
            for r in rows
        )  # fmt: skip
        out["first_press"] = {k: first.get(k, 0) for k in ("due", "another of the three", "not in the order", "none")}
        out["presses_done"] = {str(k): sum(r["done"] == k for r in rows) for k in range(4)}
    elif task_name == "PinchPlace-v0":
        from lerobot_env_unidextok.pinch_place import PinchPlace

        lifted = [r for r in rows if r["lifted"]]
        reasons = Counter(r["reason"] for r in rows)
        # let go standing on the table: the task's resting height and upright tilt (its success test but the place)
        on_table = [r for r in rows if r["released"] and abs(r["final_up_mm"]) <= 1000 * PinchPlace.RESTING_M]
        upright_deg = np.degrees(PinchPlace.UPRIGHT_RAD)
        out.update(
            lifted=len(lifted), never_lifted=len(rows) - len(lifted), knocked_over=reasons["knocked over"],
            dropped=reasons["dropped"], released=sum(r["released"] for r in rows), released_on_table=len(on_table),
            released_standing=sum(bool(r["final_tilt_deg"] <= upright_deg) for r in on_table),
            resting_mm=1000 * PinchPlace.RESTING_M, upright_deg=round(float(upright_deg), 1),
            let_go_mm_median=_median([r["let_go_mm"] for r in rows]),
            closest_lifted_mm_median=_median([r["closest_lifted_mm"] for r in lifted]),
            carry_along_mm_median=_median([r.get("carry_along_mm") for r in lifted]),
            carry_across_mm_median=_median([r.get("carry_across_mm") for r in lifted]),
            start_mm_median=_median([r["start_mm"] for r in rows]),
            final_tilt_deg_median=_median([r["final_tilt_deg"] for r in rows]),
        )  # fmt: skip
        if n_action_steps and n_action_steps > 1:
            phases: dict[int, list[float]] = {p: [] for p in range(n_action_steps)}
            for r in lifted:
                for k, gain in r["held_up_progress_mm"]:
                    phases[(k - 1) % n_action_steps].append(gain)
            out["chunk_phase_progress_mm"] = [
                {"phase": p, "steps": len(v), "mean_mm": round(float(np.mean(v)), 1) if v else None}
                for p, v in phases.items()
            ]  # fmt: skip
    elif task_name == "PinchLift-v0":
        pinch = Counter(r["pinch"] for r in rows)
        out["pinch"] = {k: pinch.get(k, 0) for k in ("none", "one finger", "both, not lifted", "lifted")}
        out["another_finger_touched"] = sum(bool(set(r["touched_by"]) - {"thumb", r["finger"]}) for r in rows)
        out["max_up_mm_median"] = _median([r["max_up_mm"] for r in rows])
    return out


# ---------------------------------------------------------------------------------------------
# running the episodes
# ---------------------------------------------------------------------------------------------
def _make_env(cfg: SimRolloutsConfig, env_cfg) -> EpisodeTrace:
    """One env as LeRobot's `EnvConfig.create_envs` makes it (gym.make with the config's kwargs), traced."""
    return EpisodeTrace(gym.make(env_cfg.gym_id, disable_env_checker=env_cfg.disable_env_checker, **env_cfg.gym_kwargs))


def run_expert(cfg: SimRolloutsConfig, env_cfg) -> list[dict]:
    """The scripted expert on each episode: `record.expert_episode`'s loop (no steps after success) through the
    traced env; its noise from EXPERT_NOISE_SEED + i."""
    from lerobot_env_unidextok.experts import Expert

    env, rows = _make_env(cfg, env_cfg), []
    for i in range(cfg.episodes):
        obs, _ = env.reset(seed=cfg.eval_seed + i)
        expert = Expert(env.unwrapped, np.random.default_rng(EXPERT_NOISE_SEED + i))
        expert.reset(obs)
        while env.end is None:
            obs, *_ = env.step(expert.act(obs))
        rows.append(summary(cfg.task, env))
    env.close()
    return rows


def check_fits(checkpoint: str, task: str, hand: str) -> dict:
    """The checkpoint's config.json, once `lerobot-eval`'s checks (`check_policy_fits`) and this one pass: its state
    holds every column today's task gives (a policy trained before the task's columns changed cannot run)."""
    from lerobot_env_unidextok.policy_fit import check_policy_fits

    check_policy_fits(checkpoint, task, hand)
    config = json.loads((Path(checkpoint) / "config.json").read_text())
    names = config.get("udt_state_names") or []
    missing = [c for c in TASK_COLUMNS[task] if c not in names]
    if names and missing:
        raise ValueError(
            f"{checkpoint}'s state has no {', '.join(missing)}: it was trained on other {task} columns than today's "
            f"({', '.join(TASK_COLUMNS[task])}); retrain it on a new recording (experiments/closed_loop.py)"
        )
    return config


def run_policy(cfg: SimRolloutsConfig, env_cfg) -> list[dict]:
    """The checkpoint as `closed_loop.evaluate` loads it, through LeRobot's `rollout` in batches (`eval_policy`'s
    seeds); each episode's success in the rollout (`eval_policy`'s mask) checked equal to the trace's."""
    import torch
    from gymnasium.vector import AutoresetMode
    from lerobot.configs.policies import PreTrainedConfig
    from lerobot.envs.factory import make_env_pre_post_processors
    from lerobot.envs.utils import FreezeAfterEpisodeEnd
    from lerobot.policies.factory import make_policy, make_pre_post_processors
    from lerobot.scripts.lerobot_eval import rollout

    policy_cfg = PreTrainedConfig.from_pretrained(cfg.checkpoint)
    policy_cfg.pretrained_path, policy_cfg.device = str(cfg.checkpoint), "cpu"
    policy = make_policy(cfg=policy_cfg, env_cfg=env_cfg).eval()
    pre, post = make_pre_post_processors(policy_cfg, pretrained_path=str(cfg.checkpoint),
                                         preprocessor_overrides={"device_processor": {"device": "cpu"},
                                                                 "rename_observations_processor": {"rename_map": {}}})  # fmt: skip
    env_pre, env_post = make_env_pre_post_processors(env_cfg=env_cfg, policy_cfg=policy_cfg)
    n = min(cfg.episodes, cfg.batch_size)
    traces_now: list[EpisodeTrace] = []

    def make_one() -> gym.Env:
        traces_now.append(_make_env(cfg, env_cfg))
        return FreezeAfterEpisodeEnd(traces_now[-1])

    vec = gym.vector.SyncVectorEnv([make_one for _ in range(n)], autoreset_mode=AutoresetMode.SAME_STEP)
    rows = []
    try:
        for start in range(0, cfg.episodes, n):
            seeds = list(range(cfg.eval_seed + start, cfg.eval_seed + start + n))
            with torch.no_grad():
                data = rollout(vec, policy, env_pre, env_post, pre, post, seeds=seeds)
            steps = data["done"].shape[1]
            first_done = torch.argmax(data["done"].to(int), dim=1)
            mask = (torch.arange(steps) <= (first_done + 1)[:, None]).int()  # eval_policy's mask
            rollout_success = (data["success"] * mask).any(dim=1).tolist()
            kept = cfg.episodes - start  # the last batch's extra envs are dropped, as eval_policy drops them
            for trace, seed, success in list(zip(traces_now, seeds, rollout_success, strict=True))[:kept]:
                row = summary(cfg.task, trace)
                if row["success"] != success or trace.seed != seed:
                    raise RuntimeError(f"episode {seed}: the rollout says success={success}, the task {row['success']}")
                rows.append(row)
    finally:
        vec.close()
    return rows


def run(cfg: SimRolloutsConfig) -> dict:
    import lerobot_policy_unidextok  # noqa: F401  (the <type>_udt policies and steps, as lerobot-eval discovers them)
    from lerobot_env_unidextok.configuration import UniDexTokEnvConfig

    env_cfg = UniDexTokEnvConfig(task=cfg.task, hand=cfg.hand)  # episodes of EPISODE_STEPS steps, as lerobot-eval's
    cpu = time.process_time()
    n_action_steps = None
    if cfg.checkpoint == EXPERT:
        rows = run_expert(cfg, env_cfg)
    else:
        n_action_steps = check_fits(cfg.checkpoint, cfg.task, cfg.hand).get("n_action_steps")
        rows = run_policy(cfg, env_cfg)
    result = {
        "name": NAME, "task": cfg.task, "hand": cfg.hand, "checkpoint": cfg.checkpoint, "eval_seed": cfg.eval_seed,
        "n_action_steps": n_action_steps, "summary": aggregate(cfg.task, rows, n_action_steps), "episodes": rows,
        "cpu_s": round(time.process_time() - cpu, 1), "commit": git_commit(),
    }  # fmt: skip
    if cfg.output:
        Path(cfg.output).parent.mkdir(parents=True, exist_ok=True)
        Path(cfg.output).write_text(json.dumps(result, indent=1))
    return result


# ---------------------------------------------------------------------------------------------
# the table
# ---------------------------------------------------------------------------------------------
def _value(x) -> str:
    return "-" if x is None else str(x)


def markdown(result: dict) -> str:
    s, n = result["summary"], result["summary"]["episodes"]
    who = "scripted expert" if result["checkpoint"] == EXPERT else f"policy {result['checkpoint']}"
    rows = [["success", f"{s['successes']}/{n}"]]
    rows += [[f"failed: {reason}", count] for reason, count in s["failure_reasons"].items()]
    if result["task"] == "FingerSequence-v0":
        rows += [[f"first press: {k}", v] for k, v in s["first_press"].items()]
        rows += [[f"presses done at the end: {k} of 3", v] for k, v in s["presses_done"].items()]
    elif result["task"] == "PinchPlace-v0":
        rows += [
            ["lifted (>= 15 mm)", s["lifted"]], ["never lifted", s["never_lifted"]],
            ["knocked over / dropped", f"{s['knocked_over']} / {s['dropped']}"],
            ["released at the end (no finger on it)", s["released"]],
            [f"of them on the table (within {s['resting_mm']:g} mm of resting) / standing (under "
             f"{s['upright_deg']:g} degrees)", f"{s['released_on_table']} / {s['released_standing']}"],
            ["let go (last touched): distance from the target's centre, median mm", _value(s["let_go_mm_median"])],
            ["closest to the target while lifted, median mm (lifted)", _value(s["closest_lifted_mm_median"])],
            ["carried toward the target, median mm (lifted)", _value(s["carry_along_mm_median"])],
            ["off the start-target line, median mm (lifted)", _value(s["carry_across_mm_median"])],
            ["start: distance from the target's centre, median mm", _value(s["start_mm_median"])],
            ["final tilt, median degrees", _value(s["final_tilt_deg_median"])],
        ]  # fmt: skip
    elif result["task"] == "PinchLift-v0":
        rows += [[f"pinch: {k}", v] for k, v in s["pinch"].items()]
        rows += [["another finger touched it", s["another_finger_touched"]],
                 ["highest the cylinder rose, median mm", _value(s["max_up_mm_median"])]]  # fmt: skip
    lines = [f"{result['task']}, {result['hand']}, {who}: {n} episodes (seeds {result['eval_seed']}-"
             f"{result['eval_seed'] + n - 1}), {result['cpu_s']} CPU-s", "", md_table(["measure", "episodes"], rows)]  # fmt: skip
    phases = s.get("chunk_phase_progress_mm")
    if phases:
        lines += ["", f"Progress toward the target per step while held >= {1000 * HELD_UP_M:.0f} mm up (lifted "
                  "episodes), by the step's place in the action chunk (mean mm, steps):", "",
                  md_table(["chunk phase", *[str(p["phase"]) for p in phases]],
                           [["mean mm", *[_value(p["mean_mm"]) for p in phases]],
                            ["steps", *[p["steps"] for p in phases]]])]  # fmt: skip
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> None:
    runtime.cli(SimRolloutsConfig, run, markdown, argv)


if __name__ == "__main__":
    main()
