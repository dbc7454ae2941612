# The two commands a new user runs: `make demo` and `make test`; `make quick` while developing.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

.PHONY: demo test quick lint clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

demo: $(STAMP)
	$(BIN)/python examples/demo.py --out out/demo

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/lint-imports

# Everything, as CI runs it: the ci hypothesis profile (1,000-example fuzzing), benches and
# subprocess sessions included.
test: lint
	HYPOTHESIS_PROFILE=ci $(BIN)/pytest

# The fast tier: no test marked slow (subprocess sessions, benches, long simulations) and
# the quick hypothesis profile.
quick: lint
	HYPOTHESIS_PROFILE=quick $(BIN)/pytest -m "not slow"

clean:
	rm -rf $(VENV) out .pytest_cache .ruff_cache .hypothesis .benchmarks
