"""``pyopencl-rt bench pbrt-scenes PATH``: what we make of pbrt-v4's scene files.

PATH is a folder such as a (partial) checkout of pbrt-v4's public scenes
(github.com/mmp/pbrt-v4-scenes); nothing of it is part of this repository, it is read from PATH.
Every ``*.pbrt`` and ``*.pbrt.gz`` file under PATH that has a ``WorldBegin`` of its own is a
scene (the geometry and material files that scenes ``Include`` have none).  Each scene is
rendered small (``--width``/``--height``/``--spp``, default 160 x 120 at 4 spp) by
``pyopencl-rt render`` in a subprocess of its own, with a time limit, and gets a row:

* ``ok``: the render finished (exit status 0, no traceback);
* ``refused``: our one-line error (``pyopencl-rt: error: ...``, exit status 1, no traceback)
  that names a feature we do not render; ``feature`` is the feature's name
  (:func:`feature_of`);
* ``missing``: our one-line error for a file the scene names that is not there (pbrt-v4-scenes'
  larger meshes and textures are often absent from a copy);
* ``error``: anything else: a traceback, death by a signal, a non-zero exit without our error
  line, or our error line for a failure of the device or of memory;
* ``timeout``: killed after ``--timeout`` seconds.

A ``missing`` scene is then *probed*: loaded (not rendered) in another subprocess with the
missing files skipped (``python -m pyopencl_rt.bench.pbrt_scenes probe SCENE``: an ``Include``
or a directive whose file is not there is left out, with a warning), so that the features the rest
of the scene asks for are seen: the row's ``probe`` holds that load's verdict, its defects and the
files skipped.  What a probe finds is counted apart (``behind_missing``): the scene is blocked by
its missing files first, and a later error may come of what was skipped (a material defined in a
missing file, say).

Each row also has the seconds the subprocess ran, its peak resident memory (``ru_maxrss`` of the
child, from ``os.wait4``) and the warnings it printed.  A warning that says a feature was
dropped or replaced (:data:`DEFECT_WORDS`: "not supported", "ignored", "using ...",
"rendered as", "read as") is a *defect* and is listed as one; the others (such as a documented
approximation) are listed as warnings.  The feature counts say how many scenes each feature
blocks (refusals) and how many it spoils (defect warnings).

With ``--pbrt BINARY`` (a pbrt-v4 the user built; nothing of pbrt is part of this repository),
every ``ok`` scene is also rendered by pbrt and judged against it (:mod:`.pbrt_reference`: the
mitsuba-suite's z-test rule, our ``--ref-spp``-sample render against pbrt's mean over
``--ref-seeds`` seeds): the row's ``pbrt`` holds the verdict (pass / fail), the accepted share of
pixel channels and the ratio of mean luminance, ours over pbrt's; a scene pbrt cannot render gets
``pbrt-error`` and the reason.
"""
from __future__ import annotations

import gzip
import json
import os
import re
import signal
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

from ..errors import UserError, one_line

ERROR_PREFIX = "pyopencl-rt: error: "
WARNING_PREFIX = "pyopencl-rt: warning: "
# a warning with one of these drops or replaces what the file asks for
DEFECT_WORDS = ("not supported", "ignored", "using ", "rendered as", "read as", "replaced")
# our one-line errors for a file that is not there
MISSING_WORDS = ("not found", "No such file", "does not exist")
# our one-line errors that are failures of the machine, not refusals of the file
FAILURE_WORDS = ("the OpenCL device failed", "out of host memory", "interrupted")
POSITION = re.compile(r"^(?:\S+?:\d+(?::\d+)?: )+")  # "file.pbrt:12: " (one per included file)


# -- the scenes --------------------------------------------------------------------------------------

def _has_world_begin(path: Path) -> bool:
    """Whether the file (gzip-compressed when it ends in .gz) has a ``WorldBegin`` outside
    comments; read line by line, and stopped at the first."""
    opener = gzip.open if path.name.endswith(".gz") else open
    try:
        with opener(path, "rb") as f:
            for line in f:
                if b"WorldBegin" in line and b"WorldBegin" in line.split(b"#", 1)[0]:
                    return True
    except (OSError, EOFError, gzip.BadGzipFile):
        return False
    return False


