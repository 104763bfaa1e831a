"""Hub push/pull for tokenizer checkpoints and converted datasets, model cards, a loopback Hub."""

from lerobot_unidextok.hub.card import tokenizer_card
from lerobot_unidextok.hub.loopback import LoopbackHub
from lerobot_unidextok.hub.push_pull import (
    cache_via_loopback,
    cached_snapshot,
    pull,
    push,
)

__all__ = [
    "LoopbackHub",
    "cache_via_loopback",
    "cached_snapshot",
    "pull",
    "push",
    "tokenizer_card",
]
