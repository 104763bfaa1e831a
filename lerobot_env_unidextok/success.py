"""Success rates with their 95 % interval, from `lerobot-eval`'s `eval_info.json` (`unidextok-sim-success`).

    lerobot-eval --policy.path=<checkpoint> --env.type=unidextok ... --output_dir=outputs/eval/grasp
    unidextok-sim-success --eval=outputs/eval/grasp   # success 31/50 = 62.0 % (95 % Wilson interval 48.2-74.1 %)

`lerobot-eval` writes `overall.pc_success` and `overall.n_episodes`; the interval is Wilson's score interval
for a binomial proportion (it stays inside [0, 1] and is not degenerate at 0 or n successes).
"""

# no `from __future__ import annotations`: the CLI wrapper reads the config class from success_cli's annotation
import json
import math
from dataclasses import dataclass
from pathlib import Path

from lerobot_env_unidextok.errors import SimInputError
from lerobot_unidextok.utils.cli import run_cli
from lerobot_unidextok.utils.draccus_cli import wrap

Z95 = 1.959963984540054


def wilson_interval(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """(low, high) of the Wilson score interval for `successes` of `n` (fractions in [0, 1])."""
    if n <= 0:
        return (0.0, 1.0)
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (max(0.0, centre - half), min(1.0, centre + half))


def from_eval_info(path: str | Path) -> tuple[int, int]:
    """(successes, episodes) of a `lerobot-eval` output folder or its `eval_info.json`."""
    path = Path(path)
    path = path / "eval_info.json" if path.is_dir() else path
    if not path.is_file():
        raise SimInputError(f"{path} is not there: pass lerobot-eval's --output_dir (it holds eval_info.json)")
    overall = json.loads(path.read_text())["overall"]
    n = int(overall["n_episodes"])
    return round(float(overall["pc_success"]) * n / 100), n


def describe(successes: int, n: int) -> str:
    lo, hi = wilson_interval(successes, n)
    return f"success {successes}/{n} = {100 * successes / max(n, 1):.1f} % (95 % Wilson interval {100 * lo:.1f}-{100 * hi:.1f} %)"


@dataclass
class SuccessConfig:
    eval: str = ""  # lerobot-eval's --output_dir (or its eval_info.json)


@wrap()
def success_cli(cfg: SuccessConfig) -> None:
    if not cfg.eval:
        raise SimInputError("pass --eval=<lerobot-eval's --output_dir> (the folder holding eval_info.json)")
    print(f"{cfg.eval}: {describe(*from_eval_info(cfg.eval))}")


def main() -> None:
    run_cli(success_cli)


if __name__ == "__main__":
    main()
