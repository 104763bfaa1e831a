"""Shared conversion machinery: raw episodes -> UDHM LeRobotDataset v3 repos.

    from lerobot_unidextok.conversion import ConvertOptions, convert, validate_dataset
    report = convert(ConvertOptions(source="linkerhand", input="raw/", root="out/linkerhand_udhm"))

Names are imported lazily so `import lerobot_unidextok` stays cheap (no pyarrow / lerobot at import).
"""

from __future__ import annotations

import importlib

_EXPORTS = {
    "HandStream": "episode",
    "Passthrough": "episode",
    "RawEpisode": "episode",
    "VideoSegment": "episode",
    "SetupError": "registry",
    "make_reader": "registry",
    "register_source": "registry",
    "get_source": "registry",
    "available_sources": "registry",
    "EpisodeError": "mapping",
    "UdhmEpisode": "mapping",
    "map_episode": "mapping",
    "ConvertOptions": "pipeline",
    "ConvertReport": "pipeline",
    "ConversionError": "pipeline",
    "convert": "pipeline",
    "merge_shards": "pipeline",
    "udhm_features": "features",
    "UdhmDatasetWriter": "writer",
    "validate_dataset": "validate",
}

__all__ = [
    "ConversionError",
    "ConvertOptions",
    "ConvertReport",
    "EpisodeError",
    "HandStream",
    "Passthrough",
    "RawEpisode",
    "SetupError",
    "UdhmDatasetWriter",
    "UdhmEpisode",
    "VideoSegment",
    "available_sources",
    "convert",
    "get_source",
    "make_reader",
    "map_episode",
    "merge_shards",
    "register_source",
    "udhm_features",
    "validate_dataset",
]


def __getattr__(name: str):
    if name in _EXPORTS:
        return getattr(importlib.import_module(f"{__name__}.{_EXPORTS[name]}"), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
