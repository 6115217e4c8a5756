# Two set-up commands for a fresh machine (see README.md):
#   make book   builds the companion (for now: runs the paper's four cases and writes their figures)
#   make test   runs the test suite
# Each creates .venv from the pinned requirements/lock.txt when it is missing or out of date.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
FIGURES := _build/figures

.PHONY: book test benchmark clean

$(STAMP): requirements/lock.txt pyproject.toml
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -r requirements/lock.txt
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-deps --no-build-isolation -e .
	touch $@

test: $(STAMP)
	$(BIN)/python -m pytest

book: $(STAMP)
	mkdir -p $(FIGURES)
	for n in 1 2 3 4; do \
	  $(BIN)/closedloop simulate --case $$n --plot $(FIGURES)/case-$$n.png --json > $(FIGURES)/case-$$n.json || exit 1; \
	  $(BIN)/python -c "import json,sys; d=json.load(open(sys.argv[1])); print(f\"case {d['case']}: {d['motion']:13s} max |f| = {d['max_constraint_error']:.1e}\")" $(FIGURES)/case-$$n.json; \
	done
	@echo "figures in $(FIGURES)/"

benchmark: $(STAMP)
	$(BIN)/python benchmarks/performance.py

clean:
	rm -rf _build
