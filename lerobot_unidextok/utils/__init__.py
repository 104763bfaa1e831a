"""Small layer-0 helpers: dataset lookup by repo id in the local caches, quiet optional-backend imports,
progress bars that throttle when not on a terminal, and one-line CLI errors."""
