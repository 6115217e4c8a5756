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
	@mkdir -p $(FIGURES)
	@for n in 1 2 3 4; do \
	  $(BIN)/closedloop simulate --case $$n --plot $(FIGURES)/case-$$n.png || exit 1; echo; \
	done

benchmark: $(STAMP)
	$(BIN)/python benchmarks/performance.py

clean:
	rm -rf _build
