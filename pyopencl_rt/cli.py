"""The ``pyopencl-rt`` command line."""
from __future__ import annotations

import json
import sys

import click

from .cli_options import check_json, comma_list, device_option, mitsuba_options, parse_intersectors, seed_options
from .errors import LOGGER, UsageError, UserError
from .progress import Progress

CONTEXT_SETTINGS = {"help_option_names": ["-h", "--help"]}


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
            + (f"\n      implementation: {i.implementation} (--device {i.implementation})"
               if i.implementation != "other" else "")
        )


@cli.command()
@click.argument("scene_path", metavar="SCENE", type=click.Path(dir_okay=False))
@click.option("-o", "--output", default="out/render.exr", show_default=True, type=click.Path(dir_okay=False),
              help="Output OpenEXR (linear, with the AOV layers) or PNG (display-referred); the other and a .json "
              "sidecar are written beside it.")
@click.option("--spp", type=int, help="Samples per pixel (default: the scene's).")
@click.option("--time-limit", type=float, metavar="SECONDS", help="Render for this long (whole passes).")
@click.option("--width", type=int)
@click.option("--height", type=int)
@click.option("--max-depth", type=int, help="Path segments at most (1: emitters only; -1: unlimited).")
@click.option("--seed", type=int)
@click.option("--integrator", type=click.Choice(["path", "bsdf", "nee"]),
              help="path: MIS of light and BSDF sampling (default); bsdf or nee alone.")
@click.option("--sampler", type=click.Choice(["sobol", "stratified", "independent"]),
              help="Where the random numbers come from: Owen-scrambled Sobol (default), progressive stratified, "
              "or independent (docs/SAMPLING.md).")
@click.option("--light-sampler", type=click.Choice(["power", "uniform", "bvh"]),
              help="How next-event estimation picks a light: by power, uniformly (Mitsuba's rule), or by importance "
              "to the shading point with the light BVH (many lights; docs/SAMPLING.md) [default: the scene's].")
@click.option("--adaptive/--no-adaptive", default=None, help="Adaptive sampling: samples where the estimated error "
              "is; --spp is each pixel's maximum with --target-error, the mean without (docs/SAMPLING.md).")
@click.option("--target-error", type=float, help="With --adaptive: a pixel stops at this relative error (e.g. 0.02).")
@click.option("--wave-size", type=int, help="Paths in flight (default: 2^20 GPU, 2^16 CPU, 2^18 CPU megakernel).")
@click.option("--profile", is_flag=True, help="Print the time spent in each wavefront stage.")
@click.option("--kernel-mode", type=click.Choice(["auto", "wavefront", "megakernel"]), default="auto", show_default=True,
              help="How paths are scheduled: a megakernel (one work-item per path; the CPU default) or the "
              "wavefront of small kernels (GPUs, --intersector embree, AOVs). The image is the same.")
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
@click.option("-D", "--define", "defines", multiple=True, metavar="NAME=VALUE",
              help="Set a Mitsuba XML scene's $NAME (overrides its <default>); repeatable.")
@click.option("--aov", "aovs", metavar="LIST",
              help="AOV layers of the EXR, comma-separated: albedo, normal, depth, position, variance, spp, or all "
              "(default: the scene's [film] aovs).")
@click.option("--denoise", is_flag=True,
              help="Denoise with Intel Open Image Denoise (needs pip install 'pyopencl-rt[denoise]'); the EXR keeps "
              "the raw image as noisy.R/G/B.")
@click.option("--exposure", type=float, default=0.0, show_default=True, metavar="EV",
              help="PNG only: scale by 2^EV before the tone curve.")
@click.option("--tonemap", type=click.Choice(["clamp", "filmic", "agx"]), default="clamp", show_default=True,
              help="PNG only: clamp, filmic (an ACES fit) or agx (docs/OUTPUT.md).")
@click.option("--no-exr", is_flag=True, help="With -o out.png: write no EXR.")
@click.option("--preview-every", type=float, metavar="SECONDS", help="Rewrite the PNG this often while rendering.")
@click.option("--device-timeout", type=float, metavar="SECONDS",
              help="With several devices: drop one that makes no progress for this long [default: 120].")
