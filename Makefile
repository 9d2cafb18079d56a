# Two entry points, each doing its own set-up in a local virtual environment.
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin

.PHONY: run test install clean

$(BIN)/aquasim-py: pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@

install: $(BIN)/aquasim-py

run: install
	$(BIN)/aquasim-py scenarios/itmtl.toml

test: install
	$(BIN)/python -m pytest -q

clean:
	rm -rf $(VENV) out
