"""Source readers, one module per dataset format: raw files -> `RawEpisode`s in native units.

This folder is the checkout's top-level `converters/`, installed as `lerobot_unidextok.converters`
(pyproject.toml's package-dir; docs/architecture.md, "Folders and import names").

Each module registers its reader with `@register_source` (`conversion.registry` imports them all) and defines
the facts of its format once (frame rates, file and key names), which the synthetic sample writers
(`lerobot_unidextok.samples`) take from it; the shared machinery (UDHM mapping, writing, validation) lives in
`lerobot_unidextok.conversion`. A module whose optional extra is missing (h5py, rosbags) leaves its source
unavailable with a note. Format notes and upstream references: README.md in this folder.
"""
