# Two entry points, each doing its own set-up in a local virtual environment from the locked
# dependency sets in requirements/ (plain pip and venv: nothing else needed on a fresh machine).
PYTHON ?= python3
VENV   ?= .venv
BIN    := $(VENV)/bin
LOCKS  := requirements
UV     ?= uv
# one universal lock for Python 3.11 and newer (markers where a newest release dropped 3.11)
COMPILE = $(UV) pip compile pyproject.toml --universal --python-version 3.11 --quiet --no-header

.PHONY: run test lint docs docs-check install install-test install-lint install-docs lock lock-check clean clean-numba

$(BIN)/python:
	$(PYTHON) -m venv $(VENV)

# each stamp records that its locked set is installed; editing a lock reinstalls
# (the C source too: the editable install compiles the optional CSV writer in place, setup.py)
$(VENV)/.installed-run: $(LOCKS)/run.txt pyproject.toml setup.py $(wildcard aquasim_py/*.c) | $(BIN)/python
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -r $(LOCKS)/run.txt
	$(BIN)/python -m pip install --quiet --disable-pip-version-check --no-deps -e .
	touch $@

$(VENV)/.installed-test: $(LOCKS)/test.txt $(VENV)/.installed-run
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -r $(LOCKS)/test.txt
	touch $@

$(VENV)/.installed-lint: $(LOCKS)/lint.txt $(VENV)/.installed-test
	$(BIN)/python -m pip install --quiet --disable-pip-version-check -r $(LOCKS)/lint.txt
	touch $@

install: $(VENV)/.installed-run
install-test: $(VENV)/.installed-test
install-lint: $(VENV)/.installed-lint

# the documentation site has a locked set of its own (requirements/docs.txt: the run set, the
# docs extra, the ocean extra) in an environment of its own, so that its pins never move the
# tested ones
DOCS_VENV ?= .venv-docs
DOCS_BIN  := $(DOCS_VENV)/bin

$(DOCS_BIN)/python:
	$(PYTHON) -m venv $(DOCS_VENV)

$(DOCS_VENV)/.installed-docs: $(LOCKS)/docs.txt pyproject.toml setup.py $(wildcard aquasim_py/*.c) | $(DOCS_BIN)/python
	$(DOCS_BIN)/python -m pip install --quiet --disable-pip-version-check -r $(LOCKS)/docs.txt
	$(DOCS_BIN)/python -m pip install --quiet --disable-pip-version-check --no-deps -e .
	touch $@

install-docs: $(DOCS_VENV)/.installed-docs

run: install
	$(BIN)/aquasim-py scenarios/itmtl.toml

test: install-test
	$(BIN)/python -m pytest -q

lint: install-lint
	$(BIN)/ruff check aquasim_py protocols tools tests docs/_ext docs/tutorials/files
	$(BIN)/ruff format --check aquasim_py protocols tools tests docs/_ext docs/tutorials/files
	$(BIN)/mypy
	$(BIN)/python tools/import_graph.py

# the site, strict (a warning, a broken link or a failing tutorial cell fails it), into site/;
# offline: nothing is fetched while it builds. The tutorials' shell blocks run the environment's
# aquasim-py (PATH); NO_MKDOCS_2_WARNING silences Material's notice about MkDocs 2 (docs/about.md)
DOCS_ENV = PATH="$(abspath $(DOCS_BIN)):$$PATH" NO_MKDOCS_2_WARNING=1
docs: install-docs
	$(DOCS_ENV) $(DOCS_BIN)/mkdocs build --strict --clean --site-dir site

# checks of the site: it loads nothing from the network, and a failing tutorial cell, a link
# to a missing page or heading each fail the build (tools/docs_check.py)
docs-check: install-docs
	$(DOCS_ENV) $(DOCS_BIN)/python tools/docs_check.py

lock:
	$(COMPILE) -o $(LOCKS)/run.txt
	$(COMPILE) --extra test -o $(LOCKS)/test.txt
	$(COMPILE) --extra test --extra lint -o $(LOCKS)/lint.txt
	$(COMPILE) --extra docs -o $(LOCKS)/docs.txt

# the committed locks must be what `make lock` writes from pyproject.toml's ranges; uv keeps the
# pins already in an output file, so a recompile of a copy changes nothing unless a range moved
lock-check:
	@tmp=$$(mktemp -d) && cp $(LOCKS)/*.txt $$tmp/ && \
	$(COMPILE) -o $$tmp/run.txt && \
	$(COMPILE) --extra test -o $$tmp/test.txt && \
	$(COMPILE) --extra test --extra lint -o $$tmp/lint.txt && \
	$(COMPILE) --extra docs -o $$tmp/docs.txt && \
	for f in run test lint docs; do \
	  diff -u $(LOCKS)/$$f.txt $$tmp/$$f.txt || { echo "$(LOCKS)/$$f.txt is out of step with pyproject.toml: run make lock"; exit 1; }; \
	done && echo "locks match pyproject.toml"

clean: clean-numba
	rm -rf $(VENV) $(DOCS_VENV) out site

# numba's compiled kernels cached beside their sources (docs/internals.md: a cache is not
# refreshed when a kernel it calls in another module changes)
clean-numba:
	find aquasim_py -name '*.nbi' -delete -o -name '*.nbc' -delete
