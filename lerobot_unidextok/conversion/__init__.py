"""Shared conversion machinery: raw episodes -> UDHM LeRobotDataset v3 repos."""
