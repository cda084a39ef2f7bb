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
	$(BIN)/sicomat margins $(EXAMPLE)
	$(BIN)/sicomat tune $(EXAMPLE) --velocity-crossover 125.6 --velocity-phase-margin 45 --position-phase-margin 80 --write out/paper_5m4s_tuned.toml
	$(BIN)/sicomat simulate out/paper_5m4s_tuned.toml --plot out/move.png --out out/move.csv
	$(BIN)/sicomat bode out/paper_5m4s_tuned.toml --loop velocity-open --nichols --plot out/nichols.png
	@echo "figures: out/modes.png out/move.png out/nichols.png; tuned model: out/paper_5m4s_tuned.toml"

test: $(STAMP)
	$(BIN)/python -m pytest -q --doctest-modules src/sicomat tests

bench: $(STAMP)
	$(BIN)/python -m pip install --quiet 'slycot>=0.6' || echo "slycot unavailable: the peers run without it"
	$(BIN)/python -m benchmarks.run

clean:
	rm -rf $(VENV) out .pytest_cache .hypothesis