@device_option
def render(scene_path, output, spp, time_limit, width, height, max_depth, seed, integrator, sampler, light_sampler,
           adaptive,
           target_error, wave_size, profile, kernel_mode, intersector,
           quiet, scheduler, checkpoint_path, checkpoint_every, resume, defines, aovs, denoise, exposure, tonemap, no_exr,
           preview_every, device_timeout, device):
    """Render SCENE (a .toml scene file, a Mitsuba 3 .xml or pbrt-v4 .pbrt scene, or any mesh file
    such as model.obj) to OUTPUT."""
    from . import validate
    from .imageio import check_output, write_outputs
    from .render.aovs import GUIDES, parse_aovs
    from .render.api import render_full
    from .render.arguments import check_outputs, check_render_arguments, parse_defines, rescued
    from .render.checkpoint import default_path
    from .render.settings import ImageSettings, check_resolution, check_run
    from .scene.loaders import load_scene

    # every option, and every file the render will write, before the scene is read
    check_run(spp, time_limit)
    if width is not None or height is not None:
        check_resolution(width if width is not None else 1, height if height is not None else 1)
    png_path = check_output(output, exr=not no_exr).with_suffix(".png")
    check_outputs(output, checkpoint_path or default_path(output), exr=not no_exr)
    check_render_arguments(spp=spp, time_limit=time_limit, width=width, height=height, max_depth=max_depth,
                           integrator=integrator, seed=seed, wave_size=wave_size, intersector=intersector,
                           kernel_mode=kernel_mode, device=list(device) or None, scheduler=scheduler,
                           checkpoint=checkpoint_path or str(default_path(output)), resume=resume,
                           checkpoint_every=checkpoint_every, device_timeout=device_timeout, adaptive=adaptive,
                           target_error=target_error)
    validate.number(exposure, "--exposure", minimum=-64, maximum=64)
    if preview_every is not None and not preview_every > 0:
        raise UserError(f"--preview-every must be positive (got {preview_every})")
    if denoise:
        from .render.denoise import _pyoidn

        _pyoidn()  # what to install, before loading the scene
    if checkpoint_every is not None and not checkpoint_every > 0:
        raise UserError(f"--checkpoint-every must be positive (got {checkpoint_every})")
    if scheduler is not None:
        from .render.distributed import _import as need_dask

        need_dask()
    checkpoint_path = checkpoint_path or str(default_path(output))
    from .host_stages import host_stage, reset

    reset()
    with host_stage("load"):
        scene = load_scene(scene_path, defines=parse_defines(defines))
    if light_sampler is not None:
        import dataclasses

        scene.settings = dataclasses.replace(scene.settings, light_sampler=light_sampler)
    aov_names = parse_aovs(scene.settings.aovs if aovs is None else aovs)
    settings = ImageSettings.resolve(scene, width=width, height=height, max_depth=max_depth, integrator=integrator,
                                     seed=seed, aovs=aov_names + (GUIDES if denoise else ()), sampler=sampler,
                                     adaptive=adaptive, target_error=target_error)
    total = spp if spp is not None else (None if time_limit is not None else scene.settings.spp)
    bar = Progress(total, time_limit, settings.n_pixels, quiet)
    result = render_full(scene, spp=total, time_limit=time_limit, device=list(device) or None, wave_size=wave_size,
                         intersector=intersector, kernel_mode=kernel_mode, progress=bar, profile=profile,
                         scheduler=scheduler,
                         checkpoint=checkpoint_path, resume=resume, checkpoint_every=checkpoint_every,
                         handle_signals=True, settings=settings, aovs=aov_names, denoise=denoise,
                         preview=lambda image: _preview(png_path, image, exposure, tonemap), preview_every=preview_every,
                         device_timeout=device_timeout)
    bar.done()
    info = result.info
    if result.film.passes == 0:
        if info["interrupted"]:
            LOGGER.error("interrupted before the first pass completed: nothing written")
            sys.exit(130)
        raise UserError("no pass completed (--time-limit too short?): nothing to write")
    from .render.aovs import exr_channels

    info["display"] = {"exposure": exposure, "tonemap": tonemap}  # of the PNG; the EXR is linear
    try:
        paths = write_outputs(output, result.image, info, layers=exr_channels(result.layers), exposure=exposure,
                              tonemap=tonemap, exr=not no_exr)
    except UserError as exc:
        raise rescued(exc, result, scene, settings, checkpoint_path, output) from None
    if profile:
        stages = info["stage_seconds"]
        total_s = sum(stages.values()) or 1.0
        peak = info.get("host_peak_rss_mb") or {}  # host stages (host_stages.py), then the device's
        click.echo("host stage    seconds  peak RSS MB\n" + "".join(
            f"{name:<12} {sec:8.3f}  {peak.get(name) or 0:11.0f}\n" for name, sec in info["host_seconds"].items()), err=True,
            nl=False)
        click.echo(f"lanes: {info.get('lanes_reason')}\nstage         seconds   share", err=True)  # lanes: which ran, why
        for name, sec in stages.items():
            click.echo(f"{name:<12} {sec:8.3f}  {100 * sec / total_s:5.1f}%", err=True)
        if "extend" in stages:  # the wavefront times its ray-casting stages apart (the megakernel cannot)
            click.echo(f"extend: {info['rays_extend'] / max(stages['extend'], 1e-9) / 1e6:.3f} Mrays/s, "
                       f"shadow: {info['rays_shadow'] / max(stages['shadow'], 1e-9) / 1e6:.3f} Mrays/s", err=True)
    note = " (interrupted)" if info["interrupted"] else ""
    if "adaptive_sampling" in info:
        note += f" (adaptive: {info['adaptive_sampling']['spp_mean']:.1f} spp per pixel on average)"
    if info["interrupted"] and info.get("checkpoint"):
        note = f" (interrupted; checkpoint {info['checkpoint']}: continue with --resume)"
    click.echo(
        f"{paths.get('exr', paths['png'])}: {info['width']}x{info['height']}, {info['spp']} spp in "
        f"{info['render_seconds']:.2f} s "
        f"({(info['samples_per_second'] or 0) / 1e6:.3f} Msamples/s) on {info['device']}; "
        f"non-finite samples: {info['nonfinite_samples']}{note}"
    )
    if info["interrupted"]:
        sys.exit(130)


