# Every target sets itself up: a fresh clone needs only python3 (>=3.11) with venv and pip.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    ?= out

.PHONY: all venv test render bench bench-rays bench-bvh bench-render stress clean

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

# The CPU benchmark set of docs/BENCHMARKS.md (results land in docs/bench/).
bench-rays: $(STAMP)
	$(VENV)/bin/pyopencl-rt bench rays --device cpu --json docs/bench/rays.json

bench-bvh: $(STAMP)
	$(PY) tools/bench_bvh.py --json docs/bench/bvh.json

bench-render: $(STAMP)
	$(VENV)/bin/pyopencl-rt bench render scenes/cornell-box.toml --device cpu --width 512 --height 512 \
		--spp 16 --max-depth 8 --json docs/bench/render.json

bench: bench-bvh bench-rays bench-render

# The long version of the numerical stress suite (docs/ROBUSTNESS.md); `make test` runs the quick one.
stress: $(STAMP)
	$(PY) tools/stress.py

clean:
	rm -rf $(VENV) build dist *.egg-info $(OUT) .pytest_cache
