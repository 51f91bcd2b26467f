"""The dataset format: audio codings, the writer and reader, damaged documents, plan seals.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
