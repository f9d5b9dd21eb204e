"""The ``pyopencl-rt`` command line."""
from __future__ import annotations

import json
import sys

import click

from .errors import UserError

CONTEXT_SETTINGS = {"help_option_names": ["-h", "--help"]}


def device_option(f):
    """``--device``, shared by every command (repeatable, or comma-separated)."""
    return click.option(
        "--device", "-d", "device", multiple=True, metavar="SPEC",
        help="cpu, gpu, all, P:D (index or name substring, as in PYOPENCL_CTX), or a name substring; "
        "repeatable. Default: $PYOPENCL_CTX, else the first GPU, else the PoCL CPU device.",
    )(f)


@click.group(context_settings=CONTEXT_SETTINGS)
@click.version_option(package_name="pyopencl-rt")
def cli():
    """pyopencl_rt: a physically based path tracer with OpenCL kernels that run on any device."""


@cli.command()
@click.option("--json", "as_json", is_flag=True, help="Print the device list as JSON.")
@device_option
def devices(as_json, device):
    """List OpenCL platforms and devices (or those selected by --device)."""
    from .device import devices as dv

    infos = dv.list_devices()
    if device:
        chosen = dv.resolve(list(device))
        infos = [i for i in infos if any(dv.describe(e) == i for e in dv.all_devices() if e[2] in chosen)]
    if as_json:
        click.echo(json.dumps([i.as_dict() for i in infos], indent=2))
        return
    if not infos:
        click.echo("no OpenCL devices found")
        return
    for i in infos:
        click.echo(
            f"[{i.index}] {i.name}\n"
            f"      platform: {i.platform}\n"
            f"      type: {i.type}   compute units: {i.compute_units}   memory: {i.global_mem_bytes / 2**30:.1f} GiB\n"
            f"      {i.opencl_version} / {i.opencl_c_version} / driver {i.driver_version}"
        )


class Progress:
    """A one-line progress bar on stderr: passes, elapsed, ETA, samples/s."""

    def __init__(self, total_passes, time_limit, n_pixels, quiet):
        self.total, self.time_limit, self.n_pixels, self.quiet = total_passes, time_limit, n_pixels, quiet
        self.last = 0.0
        self.tty = sys.stderr.isatty()
        self.base = 0  # passes already in the film (a resumed render); set by render_full
        self.rows = None  # per-device rows of a multi-device or Dask render
        self.shown = None

    def device_rows(self, rows):
        """Each device's (or Dask worker's) samples/s and share of the passes, as LuxCore shows them."""
        self.rows = rows

    def __call__(self, passes, elapsed):
        rate = passes * self.n_pixels / elapsed if elapsed > 0 else 0.0
        passes += self.base
        if self.quiet or (elapsed - self.last < 0.5 and passes != self.total) or passes == self.shown == self.total:
            return
        self.last, self.shown = elapsed, passes
        if self.total:
            frac = passes / self.total
            eta = elapsed * (1 - frac) / frac if frac > 0 else 0.0
        else:
            frac = min(1.0, elapsed / self.time_limit)
            eta = max(0.0, self.time_limit - elapsed)
        bar = "#" * int(24 * frac) + "-" * (24 - int(24 * frac))
        total = self.total if self.total else "?"
        line = (f"[{bar}] {passes}/{total} spp  {_clock(elapsed)} elapsed  ETA {_clock(eta)}  "
                f"{rate / 1e6:.3f} Msamples/s")
        for r in self.rows or ():
            sps = r["samples_per_second"]
            name = r["device"].split(" (")[0][:28]
            state = "failed" if r["failed"] else f"{sps / 1e6:.3f} Ms/s" if sps else "starting"
            line += f"  | {name}: {state} {100 * r['share']:.0f}%"
        click.echo(("\r" + line) if self.tty else line, err=True, nl=not self.tty)

    def done(self):
        if self.tty and not self.quiet:
            click.echo("", err=True)


