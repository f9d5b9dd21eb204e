#!/usr/bin/env bash
# The GPU check (docs/DEVICES.md): participating media by the wavefront stages on the GPU (the media
# tests: the wavefront's film against the megakernel's bit for bit, closed forms), the test suite on the
# GPU, then the ray and render benchmarks on every device (a media scene by both schedules too),
# results as files in $OUT/gpu/ (at most 8 files: what the device tool brings back; the media tests'
# results go to log.txt).
#
#   tools/gpu_check.sh [PYTHON]        # PYTHON: default python3
#
# Made for a lent machine with no network (the device tool): if .whl/ holds wheels (`make
# gpu-wheels` downloads the project's dependencies for CPython 3.12 there, here), they are
# installed into /tmp/site first; the machine's own Python brings numpy, scipy, numba, click,
# pillow, pytest and hypothesis.  PoCL's wheel (58 MB) does not fit the 64 MiB a call may carry,
# so there only the GPU is an OpenCL device.  The NVIDIA driver ships libnvidia-opencl.so.1 but no
# ICD file: one is written so that the ICD loader pyopencl bundles finds it.
set -u
py="${1:-python3}"
out="${OUT:-out}/gpu"
mkdir -p "$out"
log="$out/log.txt"
: > "$log"
say() { echo "== $*" | tee -a "$log"; }

if ls .whl/*.whl > /dev/null 2>&1; then
    say "installing $(ls .whl/*.whl | wc -l) wheels from .whl/ into /tmp/site"
    "$py" -m pip install -q --no-index --no-deps --no-compile --no-cache-dir --upgrade --target /tmp/site \
        .whl/*.whl >> "$log" 2>&1 || { say "wheel install failed"; exit 1; }
    export PYTHONPATH="/tmp/site:$PWD${PYTHONPATH:+:$PYTHONPATH}"
fi
if [ ! -e /etc/OpenCL/vendors/nvidia.icd ]; then
    lib=$(ldconfig -p 2> /dev/null | awk '/libnvidia-opencl\.so\.1/ {print $NF; exit}')
    for dir in /usr/local/nvidia/lib64 /usr/local/nvidia/lib /usr/lib/x86_64-linux-gnu; do
        [ -z "$lib" ] && [ -e "$dir/libnvidia-opencl.so.1" ] && lib="$dir/libnvidia-opencl.so.1"
    done
    mkdir -p /etc/OpenCL/vendors && echo "${lib:-libnvidia-opencl.so.1}" > /etc/OpenCL/vendors/nvidia.icd
    say "ICD file: $(cat /etc/OpenCL/vendors/nvidia.icd)"
fi
nvidia-smi -L >> "$log" 2>&1
cli() { "$py" -m pyopencl_rt.cli "$@"; }
say "devices"
cli devices --json > "$out/devices.json" 2>> "$log"
cli devices >> "$log" 2>&1
# first, so that the media are covered whatever the suite's time limit leaves (issue 25: the wavefront
# with media had never run on a GPU)
say "media by the wavefront stages on the GPU (tests/render/test_volpath.py)"
PYOPENCL_TEST=gpu PYTHONUNBUFFERED=1 timeout 90 "$py" -m pytest -q -p no:cacheprovider -rfE \
    tests/render/test_volpath.py -k "megakernel_bits or furnace or slab" >> "$log" 2>&1
say "media tests exit $?"
say "test suite on the GPU (PYOPENCL_TEST=gpu)"
PYOPENCL_TEST=gpu PYTHONUNBUFFERED=1 timeout 300 "$py" -m pytest -q -p no:cacheprovider --maxfail=25 -rfE tests \
    --report-json "$out/tests.json" >> "$log" 2>&1
say "pytest exit $?"
say "bench rays"
timeout 120 cli bench rays --device all --layout both --sizes 100k,1M --repeat 3 --json "$out/rays.json" >> "$log" 2>&1
say "bench rays exit $?"
say "bench render"
timeout 90 cli bench render scenes/cornell-box.toml --device all --width 512 --height 512 --spp 64 --max-depth 8 \
    --kernel-mode wavefront,megakernel --json "$out/render.json" >> "$log" 2>&1
say "bench render exit $?"
say "bench render, media (scenes/cornell-fog.toml)"
timeout 60 cli bench render scenes/cornell-fog.toml --device all --width 256 --height 256 --spp 16 --max-depth 8 \
    --kernel-mode wavefront,megakernel --json "$out/render-media.json" >> "$log" 2>&1
say "bench render media exit $?"
