# Every target sets itself up: a fresh clone needs only python3 (>=3.11) with venv and pip.
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed
OUT    ?= out

.PHONY: all venv test render bench bench-rays bench-bvh bench-render bench-materials stress isa-check gpu-check gpu-wheels clean

all: test

$(STAMP): setup.cfg pyproject.toml
	test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -e '.[dev]'
	touch $(STAMP)

venv: $(STAMP)

test: $(STAMP)
	$(PY) -m pytest -q -n auto tests

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

# The ISA matrix (docs/DEVICES.md, "SIMD width on CPUs"): tools/isa_check.py under qemu-user as an AVX2
# (Haswell) and an SSE4.2 (Nehalem) CPU, each with an empty PoCL cache; installs Debian's qemu-user
# where qemu-x86_64 is missing (as root, else through sudo).
isa-check: $(STAMP)
	command -v qemu-x86_64 > /dev/null || { s=$$([ "$$(id -u)" = 0 ] || echo sudo); \
		$$s apt-get update -qq && $$s apt-get install -y -qq qemu-user; }
	$(PY) -m pytest -m isa tests -q -rA -p no:cacheprovider

# On a machine with an NVIDIA GPU (docs/DEVICES.md): make its OpenCL driver visible, then the media tests
# (the wavefront stages against the megakernel) and the suite on the GPU device, and the ray and render
# benchmarks (cornell-box, and cornell-fog for media) on every device, all results in $(OUT)/gpu/.
# On the lent GPU machine (no network, Python 3.12): run `make gpu-wheels` here first, then there
# `tools/gpu_check.sh` with .whl carried (it installs the wheels itself; no venv).
gpu-check: $(STAMP)
	OUT=$(OUT) tools/gpu_check.sh $(PY)

GPU_WHEELS := pyopencl==2026.1.4 pytools==2026.1.1 platformdirs==4.14.9 siphash24==1.9 embreex==4.4.0.post1 \
	trimesh==5.2.0 OpenEXR==3.5.3
gpu-wheels:
	$(PYTHON) -m pip download -q --no-deps --only-binary=:all: --python-version 3.12 --implementation cp \
		--platform manylinux_2_28_x86_64 --platform manylinux_2_27_x86_64 --platform manylinux_2_17_x86_64 \
		--platform manylinux2014_x86_64 -d .whl $(GPU_WHEELS)

clean:
	rm -rf $(VENV) build dist *.egg-info $(OUT) .pytest_cache
