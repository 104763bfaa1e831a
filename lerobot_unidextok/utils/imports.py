"""Optional dependencies in one place: import one, or fail with the pip extra that installs it.

    yourdfpy = require_package("yourdfpy", "urdf", purpose="the URDF kinematic check")

LeRobot has the same helper (huggingface/lerobot `src/lerobot/utils/import_utils.py`, `require_package`);
this one imports the module (a broken install fails here too, with the same advice) and returns it.
"""

from __future__ import annotations

import importlib
from types import ModuleType


def missing_package_message(pkg: str, extra: str, purpose: str, hint: str = "") -> str:
    """`<purpose> needs <pkg>: pip install 'lerobot_policy_unidextok[<extra>]'<hint>`."""
    return f"{purpose} needs {pkg}: pip install 'lerobot_policy_unidextok[{extra}]'{hint}"


def require_package(
    pkg: str, extra: str, *, purpose: str, import_name: str | None = None, hint: str = ""
) -> ModuleType:
    """The module `import_name` (default `pkg`), or an ImportError naming `extra` (`missing_package_message`).

    `pkg` is the name pip installs, `purpose` what needs it ("reading ROS bags"), `hint` anything to add
    after the install command (" (Python < 3.13)").
    """
    try:
        return importlib.import_module(import_name or pkg)
    except ImportError as err:
        raise ImportError(missing_package_message(pkg, extra, purpose, hint)) from err
