"""The objects `GraspLift-v0` draws: shape, size ranges and the grasp each needs. Data below the tasks and the hands:
`tasks.py` puts them in the scene, `urdf_hand.py` sizes a built hand's pre-shapes and pinch from them."""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Shape:
    name: str
    geom: str  # MuJoCo geom type
    half_m: tuple[tuple[float, float], ...]  # per size parameter: (low, high), drawn uniformly
    grasp: str  # "power" or "pinch"
    yaw: bool  # drawn yaw matters (boxes)


SHAPES = (
    Shape("box", "box", ((0.022, 0.028), (0.022, 0.028), (0.025, 0.035)), "power", True),
    Shape("cylinder", "cylinder", ((0.022, 0.028), (0.03, 0.04)), "power", False),
    Shape("block", "box", ((0.012, 0.015), (0.012, 0.015), (0.018, 0.024)), "pinch", True),
    Shape("cube", "box", ((0.013, 0.017),), "pinch", True),
)
DENSITY = 400.0  # kg/m^3: 20-100 g objects

__all__ = ["DENSITY", "SHAPES", "Shape"]
