# The README's commands. Everything installs from scratch into .venv.
PYTHON ?= python3
VENV := .venv
PY := $(VENV)/bin/python
PIP := $(PY) -m pip
STAMP := $(VENV)/.installed

.PHONY: setup demo test lab bench clean

setup: $(STAMP)

# CPU torch first: a bare `torch` requirement resolved by pip may pull a multi-GB GPU build.
$(STAMP): pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PIP) install --quiet --upgrade pip
	$(PIP) install --quiet torch==2.13.0
	$(PIP) install --quiet -e ".[test]"
	touch $(STAMP)

demo: setup
	$(VENV)/bin/nlo-lab demo

test: setup
	$(PY) -m pytest -q

lab: setup
	$(VENV)/bin/nlo-lab lab

bench: setup
	$(PY) benchmarks/fk.py

clean:
	rm -rf $(VENV) build *.egg-info
