# Every target sets itself up: a fresh clone needs only python3 (>=3.11) with venv and pip.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    ?= out

.PHONY: all venv test render bench bench-rays bench-bvh bench-render bench-materials stress gpu-check clean

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
	$(VENV)/bin/pyopencl-rt bench bvh --json docs/bench/bvh.json

bench-render: $(STAMP)
	$(VENV)/bin/pyopencl-rt bench render scenes/cornell-box.toml --device cpu --width 512 --height 512 \
		--spp 16 --max-depth 8 --json docs/bench/render.json

bench-materials: $(STAMP)
	$(VENV)/bin/pyopencl-rt bench materials --device cpu --json docs/bench/materials.json

bench: bench-bvh bench-rays bench-render bench-materials

# The long variants of the size-dependent tests, marked `stress` (docs/ROBUSTNESS.md; `make test`
# runs the quick ones), with their summary in docs/bench/stress.{json,md}.
stress: $(STAMP)
	$(PY) -m pytest -m stress tests -q -rxXf -p no:cacheprovider --report-json docs/bench/stress.json

# On a machine with an NVIDIA GPU (docs/DEVICES.md): make its OpenCL driver visible, then the suite on
# the GPU device and the ray and render benchmarks on every device, all results as JSON in $(OUT)/gpu/.
gpu-check: $(STAMP)
	mkdir -p $(OUT)/gpu /etc/OpenCL/vendors
	test -e /etc/OpenCL/vendors/nvidia.icd || echo libnvidia-opencl.so.1 > /etc/OpenCL/vendors/nvidia.icd
	$(VENV)/bin/pyopencl-rt devices --json > $(OUT)/gpu/devices.json
	-PYOPENCL_TEST=gpu $(PY) -m pytest -q -p no:cacheprovider tests --report-json $(OUT)/gpu/tests.json
	-$(VENV)/bin/pyopencl-rt bench rays --device all --layout both --sizes 100k,1M --json $(OUT)/gpu/rays.json
	-$(VENV)/bin/pyopencl-rt bench render scenes/cornell-box.toml --device all --width 512 --height 512 \
		--spp 64 --max-depth 8 --json $(OUT)/gpu/render.json

clean:
	rm -rf $(VENV) build dist *.egg-info $(OUT) .pytest_cache
