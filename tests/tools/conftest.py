"""Tools over finished datasets: evaluate, the DCASE SELD metrics, verify, stats, inspect, pictures, the PyTorch adapter.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