def list_scenes(path) -> list[Path]:
    """The scene files under ``path`` (a scene file itself is a list of one), sorted."""
    root = Path(path)
    if root.is_file():
        return [root]
    if not root.is_dir():
        raise UserError(f"{path}: no such folder")
    files = sorted(p for p in root.rglob("*") if p.is_file() and p.name.endswith((".pbrt", ".pbrt.gz")))
    return [p for p in files if _has_world_begin(p)]


# -- reading what the render said --------------------------------------------------------------------

def strip_position(message: str) -> str:
    """``a.pbrt:12: b.pbrt:3: Shape "x": ...`` -> ``Shape "x": ...``."""
    return POSITION.sub("", message, count=1)


_FEATURES = [
    re.compile(r'((?:Material|material|Shape|LightSource|AreaLightSource|Camera|Film|Sampler|Integrator|PixelFilter|'
               r'Texture|MakeNamedMedium|ColorSpace|Option|Attribute)\s*(?:"[^"]*"|\'[^\']*\'))'),
    re.compile(r'("(?:float|integer|bool|string|rgb|spectrum|texture|point3?|normal3?|vector3?|point2|blackbody) '
               r'[^"]+" of [A-Za-z]+(?: "[^"]*")?)'),
    re.compile(r"^([A-Za-z]+)\b"),
]


def feature_of(message: str) -> str:
    """The feature a refusal or a defect warning names, as a key that is the same from scene to
    scene: the directive and its type (``Shape "loopsubdiv"``, ``Material "hair"``), or a
    parameter and its directive (``"float whitebalance" of Film``); else the message's first
    words.  Named materials and textures are told by their type: loaders say
    ``material type "hair"`` for them."""
    text = strip_position(one_line(message))
    typed = re.search(r'(?:material|medium|shape|light) type "([^"]*)"', text)
    if typed:
        kind = text[typed.start():].split(" ", 1)[0].capitalize()
        return f'{kind} "{typed.group(1)}"'
    texture = re.search(r'texture class "([^"]*)"', text)
    if texture:
        return f'Texture "{texture.group(1)}"'
    texture_param = re.match(r'(?:material "[^"]*"|Material "([^"]*)"): "texture (\w+)": textures are not', text)
    if texture_param:
        return f'"texture {texture_param.group(2)}" of Material'
    texture = re.match(r'Texture "[^"]*": (\w+)(?: "([^"]*)")?', text)  # a named texture's: by its parameter
    if texture:
        return f'Texture {texture.group(1)}' + (f' "{texture.group(2)}"' if texture.group(2) else "")
    named = re.match(r'material "[^"]*": (.*)', text)  # a named material's: by what it asks for
    if named:
        rest = feature_of(named.group(1))
        return rest if rest.startswith(("Material", '"')) else f"Material {rest}"
    param = _FEATURES[1].search(text)
    if param:
        return re.sub(r' of Texture "[^"]*"$', " of Texture", param.group(1))  # a texture's name is no type
    head = _FEATURES[0].search(text)
    if head:
        word, _, name = head.group(1).partition(" ")
        return f"{word[0].upper()}{word[1:]} {name.strip()}".strip()
    head = re.sub(r"'[^']*'", "", text.split(";")[0])
    head = re.split(r"(?:\s+(?:is |are )?not supported|: rendered as|: read as|: using|: ignored)", head)[0]
    return " ".join(head.split()[:6]).rstrip(":")


def is_defect(warning: str) -> bool:
    return any(w in warning for w in DEFECT_WORDS)


