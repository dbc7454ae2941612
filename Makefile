# The two commands a new user runs: `make demo` and `make test`; `make quick` while developing.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed

# Tools the tests drive outside Python: the Khronos glTF validator (npm, under Debian's
# nodejs) in a git-ignored folder, and Debian's chromium with its driver for the web
# viewer's browser tests (apt, as root). A test whose tool is missing skips, saying why.
TOOLS  := .tools
GLTF_VALIDATOR := $(TOOLS)/node_modules/gltf-validator/package.json

.PHONY: demo test quick lint clean tools debian-tools

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

$(GLTF_VALIDATOR): | debian-tools
	npm install --prefix $(TOOLS) --no-save --no-audit --no-fund gltf-validator@2.0.0-dev.3.10 \
	  || echo "gltf-validator not installed (no npm or no registry): its tests will skip"

DEBIAN_TOOLS := chromium chromium-driver nodejs npm
debian-tools:
	command -v chromium >/dev/null && command -v chromedriver >/dev/null && command -v npm >/dev/null \
	  || apt-get install -y --no-install-recommends $(DEBIAN_TOOLS) \
	  || (apt-get update -qq && apt-get install -y --no-install-recommends $(DEBIAN_TOOLS)) \
	  || echo "$(DEBIAN_TOOLS) not installed (needs root and Debian's apt): their tests will skip"

tools: $(GLTF_VALIDATOR) debian-tools

# Everything, as CI runs it: the ci hypothesis profile (1,000-example fuzzing), benches,
# subprocess sessions and the browser tests included; on every core, a test module's tests
# on one worker (its module fixtures, the recorded sessions, are built once).
test: lint tools
	HYPOTHESIS_PROFILE=ci $(BIN)/pytest -n auto --dist loadscope

# The fast tier: no test marked slow (subprocess sessions, benches, long simulations) and
# the quick hypothesis profile, on every core (pytest-xdist).
quick: lint
	HYPOTHESIS_PROFILE=quick $(BIN)/pytest -m "not slow" -n auto

clean:
	rm -rf $(VENV) $(TOOLS) out .pytest_cache .ruff_cache .hypothesis .benchmarks
