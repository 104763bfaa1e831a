"""A pip user's day: the wheel built from this checkout, installed outside it, runs the README's pip commands.

The wheel is installed with `pip install --no-deps --target` and put first on PYTHONPATH, so its copy of the
package shadows the editable one and the dependencies already installed here are reused (no download). Every
command runs from a folder outside the checkout, offline, and must import the wheel's files, not the checkout's.
"""

import os
import re
import shutil
import subprocess
import sys
import zipfile
from pathlib import Path

import pytest
from linkerhand_udhm import subprocess_env

REPO = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def installed(tmp_path_factory):
    """(site folder holding the installed wheel, its bin folder, the wheel file)."""
    work = tmp_path_factory.mktemp("wheel")
    src = work / "src"
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(".venv", ".git", "outputs", "__pycache__", "*.egg-info",
                                                             "build", "dist", ".pytest_cache"))  # fmt: skip
    pip = [sys.executable, "-m", "pip", "--disable-pip-version-check", "-q"]
    subprocess.run([*pip, "wheel", "--no-deps", "--no-build-isolation", "-w", str(work / "dist"), str(src)],
                   check=True, capture_output=True, timeout=300)  # fmt: skip
    (wheel,) = sorted((work / "dist").glob("lerobot_policy_unidextok-*.whl"))
    site = work / "site"
    subprocess.run([*pip, "install", "--no-deps", "--target", str(site), str(wheel)], check=True, capture_output=True,
                   timeout=300)  # fmt: skip
    return site, site / "bin", wheel


def _run(installed, args: list[str], cwd: Path, timeout: int = 600, unset=(), **extra: str) -> subprocess.CompletedProcess:
    """`args` run from `cwd` on the installed wheel, offline, without the checkout's data folders (and without the
    variables in `unset`; with those in `extra`)."""
    site, bin_dir, _ = installed
    env = subprocess_env(**{"PYTHONPATH": str(site), "HF_HUB_OFFLINE": "1", "HF_HOME": str(cwd / "hf"), "MPLBACKEND": "Agg",
                            "PATH": f"{bin_dir}{os.pathsep}{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}",
                            **extra})  # fmt: skip
    for name in ("UNIDEXTOK_REAL_DATA", "UNIDEXTOK_URDF_DIR", *unset):
        env.pop(name, None)
    r = subprocess.run(args, cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout)
    assert r.returncode == 0, f"{args}\n{r.stdout[-3000:]}\n{r.stderr[-3000:]}"
    return r


def test_the_wheel_holds_the_library_its_data_and_licences(installed):
    _, _, wheel = installed
    names = zipfile.ZipFile(wheel).namelist()
    assert "lerobot_unidextok/converters/lerobot.py" in names and "lerobot_unidextok/samples/formats.py" in names
    assert "lerobot_unidextok/hands/specs/inspire_rh56_unitree.yaml" in names
    assert "lerobot_unidextok/configs/lerobot/act_udt_cpu.yaml" in names
    assert "lerobot_unidextok/pretrained/universal-small/model.safetensors" in names
    assert {"lerobot_env_unidextok/hand_models/shadow.yaml", "lerobot_env_unidextok/assets/inspire/inspire_right_hand.xml",
            "lerobot_env_unidextok/assets/inspire/LICENSE.robosuite", "lerobot_env_unidextok/assets/allegro/allegro_right.xml",
            "lerobot_env_unidextok/assets/allegro/LICENSE.allegro_hand"} <= set(names)  # fmt: skip
    for folder in (REPO / "lerobot_env_unidextok" / "assets").iterdir():  # every shipped model with its licence
        shipped = {f"lerobot_env_unidextok/assets/{folder.name}/{f.name}" for f in folder.iterdir()}
        assert shipped <= set(names) and any("/LICENSE" in n for n in shipped), folder.name
    assert any(n.endswith("licenses/LICENSE") for n in names) and any(n.endswith("licenses/NOTICE") for n in names)
    # the checkout's top-level converters/ and configs/ install inside the package, nowhere else
    assert "lerobot_unidextok/converters/README.md" in names and "lerobot_unidextok/configs/__init__.py" in names
    assert not [n for n in names if n.startswith(("tests/", "experiments/", "benchmarks/", "converters/", "configs/"))]


