"""Captioned clips: manifest readers, the demo corpus, corpora in the layouts people have, ambience, prepared clips, caption paraphrases, clip fingerprints.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