@cli.command("compare")
@click.argument("image", type=click.Path(dir_okay=False))
@click.argument("reference", type=click.Path(dir_okay=False))
@click.option("--heatmap", type=click.Path(dir_okay=False), help="Write an error heat map PNG (FLIP's if installed).")
@click.option("--json", "as_json", is_flag=True, help="Print the metrics as JSON.")
def compare_command(image, reference, heatmap, as_json):
    """Error of IMAGE against REFERENCE (OpenEXR, linear R/G/B): MSE, RMSE, relMSE, FLIP and the
    per-channel mean ratio (docs/OUTPUT.md)."""
    from .compare import compare
    from .imageio import read_exr

    if heatmap is not None and not str(heatmap).lower().endswith(".png"):
        raise UserError(f"{heatmap}: the heat map is written as a .png file")
    result = compare(read_exr(image), read_exr(reference), heatmap)
    if as_json:
        click.echo(json.dumps(result, indent=2))
        return
    flip = "not installed (pip install 'pyopencl-rt[flip]')" if result["flip"] is None else f"{result['flip']:.6f}"
    ratio = "  ".join(f"{c} {'n/a' if r is None else f'{r:.6f}'}" for c, r in zip("RGB", result["mean_ratio"]))
    click.echo(f"MSE         {result['mse']:.6e}\nRMSE        {result['rmse']:.6e}\n"
               f"relMSE      {result['relmse']:.6e}\nFLIP        {flip}\nmean ratio  {ratio}")
    if heatmap is not None:
        click.echo(f"heat map    {result['heatmap']}")


def _preview(png_path, image, exposure, tonemap):
    from .imageio import write_png

    png_path.parent.mkdir(parents=True, exist_ok=True)
    write_png(png_path, image, exposure, tonemap)


@cli.group()
def bench():
    """Benchmarks (results as a table and as JSON)."""


@bench.command("rays")
@device_option
@click.option("--sizes", default="10k,100k,1M", show_default=True, help="Mesh sizes in triangles.")
@click.option("--rays", "n_rays", default=1_000_000, show_default=True, type=click.IntRange(min=1),
              help="Rays per ray set.")
@click.option("--repeat", default=3, show_default=True, type=click.IntRange(min=1),
              help="Timed repetitions (the median is reported).")
