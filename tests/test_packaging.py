"""pyproject.toml lists the package's folders (a package-dir mapping needs the list): every folder that holds an
`__init__.py`, with the checkout's top-level `converters/` and `configs/` mapped into the package, and nothing else."""

import tomllib
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]


def _setuptools() -> dict:
    return tomllib.loads((REPO / "pyproject.toml").read_text())["tool"]["setuptools"]


def test_the_listed_packages_are_the_folders_with_an_init():
    cfg = _setuptools()
    mapped = {name: REPO / folder for name, folder in cfg["package-dir"].items()}
    assert mapped == {"lerobot_unidextok.converters": REPO / "converters", "lerobot_unidextok.configs": REPO / "configs"}
    on_disk = set()
    for top in ("lerobot_unidextok", "lerobot_policy_unidextok", "lerobot_env_unidextok"):
        on_disk |= {".".join(p.parent.relative_to(REPO).parts) for p in (REPO / top).rglob("__init__.py")}
    for name, folder in mapped.items():
        on_disk |= {".".join([name, *p.parent.relative_to(folder).parts]) for p in folder.rglob("__init__.py")}
    assert sorted(cfg["packages"]) == sorted(on_disk)


def test_the_card_top_level_is_the_checkout_top_level():
    for name in ("pyproject.toml", "README.md", "lerobot_unidextok", "converters", "configs", "tests", "notebooks"):
        assert (REPO / name).exists(), name
