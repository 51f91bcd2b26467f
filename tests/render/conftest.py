"""The renderer: labels against the audio, noise beds, moving sources, several receivers in one pass.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
