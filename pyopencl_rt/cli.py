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
    from . import devices as dv

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

    def __call__(self, passes, elapsed):
        if self.quiet or (elapsed - self.last < 0.5 and passes != self.total):
            return
        self.last = elapsed
        rate = passes * self.n_pixels / elapsed if elapsed > 0 else 0.0
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
@click.option("--quiet", "-q", is_flag=True, help="No progress bar.")
@device_option
def render(scene_path, output, spp, time_limit, width, height, max_depth, seed, integrator, wave_size, profile,
           quiet, device):
    """Render SCENE (a .toml scene file, or any mesh file such as model.obj) to OUTPUT."""
    from .imageio import write_outputs
    from .render import check_settings, render_full
    from .scenefile import load_scene

    check_settings(width if width is not None else 1, height if height is not None else 1, spp, max_depth,
                   integrator, time_limit)
    if not str(output).lower().endswith(".exr"):
        raise UserError(f"{output}: the output must be an .exr file (a .png and a .json are written beside it)")
    scene = load_scene(scene_path)
    w = width or scene.settings.width
    h = height or scene.settings.height
    check_settings(w, h, None, None, None, None)
    total = spp if spp is not None else (None if time_limit is not None else scene.settings.spp)
    bar = Progress(total, time_limit, w * h, quiet)
    result = render_full(scene, spp=total, time_limit=time_limit, device=list(device) or None, seed=seed,
                         width=w, height=h, max_depth=max_depth, integrator=integrator, wave_size=wave_size,
                         progress=bar, profile=profile)
    bar.done()
    info = result.info
    if result.stats.passes == 0:
        raise UserError("interrupted before the first pass completed: nothing to write")
    paths = write_outputs(output, result.image, info)
    if profile:
        stages = info["stage_seconds"]
        total_s = sum(stages.values()) or 1.0
        click.echo("stage         seconds   share", err=True)
        for name, sec in stages.items():
            click.echo(f"{name:<12} {sec:8.3f}  {100 * sec / total_s:5.1f}%", err=True)
        click.echo(f"extend: {info['rays_extend'] / max(stages['extend'], 1e-9) / 1e6:.3f} Mrays/s, "
                   f"shadow: {info['rays_shadow'] / max(stages['shadow'], 1e-9) / 1e6:.3f} Mrays/s", err=True)
    note = " (interrupted)" if info["interrupted"] else ""
    click.echo(
        f"{paths['exr']}: {info['width']}x{info['height']}, {info['spp']} spp in {info['render_seconds']:.2f} s "
        f"({info['samples_per_second'] / 1e6:.3f} Msamples/s) on {info['device']}; "
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
def bench_rays(device, sizes, n_rays, repeat, no_embree, json_path):
    """Rays/s of the OpenCL traversal beside embreex on the very same rays, and BVH build time."""
    from .bench import parse_sizes, run_ray_bench

    run_ray_bench(
        devices=list(device) or None, sizes=parse_sizes(sizes), n_rays=n_rays, repeat=repeat,
        embree=not no_embree, json_path=json_path, echo=click.echo,
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
    from .bench import run_render_bench

    run_render_bench(scene_path, devices=list(device) or None, width=width, height=height, spp=spp,
                     max_depth=max_depth, repeat=repeat, wave_size=wave_size, json_path=json_path, echo=click.echo)


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
