#!/usr/bin/env bash
# Build pbrt-v4 (CPU only) as the reference for our renders of pbrt scenes
# (pyopencl_rt/bench/pbrt_reference.py, `bench pbrt-scenes --pbrt`; docs/BENCHMARKS.md, "pbrt-v4 as the
# reference").  Nothing of pbrt is kept in this repository: this fetches its public source at a pinned
# commit, with its submodules, and builds the `pbrt` executable outside the checkout.
#
#   tools/build_pbrt.sh [WORKDIR]          # default /tmp/pbrt-v4; prints the binary's path last
#   PBRT_SOURCE=/path/to/pbrt-v4 tools/build_pbrt.sh   # a source tree you already have (no network)
#
# Needs git, cmake >= 3.12, a C++17 compiler, and (Debian/Ubuntu) libopenexr-dev zlib1g-dev
# libx11-dev libxrandr-dev libxinerama-dev libxcursor-dev libxi-dev (pbrt's viewer library, GLFW,
# is compiled even when unused).  About 16 minutes on 2 cores.
set -euo pipefail

COMMIT=5f7a6068   # mmp/pbrt-v4, 2026-06-14: the build our figures in docs/BENCHMARKS.md come from
WORK=${1:-/tmp/pbrt-v4}
SRC=${PBRT_SOURCE:-$WORK/src}
BUILD=$WORK/build
JOBS=${JOBS:-$(nproc)}

if [[ -z "${PBRT_SOURCE:-}" ]]; then
    if [[ ! -d "$SRC/.git" ]]; then
        mkdir -p "$WORK"
        git clone https://github.com/mmp/pbrt-v4.git "$SRC"
    fi
    git -C "$SRC" fetch --quiet origin || true
    git -C "$SRC" checkout --quiet "$COMMIT"
    git -C "$SRC" submodule update --init --recursive
fi
[[ -f "$SRC/CMakeLists.txt" ]] || { echo "build_pbrt: no pbrt-v4 source at $SRC" >&2; exit 1; }

# pbrt's PMJ02BN tables and blue-noise textures are source files over 4 MiB; a tree assembled from
# snapshots that leave such files out lacks them.  Only the `pmj02bn` sampler reads them; say so
# rather than fail deep in the build.
for f in src/pbrt/util/pmj02tables.cpp src/pbrt/util/bluenoise.cpp; do
    [[ -s "$SRC/$f" ]] || echo "build_pbrt: $SRC/$f is missing: the build will fail (a full clone has it)" >&2
done

cmake -S "$SRC" -B "$BUILD" -DCMAKE_BUILD_TYPE=Release -DPBRT_BUILD_NATIVE_EXECUTABLE=OFF \
      -DPBRT_USE_PREGENERATED_RGB_TO_SPECTRUM_TABLES=OFF -DGLFW_BUILD_WAYLAND=OFF -Wno-dev
cmake --build "$BUILD" --target pbrt_exe -j "$JOBS"
"$BUILD/pbrt" --help > /dev/null 2>&1 || true
echo "$BUILD/pbrt"
