"""Light imports, one-way layers and no import side effects, each checked in a fresh interpreter.

`from lerobot_unidextok import UniDexTok` took 8-11 s and left `lerobot.policies`, `lerobot.processor` and
`lerobot.datasets` in `sys.modules` (the package imported its LeRobot registration); every CLI's `--help`
imported LeRobot and torch. The timings are in benchmarks/bench_startup.py; here: what gets imported.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import tomllib
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
LEROBOT_HEAVY = ("lerobot.policies", "lerobot.processor", "lerobot.datasets")
CLI_HEAVY = ("torch", "lerobot", "datasets", "accelerate", "matplotlib", "huggingface_hub")

PROBE = """
import json, logging, os, sys
{code}
print(json.dumps({{
    "modules": sorted(sys.modules),
    "tqdm_mininterval": os.environ.get("TQDM_MININTERVAL"),
    "lerobot_log_filters": [type(f).__name__ for f in logging.getLogger("lerobot.utils.import_utils").filters],
}}))
"""


def _probe(code: str, cwd: Path) -> dict:
    """sys.modules, TQDM_MININTERVAL and LeRobot's logger filters after `code` in a fresh interpreter, run in
    `cwd` outside the checkout so that only the installed distribution is found."""
    env = {k: v for k, v in os.environ.items() if k != "TQDM_MININTERVAL"}
    r = subprocess.run([sys.executable, "-c", PROBE.format(code=code)], env=env, cwd=cwd, check=False,
                       capture_output=True, text=True, timeout=300)  # fmt: skip
    assert r.returncode == 0, r.stderr[-3000:]
    return json.loads(r.stdout.strip().splitlines()[-1])


def _loaded(modules: list[str], prefixes: tuple[str, ...]) -> list[str]:
    return sorted(m for m in modules if any(m == p or m.startswith(p + ".") for p in prefixes))


def test_the_package_imports_without_torch_or_lerobot(tmp_path):
    found = _probe("import lerobot_unidextok", tmp_path)
    assert _loaded(found["modules"], ("torch", "lerobot")) == []


@pytest.mark.parametrize(
    "code",
    [
        "from lerobot_unidextok import UniDexTok",
        "from lerobot_unidextok import udhm, hands, UniDexTok",
        "import lerobot_unidextok.udhm",
        "import lerobot_unidextok.hands",
        "import lerobot_unidextok.tokenizer",
    ],
)
def test_udhm_hands_and_tokenizer_never_import_lerobot(code, tmp_path):
    """Layers 1-2 know nothing of LeRobot (docs/architecture.md); the public API stays importable."""
    found = _probe(code, tmp_path)
    assert _loaded(found["modules"], ("lerobot",)) == [], code
    assert _loaded(found["modules"], LEROBOT_HEAVY) == []


def _cli_modules() -> list[str]:
    scripts = tomllib.loads((REPO / "pyproject.toml").read_text())["project"]["scripts"]
    return sorted({target.split(":")[0] for target in scripts.values()})


@pytest.mark.parametrize("module", _cli_modules())
def test_cli_modules_import_their_config_without_heavy_dependencies(module, tmp_path):
    """`unidextok-* --help` only needs the draccus config: LeRobot, torch, datasets, accelerate and matplotlib
    are imported by the functions that use them."""
    found = _probe(f"import {module}", tmp_path)
    assert _loaded(found["modules"], CLI_HEAVY) == [], module


def test_registration_has_no_output_side_effects(tmp_path):
    """Importing the package set TQDM_MININTERVAL and filtered LeRobot's logger; a CLI does that when it starts
    (utils/cli.py: configure_output)."""
    code = (
        "import lerobot_unidextok, lerobot_unidextok.policies, lerobot_unidextok.processor\n"
        "from lerobot.configs.policies import PreTrainedConfig\n"
        "assert 'act_udt' in PreTrainedConfig.get_known_choices()\n"
    )
    found = _probe(code, tmp_path)
    assert found["tqdm_mininterval"] is None and found["lerobot_log_filters"] == []


def test_lerobot_plugin_discovery_registers_the_policies_and_steps(tmp_path):
    """What lerobot-train / -eval / -record / -replay / -rollout call at start: the distribution is named
    `lerobot_policy_unidextok`, so LeRobot imports our plugin package without --policy.discover_packages_path."""
    code = (
        "from lerobot.utils.import_utils import register_third_party_plugins\n"
        "register_third_party_plugins()\n"
        "from lerobot.configs.policies import PreTrainedConfig\n"
        "from lerobot.processor import ProcessorStepRegistry\n"
        "assert {'act_udt', 'diffusion_udt', 'vqbet_udt'} <= set(PreTrainedConfig.get_known_choices())\n"
        "assert {'unidextok.state_tokenizer', 'unidextok.udhm_to_native'} <= set(ProcessorStepRegistry.list())\n"
    )
    found = _probe(code, tmp_path)
    assert "lerobot_policy_unidextok" in found["modules"]
    assert found["lerobot_log_filters"] == ["_TorchcodecNote"]  # the one-line FFmpeg note in LeRobot's CLIs
