"""SYNTHETIC sample datasets in each source's native file format, for the demo, the tests, the benchmarks and the
experiments (the conversion itself never imports them).

    from lerobot_unidextok.samples import write_samples
    folders = write_samples("raw", sources=["dexycb", "lerobot"], episodes_per_source=4)

`motion.py` generates named gestures in UDHM, `bags.py` writes ROS bags with `rosbags`' own writers, and
`formats.py` writes each source's files, taking the format's facts (frame rates, names) from its reader in
`lerobot_unidextok.converters`. Imports go one way: samples -> converters.
"""

from lerobot_unidextok.samples.formats import (
    MANO_SOURCES,
    SAMPLE_SOURCE_OPTIONS,
    SAMPLE_SOURCES,
    SYNTHETIC_NOTE,
    TRUTH_FILE,
    SampleSpec,
    available_sample_sources,
    write_samples,
)

__all__ = [
    "MANO_SOURCES",
    "SAMPLE_SOURCES",
    "SAMPLE_SOURCE_OPTIONS",
    "SYNTHETIC_NOTE",
    "TRUTH_FILE",
    "SampleSpec",
    "available_sample_sources",
    "write_samples",
]
