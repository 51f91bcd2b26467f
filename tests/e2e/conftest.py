"""Cross-cutting suites through the command line: trust after anything, reliability, signals, bad input, messages, first days, portable datasets, side outputs, a lean start.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
