# Two entry points: `make demo` (set up, then run the main job on the paper's 5M4S example)
# and `make test` (set up, then run the whole test suite). Needs only python3 (3.11+), git and make.
PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
EXAMPLE ?= examples/paper_5m4s.toml
# The tested versions (docs/conventions.md, "Tests and tolerances"): every install below is constrained
# to them, the build backend's isolated environment too; `make lock` refreshes the file.
LOCK := requirements.lock
export PIP_CONSTRAINT := $(CURDIR)/$(LOCK)
PIP_INSTALL := $(BIN)/python -m pip install --quiet -c $(LOCK)

.PHONY: demo test bench setup clean lock

setup: $(STAMP)

$(STAMP): pyproject.toml $(LOCK)
	$(PYTHON) -c 'import sys; sys.exit("Python 3.11+ is required, found " + sys.version.split()[0]) if sys.version_info < (3, 11) else None'
	$(PYTHON) -m venv $(VENV)
	$(PIP_INSTALL) --upgrade pip
	$(PIP_INSTALL) --build-constraint $(LOCK) -e '.[test]'
	touch $(STAMP)

# A fresh temporary venv gets the newest versions pyproject.toml's open ranges allow (and its build
# requirements), nothing is run in it, and its freeze replaces requirements.lock in one rename. Run
# `make test` afterwards: the lock is only worth committing once the suite passes on it.
lock:
	@set -e; tmp=$$(mktemp -d); trap 'rm -rf "$$tmp" $(LOCK).tmp' EXIT; \
	env -u PIP_CONSTRAINT $(PYTHON) -m venv "$$tmp/venv"; \
	build=$$($(PYTHON) -c 'import tomllib; print(" ".join(tomllib.load(open("pyproject.toml", "rb"))["build-system"]["requires"]))'); \
	env -u PIP_CONSTRAINT "$$tmp/venv/bin/python" -m pip install --quiet --upgrade pip $$build; \
	env -u PIP_CONSTRAINT "$$tmp/venv/bin/python" -m pip install --quiet -e '.[test]'; \
	{ echo "# Tested versions of every runtime, test and build dependency of sicomat (a pip constraints file)."; \
	  echo "# Made by \`make lock\`: a fresh venv, \`pip install -e '.[test]'\` with pyproject.toml's open ranges,"; \
	  echo "# then \`pip freeze --all --exclude-editable\`. Refresh: \`make lock && make clean test\`, commit if green."; \
	  echo "# Made with Python $$("$$tmp/venv/bin/python" -c 'import platform; print(platform.python_version(), platform.system(), platform.machine())')."; \
	  env -u PIP_CONSTRAINT "$$tmp/venv/bin/python" -m pip freeze --all --exclude-editable; } > $(LOCK).tmp; \
	mv $(LOCK).tmp $(LOCK); echo "wrote $(LOCK)"

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
	$(PIP_INSTALL) 'slycot>=0.6' || echo "slycot unavailable: the peers run without it"
	$(BIN)/python -m benchmarks.run

clean:
	rm -rf $(VENV) out .pytest_cache .hypothesis
