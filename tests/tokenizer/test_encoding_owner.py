"""One owner of the encoding: `EncodingConfig`, a field of the tokenizer's config. Everything else takes the
tokenizer as configured or one `EncodingConfig | None` override; the flat settings of before (`search_rounds`,
`udt_search_rounds`, ...) live on only where old configs are upgraded."""

import re
from pathlib import Path

import pytest

from lerobot_unidextok.errors import ConfigError
from lerobot_unidextok.tokenizer import EncodingConfig, UniDexTokConfig
from lerobot_unidextok.tokenizer.configuration_unidextok import upgrade_legacy_encoding

REPO = Path(__file__).resolve().parents[2]
SCANNED = ("lerobot_unidextok", "lerobot_policy_unidextok", "lerobot_env_unidextok", "experiments", "benchmarks",
           "configs", "tools", "converters", "docs", "README.md")  # fmt: skip
LEGACY = re.compile(r"\b(udt_)?search_(rounds|method|sweeps|changes|tolerance_deg)\b")
# file -> why it may name a legacy setting
ALLOWED = {
    "lerobot_unidextok/tokenizer/configuration_unidextok.py": "the legacy-config upgrade (LEGACY_ENCODING_KEYS)",
    "lerobot_unidextok/processor/processor_unidextok.py": "a saved step's legacy `search_rounds`, upgraded on load",
    "lerobot_unidextok/processor/mixed.py": "the same legacy argument, passed to the base step's upgrade",
    "lerobot_unidextok/policies/udt_config.py": "a policy checkpoint's legacy `udt_search_rounds`, upgraded on load",
}
# Markdown may name them where it explains the upgrade: on a line that says "legacy" or "before"
EXPLAINS = re.compile(r"legacy|before", re.I)


def _files():
    for top in SCANNED:
        for path in [REPO / top] if (REPO / top).is_file() else sorted((REPO / top).rglob("*")):
            if path.is_file() and path.suffix in (".py", ".yaml", ".yml", ".json", ".md", ".toml"):
                yield path


def test_only_the_tokenizer_config_and_the_legacy_upgrade_name_the_old_settings():
    hits = {}
    for path in _files():
        rel = path.relative_to(REPO).as_posix()
        lines = path.read_text(errors="replace").splitlines()
        if path.suffix == ".md":
            lines = [line for line in lines if not EXPLAINS.search(line)]
        found = sorted({m.group(0) for line in lines for m in LEGACY.finditer(line)})
        if found and rel not in ALLOWED:
            hits[rel] = found
    assert not hits, f"encoding settings outside EncodingConfig: {hits}"


def test_exactly_one_place_decides_the_encoding():
    """One declaration of an encoding that is not an override (UniDexTokConfig.encoding); every other field of
    that type is `EncodingConfig | None` (None = the tokenizer's own); and only the model calls the search."""
    owned, overrides, searches = [], [], []
    for path in _files():
        if path.suffix != ".py":
            continue
        text, rel = path.read_text(), path.relative_to(REPO).as_posix()
        owned += [rel for _ in re.finditer(r"^\s+\w+: EncodingConfig = ", text, re.M)]
        overrides += [rel for _ in re.finditer(r"^\s+\w+: EncodingConfig \| None = None", text, re.M)]
        searches += [rel for _ in re.finditer(r"\b(greedy_codes|search_codes)\(", text)
                     if rel != "lerobot_unidextok/tokenizer/search.py"]  # fmt: skip
    assert owned == ["lerobot_unidextok/tokenizer/configuration_unidextok.py"]
    assert "lerobot_unidextok/policies/udt_config.py" in overrides and len(overrides) >= 4
    assert set(searches) == {"lerobot_unidextok/tokenizer/modeling_unidextok.py"}


def test_the_encoding_is_checked_once_by_its_own_config():
    for bad, message in [({"rounds": -1}, "encoding.rounds must be >= 0"), ({"method": "beam"}, "encoding.method"),
                         ({"sweeps": 0}, "encoding.sweeps"), ({"changes": 0}, "encoding.changes"),
                         ({"tolerance_deg": -1.0}, "encoding.tolerance_deg"), ({"rounds": "2"}, "encoding.rounds")]:  # fmt: skip
        with pytest.raises(ConfigError, match=message):
            EncodingConfig(**bad)
        with pytest.raises(ConfigError, match=message):
            UniDexTokConfig(encoding=bad)
    with pytest.raises(ConfigError, match="does not know: \\['depth'\\]"):
        EncodingConfig.from_dict({"rounds": 1, "depth": 3})
    assert UniDexTokConfig(encoding={"rounds": 1}).encoding == EncodingConfig(rounds=1)


def test_legacy_flat_keys_are_upgraded_into_one_encoding():
    old = {"hidden_dim": 64, "search_rounds": 2, "search_sweeps": 3}
    assert upgrade_legacy_encoding(old) == {"hidden_dim": 64, "encoding": {"rounds": 2, "sweeps": 3, "method": "sweeps"}}
    assert upgrade_legacy_encoding(old, method_when_absent=None)["encoding"] == {"rounds": 2, "sweeps": 3}
    assert upgrade_legacy_encoding({"hidden_dim": 64}) == {"hidden_dim": 64}
    with pytest.raises(ConfigError, match="both `encoding` and the legacy keys"):
        upgrade_legacy_encoding({"encoding": {"rounds": 1}, "search_rounds": 2})
    cfg = UniDexTokConfig.from_dict({"format_version": 1, "search_rounds": 1, "search_method": "greedy",
                                     "search_tolerance_deg": 0.1})  # fmt: skip
    assert cfg.encoding == EncodingConfig(rounds=1, method="greedy", tolerance_deg=0.1)
