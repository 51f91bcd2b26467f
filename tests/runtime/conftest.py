"""Where work runs: the local pool, a local Dask cluster and shard ranges give the same files.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
