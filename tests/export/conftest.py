"""Exports: the folder rules every export keeps, each format read back by the package that reads it, recipe releases.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