def _clock(seconds):
    seconds = int(seconds)
    return f"{seconds // 60:02d}:{seconds % 60:02d}" if seconds < 3600 else f"{seconds // 3600}h{seconds // 60 % 60:02d}m"


@cli.command()
@click.argument("scene_path", metavar="SCENE", type=click.Path(dir_okay=False))
@click.option("-o", "--output", default="out/render.exr", show_default=True, type=click.Path(dir_okay=False),
              help="Output OpenEXR (linear); a .png (sRGB) and a .json sidecar are written beside it.")
@click.option("--spp", type=int, help="Samples per pixel (default: the scene's).")
@click.option("--time-limit", type=float, metavar="SECONDS", help="Render for this long (whole passes).")
@click.option("--width", type=int)
@click.option("--height", type=int)
@click.option("--max-depth", type=int, help="Path segments at most (1: emitters only; -1: unlimited).")
@click.option("--seed", type=int)
@click.option("--integrator", type=click.Choice(["path", "bsdf", "nee"]),
              help="path: MIS of light and BSDF sampling (default); bsdf or nee alone.")
@click.option("--wave-size", type=int, help="Paths in flight (default: 2^20 on a GPU, 2^16 on a CPU).")
@click.option("--profile", is_flag=True, help="Print the time spent in each wavefront stage.")
@click.option("--intersector", type=click.Choice(["opencl", "embree"]), default="opencl", show_default=True,
              help="Who traces the extend and shadow rays: our OpenCL traversal, or Embree on the host.")
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
@click.option("--scheduler", metavar="ADDRESS",
              help="Render on a Dask cluster (tcp://host:8786), or 'local[:N]' for a LocalCluster of N workers "
              "(needs pip install 'pyopencl-rt[distributed]').")
@click.option("--checkpoint", "checkpoint_path", type=click.Path(dir_okay=False),
              help="Checkpoint file (default: OUTPUT with .ckpt.npz), written on Ctrl-C/SIGTERM.")
@click.option("--checkpoint-every", type=float, metavar="SECONDS", help="Also write the checkpoint this often.")
@click.option("--resume", is_flag=True, help="Continue from the checkpoint up to --spp (same scene and settings).")
@device_option
def render(scene_path, output, spp, time_limit, width, height, max_depth, seed, integrator, wave_size, profile, intersector,
           quiet, scheduler, checkpoint_path, checkpoint_every, resume, device):
    """Render SCENE (a .toml scene file, or any mesh file such as model.obj) to OUTPUT."""
    from .imageio import write_outputs
    from .render.api import check_settings, render_full
    from .scene.scenefile import load_scene

    check_settings(width if width is not None else 1, height if height is not None else 1, spp, max_depth,
                   integrator, time_limit)
    if not str(output).lower().endswith(".exr"):
        raise UserError(f"{output}: the output must be an .exr file (a .png and a .json are written beside it)")
    if checkpoint_every is not None and not checkpoint_every > 0:
        raise UserError(f"--checkpoint-every must be positive (got {checkpoint_every})")
    if scheduler is not None:
        from .render.distributed import _import as need_dask

        need_dask()
    from .render.checkpoint import default_path

    checkpoint_path = checkpoint_path or str(default_path(output))
    scene = load_scene(scene_path)
    w = width or scene.settings.width
    h = height or scene.settings.height
    check_settings(w, h, None, None, None, None)
    total = spp if spp is not None else (None if time_limit is not None else scene.settings.spp)
    bar = Progress(total, time_limit, w * h, quiet)
    wavefront = None
    if intersector == "embree":
        from .device.devices import select_device
        from .render.embree_wavefront import EmbreeWavefront

        wavefront = EmbreeWavefront(scene, select_device(list(device) or None), width=w, height=h,
                                    integrator=integrator, max_depth=max_depth, seed=seed, wave_size=wave_size)
    result = render_full(scene, wavefront=wavefront, spp=total, time_limit=time_limit, device=list(device) or None, seed=seed,
                         width=w, height=h, max_depth=max_depth, integrator=integrator, wave_size=wave_size,
                         progress=bar, profile=profile, scheduler=scheduler, checkpoint=checkpoint_path,
                         resume=resume, checkpoint_every=checkpoint_every, handle_signals=True)
    bar.done()
    info = result.info
    if result.film.passes == 0:
        raise UserError("interrupted before the first pass completed: nothing to write")
    paths = write_outputs(output, result.image, info)
    if profile and wavefront is not None:
        info["stage_seconds"].update(wavefront.host_seconds)  # host-side Embree stages (with transfers)
    if profile:
        stages = info["stage_seconds"]
        total_s = sum(stages.values()) or 1.0
        click.echo("stage         seconds   share", err=True)
        for name, sec in stages.items():
            click.echo(f"{name:<12} {sec:8.3f}  {100 * sec / total_s:5.1f}%", err=True)
        click.echo(f"extend: {info['rays_extend'] / max(stages['extend'], 1e-9) / 1e6:.3f} Mrays/s, "
                   f"shadow: {info['rays_shadow'] / max(stages['shadow'], 1e-9) / 1e6:.3f} Mrays/s", err=True)
    note = " (interrupted)" if info["interrupted"] else ""
    if info["interrupted"] and info.get("checkpoint"):
        note = f" (interrupted; checkpoint {info['checkpoint']}: continue with --resume)"
    click.echo(
        f"{paths['exr']}: {info['width']}x{info['height']}, {info['spp']} spp in {info['render_seconds']:.2f} s "
        f"({(info['samples_per_second'] or 0) / 1e6:.3f} Msamples/s) on {info['device']}; "
        f"non-finite samples: {info['nonfinite_samples']}{note}"
    )
    if info["interrupted"]:
        sys.exit(130)


