"""Signal processing: the time-varying convolution of moving sources, exact and without level ripple.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
