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


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def import_graph(package: Path = None) -> dict:
    """module -> the package's modules it imports, at the top or inside a function alike (an import
    inside a function is a dependency all the same)."""
    package = package or PACKAGE
    names = {_module_name(p): p for p in modules()}
    graph = {}
    for name, path in names.items():
        is_package = path.name == "__init__.py"
        here = name.split(".") if is_package else name.split(".")[:-1]
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                if node.level:
                    base = here[: len(here) - (node.level - 1)] + (node.module.split(".") if node.module else [])
                elif node.module and node.module.split(".")[0] == "pyopencl_rt":
                    base = node.module.split(".")[1:]
                else:
                    continue
                for alias in node.names:
                    full = ".".join(base + [alias.name])
                    targets.add(full if full in names else ".".join(base))
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    if alias.name.startswith("pyopencl_rt."):
                        targets.add(alias.name.split(".", 1)[1])
        graph[name] = {t for t in targets if t in names and t != name}
    return graph


def import_cycles(graph: dict) -> list:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, cycles = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph.get(v, ())):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return cycles


# Cycles docs/ARCHITECTURE.md ("Imports") explains, each a reason to keep it for now.
EXPLAINED_CYCLES = [["accel.bvh", "accel.bvh_sweep"]]


def test_no_import_cycles():
    """No module imports itself through others, not even from inside a function, but the cycles
    docs/ARCHITECTURE.md explains ("Imports")."""
    assert import_cycles(import_graph()) == EXPLAINED_CYCLES


def test_cycle_finder_sees_a_cycle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert import_cycles(graph) == [["a", "b", "c"]]
