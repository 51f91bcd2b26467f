"""Jobs over datasets: plan -> render -> finalize, scenes on demand, stems.

Shared fixtures (the demo corpus, generated datasets by name, the in-process CLI) are
in tests/conftest.py; helpers in tests/support/."""
