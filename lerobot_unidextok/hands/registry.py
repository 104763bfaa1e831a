"""The shipped hands: one YAML per hand in ``hands/specs/``; ``names()``, ``get()``, ``describe()``."""

from __future__ import annotations

from functools import cache
from pathlib import Path

from lerobot_unidextok.errors import UserError
from lerobot_unidextok.hands.loading import load_spec
from lerobot_unidextok.hands.spec import HandSpec

SPECS_DIR = Path(__file__).parent / "specs"


class UnknownHandError(UserError, KeyError, ValueError):
    """A hand name that has no spec; the message lists the known ones."""

    def __str__(self) -> str:  # KeyError would repr() the message
        return str(self.args[0])


def names() -> tuple[str, ...]:
    """Names of the shipped hand specs, sorted."""
    return tuple(sorted(p.stem for p in SPECS_DIR.glob("*.yaml")))


@cache
def _get(name: str) -> HandSpec:
    return load_spec(SPECS_DIR / f"{name}.yaml")


def get(name: str) -> HandSpec:
    """The shipped spec called ``name``; ``UnknownHandError`` (KeyError and ValueError) lists known names."""
    if name not in names():
        raise UnknownHandError(f"unknown hand {name!r}; known hands: {', '.join(names())}")
    return _get(name)


def all_specs() -> list[HandSpec]:
    return [get(n) for n in names()]


def describe(hand_names: list[str] | tuple[str, ...] | None = None) -> str:
    """Printable tables: per hand, its native joints, units/ranges and the UDHM slots they fill."""
    blocks = [describe_spec(get(n)) for n in (hand_names or names())]
    return "\n\n".join(blocks)


def describe_spec(spec: HandSpec) -> str:
    head = (
        f"== {spec.name} (embodiment {spec.embodiment}; sides {', '.join(spec.sides)}; "
        f"{spec.num_active}/22 UDHM slots active)\n   native: {spec.native_units}"
    )
    if spec.kind == "keypoints":
        return head + "\n   MANO-21 keypoints -> all 22 UDHM slots by inverse kinematics; back by FK"
    side = "right" if "right" in spec.sides else spec.sides[0]
    other = next((x for x in spec.sides if x != side), None)
    rows = [("#", "native joint", f"raw range ({side})", "rad at raw ends", "sign", "rest rad", "UDHM slot", "")]
    for i, j in enumerate(spec.joints):
        js = j.sides[side]
        slot = js.slot or "- (dropped)"
        if other is not None and j.sides[other].slot != js.slot:
            slot += f" ({other}: {j.sides[other].slot})"
        rows.append(
            (
                str(i),
                j.name,
                f"{js.raw_range[0]:g}..{js.raw_range[1]:g}",
                f"{js.rad_at_raw_range[0]:+.3f}..{js.rad_at_raw_range[1]:+.3f}",
                f"{js.sign:+.0f}",
                f"{js.rest_rad:+.3f}" if js.rest_rad else "",
                slot,
                "judgement" if j.judgement else "",
            )
        )
    widths = [max(len(r[c]) for r in rows) for c in range(len(rows[0]))]
    lines = ["   " + "  ".join(cell.ljust(w) for cell, w in zip(r, widths, strict=True)).rstrip() for r in rows]
    return head + "\n" + "\n".join(lines)
