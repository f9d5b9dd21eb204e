"""Mitsuba 3, the peer renderer of the benchmarks, run in its own interpreter (this module is the
host side; it is not called ``mitsuba.py`` because the scripts beside it, run by file path, would
then import it instead of the real ``mitsuba``).

Mitsuba often lives in a virtual environment of its own, so it runs as a subprocess: scripts in
this folder that need only numpy and mitsuba (:mod:`.mitsuba_runner`, :mod:`.mitsuba_cornell_box`)
are started with that interpreter: for convergence curves (:func:`run_mitsuba_curve`), for renders
timed in turns with ours (:class:`MitsubaServer`), and on Mitsuba's own Cornell box
(:func:`run_mitsuba_cornell_box`).  Nothing here guesses system paths; what it needs comes from
options or the environment, in this order:

* the interpreter: ``--mitsuba-python``, else ``$PYOPENCL_RT_MITSUBA_PYTHON``, else this one.  The
  first of them that is set is the one used: a named interpreter that cannot import mitsuba is
  reported, not silently replaced by another;
* libLLVM, which the ``llvm_*`` variants load at run time: ``--llvm-path``, else Dr.Jit's own
  ``$DRJIT_LIBLLVM_PATH``, else Dr.Jit's own search (``libLLVM.so`` on the library path).

:func:`find_mitsuba_python` tries the interpreter and the variant once and says in one line what
is missing and how to provide it.
"""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from ..errors import UserError
from .convergence_analysis import mean_points, metrics, spp_schedule

PYTHON_ENV = "PYOPENCL_RT_MITSUBA_PYTHON"
LLVM_ENV = "DRJIT_LIBLLVM_PATH"  # Dr.Jit's own variable
DEFAULT_VARIANT = "llvm_ad_rgb"
HERE = Path(__file__).resolve().parent

INSTALL_HINT = (f"pip install mitsuba in this environment, or point --mitsuba-python or ${PYTHON_ENV} at an "
                "interpreter that has it")
LLVM_HINT = (f"pass --llvm-path /path/to/libLLVM.so or set ${LLVM_ENV} (see docs/BENCHMARKS.md for the LLVM "
             "versions that work), or pick a scalar_* variant")

# Run in the candidate interpreter: exit 3 = no mitsuba, 4 = the variant does not work (LLVM
# itself aborts the process when it cannot compile).  A whole path tracer is compiled, on a 4x4
# image: an llvm_* variant that loads too old a libLLVM passes set_variant and simple kernels,
# and fails only there ("Cannot select: fminimum" with LLVM 15).
PROBE = """
import sys
try:
    import mitsuba as mi
except Exception as exc:
    print(f"{type(exc).__name__}: {exc}"); sys.exit(3)
try:
    import drjit as dr
    mi.set_variant(sys.argv[1])
    scene = mi.cornell_box()
    scene["sensor"]["film"]["width"] = scene["sensor"]["film"]["height"] = 4
    dr.eval(mi.render(mi.load_dict(scene), spp=1))
except Exception as exc:
    print(f"{type(exc).__name__}: {exc}"); sys.exit(4)
print(mi.__version__)
"""


def mitsuba_env(llvm_path=None) -> dict:
    """The environment of a Mitsuba subprocess: ours, with ``$DRJIT_LIBLLVM_PATH`` set to
    ``llvm_path`` when given."""
    env = dict(os.environ)
    if llvm_path:
        env[LLVM_ENV] = str(llvm_path)
    return env


