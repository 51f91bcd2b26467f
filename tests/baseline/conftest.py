"""The baseline trainer (tsel_baseline); skipped without torch.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
