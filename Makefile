# The two commands a new user runs: `make demo` and `make test`.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

# Tools the tests drive outside Python: the Khronos glTF validator (npm, under Debian's
# nodejs) in a git-ignored folder, and Debian's chromium with its driver for the web
# viewer's browser tests (apt, as root). A test whose tool is missing skips, saying why.
TOOLS  := .tools
GLTF_VALIDATOR := $(TOOLS)/node_modules/gltf-validator/package.json

.PHONY: demo test lint clean tools chromium

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

chromium:
	command -v chromium >/dev/null && command -v chromedriver >/dev/null \
	  || apt-get install -y --no-install-recommends chromium chromium-driver \
	  || echo "chromium not installed (needs root and Debian's apt): the browser tests will skip"

tools: $(GLTF_VALIDATOR) chromium

test: lint tools
	$(BIN)/pytest

clean:
	rm -rf $(VENV) $(TOOLS) out .pytest_cache .ruff_cache .hypothesis .benchmarks
