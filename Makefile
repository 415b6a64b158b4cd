# The two commands of the README's quick start are `make serve` and `make test`.
# Each sets up the virtual environment first (idempotent), so a fresh clone needs nothing else.
PY ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed

.PHONY: setup demo serve test lint clean

$(STAMP): pyproject.toml setup.py $(wildcard policy/*.c policy/*.h)
	$(PY) -m venv $(VENV)
	$(BIN)/pip install --quiet --upgrade pip
	# The CPU build of torch first, exactly: a bare `torch` requirement would pull CUDA wheels.
	$(BIN)/pip install --quiet "torch==2.13.0"
	# The ray extra too: the test suite trains through a real local Ray instance.
	$(BIN)/pip install --quiet -e ".[dev,ray,otel]"
	touch $(STAMP)

setup: $(STAMP)

# The main job: the inference server on the embedded SQLite store (trains the zoo on first run).
# Development mode allows the default registry admin token; set COEXIST_ADMIN_TOKEN in production.
serve: $(STAMP)
	COEXIST_DEV_MODE=1 $(BIN)/coexist serve

demo: $(STAMP)
	$(BIN)/coexist demo --out demo/particle.gif

test: $(STAMP)
	./scripts/test.sh

lint: $(STAMP)
	$(BIN)/ruff check .
	$(BIN)/ruff format --check .
	$(BIN)/mypy .

clean:
	rm -rf $(VENV) .pytest_cache .mypy_cache .ruff_cache
