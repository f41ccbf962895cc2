# Every target sets up what it needs: system libraries, the virtual environment, the packages.
PYTHON ?= python3.11
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: setup dataset test bench train eval lint preview clean

setup: $(STAMP)

$(STAMP): pyproject.toml scripts/ensure_system_libs.sh scripts/apt_ensure.sh
	bash scripts/ensure_system_libs.sh
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev]'
	touch $(STAMP)

dataset: $(STAMP)
	$(PY) -m nbv.dataset $(ARGS)

test: $(STAMP)
	$(PY) -m pytest -q $(ARGS)

# Settings as key=value (conf/bench.yaml), e.g. make bench ARGS="network=false render=false".
bench: $(STAMP)
	$(PY) -m nbv.bench $(ARGS)

train: $(STAMP)
	$(PY) -m train $(ARGS)

eval: $(STAMP)
	$(PY) -m nbv.eval $(ARGS)

lint: $(STAMP)
	$(VENV)/bin/ruff check nbv train blender_scripts tests scripts
	$(VENV)/bin/ruff format --check nbv train blender_scripts tests scripts
	$(VENV)/bin/lint-imports

preview: $(STAMP)
	$(PY) -m nbv.synthetic preview=outputs/synthetic_preview.png

clean:
	rm -rf $(VENV) outputs multirun .pytest_cache
