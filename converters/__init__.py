"""Source readers, one module per dataset: raw files -> `RawEpisode`s in native units.

Installed as `lerobot_unidextok.converters` (see pyproject `package-dir`); the shared
machinery (UDHM mapping, writing, validation) lives in `lerobot_unidextok.conversion`.
"""
