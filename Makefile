# building-twin: the two commands are `make demo` (the main job) and `make test` (what CI runs).
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
VAR    := var

.PHONY: demo test test-fast lint docs bench clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

## demo: install, then the live loop on the bundled lab: import, daemon, a robot observes, a watcher
## receives the map updates, the daemon stops cleanly; maps and the recording land in var/
demo: $(STAMP)
	$(BIN)/twin demo --workdir $(VAR)
	@echo "The 'twin' command is in $(BIN)/: activate the venv ('. $(BIN)/activate') or run '$(BIN)/twin --help'."
	@echo "Next: the five-minute tour in README.md; the documentation: 'make docs', then open site/index.html."

## test: install, then run the whole test suite on both cores (what CI runs; about 7.5 min on 2 cores);
## each test file runs whole on one worker, slowest files first (tests/durations.json)
test: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 --dist loadfile

## test-fast: the inner loop, without processes, shared models and the viewer (about 1 min on 2 cores)
test-fast: $(STAMP)
	$(BIN)/python -m pytest -q -n 2 --dist loadfile -m "not slow"

## lint: ruff and mypy on the library code
lint: $(STAMP)
	$(BIN)/ruff check twin adapters tests benchmarks references
	$(BIN)/mypy

## docs: the documentation site (MkDocs, Material theme) into site/, warnings as errors (broken links fail)
docs: $(STAMP)
	NO_MKDOCS_2_WARNING=1 $(BIN)/mkdocs build --strict  # not --quiet: it hides the warnings that strict counts

## bench: the performance harness (prints a table, writes JSON)
bench: $(STAMP)
	$(BIN)/python benchmarks/run.py --json benchmarks/results/latest.json

clean:
	rm -rf $(VAR) site .pytest_cache .mypy_cache .ruff_cache