@click.option("--no-embree", is_flag=True, help="Skip the embreex reference.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), help="Write the results to this JSON file.")
@click.option("--layout", type=click.Choice(["binary", "wide", "wide8", "both", "all"]), default=None,
              help="BVH layout(s) to time: wide = 4-wide, wide8 = 8-wide, both = binary and wide, all = "
                   "the three [default: the device's default, wide8 on CPUs, binary on GPUs].")
@click.option("--embree-threads", type=click.IntRange(min=1), default=None,
              help="Embree worker processes for its parallel figure [default: PoCL's threads].")
def bench_rays(device, sizes, n_rays, repeat, no_embree, json_path, layout, embree_threads):
    """Rays/s of the OpenCL traversal beside embreex (one thread, and as many as PoCL uses) on the
    very same rays, and BVH build time."""
    from .bench.rays import run_ray_bench
    from .bench.workloads import parse_sizes

    groups = {"both": ("binary", "wide"), "all": ("binary", "wide", "wide8")}
    sizes = parse_sizes(sizes)
    check_json(json_path)
    run_ray_bench(
        devices=list(device) or None, sizes=sizes, n_rays=n_rays, repeat=repeat,
        embree=not no_embree, json_path=json_path, echo=click.echo,
        layouts=None if layout is None else groups.get(layout, (layout,)), embree_threads=embree_threads,
    )


@bench.command("render")
@click.argument("scene_paths", metavar="[SCENE]...", nargs=-1, type=click.Path(dir_okay=False))
@device_option
@click.option("--width", default=512, show_default=True, type=click.IntRange(min=1))
@click.option("--height", default=512, show_default=True, type=click.IntRange(min=1))
@click.option("--spp", default=16, show_default=True, type=click.IntRange(min=1), help="Samples per pixel per timed render.")
@click.option("--max-depth", default=8, show_default=True, type=click.IntRange(min=-1))
@click.option("--repeat", default=3, show_default=True, type=click.IntRange(min=1),
              help="Timed renders per device (median reported).")
@click.option("--wave-size", type=click.IntRange(min=1))
@click.option("--intersector", default="opencl", show_default=True,
              help="Comma-separated: opencl,embree (extend and shadow rays on embreex), each timed on each device.")
@click.option("--kernel-mode", default="auto", show_default=True,
              help="Comma-separated: auto,wavefront,megakernel (path schedules), each timed on each device.")
@click.option("--sampler", help="Comma-separated: sobol,stratified,independent, each timed [default: the scene's].")
@click.option("--mitsuba", is_flag=True, help="Also time Mitsuba 3 on the same scene (our export), a render after ours in each repetition.")
@mitsuba_options
@click.option("--json", "json_path", type=click.Path(dir_okay=False), help="Write the results to this JSON file.")
def bench_render(scene_paths, device, width, height, spp, max_depth, repeat, wave_size, intersector, kernel_mode, sampler,
                 mitsuba, mitsuba_variant, mitsuba_python, llvm_path, json_path):
    """Samples/s of the path tracer on each device, for each SCENE in turn [default:
    scenes/cornell-box.toml] (kernel build and BVH not timed)."""
    from .bench.render import run_render_bench
    from .scene.model import SAMPLERS

    intersectors = parse_intersectors(intersector)
    kernel_modes = comma_list(kernel_mode, ("auto", "wavefront", "megakernel"), "kernel mode")
    samplers = comma_list(sampler, SAMPLERS, "sampler") if sampler is not None else [None]
    check_json(json_path)
    options = dict(mitsuba_python=mitsuba_python, llvm_path=llvm_path, variant=mitsuba_variant) if mitsuba else None
    run_render_bench(list(scene_paths) or ["scenes/cornell-box.toml"], devices=list(device) or None, width=width,
                     height=height, spp=spp, max_depth=max_depth, repeat=repeat, wave_size=wave_size, intersectors=intersectors,
                     kernel_modes=kernel_modes, mitsuba=options, json_path=json_path, samplers=samplers,
                     echo=click.echo)


@bench.command("bvh")
@click.option("--sizes", default="10k,100k,1M", show_default=True, help="Mesh sizes in triangles.")
@click.option("--kinds", default="sphere,torus,soup,slivers", show_default=True, help="Mesh kinds.")
@click.option("--sweep-size", default=100_000, show_default=True, type=click.IntRange(min=0),
              help="Size at which the full-sweep SAH builder runs too, as the quality reference (0: never).")
@click.option("--repeat", default=3, show_default=True, type=click.IntRange(min=1),
              help="Timed builds per mesh (median reported).")
@click.option("--check", is_flag=True, help="Validate every BVH (slow on big meshes).")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), help="Write the results to this JSON file.")
def bench_bvh(sizes, kinds, sweep_size, repeat, check, json_path):
    """Build time and SAH cost of the host BVH builder, against the full-sweep SAH build."""
    from .bench.bvh_build import run_bvh_bench
    from .bench.workloads import MESH_KINDS, parse_sizes

    sizes, kinds = parse_sizes(sizes), comma_list(kinds, MESH_KINDS, "mesh kind")
    check_json(json_path)
    run_bvh_bench(sizes=sizes, kinds=kinds, sweep_size=sweep_size, repeat=repeat, check=check,
                  json_path=json_path, echo=click.echo)


