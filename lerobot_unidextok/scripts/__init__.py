"""Thin draccus CLIs: parse arguments, call one library function."""
