"""The package's structure (docs/ARCHITECTURE.md): subpackages by domain, imports that only point
down the layers, and modules short enough to read in one sitting.  Host-only: reads the sources."""
import ast
from pathlib import Path

import pytest

PACKAGE = Path(__file__).resolve().parents[1] / "pyopencl_rt"

# Lowest first: a module may import from its own layer and the layers below it.
LAYERS = [
    # display: tone curves; compare: image metrics; validate: argument checks; host_stages: --profile's host timers
    {"errors", "imageio", "display", "compare", "validate", "host_stages"},
    {"device"},
    {"accel"},
    {"scene"},
    {"render", "trace"},  # trace: the ray-casting API (accel + device), which bench times
    {"bench"},
    {"cli", "cli_options", "progress", "__init__"},  # progress: the render command's progress bar
]
MAX_LINES = 600


def layer_of(top: str) -> int:
    for i, names in enumerate(LAYERS):
        if top in names:
            return i
    raise KeyError(top)


def modules():
    for path in sorted(PACKAGE.rglob("*.py")):
        if "cl" in path.relative_to(PACKAGE).parts[:1]:
            continue
        yield path


def top_of(path: Path) -> str:
    """The layer name of a module: its subpackage, or its own name at the top level."""
    parts = path.relative_to(PACKAGE).with_suffix("").parts
    return parts[0]


def imported_tops(path: Path):
    """(line, top-level name inside pyopencl_rt) of every import of the package in ``path``."""
    tree = ast.parse(path.read_text())
    package_parts = path.relative_to(PACKAGE).parent.parts
    for node in ast.walk(tree):
        if isinstance(node, ast.ImportFrom):
            if node.level:
                base = list(package_parts[: len(package_parts) - (node.level - 1)])
                if node.level - 1 > len(package_parts):
                    raise AssertionError(f"{path}: import above the package")
                target = base + (node.module.split(".") if node.module else [])
                if target:
                    yield node.lineno, target[0]
                else:  # from . import x at the top level
                    for alias in node.names:
                        yield node.lineno, alias.name
            elif node.module and node.module.split(".")[0] == "pyopencl_rt":
                parts = node.module.split(".")[1:]
                if parts:
                    yield node.lineno, parts[0]
                else:
                    for alias in node.names:
                        yield node.lineno, alias.name
        elif isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                if parts[0] == "pyopencl_rt" and len(parts) > 1:
                    yield node.lineno, parts[1]


def test_at_least_four_domain_subpackages():
    subpackages = {p.parent.name for p in PACKAGE.glob("*/__init__.py")}
    assert {"device", "accel", "scene", "render"} <= subpackages, subpackages


def test_imports_only_point_down():
    wrong = []
    for path in modules():
        mine = layer_of(top_of(path))
        for line, top in imported_tops(path):
            try:
                theirs = layer_of(top)
            except KeyError:  # a public name of the top-level package (load_scene, render, ...)
                theirs = len(LAYERS) - 1
            if theirs > mine:
                wrong.append(f"{path.relative_to(PACKAGE)}:{line} imports {top}")
    assert not wrong, "imports that point up a layer:\n" + "\n".join(wrong)


@pytest.mark.parametrize("path", list(modules()), ids=lambda p: str(p.relative_to(PACKAGE)))
def test_module_length(path):
    n = len(path.read_text().splitlines())
    assert n <= MAX_LINES, f"{path.relative_to(PACKAGE)} has {n} lines (at most {MAX_LINES})"


def test_checker_sees_an_upward_import(tmp_path, monkeypatch):
    """The import checker itself: a device/ module importing render/ must be reported."""
    fake = tmp_path / "pyopencl_rt"
    (fake / "device").mkdir(parents=True)
    bad = fake / "device" / "bad.py"
    bad.write_text("from ..render.api import render_full\nfrom . import abi\n")
    monkeypatch.setattr(__import__(__name__), "PACKAGE", fake)
    assert [top for _, top in imported_tops(bad)] == ["render", "device"]
    assert layer_of("render") > layer_of(top_of(bad))
