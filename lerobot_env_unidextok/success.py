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
MAX_EPISODES = 10_000_000  # more episodes than any lerobot-eval run holds: a larger count is a damaged file


def wilson_interval(successes: int, n: int, z: float = Z95) -> tuple[float, float]:
    """(low, high) of the Wilson score interval for `successes` of `n` (fractions in [0, 1])."""
    if n <= 0:
        return (0.0, 1.0)
    p = successes / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return (max(0.0, centre - half), min(1.0, centre + half))


def from_eval_info(path: str | Path) -> tuple[int, int]:
    """(successes, episodes) of a `lerobot-eval` output folder or its `eval_info.json`; a file that is not
    JSON (or a folder), has no `overall` numbers, a rate outside 0-100 %, no episodes, more than `MAX_EPISODES`,
    or a rate that is no whole number of its episodes is refused, naming the file."""
    path = Path(path)
    path = path / "eval_info.json" if path.is_dir() and path.name != "eval_info.json" else path
    if path.is_dir():
        raise SimInputError(f"{path} is a folder, not the file lerobot-eval writes: pass lerobot-eval's --output_dir "
                            "holding the eval_info.json it wrote")  # fmt: skip
    if not path.is_file():
        raise SimInputError(f"{path} is not there: pass lerobot-eval's --output_dir (it holds eval_info.json)")
    try:
        info = json.loads(path.read_text())
    except (UnicodeDecodeError, ValueError) as err:
        raise SimInputError(f"{path} is not JSON ({err}): pass the eval_info.json lerobot-eval wrote") from None
    overall = info.get("overall") if isinstance(info, dict) else None
    if not isinstance(overall, dict):
        raise SimInputError(f"{path} has no 'overall' section: is it the eval_info.json lerobot-eval wrote?")
    n = _number(path, overall, "n_episodes")
    if n != int(n) or n < 0:
        raise SimInputError(f"{path}: 'overall.n_episodes' is {overall['n_episodes']}, not a whole number >= 0")
    if n > MAX_EPISODES:
        raise SimInputError(f"{path}: 'overall.n_episodes' is {overall['n_episodes']}, more than any lerobot-eval run "
                            f"holds (at most {MAX_EPISODES:,}): is the file damaged?")  # fmt: skip
    n = int(n)
    if n == 0:  # lerobot-eval writes a NaN rate then
        raise SimInputError(
            f"{path}: no episodes: 'overall.n_episodes' is 0, so there is no success rate (run lerobot-eval with "
            "--eval.n_episodes >= 1)"
        )
    pc = _number(path, overall, "pc_success")
    if not 0 <= pc <= 100:
        raise SimInputError(f"{path}: 'overall.pc_success' is {overall['pc_success']}, outside 0-100 %")
    successes = pc * n / 100
    if abs(successes - round(successes)) > 1e-6 * n:
        raise SimInputError(f"{path}: 'overall.pc_success' {pc} % of {n} episodes is not a whole number of episodes")
    return round(successes), n


def _number(path: Path, overall: dict, key: str) -> float:
    if key not in overall:
        raise SimInputError(f"{path}: 'overall' has no '{key}': is it the eval_info.json lerobot-eval wrote?")
    value = overall[key]
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise SimInputError(f"{path}: 'overall.{key}' is {value!r}, not a number")
    return float(value)


def describe(successes: int, n: int) -> str:
    if n < 1:
        raise SimInputError("no episodes: a success rate needs at least one episode")
    lo, hi = wilson_interval(successes, n)
    return f"success {successes}/{n} = {100 * successes / n:.1f} % (95 % Wilson interval {100 * lo:.1f}-{100 * hi:.1f} %)"


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