def failure_reason(output: str, variant: str) -> str:
    """One line out of a failed Mitsuba process's output, with how to fix it where it is LLVM's."""
    lines = [line.strip() for line in output.splitlines() if line.strip()]
    llvm_error = next((line for line in lines if "LLVM ERROR" in line), None)
    if llvm_error:
        llvm_error = re.sub(r",?\s*0x[0-9a-f]+:?", "", llvm_error).strip(" ,")[:120]  # node addresses say nothing
        return f"Mitsuba's {variant} cannot compile with the libLLVM that Dr.Jit loaded ({llvm_error}): {LLVM_HINT}"
    last = lines[-1] if lines else "no output"
    if variant.startswith("llvm") and "llvm" in last.lower():
        return f"Mitsuba's {variant} cannot load libLLVM ({last}): {LLVM_HINT}"
    return f"Mitsuba ({variant}) failed: {' | '.join(lines[-3:]) or 'no output'}"


def _interpreter_choice(explicit):
    if explicit:
        return explicit, "--mitsuba-python"
    if os.environ.get(PYTHON_ENV):
        return os.environ[PYTHON_ENV], f"${PYTHON_ENV}"
    return sys.executable, "this interpreter"


def _llvm_problem(llvm_path, variant):
    """Why the libLLVM setting cannot work (one line), or None."""
    if not variant.startswith("llvm"):
        return None
    path, source = (llvm_path, "--llvm-path") if llvm_path else (os.environ.get(LLVM_ENV), f"${LLVM_ENV}")
    if path and not Path(path).is_file():
        return f"Mitsuba's {variant} needs libLLVM, and {source}={path} is no such file: {LLVM_HINT}"
    return None


def find_mitsuba_python(explicit=None, variant=DEFAULT_VARIANT, llvm_path=None):
    """(interpreter, where it came from and Mitsuba's version) when it imports mitsuba and runs
    ``variant``; else (None, one line saying what is missing and how to provide it).  Every
    "not installed" reason starts with "Mitsuba 3 not found"."""
    python, source = _interpreter_choice(explicit)
    if not Path(python).is_file():
        return None, f"Mitsuba 3 not found: {source}={python} is no such file; {INSTALL_HINT}"
    problem = _llvm_problem(llvm_path, variant)
    if problem:
        return None, problem
    try:
        probe = subprocess.run([python, "-c", PROBE, variant], capture_output=True, text=True, timeout=120,
                               env=mitsuba_env(llvm_path))
    except (OSError, subprocess.TimeoutExpired) as exc:
        return None, f"Mitsuba 3 not found: {source}={python} did not run ({exc}); {INSTALL_HINT}"
    output = probe.stdout + probe.stderr
    lines = output.strip().splitlines()
    last = lines[-1] if lines else f"exit status {probe.returncode}"
    if probe.returncode == 0:
        return python, f"{source}, Mitsuba {last}"
    if probe.returncode == 3:
        return None, f"Mitsuba 3 not found: {source}={python} cannot import mitsuba ({last}); {INSTALL_HINT}"
    return None, failure_reason(output, variant)


def require_mitsuba_python(mitsuba_python=None, variant=DEFAULT_VARIANT, llvm_path=None, echo=print) -> str:
    """:func:`find_mitsuba_python`'s interpreter, said with where it came from; a UserError with its
    one-line reason when there is none."""
    python, how = find_mitsuba_python(mitsuba_python, variant, llvm_path)
    if python is None:
        raise UserError(how)
    echo(f"Mitsuba: {python} ({how})")
    return python


