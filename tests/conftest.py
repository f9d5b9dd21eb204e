"""Shared fixtures: every device test runs on each available OpenCL device.

Select devices with ``PYOPENCL_TEST`` (comma-separated specs as for ``--device``, e.g.
``PYOPENCL_TEST=cpu`` or ``PYOPENCL_TEST=0:0,1:0``); by default every device found is used.

Long variants of size-dependent tests carry the ``stress`` marker (registered in setup.cfg), the
ISA matrix under qemu-user the ``isa`` marker (``make isa-check``).  Both are deselected unless ``-m`` is given: ``pytest tests`` (``make test``) runs the quick
versions, ``pytest -m stress tests`` (``make stress``) only the long ones.  ``--report-json PATH``
writes a summary of the run (counts, failures and xfails, and every line a test reported
through the ``measured`` fixture) to PATH, and as markdown next to it (``make stress`` writes
docs/bench/stress.json and stress.md).
"""
import json
import os
import shlex
import time
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt.device import devices as dv
from pyopencl_rt.render.settings import FEATURES_ENV

# Every feature compiled into each kernel (render/settings.py, EVERY_FEATURE): the suite's scenes
# then share a few dozen programs instead of building one per feature set (most of its CPU time
# on a fresh machine).  tests/render/test_features.py checks that this changes no image bit;
# ``PYOPENCL_RT_KERNEL_FEATURES=scene make test`` runs the suite with each scene's own kernel.
os.environ.setdefault(FEATURES_ENV, "all")


# The device tests of these (test ids or their prefixes) run on every device, so on every OpenCL
# implementation present: the kernels' arithmetic and ABI, the BSDFs' sampling and densities,
# textures, traversal, the lanes, the sampler, several implementations in one render.  The other
# device tests (whole renders, mostly) run on every device but the CPU devices beyond the one
# `--device cpu` picks (PoCL): with Intel's CPU runtime installed (the dev extra) they would double
# the suite's time for what the tests above already cover.  ``PYOPENCL_TEST`` set
# (``PYOPENCL_TEST=all``) runs every device test on the devices it names.
EVERY_IMPLEMENTATION = (
    "tests/accel/", "tests/device/", "tests/render/test_lanes_math.py", "tests/render/test_shading.py",
    "tests/scene/test_textures.py",
    *(f"tests/render/test_sampler.py::test_{name}" for name in (
        "device_equals_numpy_copy", "lanes_draw_the_same_samples", "small_round_equals_numpy_copy",
        "sobol_pixels_are_02_sequences", "sobol_pixel_groups_are_nets_at_block_ends", "stratified_fills_grids",
        "every_dimension_uniform", "scrambles_independent")),
    *(f"tests/scene/test_materials.py::test_{name}" for name in (
        "sampled_directions_follow_the_pdf", "pdf_integrates_to_the_sampling_probability", "eval_is_reciprocal",
        "smooth_dielectric_fresnel_snell_tir", "smooth_conductor_is_a_mirror_with_exact_fresnel",
        "smooth_gltf_mirror_fraction", "no_nan_or_inf_for_extreme_parameters", "lane_widths_give_the_one_lane_bits",
        "type_constants_and_layout_agree")))
_ROOT = Path(__file__).resolve().parents[1]


def device_specs_for(nodeid: str) -> list[str]:
    """The devices of a device test (``nodeid`` relative to the repository, as pytest gives it)."""
    specs = dv.device_test_specs()
    if os.environ.get("PYOPENCL_TEST", "").strip() or nodeid.startswith(EVERY_IMPLEMENTATION):
        return specs
    import pyopencl as cl

    cpus = [e for e in dv.all_devices() if e[2].type & cl.device_type.CPU]
    first_cpu = dv.resolve("cpu")[0] if cpus else None
    return [dv.describe(e).index for e in dv.all_devices() if dv.describe(e).index in specs
            and (not e[2].type & cl.device_type.CPU or e[2] == first_cpu)]


def pytest_generate_tests(metafunc):
    if "device" in metafunc.fixturenames:
        path = Path(metafunc.definition.fspath).resolve().relative_to(_ROOT).as_posix()
        specs = device_specs_for(f"{path}::{metafunc.definition.name}")
        metafunc.parametrize("device", specs, ids=[f"dev{s}" for s in specs], indirect=True)


@pytest.fixture
def device(request):
    return dv.select_device(request.param)


@pytest.fixture
def runtime(device):
    from pyopencl_rt.device.kernels import runtime as rt

    return rt(device)


@pytest.fixture
def own_features(monkeypatch):
    """Kernels with only what each scene uses, as users get them (the suite's default: every feature)."""
    monkeypatch.setenv(FEATURES_ENV, "scene")


@pytest.fixture
def rng():
    return np.random.default_rng(12345)


@pytest.fixture
def device_spec(device):
    """The ``P:D`` spec of ``device``: for what cannot be handed the pyopencl.Device itself (a
    subprocess, a Dask worker) or where a spec string is the thing under test."""
    import harness

    return harness.device_spec(device)


