"""`python -m lerobot_unidextok.hands [name ...]`: print each hand's native joints and UDHM slots."""

from __future__ import annotations

import sys

from lerobot_unidextok.hands.registry import describe


def main(argv: list[str] | None = None) -> None:
    names = (sys.argv[1:] if argv is None else argv) or None
    print(describe(names))


if __name__ == "__main__":
    main()