def run_mitsuba_curve(scene, python, *, width, height, max_depth, rr_depth, reference, seconds, variant,
                      workdir, llvm_path=None, sampler="independent", seeds=1, first_seed=0, echo=print) -> dict:
    """One convergence curve of Mitsuba on ``scene`` (exported by :mod:`.mitsuba_export`), rendered
    progressively by :mod:`.mitsuba_runner` for about ``seconds`` with Mitsuba's ``sampler``
    plugin (other than independent, each point is a render of its own: see the runner).
    ``seeds``: the runner renders it with that many seeds (``--seed-offset first_seed``, the next
    offsets after it), ``seconds`` for all; the points are then their mean
    (:func:`.convergence_analysis.mean_points`) and ``seed_curves`` has each seed's own."""
    from ..render.settings import ImageSettings
    from .mitsuba_export import save_scene_npz, scene_arrays

    scene_file = Path(workdir) / "scene.npz"
    settings = ImageSettings.resolve(scene, width=width, height=height, max_depth=max_depth, rr_depth=rr_depth)
    save_scene_npz(scene_file, scene_arrays(scene, settings, spp=1))
    command = [python, str(HERE / "mitsuba_runner.py"), str(scene_file), str(workdir), "--variant", variant,
               "--budget", f"{seconds:.3f}", "--checkpoints", ",".join(str(s) for s in spp_schedule()),
               "--sampler", sampler, "--seeds", str(int(seeds)), "--seed-offset", str(int(first_seed))]
    start = time.perf_counter()
    run = subprocess.run(command, capture_output=True, text=True, env=mitsuba_env(llvm_path))
    wall = time.perf_counter() - start
    if run.returncode != 0:
        raise UserError(failure_reason(run.stdout + run.stderr, variant))
    info = json.loads((Path(workdir) / "mitsuba.json").read_text())
    runs = []
    for k, checkpoints in enumerate(info.get("seed_points") or [info["points"]]):
        points = []
        for checkpoint in checkpoints:
            image = np.load(checkpoint["image"]).astype(np.float64)
            seconds_so_far = checkpoint["seconds"]
            points.append({"spp": checkpoint["spp"], "seconds": seconds_so_far, **metrics(image, reference),
                           "samples_per_second": checkpoint["spp"] * width * height / seconds_so_far
                           if seconds_so_far > 0 else None})
        runs.append({"seed_offset": int(first_seed) + k, "points": points})
    points = mean_points([r["points"] for r in runs], width * height)
    last = points[-1] if points else {"spp": 0, "seconds": 0.0}
    echo(f"  mitsuba {info['version']} {variant} {sampler}: " + (f"{len(runs)} seeds x " if len(runs) > 1 else "")
         + f"{last['spp']} spp in {sum(r['points'][-1]['seconds'] for r in runs if r['points']):.2f} s "
         f"(JIT warm-up {info['warmup_seconds']:.2f} s)")
    curve = {"label": f"Mitsuba {info['version']} {variant} / path / {sampler}", "renderer": "mitsuba",
             "device": variant, "integrator": "path", "intersector": "mitsuba", "sampler": sampler,
             "build_seconds": info["warmup_seconds"],
             "warmup_seconds": info["warmup_seconds"], "setup_seconds": info["load_seconds"] + info["import_seconds"],
             "process_seconds": wall, "version": info["version"], "seed_offsets": [r["seed_offset"] for r in runs],
             "points": points}
    if len(runs) > 1:
        curve["seed_curves"] = runs
    return curve


def parse_spps(text: str) -> list[int]:
    """'16,64,256' -> [16, 64, 256]: one line of error for anything but positive integers."""
    from ..errors import UsageError

    try:
        spps = [int(value) for value in text.split(",") if value.strip()]
    except ValueError:
        raise UserError(f"--spp {text}: expected comma-separated integers") from None
    if not spps or min(spps) < 1:
        raise UsageError(f"--spp {text}: expected comma-separated positive integers")
    return spps


def run_mitsuba_cornell_box(*, mitsuba_python=None, llvm_path=None, variant=DEFAULT_VARIANT, spps=(16, 64, 256),
                            json_path=None, echo=print) -> dict:
    """Samples/s of Mitsuba on its own Cornell box (``mi.cornell_box()``), for scale beside ours:
    one render per entry of ``spps``, the first including the JIT compilation."""
    from .timing import machine_info, write_results

    python = require_mitsuba_python(mitsuba_python, variant, llvm_path, echo)
    command = [python, str(HERE / "mitsuba_cornell_box.py"), "--variant", variant,
               "--spp", ",".join(str(s) for s in spps)]
    run = subprocess.run(command, capture_output=True, text=True, env=mitsuba_env(llvm_path))
    if run.returncode != 0:
        raise UserError(failure_reason(run.stdout + run.stderr, variant))
    results = {**json.loads(run.stdout.strip().splitlines()[-1]), "python": python, "machine": machine_info()}
    width, height = results["width"], results["height"]
    for render in results["renders"]:
        rate = width * height * render["spp"] / render["seconds"]
        render["samples_per_second"] = rate
        echo(f"{render['spp']:4d} spp at {width}x{height}: {render['seconds']:6.2f} s, {rate / 1e6:.2f} Msamples/s")
    if json_path:
        write_results(json_path, results, echo)
    return results


