"""Shared test helpers: one way to run device functions through harness kernels, and one
chi-square test.

Harness kernels
---------------
A test declares its kernels once, as OpenCL C text that includes headers of ``cl/``::

    SAMPLING = harness.Kernels(r'''
    #include "render/sampling.h"
    __kernel void h_cone(__global const float *u, float cos_max, __global float *out)
    { const int i = get_global_id(0); store3(out, i, sample_uniform_cone(vload2(i, u), cos_max)); }
    ''', defines={...})

and runs one of them over ``n`` work items, with the arguments in the kernel's order
(positionally, or by their C names)::

    w = SAMPLING(runtime, "h_cone", n, u, cos_max=0.5, out=(n, 3))

The kernel's signature decides what each argument is:

* ``__global const T *`` (or ``__constant``): an input array, copied to the device.  For the
  OpenCL scalar and vector types (``float``, ``uint``, ``float4``, ...) it is converted to the
  matching numpy dtype (a same-kind cast only: float64 -> float32 yes, float -> int no); for a
  struct (``Material``, ``Light``, ...) it must already be a record array of the ``abi`` dtype.
* ``__global T *`` (not const): an output.  Pass its shape (an int or a tuple; the array starts
  as zeros of T's dtype), or an array: its contents are the initial values (a copy is made).
* anything else (``int mode``, ``float tmax``): a scalar, converted to the C type.

The outputs come back as numpy arrays, in the kernel's parameter order: one array, or a tuple
of several.  Programs are assembled and built by ``pyopencl_rt.device.kernels`` (``cl/``
includes expanded, the ``abi`` struct declarations prepended, ``defines`` as ``-D``) and cached
per device runtime, as the renderer's own kernels are.

Chi-square
----------
:func:`chi2_test` / :func:`assert_chi2`: Pearson's test of binned samples against expected
counts, with Mitsuba 3's pooling rule (``mitsuba.math.chi2`` with a threshold of 5, as its
``ChiSquareTest`` uses it): the bins are sorted by expected count, increasing; a bin where both
the expected and the observed count are 0 is left out; bins expecting fewer than 5 samples are
pooled, in that order, into groups that are closed as soon as they expect more than 5 (each
group is one cell of the statistic); the last group, if it never reaches 5, is left out; the
degrees of freedom are the cells - 1.  Samples in a bin of expected count 0 fail the test
outright, as in Mitsuba.  Each test chooses its significance level.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

# ----------------------------------------------------------------------------- harness kernels
_SCALARS = {
    "char": np.int8, "uchar": np.uint8, "short": np.int16, "ushort": np.uint16, "int": np.int32,
    "uint": np.uint32, "long": np.int64, "ulong": np.uint64, "float": np.float32, "double": np.float64,
    "half": np.float16,
}
_QUALIFIERS = {"__global", "global", "__constant", "constant", "const", "restrict", "volatile", "__restrict"}
_KERNEL = re.compile(r"\b(?:__kernel|kernel)\s+(?:LANE_KERNEL\s+)?void\s+(\w+)\s*\(([^)]*)\)", re.S)


def _c_dtype(ctype: str):
    """numpy dtype of a C scalar or vector type (float4 -> float32: one element of the vector),
    None for anything else (a struct)."""
    if ctype.startswith("unsigned "):
        ctype = "u" + ctype.split()[1]
    m = re.fullmatch(r"([a-z]+?)(2|3|4|8|16)?", ctype)
    if m and m.group(1) in _SCALARS:
        if m.group(2) == "3":
            raise TypeError(f"{ctype} buffers are padded to 4 elements: use float with load3/store3")
        return np.dtype(_SCALARS[m.group(1)])
    return None


@dataclass(frozen=True)
class Param:
    name: str
    ctype: str       # the element type as written ("float", "Material", "float4")
    kind: str        # "in", "out" or "scalar"
    dtype: object    # numpy dtype, or None for a struct

    def input(self, value):
        if self.dtype is None:
            a = np.asarray(value)
            if a.dtype.fields is None:
                raise TypeError(f"{self.name}: a {self.ctype} buffer needs a record array of its abi dtype")
            return np.ascontiguousarray(a)
        a = np.asarray(value)
        integers = a.dtype.kind in "biu" and self.dtype.kind in "iu"
        if not (integers or np.can_cast(a.dtype, self.dtype, "same_kind")):
            raise TypeError(f"{self.name}: {a.dtype} values for a {self.ctype} buffer")
        out = np.ascontiguousarray(a, self.dtype)
        if integers and not np.array_equal(out, a):
            raise TypeError(f"{self.name}: values out of the range of {self.ctype}")
        return out

    def output(self, value):
        if isinstance(value, np.ndarray):
            return np.array(value, self.dtype if self.dtype is not None else value.dtype, copy=True)
        if self.dtype is None:
            raise TypeError(f"{self.name}: give a {self.ctype} output as an initial record array")
        return np.zeros(value, self.dtype)

    def scalar(self, value):
        if self.dtype is None or self.ctype[-1].isdigit():
            raise TypeError(f"{self.name}: {self.ctype} arguments by value are not supported")
        return self.dtype.type(value)


def parse_signatures(source: str) -> dict[str, tuple[Param, ...]]:
    """{kernel name: its parameters} of every ``__kernel void`` in ``source``."""
    found = {}
    for name, args in _KERNEL.findall(re.sub(r"/\*.*?\*/|//[^\n]*", "", source, flags=re.S)):
        params = []
        for text in filter(None, (a.strip() for a in args.split(","))):
            words = re.findall(r"\w+|\*", text)
            if "__local" in words or "local" in words:
                raise TypeError(f"{name}: __local parameters are not supported ({text!r})")
            pname = words[-1]
            pointer = "*" in words
            ctype = " ".join(w for w in words[:-1] if w not in _QUALIFIERS and w != "*")
            if pointer:  # const data (const before the *) or __constant memory: an input
                before = words[:words.index("*")]
                kind = "in" if {"const", "__constant", "constant"} & set(before) else "out"
            else:
                kind = "scalar"
            params.append(Param(pname, ctype, kind, _c_dtype(ctype)))
        found[name] = tuple(params)
    return found


def cpu_group(runtime) -> int | None:
    """The work-group size of a harness launch that names none: 1 on a CPU device, else the
    driver's choice.  PoCL compiles a kernel once per work-group size and, left to choose, takes
    the whole grid as one group, so every new item count was a new compile of the same kernel
    (33 of one BSDF kernel in one test run); groups of one item divide every count."""
    import pyopencl as cl

    return 1 if runtime.device.type & cl.device_type.CPU else None


class Kernels:
    """Harness kernels: ``source`` (OpenCL C; ``#include "x.h"`` pulls in ``cl/x.h``) built after
    the ``cl/`` files ``names`` (usually none) with the preprocessor ``defines``.  ``local_size``:
    work-groups of that size (the global size rounded up to it: kernels then ignore work-items
    beyond ``n``), else :func:`cpu_group`'s.  PoCL's CPU device keeps a work-group's private
    memory on one thread's stack, so a kernel with large private arrays (a packet's rays and
    traversal stack) needs small groups: the whole grid in one group overflowed it."""

    def __init__(self, source: str, *, defines: dict | None = None, names: tuple[str, ...] = (),
                 local_size: int | None = None):
        self.source = source
        self.defines = dict(defines or {})
        self.names = tuple(names)
        self.signatures = parse_signatures(source)
        self.local_size = local_size

    def program(self, runtime):
        """The built program (pyopencl.Program), cached per runtime."""
        return runtime.program(self.names, self.defines, self.source)

    def kernel(self, runtime, name: str):
        return runtime.kernel(self.names, name, self.defines, self.source)

    def bind(self, name: str, args: tuple, named: dict, /) -> list:
        """The kernel's arguments as values (input arrays, output arrays, numpy scalars), in order."""
        if name not in self.signatures:
            raise KeyError(f"no kernel {name!r} in this harness (has {', '.join(self.signatures)})")
        params = self.signatures[name]
        if len(args) > len(params):
            raise TypeError(f"{name} takes {len(params)} arguments, {len(args)} given")
        values = dict(zip((p.name for p in params), args))
        for key, value in named.items():
            if key in values:
                raise TypeError(f"{name}: {key} given twice")
            if key not in (p.name for p in params):
                raise TypeError(f"{name} has no parameter {key!r}")
            values[key] = value
        missing = [p.name for p in params if p.name not in values]
        if missing:
            raise TypeError(f"{name}: missing {', '.join(missing)}")
        return [getattr(p, {"in": "input", "out": "output", "scalar": "scalar"}[p.kind])(values[p.name])
                for p in params]

    def __call__(self, runtime, name: str, n: int, /, *args, **named):
        """Run kernel ``name`` over ``n`` work items; returns its output arrays (one, or a tuple).
        (``runtime``, ``name`` and ``n`` are positional-only: kernel parameters may have those names.)"""
        import pyopencl as cl

        params = self.signatures.get(name, ())
        values = self.bind(name, args, named)
        ctx, q = runtime.context, runtime.queue
        mf = cl.mem_flags
        bufs, outs = [], []
        for p, v in zip(params, values):
            if p.kind == "scalar":
                bufs.append(v)
                continue
            flags = mf.READ_ONLY if p.kind == "in" else mf.READ_WRITE
            if v.nbytes == 0:  # an empty array: a valid (unused) buffer
                bufs.append(cl.Buffer(ctx, flags, 1))
            else:
                bufs.append(cl.Buffer(ctx, flags | mf.COPY_HOST_PTR, hostbuf=v))
            if p.kind == "out":
                outs.append((v, bufs[-1]))
        local = self.local_size or cpu_group(runtime)
        if local:
            size = -(-int(n) // local) * local
            self.kernel(runtime, name)(q, (size,), (local,), *bufs)
        else:
            self.kernel(runtime, name)(q, (int(n),), None, *bufs)
        for host, buf in outs:
            if host.nbytes:
                cl.enqueue_copy(q, host, buf)
        q.finish()
        result = tuple(host for host, _ in outs)
        return result[0] if len(result) == 1 else result


def device_spec(device) -> str:
    """The ``P:D`` spec of a ``pyopencl.Device`` (for a subprocess or a Dask worker, which cannot
    be handed the Device object itself)."""
    from pyopencl_rt.device import devices as dv

    for entry in dv.all_devices():
        if entry[2] == device:
            return dv.describe(entry).index
    raise LookupError(f"{device} is not among the OpenCL devices found")


def lane_kernels_build_on(device) -> bool:
    """Whether the lane kernels (cl/megakernel/path.cl at 8 or 16 lanes, cl/accel/bvh_packet.h) are
    meant for ``device``: a CPU device of an x86 host, under any OpenCL implementation (the lane
    code is portable OpenCL C).  Written here apart from pyopencl_rt.device.isa.x86_cpu, which
    tests/render/test_path_lanes.py checks against it."""
    import platform

    import pyopencl as cl

    return bool(device.type & cl.device_type.CPU) and platform.machine().lower() in ("x86_64", "amd64")


def require_lane_kernels(device, width: int = 16) -> None:
    """Skip a test of the lane kernels' code at ``width`` lanes on a device they are never built
    for: not a CPU device of an x86 host, or one whose implementation does not build that width
    alike (PoCL where its compile and built-in library pass vectors of that width differently:
    pyopencl_rt/device/isa.py's LaneRule refuses the width there, as tests/device/test_isa.py checks)."""
    import pytest

    from pyopencl_rt.device import isa

    if not lane_kernels_build_on(device):
        pytest.skip("the lane kernels are built for CPU devices of x86 hosts only (never selected elsewhere)")
    rule = isa.lane_rule(device)
    if int(width) not in rule.widths:
        pytest.skip(f"{width} lanes are never built here: {rule.describe}")


def forced_lanes(device) -> str:
    """The lane count a test forces on ``device``, as $PYOPENCL_RT_LANES gives it: the width the
    rule picks (what users get), else the widest the device builds ("16", else "8"); skips where
    neither is built.  Every width at once: :func:`lane_widths`."""
    from pyopencl_rt.device import isa

    require_lane_kernels(device, 8)
    rule = isa.lane_rule(device)
    return str(rule.default or max(rule.widths))


def lane_widths(device) -> tuple[str, ...]:
    """One path per work-item and every lane count the device builds alike ("0", "8", "16" where
    16 builds alike): each is a kernel build of several seconds, so only the broadest tests take
    them all."""
    from pyopencl_rt.device import isa

    require_lane_kernels(device, 8)
    return ("0", *(str(w) for w in isa.lane_rule(device).widths))


# ----------------------------------------------------------------------------- random numbers
def uniforms(rng, shape):
    """float32 uniforms on the 2^-24 grid of [0, 1) (a float64 draw cast to float32 can round to 1)."""
    return (rng.integers(0, 1 << 24, size=shape) * 2.0 ** -24).astype(np.float32)


# ----------------------------------------------------------------------------- chi-square
CHI2_POOL = 5.0  # Mitsuba 3's pool_threshold


@dataclass(frozen=True)
class Chi2:
    p: float            # p-value: the probability of a statistic at least this large under H0
    statistic: float
    dof: int
    pooled_in: int      # bins expecting < CHI2_POOL ...
    pooled_out: int     # ... and the cells they were pooled into


def chi2_test(observed, expected, pool: float = CHI2_POOL) -> Chi2:
    """Pearson's chi-square test with Mitsuba 3's pooling (see the module docstring)."""
    from scipy import stats

    o = np.asarray(observed, np.float64).ravel()
    e = np.asarray(expected, np.float64).ravel()
    assert o.shape == e.shape, f"{o.shape} observed vs {e.shape} expected bins"
    assert np.all(e >= 0) and np.all(np.isfinite(e)), "negative or non-finite expected counts"
    assert not np.any((e == 0) & (o > 0)), "samples in a bin where the pdf is zero"
    order = np.argsort(e, kind="stable")
    o, e = o[order], e[order]
    keep = (e > 0) | (o > 0)
    o, e = o[keep], e[keep]
    small = e < pool
    stat, cells = float(np.sum((o[~small] - e[~small]) ** 2 / e[~small])), int(np.count_nonzero(~small))
    pooled_in, pooled_out = int(np.count_nonzero(small)), 0
    po = pe = 0.0
    for oi, ei in zip(o[small], e[small]):
        po += oi
        pe += ei
        if pe > pool:
            stat += (po - pe) ** 2 / pe
            cells += 1
            pooled_out += 1
            po = pe = 0.0
    dof = cells - 1
    assert dof >= 1, "too few cells for a chi-square test"
    return Chi2(float(stats.chi2.sf(stat, dof)), stat, dof, pooled_in, pooled_out)


def chi2_pvalue(observed, expected) -> float:
    return chi2_test(observed, expected).p


def assert_chi2(observed, expected, alpha: float, what: str = ""):
    """Fail unless the chi-square p-value exceeds ``alpha`` (the test's significance level)."""
    r = chi2_test(observed, expected)
    assert r.p > alpha, (f"{what}: chi-square p = {r.p:.3g} < {alpha} (statistic {r.statistic:.1f}, "
                         f"{r.dof} dof, {r.pooled_in} bins pooled into {r.pooled_out})")
    return r


# ----------------------------------------------------------------------------- shared fixtures
def random_slivers(n, rng):
    """``n`` random slivers (triangles ~0.3 long and ~1e-3 wide) in the unit cube."""
    c = rng.random((n, 1, 3))
    d = rng.normal(size=(n, 1, 3))
    d /= np.linalg.norm(d, axis=-1, keepdims=True)
    v = c + d * np.array([-0.15, 0.15, 0.0])[None, :, None] + rng.normal(size=(n, 3, 3)) * 1e-3
    return v.reshape(-1, 3).astype(np.float32), np.arange(3 * n, dtype=np.int32).reshape(n, 3)


def width_sets():
    """The parameters of a feature's lane test: "users" compares one path per work-item with the
    width users get (``make test``), "every" with every width the device builds (``make stress``:
    each width is a kernel build of its own, and the broad test of tests/render/test_path_lanes.py
    already takes every width in ``make test``)."""
    import pytest

    return [pytest.param("users", id="users-width"), pytest.param("every", id="every-width", marks=pytest.mark.stress)]


def widths_of(device, width_set: str) -> tuple[str, ...]:
    """The lane counts of a :func:`width_sets` parameter on ``device``."""
    return lane_widths(device) if width_set == "every" else ("0", forced_lanes(device))


def lane_renders(scene, device, monkeypatch, widths, **options):
    """The same megakernel render at each lane width of ``widths`` ($PYOPENCL_RT_LANES; "0": one
    path per work-item), by width."""
    import pyopencl_rt as rt
    from pyopencl_rt.render import megakernel

    out = {}
    for width in widths:
        monkeypatch.setenv(megakernel.LANES_ENV, width)
        out[width] = rt.render_full(scene, device=device, kernel_mode="megakernel", **options)
    return out


def mitsuba():
    """Mitsuba 3's module in its scalar_rgb variant (the test is skipped where it is not installed)."""
    try:
        import mitsuba as mi
    except ImportError as exc:
        import pytest
        pytest.skip(f"Mitsuba 3 is not installed (pip install mitsuba): {exc}")
    mi.set_variant("scalar_rgb")
    return mi


def assert_same_lanes(results):
    """Renders by lane width (:func:`lane_renders`, "0" among them): each ran at its width and gave
    one path per work-item's film bit for bit (sums and sums of squares) and its ray counts."""
    import numpy as np

    base = results["0"]
    assert base.info["lanes"] == 0 and base.stats.rays_extend > 0
    for width, r in results.items():
        assert r.info["lanes"] == int(width), (width, r.info["lanes"])
        assert np.array_equal(r.film.sum, base.film.sum), width
        assert np.array_equal(r.film.sum_sq, base.film.sum_sq), width
        assert (r.stats.rays_extend, r.stats.rays_shadow) == (base.stats.rays_extend, base.stats.rays_shadow), width


def mitsuba_sensor(origin, fov, width, height, max_depth=3, spp=64, target="0, 0, 0", integrator=None,
                   up="0, 1, 0") -> str:
    """The path integrator (or the ``integrator`` XML given) and a perspective sensor (box filter,
    independent sampler) of a small Mitsuba 3 test scene, as XML (width, height, spp: numbers or
    ``$name`` references to the file's defaults)."""
    integrator = integrator or f'<integrator type="path"><integer name="max_depth" value="{max_depth}"/></integrator>'
    return f"""
{integrator}
<sensor type="perspective"><float name="fov" value="{fov}"/>
  <transform name="to_world"><lookat origin="{origin}" target="{target}" up="{up}"/></transform>
  <sampler type="independent"><integer name="sample_count" value="{spp}"/></sampler>
  <film type="hdrfilm"><integer name="width" value="{width}"/><integer name="height" value="{height}"/>
    <rfilter type="box"/></film>
</sensor>
"""


def mitsuba_rect(x, y, bsdf, angle=0.0, axis="y", size=0.9) -> str:
    """A panel of a Mitsuba test scene: a rectangle ``2 size`` wide with ``bsdf``, turned by ``angle``
    degrees about ``axis``, its centre at (x, y, 0)."""
    return (f'<shape type="rectangle"><transform name="to_world"><scale value="{size}"/>'
            f'<rotate {axis}="1" angle="{angle}"/><translate x="{x}" y="{y}"/></transform>{bsdf}</shape>')


def mitsuba_stage(sensor, content, wall_bsdf, light_z=5, intensity=20) -> str:
    """The XML of a small Mitsuba 3 test scene: ``sensor`` (:func:`mitsuba_sensor`), a point light of
    ``intensity`` at (1, 2, light_z), a constant sky of 0.3, ``content``, and behind it a wall of
    ``wall_bsdf``, 12 x 12 at z = -1.5."""
    return f"""{sensor}
<emitter type="point"><point name="position" x="1" y="2" z="{light_z}"/><rgb name="intensity" value="{intensity}"/></emitter>
<emitter type="constant"><rgb name="radiance" value="0.3"/></emitter>
{content}
<shape type="rectangle"><transform name="to_world"><scale value="6"/><translate z="-1.5"/></transform>
  {wall_bsdf}</shape>
"""


def write_mitsuba_scene(path, body) -> str:
    """Writes ``body`` (XML elements) as the Mitsuba 3 scene file ``path``; returns the path as a string."""
    path.write_text(f'<scene version="3.0.0">{body}</scene>\n')
    return str(path)


def mitsuba_batches(mi, path, batches=8):
    """Mitsuba's render of the XML file ``path`` as ``batches`` renders of other seeds: their mean
    and the variance of that mean (the spread of the batches), RGB as float64."""
    import numpy as np

    scene = mi.load_file(str(path))
    images = np.stack([np.asarray(mi.render(scene, seed=i), np.float64)[..., :3] for i in range(batches)])
    return images.mean(0), images.var(0, ddof=1) / batches


def against_mitsuba(mi, path, spp=256, seed=0):
    """Mitsuba's render of the XML file ``path`` (:func:`mitsuba_batches`) and ours of the same file,
    loaded without a warning (``spp``, ``seed``): (z per 8 x 8 tile (:func:`tile_z`), our image and
    the variance of its mean, theirs and the variance of theirs)."""
    import warnings

    import numpy as np

    import pyopencl_rt as rt

    theirs, their_var = mitsuba_batches(mi, path)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        scene = rt.load_scene(path)
    r = rt.render_full(scene, spp=spp, device="cpu", seed=seed)
    ours, var = r.image.astype(np.float64), r.film.variance_of_mean()
    return tile_z(ours, var, theirs, their_var), ours, var, theirs, their_var


def tiles(a, tile=8):
    """The means of the tile x tile blocks of an H x W x 3 image (H, W multiples of tile)."""
    h, w = a.shape[:2]
    return a.reshape(h // tile, tile, w // tile, tile, 3).mean(axis=(1, 3))


def tile_z(a, a_var, b, b_var, tile=8):
    """|a - b| per tile x tile block in standard errors, from the per-pixel variances of the two
    means (0 / 0, as where both see a constant sky, gives 0)."""
    import numpy as np

    return np.abs(tiles(a, tile) - tiles(b, tile)) / np.sqrt((tiles(a_var, tile) + tiles(b_var, tile)) / tile**2
                                                            + 1e-12)


def gauss_legendre_cells(edges, x, w):
    """Nodes and weights of a Gauss-Legendre rule (``x``, ``w`` on [-1, 1]) over each cell between
    consecutive ``edges``, flattened cell by cell."""
    mid, half = (edges[1:] + edges[:-1]) / 2, (edges[1:] - edges[:-1]) / 2
    return (mid[:, None] + half[:, None] * x).ravel(), (half[:, None] * w).ravel()


def load_warned(path, defines=None):
    """(scene, the messages of its warnings) of ``load_scene(path, defines)``, every warning recorded
    (none shown)."""
    import warnings

    from pyopencl_rt.scene.loaders import load_scene

    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(path, defines=defines)
    return scene, [str(w.message) for w in caught]


def load_error(path) -> str:
    """The message of the SceneError that loading ``path`` raises, checked to be one line."""
    import pytest

    from pyopencl_rt.scene.loaders import SceneError, load_scene

    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg, msg
    return msg


def toml_tables(**tables) -> str:
    """The TOML text of tables of plain values (numbers, strings, booleans, lists of them), in order:
    ``toml_tables(camera=dict(eye=[0, 0, 3], look_at=[0, 0, 0], fov=45), render=dict(max_depth=4))``,
    the header of a test's scene file."""
    import json

    return "".join(f"[{name}]\n" + "".join(f"{k} = {json.dumps(v)}\n" for k, v in table.items())
                   for name, table in tables.items())
