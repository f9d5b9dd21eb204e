# Every target sets itself up: a fresh clone needs only python3 (>=3.10) with venv and pip.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    ?= out

.PHONY: all venv test test-fast render bench bench-rays bench-bvh wheel-test stress clean

all: test

$(STAMP): setup.cfg pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	touch $(STAMP)

venv: $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -q tests

render: $(STAMP)
	$(VENV)/bin/pyopencl-rt render scenes/cornell-box.toml -o $(OUT)/cornell-box.exr --spp 64

bench-rays: $(STAMP)
	$(VENV)/bin/pyopencl-rt bench rays --json docs/bench-rays.json

bench-bvh: $(STAMP)
	$(PY) tools/bench_bvh.py --json docs/bench-bvh.json

bench: bench-bvh bench-rays

clean:
	rm -rf $(VENV) build dist *.egg-info $(OUT) .pytest_cache
