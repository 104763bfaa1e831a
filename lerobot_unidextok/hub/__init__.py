"""Hub push/pull for tokenizer checkpoints, policies and converted datasets; model cards; a loopback Hub."""

from lerobot_unidextok.hub.card import model_card, policy_card, tokenizer_card
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
    "model_card",
    "policy_card",
    "pull",
    "push",
    "tokenizer_card",
]
