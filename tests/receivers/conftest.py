"""Receivers: one spec per receiver read by every stage, and each receiver heard from its audio.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