@pytest.fixture
def measured(record_property):
    """``measured(line)``: one line of what a test measured (escape counts, z-scores, ...):
    printed (``pytest -s`` shows it) and kept in the ``--report-json`` summary."""
    def note(line):
        print(line)
        record_property("measured", str(line))

    return note


# ----------------------------------------------------------------------------- the stress marker
def pytest_addoption(parser):
    parser.addoption("--report-json", metavar="PATH", default=None,
                     help="write a summary of the run (outcomes and `measured` lines) to PATH, "
                          "and as markdown to PATH with the suffix .md")


def secondary_implementation(spec: str) -> bool:
    """Whether the device test spec ``spec`` is a CPU device beyond the one ``--device cpu`` picks
    (Intel's CPU runtime beside PoCL): a second compiler of the same kernels."""
    import pyopencl as cl

    entry = dv.resolve(spec)[0]
    return bool(entry.type & cl.device_type.CPU) and entry != dv.resolve("cpu")[0]


@pytest.fixture
def second_implementation(request) -> bool:
    """Whether this device test runs on a second CPU implementation (:func:`secondary_implementation`)."""
    return secondary_implementation(request.node.callspec.params["device"])


def mark_second_implementation_subsets(items):
    """A test module's ``SECOND_IMPLEMENTATION = {test name: keep(params, device)}`` names the
    cases that a second implementation runs in ``make test`` (one per code path, where the first
    runs every case); the others there get the ``stress`` marker (``make stress`` runs them)."""
    for item in items:
        keep = getattr(item.module, "SECOND_IMPLEMENTATION", {}).get(item.originalname)
        params = getattr(getattr(item, "callspec", None), "params", {})
        if keep is not None and "device" in params and secondary_implementation(params["device"]):
            if not keep(params, dv.select_device(params["device"])):
                item.add_marker(pytest.mark.stress)


def pytest_collection_modifyitems(config, items):
    """Without ``-m``, deselect the long (``stress``) variants and the ISA matrix (``isa``)."""
    mark_second_implementation_subsets(items)
    if config.option.markexpr:
        return
    slow = [item for item in items if item.get_closest_marker("stress") or item.get_closest_marker("isa")]
    if slow:
        config.hook.pytest_deselected(items=slow)
        items[:] = [item for item in items if item not in slow]


def pytest_configure(config):
    path = config.getoption("--report-json")
    if path:
        config.pluginmanager.register(RunReport(config, Path(path)), "pyopencl-rt-run-report")


class RunReport:
    """The summary written by ``--report-json`` (what tools/stress.py used to scrape from the
    output of ``pytest -s``)."""

    def __init__(self, config, path: Path):
        self.config, self.path = config, path
        self.t0 = time.time()
        self.counts: Counter = Counter()
        self.measured: list[str] = []
        self.outcomes: list[str] = []
        self.deselected = 0

    def pytest_deselected(self, items):
        self.deselected += len(items)

    def pytest_runtest_logreport(self, report):
        if report.when == "call":
            self.measured += [str(v) for k, v in report.user_properties if k == "measured"]
        xfail = getattr(report, "wasxfail", None)
        if report.failed:
            kind, word = ("failed", "FAILED") if report.when == "call" else ("error", "ERROR")
            crash = getattr(report.longrepr, "reprcrash", None)
            why = crash.message.splitlines()[0] if crash is not None and crash.message else ""
        elif report.skipped:
            kind, word, why = ("xfailed", "XFAIL", xfail) if xfail is not None else ("skipped", None, "")
        elif report.when == "call":
            kind, word, why = ("xpassed", "XPASS", xfail) if xfail is not None else ("passed", None, "")
        else:
            return
        self.counts[kind] += 1
        if word:
            self.outcomes.append(f"{word} {report.nodeid}" + (f" - {why}" if why else ""))

    def pytest_sessionfinish(self, session, exitstatus):
        seconds = time.time() - self.t0
        order = ("failed", "passed", "skipped", "xfailed", "xpassed", "error")
        counts = ", ".join(f"{self.counts[k]} {k}" for k in order if self.counts[k])
        command = "python -m pytest " + shlex.join(self.config.invocation_params.args)
        result = {"command": command, "seconds": round(seconds, 1), "returncode": int(exitstatus),
                  "summary": f"{counts or 'no tests ran'} in {seconds:.2f}s", "measured": self.measured,
                  "outcomes": self.outcomes}
        if self.deselected:
            result["deselected"] = self.deselected
        self.path.parent.mkdir(parents=True, exist_ok=True)
        self.path.write_text(json.dumps(result, indent=2) + "\n")
        md = [f"# {self.path.stem}", "", f"`{command}`: {result['summary']} ({seconds:.0f} s)", "", "```"]
        md += self.measured + self.outcomes + ["```", ""]
        self.path.with_suffix(".md").write_text("\n".join(md))
