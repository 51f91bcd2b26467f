"""RIR banks: TAU-SRIR DB, SOFA and native layouts, paths, plausibility checks.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