@bench.command("scale")
@click.option("--sizes", default="0.5,2,8", show_default=True, metavar="LIST",
              help="Millions of triangles of the height-field scenes, comma-separated.")
@click.option("--with-32m", "with_32m", is_flag=True, help="Also 32 million triangles (about 20 GB of memory for ours).")
@click.option("--workdir", type=click.Path(file_okay=False), default="bench-scale", show_default=True,
              help="Where the scenes (PLY + XML, reused) and the images go.")
@click.option("--repeat", default=1, show_default=True, type=click.IntRange(min=1), help="Runs of each, in turn.")
@click.option("--width", default=256, show_default=True, type=int)
@click.option("--height", default=256, show_default=True, type=int)
@click.option("--spp", default=16, show_default=True, type=int)
@click.option("--no-mitsuba", is_flag=True, help="Ours only.")
@click.option("--baseline", type=click.Path(file_okay=False, exists=True),
              help="Another version's checkout (e.g. git archive of a commit): its render too, in turn.")
@mitsuba_options
@click.option("--json", "json_path", type=click.Path(dir_okay=False), help="Write the results to this JSON file.")
@device_option
def bench_scale(sizes, with_32m, workdir, repeat, width, height, spp, no_mitsuba, baseline, mitsuba_python,
                llvm_path, mitsuba_variant, json_path, device):
    """Wall time and peak RSS of the whole `pyopencl-rt render` command beside Mitsuba 3's load and
    render of the same Mitsuba XML, on height-field meshes of millions of triangles (issue 35)."""
    from .bench.scale import parse_millions, run_scale_bench

    check_json(json_path)
    run_scale_bench(sizes=parse_millions(sizes, with_32m), workdir=workdir, repeat=repeat, width=width,
                    height=height, spp=spp, device=list(device) or None, mitsuba=not no_mitsuba, baseline=baseline,
                    mitsuba_python=mitsuba_python, llvm_path=llvm_path, variant=mitsuba_variant,
                    json_path=json_path, echo=click.echo)


@bench.command("materials")
@device_option
@click.option("--scenes", "scenes_dir", default="scenes", show_default=True, type=click.Path(file_okay=False),
              help="Folder with textured.toml, cornell-jensen.toml and cornell-box.toml.")
@click.option("--pairs", default="textures,rough,gltf", show_default=True,
              help="Comma-separated: textures (with/without), rough (vs smooth), gltf (plastic vs diffuse).")
@click.option("--width", default=256, show_default=True, type=click.IntRange(min=1))
@click.option("--height", default=256, show_default=True, type=click.IntRange(min=1))
@click.option("--spp", default=8, show_default=True, type=click.IntRange(min=1), help="Samples per pixel per timed render.")
@click.option("--repeat", default=3, show_default=True, type=click.IntRange(min=1),
              help="Timed renders per variant (median reported).")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), help="Write the results to this JSON file.")
def bench_materials(device, scenes_dir, pairs, width, height, spp, repeat, json_path):
    """Samples/s with and without textures, rough against smooth, glTF against diffuse (a / b)."""
    from .bench.materials import PAIRS, run_materials_bench

    pairs = comma_list(pairs, PAIRS, "pair")
    check_json(json_path)
    run_materials_bench(devices=list(device) or None, scenes_dir=scenes_dir, pairs=pairs,
                        width=width, height=height, spp=spp, repeat=repeat, json_path=json_path, echo=click.echo)