class MitsubaServer:
    """Mitsuba rendering our ``scene`` (exported by :mod:`.mitsuba_export` with ``settings``) on
    request, for timings interleaved with ours (``bench render --mitsuba``): :mod:`.mitsuba_runner`
    ``--serve`` in Mitsuba's interpreter, one persistent process, warmed up (JIT) with one
    ``warmup_spp`` render when entered; :meth:`render` times one more.  ``info``: Mitsuba's
    version, variant, sampler and image size; ``renders``: every timed render.  ``python``: the
    interpreter :func:`require_mitsuba_python` found already (else it is looked for here)."""

    def __init__(self, scene, settings, *, mitsuba_python=None, llvm_path=None, variant=DEFAULT_VARIANT,
                 warmup_spp=16, python=None, echo=print):
        self.scene, self.settings, self.python = scene, settings, python
        self.mitsuba_python, self.llvm_path, self.variant = mitsuba_python, llvm_path, variant
        self.warmup_spp, self.echo = warmup_spp, echo
        self.process = self.info = None
        self.renders: list[dict] = []

    def __enter__(self):
        import tempfile

        from .mitsuba_export import save_scene_npz, scene_arrays

        python = self.python or require_mitsuba_python(self.mitsuba_python, self.variant, self.llvm_path, self.echo)
        self._workdir = tempfile.TemporaryDirectory(prefix="pyopencl_rt_mitsuba_")
        scene_file = Path(self._workdir.name) / "scene.npz"
        save_scene_npz(scene_file, scene_arrays(self.scene, self.settings, spp=self.warmup_spp))
        self._stderr = tempfile.TemporaryFile(mode="w+")  # a file, not a pipe nobody drains
        self.process = subprocess.Popen(
            [python, str(HERE / "mitsuba_runner.py"), str(scene_file), self._workdir.name, "--serve",
             "--variant", self.variant, "--warmup-spp", str(self.warmup_spp)],
            stdin=subprocess.PIPE, stdout=subprocess.PIPE, stderr=self._stderr, text=True,
            env=mitsuba_env(self.llvm_path))
        try:
            self.info = self._reply()
        except UserError:
            self.__exit__()  # a failed __enter__ gets no __exit__ from the with statement
            raise
        return self

    def _reply(self) -> dict:
        line = self.process.stdout.readline()
        try:
            return json.loads(line)
        except ValueError:  # it died (no line) or said something else
            self.process.kill()
            self.process.wait()
            self._stderr.seek(0)
            raise UserError(failure_reason(self._stderr.read() + line, self.variant)) from None

    def render(self, spp: int) -> float:
        """Samples/s of one render of ``spp`` samples per pixel (timed in Mitsuba's process)."""
        self.process.stdin.write(f"{int(spp)}\n")
        self.process.stdin.flush()
        render = self._reply()
        render["samples_per_second"] = self.info["width"] * self.info["height"] * render["spp"] / render["seconds"]
        self.renders.append(render)
        return render["samples_per_second"]

    def __exit__(self, *exc):
        if self.process is not None:
            self.process.stdin.close()
            try:
                self.process.wait(timeout=30)
            except subprocess.TimeoutExpired:
                self.process.kill()
                self.process.wait()
        if hasattr(self, "_stderr"):
            self._stderr.close()
            self._workdir.cleanup()
        return False
