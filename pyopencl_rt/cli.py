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
