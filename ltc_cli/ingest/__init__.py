"""Ingest sessions: look-ahead loading and detection, map-frame set-up, checkpoints and resume."""