@pytest.mark.slow
def test_readme_pip_commands_run_from_the_installed_wheel(installed, tmp_path):
    """What the README's pip section promises, outside the checkout: the package imports from the wheel, the
    shipped tokenizer loads by id, configs are found by name, the demo runs (quick, few steps), its converted
    G1-like sample trains a policy with the stock lerobot-train and a shipped config, and unidextok-config
    lists the configs. Before: the configs were not in the wheel and the demo needed h5py."""
    site = installed[0]
    where = _run(installed, [sys.executable, "-c", "import lerobot_unidextok, lerobot_policy_unidextok; "
                             "import lerobot_unidextok.converters as c, lerobot_unidextok.configs as g; "
                             "from lerobot_unidextok import UniDexTok; "
                             "t = UniDexTok.from_pretrained('unidextok/universal-small'); "
                             "print(lerobot_unidextok.__file__, c.__file__, g.__file__, len(t.config.hand_names))"],
                 tmp_path)  # fmt: skip
    assert all(p.startswith(str(site)) for p in where.stdout.split()[:3]), where.stdout
    listed = _run(installed, ["unidextok-config"], tmp_path).stdout
    assert "train/small" in listed and "lerobot/act_udt_cpu" in listed
    config = _run(installed, ["unidextok-config", "lerobot/act_udt_cpu"], tmp_path).stdout.strip()
    assert config.startswith(str(site)) and Path(config).is_file()
    # the demo, every stage (tests/test_demo.py pins that `make demo` runs this module): the loopback Hub is the only
    # network (the conftest proxy settings), so its hub-cache stage runs too
    out = tmp_path / "demo"
    demo = _run(installed, ["unidextok-demo", "--quick", "--preset=tiny", "--steps=60", f"--out={out}"], tmp_path,
                HF_HUB_OFFLINE="0", HF_LEROBOT_HOME=str(tmp_path / "hf" / "lerobot"), OMP_NUM_THREADS="1").stdout  # fmt: skip
    _the_demo_ran_every_stage(demo, out)
    # the demo converts a sample of every source format with the wheel's converters
    from lerobot_unidextok.samples import available_sample_sources

    sources, skipped = available_sample_sources()
    assert len(sources) == 6 and not skipped, skipped
    for source in sources:
        assert (tmp_path / "demo" / "converted" / source / "meta" / "unidextok_conversion.json").is_file(), source
    g1 = tmp_path / "demo" / "converted" / "lerobot"
    _run(installed, ["lerobot-train", f"--config_path={config}", "--dataset.repo_id=demo/lerobot_udhm",
                     f"--dataset.root={g1}", "--steps=2", "--batch_size=4", "--log_freq=1", "--save_freq=2",
                     f"--output_dir={tmp_path / 'policy'}", "--policy.udt_pretrained=unidextok/universal-small"],
         tmp_path)  # fmt: skip
    assert (tmp_path / "policy" / "checkpoints" / "last" / "pretrained_model" / "config.json").is_file()


def _the_demo_ran_every_stage(text: str, out: Path) -> None:
    """Every stage of the demo ran and left its outputs: converted datasets, a trained tokenizer that reloads by
    repo id from the local hub cache with identical weights, the evaluation, the pictures. Catches a stage that
    crashes, one that silently writes nothing, a tokenizer that does not round-trip through the hub cache."""
    for n in range(1, 7):
        assert f"\n{n}. " in text, f"stage {n} missing"
    assert "UniDexTok shipped" in text and "weights identical = True" in text and "Demo finished" in text
    trained = re.search(r"trained (\d+) steps .* best selection-episode joint MAE ([\d.]+) deg", text)
    assert trained and int(trained.group(1)) == 60 and float(trained.group(2)) > 0
    converted = sorted(p.name for p in (out / "converted").iterdir())
    assert len(converted) >= 6 and all((out / "converted" / c / "meta" / "info.json").is_file() for c in converted)
    assert (out / "tokenizer" / "model.safetensors").is_file() and (out / "tokenizer" / "config.json").is_file()
    assert (out / "eval.json").is_file() and (out / "eval.md").is_file()
    pictures = sorted(p.name for p in (out / "plots").glob("*.png"))
    assert {"per_joint_error.png", "codebook_usage.png"} <= set(pictures) and len(pictures) >= 4, pictures


@pytest.mark.slow
def test_lerobot_finds_the_simulator_in_the_installed_wheel(installed, tmp_path):
    """What lerobot-eval does before parsing `--env.type=unidextok` (register_third_party_plugins), from the wheel:
    the env config is registered, its gym id made and reset, all from the wheel's files."""
    site = installed[0]
    code = ("from lerobot.utils.import_utils import register_third_party_plugins\n"
            "register_third_party_plugins()\n"
            "from lerobot.envs.configs import EnvConfig\n"
            "cfg = EnvConfig.get_choice_class('unidextok')(hand='allegro', task='FingerPress-v0')\n"
            "import gymnasium as gym, lerobot_env_unidextok\n"
            "obs, _ = gym.make(cfg.gym_id, **cfg.gym_kwargs).reset(seed=0)\n"
            "print(lerobot_env_unidextok.__file__, obs['agent_pos'].shape, cfg.features['action'].shape)\n")  # fmt: skip
    out = _run(installed, [sys.executable, "-c", code], tmp_path).stdout.split()
    assert out[0].startswith(str(site)) and out[1:] == ["(29,)", "(28,)"], out