def classify(returncode: int | None, stderr: str, timed_out: bool = False) -> dict:
    """The verdict of one render from its exit status and its standard error: ``status`` (ok,
    refused, missing, error, timeout), ``reason`` (one line), ``feature`` (refused),
    ``warnings`` and ``defects`` (each one line, without the prefix)."""
    lines = stderr.splitlines()
    warnings_ = [one_line(line[len(WARNING_PREFIX):]) for line in lines if line.startswith(WARNING_PREFIX)]
    errors = [one_line(line[len(ERROR_PREFIX):]) for line in lines if line.startswith(ERROR_PREFIX)]
    traceback = any(line.startswith("Traceback (most recent call last)") for line in lines)
    out = {"status": "ok", "reason": None, "feature": None, "warnings": [w for w in warnings_ if not is_defect(w)],
           "defects": [w for w in warnings_ if is_defect(w)]}
    if timed_out:
        out.update(status="timeout", reason="killed at the time limit")
    elif traceback:
        last = next((line for line in reversed(lines) if line.strip() and not line.startswith(" ")), "")
        out.update(status="error", reason=f"traceback: {one_line(last)}")
    elif returncode is not None and returncode < 0:
        out.update(status="error", reason=f"killed by signal {-returncode} ({_signal_name(-returncode)})")
    elif returncode == 0:
        pass
    elif len(errors) == 1:
        message = errors[0]
        if any(w in message for w in FAILURE_WORDS):
            out.update(status="error", reason=message)
        elif any(w in message for w in MISSING_WORDS):
            out.update(status="missing", reason=message)
        else:
            out.update(status="refused", reason=message, feature=feature_of(message))
    else:
        tail = next((line for line in reversed(lines) if line.strip()), "")
        out.update(status="error", reason=f"exit status {returncode} without one error line"
                   + (f": {one_line(tail)}" if tail else ""))
    return out


def _signal_name(number: int) -> str:
    try:
        return signal.Signals(number).name
    except ValueError:
        return "?"


# -- one scene ---------------------------------------------------------------------------------------

def render_command(scene: Path, output: Path, width: int, height: int, spp: int) -> list[str]:
    return [sys.executable, "-m", "pyopencl_rt.cli", "render", str(scene), "-o", str(output), "--width", str(width),
            "--height", str(height), "--spp", str(spp), "--quiet"]


def probe_command(scene: Path) -> list[str]:
    return [sys.executable, "-m", "pyopencl_rt.bench.pbrt_scenes", "probe", str(scene)]


