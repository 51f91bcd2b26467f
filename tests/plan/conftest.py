"""The planner: catalogs and plans over the real AudioCaps manifests, caption pairing and similarity.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
