"""The ISA matrix (`make isa-check`, marked `isa`: deselected unless -m selects it): tools/isa_check.py
under Debian's qemu-user as an AVX2 CPU (Haswell: 8 lanes) and an SSE4.2 one (Nehalem: one path per
work-item), each with an empty PoCL cache, so PoCL compiles every kernel for that CPU and links the
built-in library its flags pick.  What it checks: the probe and the rule's width, no wide vector
passed to a built-in, renders at every width equal to one path bit for bit, trace() packets equal
single rays.  Minutes per CPU model (qemu emulates every instruction, LLVM's included)."""
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]


@pytest.mark.isa
@pytest.mark.parametrize("cpu, width", [("Haswell", 8), ("Nehalem", 0)])
def test_isa_matrix(cpu, width, tmp_path):
    qemu = shutil.which("qemu-x86_64")
    if qemu is None:
        pytest.fail("qemu-x86_64 not found: `make isa-check` installs Debian's qemu-user")
    # the kernels users get: each scene's own features (the suite's default is every feature)
    env = {**os.environ, "POCL_CACHE_DIR": str(tmp_path / "pocl"), "PYOPENCL_RT_KERNEL_FEATURES": "scene"}
    env.pop("PYOPENCL_RT_LANES", None)
    r = subprocess.run([qemu, "-cpu", cpu, sys.executable, str(REPO / "tools" / "isa_check.py"),
                        "--expect-width", str(width)], env=env, capture_output=True, text=True, timeout=3600,
                       cwd=REPO)
    print(r.stdout)
    assert r.returncode == 0, r.stdout + r.stderr[-3000:]
    assert "all passed" in r.stdout
