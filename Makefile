# Every target installs what is missing first (a virtualenv in .venv), so each works on a fresh machine.
PYTHON ?= python3
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed-stamp
ARGS ?=

.PHONY: install train test test-slow bench lint baseline clean

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --upgrade pip >/dev/null
	$(PY) -m pip install -e ".[dev]"
	touch $(STAMP)

install: $(STAMP)

# The main job on its defaults: a short real training run (see README). Extra Hydra overrides: make train ARGS="task=uniform speed=50"
train: install
	$(PY) -m agrl.train $(ARGS)

# The fast default suite (slow-marked tests excluded by pyproject's addopts).
test: install
	$(PY) -m pytest

test-slow: install
	$(PY) -m pytest -m slow

bench: install
	$(PY) -m agrl.bench $(ARGS)

lint: install
	$(PY) -m ruff check agrl tests

clean:
	rm -rf $(VENV) .pytest_cache .ruff_cache
