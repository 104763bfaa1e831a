"""lerobot-unidextok's simulator (placeholder while it is built)."""
