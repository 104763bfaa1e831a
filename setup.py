"""Package discovery only (everything else is in pyproject.toml).

The per-source dataset readers live at the top level in `converters/` (one thin module per
source) but install as `lerobot_unidextok.converters`, which pyproject tables cannot express.
`lerobot_policy_unidextok` is the package LeRobot's plugin discovery imports (pyproject.toml, name).
"""

from setuptools import find_packages, setup

setup(
    packages=find_packages(include=["lerobot_unidextok", "lerobot_unidextok.*", "lerobot_policy_unidextok"])
    + ["lerobot_unidextok.converters"],
    package_dir={"lerobot_unidextok.converters": "converters"},
)
