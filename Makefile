# The two commands of the README's quick start are `make serve` and `make test`.
# Each sets up the virtual environment first (idempotent) with what it needs, so a fresh clone
# needs nothing else: `make serve` the server and training (`.[train]`: torch, matplotlib; no dev
# tools, no Ray), `make test` everything (`.[dev,ray,otel]`; dev brings train, eval and postgres).
PY ?= python3
comma := ,
VENV ?= .venv
BIN := $(VENV)/bin
DEPS := pyproject.toml setup.py VERSION sdk/pyproject.toml docker/requirements.lock $(wildcard policy/*.c policy/*.h services/rest/*.c)

.PHONY: setup setup-serve demo serve test lint clean

$(BIN)/python:
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip

# $(call install,EXTRAS): the CPU build of torch first, exactly (a bare `torch` requirement
# would pull CUDA wheels), then the client (sdk/, its own distribution), then the server.
# The images' lock constrains every dependency it names, so a fresh clone installs the versions
# the images run and the tests were run on, whatever the index published since; the dev tools
# the lock does not name float within pyproject's ranges.
LOCK := docker/requirements.lock
define install
	$(BIN)/pip install --quiet "torch==2.13.0"
	$(BIN)/pip install --quiet -c $(LOCK) -e ./sdk
	$(BIN)/pip install --quiet -c $(LOCK) -e ".[$(1)]"
endef

$(VENV)/.installed-serve: $(DEPS) | $(BIN)/python
	$(call install,train)
	touch $@

# The ray and otel extras too: the test suite trains through a real local Ray instance and
# checks the optional traces.
$(VENV)/.installed: $(DEPS) | $(BIN)/python
	$(call install,dev$(comma)ray$(comma)otel)
	touch $@ $(VENV)/.installed-serve

setup: $(VENV)/.installed
setup-serve: $(VENV)/.installed-serve

# The main job: the inference server on the embedded SQLite store (trains the zoo on first run).
# Development mode allows the default registry admin token; set COEXIST_ADMIN_TOKEN in production.
serve: $(VENV)/.installed-serve
	COEXIST_DEV_MODE=1 $(BIN)/coexist serve

demo: $(VENV)/.installed-serve
	$(BIN)/coexist demo --out demo/particle.gif

test: $(VENV)/.installed
	./scripts/test.sh

lint: $(VENV)/.installed
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy .

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache
