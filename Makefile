# Two entry points: `make demo` (set up, then run the main job on the paper's 5M4S example)
# and `make test` (set up, then run the whole test suite). Needs only python3 (3.11+), git and make.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
EXAMPLE ?= examples/paper_5m4s.toml

.PHONY: demo test bench setup clean

setup: $(STAMP)

$(STAMP): pyproject.toml
	$(PYTHON) -c 'import sys; sys.exit("Python 3.11+ is required, found " + sys.version.split()[0]) if sys.version_info < (3, 11) else None'
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/sicomat check $(EXAMPLE)
	$(BIN)/sicomat modal $(EXAMPLE) --plot out/modes.png
	@echo "mode-shape figure: out/modes.png"

test: $(STAMP)
	$(BIN)/python -m pytest -q --doctest-modules src/sicomat tests

bench: $(STAMP)
	$(BIN)/python -m benchmarks.run

clean:
	rm -rf $(VENV) out .pytest_cache .hypothesis