@bench.command("mitsuba-cornell-box")
@mitsuba_options
@click.option("--spp", default="16,64,256", show_default=True, help="One render per value; the first includes the JIT.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), help="Write the results to this JSON file.")
def bench_mitsuba_cornell_box(mitsuba_python, llvm_path, mitsuba_variant, spp, json_path):
    """Samples/s of Mitsuba 3 on its own Cornell box (mi.cornell_box()), for scale beside ours."""
    from .bench.mitsuba_host import parse_spps, run_mitsuba_cornell_box

    check_json(json_path)
    run_mitsuba_cornell_box(mitsuba_python=mitsuba_python, llvm_path=llvm_path, variant=mitsuba_variant,
                            spps=parse_spps(spp), json_path=json_path, echo=click.echo)


@bench.command("convergence")
@click.argument("scene_path", metavar="SCENE", type=click.Path(dir_okay=False))
@device_option
@click.option("--integrator", default="path", show_default=True, help="Comma-separated: path,bsdf,nee.")
@click.option("--intersector", default="opencl", show_default=True, help="Comma-separated: opencl,embree.")
@click.option("--sampler", help="Comma-separated: sobol,stratified,independent, a curve each [default: the scene's].")
@click.option("--adaptive", is_flag=True, help="Also an adaptive curve per sampler (refining the worst pixels).")
@click.option("--reference", type=click.Path(dir_okay=False), help="Reference OpenEXR (default: render one and cache it).")
@click.option("--reference-spp", type=click.IntRange(min=1), help="Samples per pixel of the rendered reference (default: a share of --budget).")
@click.option("--no-cache", is_flag=True, help="Neither read nor write the cached reference.")
@click.option("--budget", type=float, default=60.0, show_default=True, metavar="SECONDS",
              help="Wall-time budget of the whole run, its own reference included.")
@click.option("--width", type=click.IntRange(min=1))
@click.option("--height", type=click.IntRange(min=1))
@click.option("--max-depth", type=int)
@click.option("--compare", default="", help="Peer renderers beside ours: 'mitsuba' (needs Mitsuba 3; skipped if absent).")
@mitsuba_options
@click.option("--mitsuba-sampler", default="independent,multijitter", show_default=True,
              help="With --compare mitsuba: Mitsuba's samplers (independent,stratified,multijitter,ldsampler,orthogonal).")
@click.option("--json", "json_path", default="out/convergence.json", show_default=True, type=click.Path(dir_okay=False))
@click.option("--plot", "plot_path", type=click.Path(dir_okay=False), help="PNG plot (default: the JSON path with .png).")
@click.option("--denoise", is_flag=True, help="Beside each of our curves, its Open Image Denoise curve (needs the "
              "denoise extra): where denoising stops helping.")
@seed_options(1)
def bench_convergence(scene_path, device, integrator, intersector, sampler, adaptive, reference, reference_spp, no_cache, budget,
                      width, height, max_depth, compare, mitsuba_python, llvm_path, mitsuba_variant, mitsuba_sampler,
                      json_path, plot_path, denoise, seeds, first_seed):
    """Error (RMSE, relMSE, MAE) against a reference as a function of render time, per device x
    integrator x intersector, optionally beside Mitsuba 3: JSON, a log-log plot and a table."""
    from .bench.convergence import MITSUBA_SAMPLERS, run_convergence
    from .scene.model import INTEGRATORS, SAMPLERS

    integrators = comma_list(integrator, INTEGRATORS, "integrator")
    samplers = comma_list(sampler, SAMPLERS, "sampler") if sampler is not None else [None]
    mitsuba_samplers = comma_list(mitsuba_sampler, MITSUBA_SAMPLERS, "Mitsuba sampler")
    intersectors = parse_intersectors(intersector)
    from . import validate

    validate.number(budget, "--budget", positive=True)
    check_json(json_path)
    if plot_path is not None:
        validate.writable_file(plot_path, "plot")
    run_convergence(scene_path, devices=list(device) or None, integrators=integrators, intersectors=intersectors,
                    reference=reference, reference_spp=reference_spp, budget=budget, width=width, height=height,
                    max_depth=max_depth, compare=[c.strip() for c in compare.split(",") if c.strip()],
                    mitsuba_python=mitsuba_python, mitsuba_variant=mitsuba_variant, llvm_path=llvm_path,
                    json_path=json_path, plot_path=plot_path, use_cache=not no_cache, denoise=denoise,
                    samplers=samplers, mitsuba_samplers=mitsuba_samplers, adaptive=adaptive, seeds=seeds,
                    first_seed=first_seed, echo=click.echo)


@bench.command("samplers")
@click.argument("scene_path", metavar="SCENE", type=click.Path(dir_okay=False))
@device_option
@click.option("--spp", default=256, show_default=True, type=click.IntRange(min=1))
@click.option("--sampler", default="sobol,stratified,independent", show_default=True, help="Ours, a row each.")
@click.option("--seeds", default=2, show_default=True, type=click.IntRange(min=1), help="Renders per row (median).")
@click.option("--width", type=click.IntRange(min=1))
@click.option("--height", type=click.IntRange(min=1))
@click.option("--reference-spp", default=16384, show_default=True, type=click.IntRange(min=2))
@click.option("--no-cache", is_flag=True, help="Neither read nor write our cached reference.")
@click.option("--compare", default="", help="'mitsuba': Mitsuba's reference, and a row per --mitsuba-sampler.")
@mitsuba_options
@click.option("--mitsuba-sampler", default="independent,stratified,multijitter,ldsampler", show_default=True)
@click.option("--json", "json_path", type=click.Path(dir_okay=False))
@click.option("--save-reference", type=click.Path(dir_okay=False), help="Write the reference as this OpenEXR.")
def bench_samplers(device, sampler, compare, mitsuba_sampler, json_path, no_cache, **options):
    """relMSE per sampler at equal spp against one reference, ours beside Mitsuba's (docs/SAMPLING.md)."""
    from .bench.samplers import MITSUBA_SAMPLERS, run_samplers
    from .scene.model import SAMPLERS

    check_json(json_path)
    if len(device) > 1:
        raise UsageError("bench samplers renders on one device")
    run_samplers(samplers=comma_list(sampler, SAMPLERS, "sampler"), device=device[0] if device else None,
                 compare=[c.strip() for c in compare.split(",") if c.strip()], json_path=json_path,
                 mitsuba_samplers=comma_list(mitsuba_sampler, MITSUBA_SAMPLERS, "Mitsuba sampler"),
                 use_cache=not no_cache, echo=click.echo, **options)


@bench.command("set")
@click.argument("scene_paths", metavar="[SCENE]...", nargs=-1, type=click.Path(dir_okay=False))
@device_option
@click.option("--size", default=256, show_default=True, type=click.IntRange(min=1), help="Width = height, samples/s.")
@click.option("--spp", default=64, show_default=True, type=click.IntRange(min=1), help="Samples per pixel a render.")
@click.option("--repeat", default=5, show_default=True, type=click.IntRange(min=1), help="Rounds of timed renders.")
@click.option("--error-size", default=64, show_default=True, type=click.IntRange(min=1), help="Width = height, error.")
@click.option("--budget", default=150.0, show_default=True, type=click.FloatRange(min=1), help="Seconds of curves a scene.")
@click.option("--reference-spp", default=16384, show_default=True, type=click.IntRange(min=2))
@click.option("--mitsuba-sampler", "mitsuba_samplers", default="independent,stratified,multijitter,ldsampler,orthogonal",
              show_default=True, help="Mitsuba's samplers, a curve each: the best counts.")
@seed_options(4)
@mitsuba_options
@click.option("--json", "json_path", type=click.Path(dir_okay=False), help="Write the results to this JSON file.")
def bench_set(scene_paths, device, json_path, **options):
    """The benchmark set against Mitsuba 3, rendering the same SCENEs [default: the four of docs/BENCHMARKS.md]:
    samples/s in turns, time to relMSE 1e-3 against Mitsuba's best sampler, and our lane width.

    Each curve (ours, and one per Mitsuba sampler) is rendered with --seeds seeds (Mitsuba's:
    the seed of mi.render; ours: the seed of the render), and the time to 1e-3 is that of the mean
    over the seeds of the relMSE at each spp: interpolated where that mean crosses 1e-3, otherwise
    extrapolated with relMSE = c/N + the reference's own noise (marked *).  Each time and ratio has
    its standard error over the seeds (+-), so that a difference within it reads as noise."""
    from .bench.bench_set import DEFAULT_SCENES, run_bench_set

    check_json(json_path)
    run_bench_set(list(scene_paths) or DEFAULT_SCENES, devices=list(device) or None, json_path=json_path,
                  echo=click.echo, **options)


@bench.command("mitsuba-suite")
@click.argument("path", type=click.Path(exists=True, file_okay=False))
@device_option
@click.option("--only", multiple=True, metavar="PATTERN", help="Scenes whose folder/name has or globs PATTERN.")
@click.option("--skip", multiple=True, metavar="PATTERN", help="Leave out the scenes PATTERN matches (as --only).")
@click.option("--seed", default=0, show_default=True, type=click.IntRange(0, 2**32 - 1))
@click.option("--timeout", type=click.FloatRange(0, min_open=True), metavar="S", help="Render a scene S seconds at most.")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), help="Write the results to this JSON file.")
def bench_mitsuba_suite(path, device, **options):
    """Mitsuba 3's render tests (PATH: a mitsuba-data checkout), judged by its z-test; exit code 1 on a fail."""
    from .bench.mitsuba_suite import run_suite

    if run_suite(path, device=list(device) or None, echo=click.echo, **options):
        sys.exit(1)

