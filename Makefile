# The two commands a new user runs: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

# Tools the tests drive outside Python (npm packages under Debian's nodejs), in a
# git-ignored folder; a test that needs one skips, saying why, when it is missing.
TOOLS  := .tools
GLTF_VALIDATOR := $(TOOLS)/node_modules/gltf-validator/package.json

.PHONY: demo test lint clean tools

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

$(GLTF_VALIDATOR):
	npm install --prefix $(TOOLS) --no-save --no-audit --no-fund gltf-validator@2.0.0-dev.3.10 \
	  || echo "gltf-validator not installed (no npm or no registry): its tests will skip"

tools: $(GLTF_VALIDATOR)

test: lint tools
	$(BIN)/pytest

clean:
	rm -rf $(VENV) $(TOOLS) out .pytest_cache .ruff_cache .hypothesis .benchmarks