@cli.group()
def bench():
    """Benchmarks (results as a table and as JSON)."""


@bench.command("rays")
@device_option
@click.option("--sizes", default="10k,100k,1M", show_default=True, help="Mesh sizes in triangles.")
@click.option("--rays", "n_rays", default=1_000_000, show_default=True, help="Rays per ray set.")
@click.option("--repeat", default=3, show_default=True, help="Timed repetitions (the median is reported).")
@click.option("--no-embree", is_flag=True, help="Skip the embreex reference.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), help="Write the results to this JSON file.")
@click.option("--layout", type=click.Choice(["binary", "wide", "both"]), default=None,
              help="BVH layout(s) to time [default: the device's default, wide on CPUs, binary on GPUs].")
def bench_rays(device, sizes, n_rays, repeat, no_embree, json_path, layout):
    """Rays/s of the OpenCL traversal beside embreex on the very same rays, and BVH build time."""
    from .bench.throughput import parse_sizes, run_ray_bench

    run_ray_bench(
        devices=list(device) or None, sizes=parse_sizes(sizes), n_rays=n_rays, repeat=repeat,
        embree=not no_embree, json_path=json_path, echo=click.echo,
        layouts=None if layout is None else (("binary", "wide") if layout == "both" else (layout,)),
    )


@bench.command("render")
@click.argument("scene_path", metavar="SCENE", default="scenes/cornell-box.toml", type=click.Path(dir_okay=False))
@device_option
@click.option("--width", default=512, show_default=True)
@click.option("--height", default=512, show_default=True)
@click.option("--spp", default=16, show_default=True, help="Samples per pixel per timed render.")
@click.option("--max-depth", default=8, show_default=True)
@click.option("--repeat", default=3, show_default=True, help="Timed renders per device (median reported).")
@click.option("--wave-size", type=int)
@click.option("--json", "json_path", type=click.Path(dir_okay=False), help="Write the results to this JSON file.")
def bench_render(scene_path, device, width, height, spp, max_depth, repeat, wave_size, json_path):
    """Samples/s of the path tracer on each device (kernel build and BVH not timed)."""
    from .bench.throughput import run_render_bench

    run_render_bench(scene_path, devices=list(device) or None, width=width, height=height, spp=spp,
                     max_depth=max_depth, repeat=repeat, wave_size=wave_size, json_path=json_path, echo=click.echo)


@bench.command("convergence")
@click.argument("scene_path", metavar="SCENE", type=click.Path(dir_okay=False))
@device_option
@click.option("--integrator", default="path", show_default=True, help="Comma-separated: path,bsdf,nee.")
@click.option("--intersector", default="opencl", show_default=True, help="Comma-separated: opencl,embree.")
@click.option("--reference", type=click.Path(dir_okay=False), help="Reference OpenEXR (default: render one and cache it).")
@click.option("--reference-spp", type=int, help="Samples per pixel of the rendered reference (default: a share of --budget).")
@click.option("--no-cache", is_flag=True, help="Neither read nor write the cached reference.")
@click.option("--budget", type=float, default=60.0, show_default=True, metavar="SECONDS",
              help="Wall-time budget of the whole run, its own reference included.")
@click.option("--width", type=int)
@click.option("--height", type=int)
@click.option("--max-depth", type=int)
@click.option("--compare", default="", help="Peer renderers beside ours: 'mitsuba' (needs Mitsuba 3; skipped if absent).")
@click.option("--mitsuba-python", type=click.Path(dir_okay=False),
              help="Interpreter with mitsuba (default: this one, else $PYOPENCL_RT_MITSUBA_PYTHON).")
@click.option("--mitsuba-variant", default="llvm_ad_rgb", show_default=True)
@click.option("--json", "json_path", default="out/convergence.json", show_default=True, type=click.Path(dir_okay=False))
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), help="PNG plot (default: the JSON path with .png).")
def bench_convergence(scene_path, device, integrator, intersector, reference, reference_spp, no_cache, budget, width,
                      height, max_depth, compare, mitsuba_python, mitsuba_variant, json_path, plot_path):
    """Error (RMSE, relMSE, MAE) against a reference as a function of render time, per device x
    integrator x intersector, optionally beside Mitsuba 3: JSON, a log-log plot and a table."""
    from .bench.convergence import run_convergence
    from .scene.model import INTEGRATORS

    integrators = [x.strip() for x in integrator.split(",") if x.strip()]
    for x in integrators:
        if x not in INTEGRATORS:
            raise UserError(f"unknown integrator {x!r}: use one or more of {', '.join(INTEGRATORS)}")
    intersectors = [x.strip() for x in intersector.split(",") if x.strip()]
    for x in intersectors:
        if x not in ("opencl", "embree"):
            raise UserError(f"unknown intersector {x!r}: use opencl and/or embree")
    if budget is not None and not budget > 0:
        raise UserError(f"--budget must be positive (got {budget})")
    run_convergence(scene_path, devices=list(device) or None, integrators=integrators, intersectors=intersectors,
                    reference=reference, reference_spp=reference_spp, budget=budget, width=width, height=height,
                    max_depth=max_depth, compare=[c.strip() for c in compare.split(",") if c.strip()],
                    mitsuba_python=mitsuba_python, mitsuba_variant=mitsuba_variant, json_path=json_path,
                    plot_path=plot_path, use_cache=not no_cache, echo=click.echo)


def main(argv=None):
    """Entry point: user errors become one line on stderr and a non-zero exit code."""
    try:
        cli.main(args=argv, prog_name="pyopencl-rt", standalone_mode=False)
    except UserError as exc:
        click.echo(f"pyopencl-rt: error: {exc}", err=True)
        sys.exit(exc.exit_code)
    except click.exceptions.Abort:
        click.echo("pyopencl-rt: interrupted", err=True)
        sys.exit(130)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except KeyboardInterrupt:
        click.echo("pyopencl-rt: interrupted", err=True)
        sys.exit(130)


if __name__ == "__main__":
    main()