@bench.command("pbrt-scenes")
@click.argument("path", type=click.Path(exists=True))
@click.option("--width", default=160, show_default=True, type=click.IntRange(min=1))
@click.option("--height", default=120, show_default=True, type=click.IntRange(min=1))
@click.option("--spp", default=4, show_default=True, type=click.IntRange(min=1))
@click.option("--timeout", default=300.0, show_default=True, type=click.FloatRange(0, min_open=True), metavar="S",
              help="Kill a scene's render after S seconds.")
@click.option("--only", multiple=True, metavar="TEXT", help="Scenes whose path contains TEXT (repeatable).")
@click.option("--json", "json_path", type=click.Path(dir_okay=False), help="Write the results to this JSON file.")
@click.option("--pbrt", type=click.Path(exists=True, dir_okay=False), metavar="BINARY",
              help="A pbrt-v4 binary: judge each ok scene against pbrt's render (z-test, as bench mitsuba-suite).")
@click.option("--ref-spp", default=64, show_default=True, type=click.IntRange(min=1),
              help="With --pbrt: our spp, and pbrt's per seed.")
@click.option("--ref-seeds", default=16, show_default=True, type=click.IntRange(min=2),
              help="With --pbrt: pbrt renders (seeds 0 .. N-1), whose spread gives its variance.")
