"""Scene recipes and query relations, true on the rendered audio and labels.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