def run_scene(scene: Path, width=160, height=120, spp=4, timeout=300.0, command=None) -> dict:
    """Render one scene in a subprocess; its row (:func:`classify`'s verdict, seconds, peak RSS).
    ``command`` (for tests): the argument list to run instead of :func:`render_command`."""
    with tempfile.TemporaryDirectory(prefix="pbrt-scenes-") as folder:
        args = command or render_command(scene, Path(folder) / "render.exr", width, height, spp)
        err_path = Path(folder) / "stderr.txt"
        start = time.perf_counter()
        with open(err_path, "wb") as err:
            proc = subprocess.Popen(args, stdout=subprocess.DEVNULL, stderr=err, stdin=subprocess.DEVNULL,
                                    start_new_session=True)
            killed = threading.Event()

            def kill():
                killed.set()
                try:
                    os.killpg(proc.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass

            timer = threading.Timer(timeout, kill) if timeout else None
            if timer:
                timer.start()
            try:
                _, status, usage = os.wait4(proc.pid, 0)
            finally:
                if timer:
                    timer.cancel()
            proc.returncode = os.waitstatus_to_exitcode(status)
        seconds = time.perf_counter() - start
        stderr = err_path.read_text(errors="replace")
    row = {"scene": str(scene), "seconds": seconds, "peak_rss_mib": usage.ru_maxrss / 1024.0,
           "returncode": proc.returncode}
    row.update(classify(proc.returncode, stderr, timed_out=killed.is_set()))
    return row


def probe_scene(scene: Path, timeout=300.0) -> dict:
    """The load of a scene with its missing files skipped: :func:`classify`'s verdict, with the
    files skipped apart (``skipped``) from the warnings."""
    from ..scene.loaders.pbrt import MISSING_SKIPPED

    row = run_scene(scene, timeout=timeout, command=probe_command(scene))
    skipped = [w[len(MISSING_SKIPPED):] for w in row["defects"] + row["warnings"] if w.startswith(MISSING_SKIPPED)]
    if skipped and row["status"] == "refused" and "has no shapes that we can render" in row["reason"]:
        row.update(status="ok", feature=None, reason="nothing left to render without the missing files")
    return {"status": row["status"], "reason": row["reason"], "feature": row["feature"], "skipped": skipped,
            "defects": [w for w in row["defects"] if not w.startswith(MISSING_SKIPPED)],
            "warnings": [w for w in row["warnings"] if not w.startswith(MISSING_SKIPPED)]}


def _probe_main(scene) -> int:
    """``python -m pyopencl_rt.bench.pbrt_scenes probe SCENE``: load SCENE with missing files
    skipped; warnings and the error as the CLI prints them; exit status 1 on an error."""
    from ..errors import LOGGER, UserError, report_to_stderr
    from ..scene.loaders import load_scene
    from ..scene.loaders import pbrt

    report_to_stderr()
    pbrt.SKIP_MISSING_FILES = True
    try:
        load_scene(scene)
    except UserError as exc:
        LOGGER.error("%s", exc)
        return 1
    return 0


# -- the bench ---------------------------------------------------------------------------------------

def feature_counts(rows) -> dict:
    """{feature: {"blocks": scenes refused for it, "spoils": scenes with a defect warning about it}},
    most scenes first."""
    counts: dict = {}

    def add(feature, column, scene):
        counts.setdefault(feature, {"blocks": set(), "spoils": set(), "behind_missing": set()})[column].add(scene)

    for row in rows:
        if row["status"] == "refused" and row["feature"]:
            add(row["feature"], "blocks", row["scene"])
        for defect in row["defects"]:
            add(feature_of(defect), "spoils", row["scene"])
        probe = row.get("probe")
        if probe:
            if probe["status"] == "refused" and probe["feature"]:
                add(probe["feature"], "behind_missing", row["scene"])
            for defect in probe["defects"]:
                add(feature_of(defect), "behind_missing", row["scene"])
    table = {k: {c: len(v[c]) for c in ("blocks", "spoils", "behind_missing")} for k, v in counts.items()}
    return dict(sorted(table.items(), key=lambda kv: (-sum(kv[1].values()), kv[0])))


def format_row(row, root: Path, width: int) -> str:
    name = _name(row["scene"], root)
    note = row["reason"] or ""
    probe = row.get("probe")
    if probe:
        found = ([f"{probe['status']}: {probe['feature'] or probe['reason']}"] if probe["status"] != "ok" else []) + [
            f"defect: {feature_of(d)}" for d in probe["defects"]]
        note = (f"{len(probe['skipped'])} file(s) missing, e.g. {strip_position(note)}; behind them: "
                + ("; ".join(found) if found else "nothing refused"))
    elif row["status"] == "ok" and row["defects"]:
        note = f"{len(row['defects'])} defect(s): " + "; ".join(strip_position(d) for d in row["defects"][:3])
    return (f"{name:<{width}} {row['status']:<8} {row['seconds']:7.1f} {row['peak_rss_mib']:8.0f} "
            f"{len(row['defects']):>3} {len(row['warnings']):>3}  {note[:200]}").rstrip()


def _name(scene, root: Path) -> str:
    try:
        return str(Path(scene).relative_to(root))
    except ValueError:
        return str(scene)


def judge_against_pbrt(row: dict, pbrt, width, height, ref_spp, ref_seeds, timeout) -> dict:
    """pbrt's verdict on an ``ok`` row's scene (:func:`.pbrt_reference.compare_scene`)."""
    from .pbrt_reference import compare_scene

    try:
        return compare_scene(pbrt, row["scene"], width, height, spp=ref_spp, ref_spp=ref_spp, seeds=ref_seeds,
                             timeout=timeout)
    except UserError as exc:
        return {"verdict": "pbrt-error", "reason": one_line(str(exc))}


def format_judgement_line(row: dict) -> str:
    from .pbrt_reference import format_judgement

    j = row["pbrt"]
    return "    against pbrt: " + (format_judgement(j) if j["verdict"] != "pbrt-error" else f"pbrt-error: {j['reason']}")


def run_bench(path, width=160, height=120, spp=4, timeout=300.0, json_path=None, only=(), echo=print, pbrt=None,
              ref_spp=64, ref_seeds=16) -> list:
    """Every scene under ``path`` (those whose path contains one of ``only``, when given), a row
    each printed as it is done, then the counts by verdict and by feature.  With ``pbrt`` (a
    pbrt-v4 binary) each ok scene is judged against pbrt's render as well.  Returns the rows."""
    from .. import validate

    if json_path is not None:
        validate.writable_file(json_path, "JSON file")
    root = Path(path)
    scenes = [s for s in list_scenes(root) if not only or any(o in str(s) for o in only)]
    if not scenes:
        raise UserError(f"{path}: no pbrt-v4 scene here (a .pbrt or .pbrt.gz file with a WorldBegin)")
    echo(f"{len(scenes)} scenes under {root}, {width}x{height} at {spp} spp, {timeout:g} s each at most")
    width_col = max(len(_name(s, root)) for s in scenes)
    echo(f"{'scene':<{width_col}} {'verdict':<8} {'seconds':>7} {'RSS MiB':>8} {'def':>3} {'wrn':>3}  note")
    rows = []
    for scene in scenes:
        rows.append(run_scene(scene, width, height, spp, timeout))
        if rows[-1]["status"] == "missing":
            rows[-1]["probe"] = probe_scene(scene, timeout)
        echo(format_row(rows[-1], root, width_col))
        if pbrt and rows[-1]["status"] == "ok":
            rows[-1]["pbrt"] = judge_against_pbrt(rows[-1], pbrt, width, height, ref_spp, ref_seeds, timeout)
            echo(format_judgement_line(rows[-1]))
    verdicts = {v: sum(r["status"] == v for r in rows) for v in ("ok", "refused", "missing", "error", "timeout")}
    clean = sum(r["status"] == "ok" and not r["defects"] for r in rows)
    echo(", ".join(f"{n} {v}" for v, n in verdicts.items()) + f" (of {len(rows)}; {clean} ok without a defect)")
    judged = [r["pbrt"]["verdict"] for r in rows if "pbrt" in r]
    if pbrt:
        echo(f"against pbrt: {judged.count('pass')} pass, {judged.count('fail')} fail, "
             f"{judged.count('pbrt-error')} pbrt-error (of {len(judged)} ok scenes)")
    counts = feature_counts(rows)
    if counts:
        echo("features (scenes each blocks / spoils with a defect warning / is found behind missing files):")
        for feature, c in counts.items():
            echo(f"  {c['blocks']:3d} {c['spoils']:3d} {c['behind_missing']:3d}  {feature}")
    if json_path:
        results = {"path": str(root), "width": width, "height": height, "spp": spp, "timeout": timeout,
                   "date": time.strftime("%Y-%m-%d"), "verdicts": verdicts, "pbrt": str(pbrt) if pbrt else None, "ok_without_defects": clean,
                   "features": counts, "scenes": [dict(r, scene=_name(r["scene"], root)) for r in rows]}
        try:
            Path(json_path).write_text(json.dumps(results, indent=2) + "\n")
        except OSError as exc:
            raise UserError(f"{json_path}: cannot write ({exc.strerror or exc})") from None
        echo(f"wrote {json_path}")
    return rows


if __name__ == "__main__":
    if len(sys.argv) != 3 or sys.argv[1] != "probe":
        sys.exit("usage: python -m pyopencl_rt.bench.pbrt_scenes probe SCENE")
    sys.exit(_probe_main(sys.argv[2]))