def bench_pbrt_scenes(path, **options):
    """pbrt-v4 scene files under PATH (e.g. a copy of mmp/pbrt-v4-scenes), each rendered small in a
    subprocess: ok, refused (the feature named), missing (a file not there), error or timeout,
    with seconds, peak RSS and the warnings (those that drop or replace a feature: defects); with
    --pbrt, each ok scene's verdict against pbrt-v4's render."""
    from .bench.pbrt_scenes import run_bench

    run_bench(path, echo=click.echo, **options)


def main(argv=None):
    """Entry point: user errors become one line on stderr and a non-zero exit code (1 for bad
    input, 2 for a wrong command line, 130 when interrupted); warnings (e.g. a scene file's
    unsupported elements) one line each, all through one logger (errors.report_to_stderr)."""
    from .device.host_memory import return_freed_memory
    from .errors import report_to_stderr, watch_sigint

    watch_sigint()
    report_to_stderr()
    return_freed_memory()  # a big scene's freed arrays go back to the system, not to a heap kept
    try:
        cli.main(args=argv, prog_name="pyopencl-rt", standalone_mode=False)
    except UserError as exc:
        LOGGER.error("%s", exc)
        sys.exit(exc.exit_code)
    except (click.exceptions.Abort, KeyboardInterrupt):
        LOGGER.error("interrupted")
        sys.exit(130)
    except click.ClickException as exc:  # a wrong command line: one line too, with where to look
        ctx = getattr(exc, "ctx", None)
        hint = f" (see '{ctx.command_path} --help')" if isinstance(exc, click.UsageError) and ctx else ""
        LOGGER.error("%s%s", exc.format_message(), hint)
        sys.exit(exc.exit_code)
    except MemoryError:
        LOGGER.error("out of host memory (a smaller --wave-size or resolution needs less)")
        sys.exit(1)
    except Exception as exc:
        if not _is_opencl_error(exc):
            raise
        LOGGER.error("the OpenCL device failed: %s", exc)
        sys.exit(1)


def _is_opencl_error(exc) -> bool:
    """A pyopencl error (out of device memory or resources, a lost device): the device's
    failure, reported in one line, not a bug's traceback."""
    cl = sys.modules.get("pyopencl")
    return cl is not None and isinstance(exc, cl.Error)


if __name__ == "__main__":
    main()
