"""The project's own promises: the layers of docs/design.md, and the docs' examples run as written.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
