"""udhm is layer 1: it may import only numpy, scipy, torch, the stdlib and layer 0 (constants, the CLI output
helpers); tests/test_light_imports.py checks in a fresh interpreter that it never imports LeRobot."""

from __future__ import annotations

import ast
import sys
from pathlib import Path

import lerobot_unidextok.udhm as udhm_pkg

ALLOWED_TOP = {"numpy", "scipy", "torch", "__future__"}
ALLOWED_OWN = ("lerobot_unidextok.constants", "lerobot_unidextok.udhm", "lerobot_unidextok.utils.cli")


def test_udhm_imports_only_lower_layers():
    pkg_dir = Path(udhm_pkg.__file__).parent
    for path in sorted(pkg_dir.glob("*.py")):
        tree = ast.parse(path.read_text())
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module:
                names = [node.module]
            for name in names:
                top = name.split(".")[0]
                ok = top in ALLOWED_TOP or top in sys.stdlib_module_names or name.startswith(ALLOWED_OWN)
                assert ok, f"{path.name} imports {name}"