SHIPPED_HANDS = """
import os, sys
from lerobot.envs.factory import make_env
from lerobot_env_unidextok.configuration import UniDexTokEnvConfig
from lerobot_env_unidextok.record import RecordConfig, record
from lerobot_env_unidextok.urdf_model import shipped_path
from lerobot_unidextok import hands
for hand in (n for n in hands.names() if shipped_path(hands.get(n))):
    report = record(RecordConfig(hand=hand, episodes=1, root=hand, max_attempts_factor=4))
    vec = make_env(UniDexTokEnvConfig(hand=hand), n_envs=1)["unidextok"][0]  # what lerobot-eval makes
    vec.reset(seed=0)
    frame = vec.envs[0].render()
    print("HAND", hand, report.episodes, report.frames, int(frame.max() > 0), os.environ.get("MUJOCO_GL"))
    vec.close()
"""


@pytest.mark.slow
def test_every_shipped_hand_records_and_runs_in_lerobot_from_the_installed_wheel(installed, tmp_path):
    """A pip user's simulator, with no URDF and no variable set (MUJOCO_GL neither, no display): the issue's
    `unidextok-sim-record --hand=unitree_dex3_1`, then in one process every hand whose built model ships recorded
    (one episode its expert completed) and made by LeRobot's own env factory (what lerobot-eval makes), a frame
    drawn. Nothing is built (the cache stays empty). Before: every built hand but the Allegro was refused ("its URDF
    ... is not under .../shared/data/urdf")."""
    site = installed[0]
    cache = tmp_path / "sim_cache"
    headless = ("MUJOCO_GL", "DISPLAY", "WAYLAND_DISPLAY")
    out = _run(installed, ["unidextok-sim-record", "--hand=unitree_dex3_1", "--episodes=1", "--root=dex3"], tmp_path,
               unset=headless).stdout  # fmt: skip
    assert "wrote" in out and "1 episodes" in out and (tmp_path / "dex3" / "meta" / "info.json").is_file(), out
    code = f"import os; os.environ['UNIDEXTOK_SIM_CACHE'] = {str(cache)!r}\n" + SHIPPED_HANDS
    lines = [line.split()[1:] for line in _run(installed, [sys.executable, "-c", code], tmp_path, unset=headless)
             .stdout.splitlines() if line.startswith("HAND")]  # fmt: skip
    shipped = sorted(p.name for p in (site / "lerobot_env_unidextok" / "assets").iterdir() if p.name != "inspire")
    assert sorted(line[0] for line in lines) == shipped and len(shipped) >= 10, lines
    for hand, episodes, frames, drawn, backend in lines:
        assert episodes == "1" and int(frames) > 5, (hand, frames)
        assert drawn == "1" or backend == "disable", (hand, backend)  # black only where no backend exists
    assert not cache.exists() or not any(cache.iterdir())


def test_the_sdist_is_the_library_with_its_licences(tmp_path):
    """The sdist carried tests/test_*.py without the conftest and fixtures they need (MANIFEST.in prunes the
    checkout's other folders); it holds the package data the wheel needs and the licences."""
    import tarfile

    src = tmp_path / "src"
    shutil.copytree(REPO, src, ignore=shutil.ignore_patterns(".venv", ".git", "outputs", "__pycache__", "*.egg-info",
                                                             "build", "dist", ".pytest_cache"))  # fmt: skip
    subprocess.run([sys.executable, "-c", f"from setuptools import build_meta; build_meta.build_sdist({str(tmp_path)!r})"],
                   cwd=src, check=True, capture_output=True, timeout=300)  # fmt: skip
    (sdist,) = tmp_path.glob("lerobot_policy_unidextok-*.tar.gz")
    names = [n.split("/", 1)[1] for n in tarfile.open(sdist).getnames() if "/" in n]
    assert {"LICENSE", "NOTICE", "README.md", "pyproject.toml"} <= set(names)
    assert "lerobot_unidextok/hands/specs/unitree_dex3_1.yaml" in names
    assert "lerobot_unidextok/pretrained/universal-small/model.safetensors" in names
    assert "lerobot_env_unidextok/assets/inspire/inspire_right_hand.xml" in names
    # the checkout's shape: converters/ and configs/ at the top, as the design card lays it out
    assert {"converters/lerobot.py", "converters/README.md", "configs/__init__.py", "configs/train/small.yaml"} <= set(names)
    stray = [n for n in names if n.startswith(("tests/", "experiments/", "benchmarks/", "docs/", "tools/"))]
    assert stray == [], stray[:5]
    # a wheel built from the sdist (what pip does with it) installs both inside the package
    tarfile.open(sdist).extractall(tmp_path / "unpacked", filter="data")
    (unpacked,) = (tmp_path / "unpacked").iterdir()
    subprocess.run([sys.executable, "-c", f"from setuptools import build_meta; build_meta.build_wheel({str(tmp_path)!r})"],
                   cwd=unpacked, check=True, capture_output=True, timeout=300)  # fmt: skip
    (wheel,) = tmp_path.glob("lerobot_policy_unidextok-*.whl")
    wheel_names = set(zipfile.ZipFile(wheel).namelist())
    assert {"lerobot_unidextok/converters/dexycb.py", "lerobot_unidextok/configs/lerobot/act_udt_cpu.yaml"} <= wheel_names
