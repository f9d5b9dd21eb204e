"""Mitsuba 3 XML scene files (``.xml``): the document.

This module reads the XML the way Mitsuba 3's parser does and hands :mod:`.mitsuba_scene` a list
of plugin objects; that module maps them onto our scene (docs/SCENE_FORMAT.md, "Mitsuba 3 XML").

* ``<scene version="...">`` is the root (files of version < 2, Mitsuba 0.6's, get Mitsuba's own
  upgrade: camelCase names become snake_case, ``<lookAt>`` becomes ``<lookat>``, ``<srgb>`` a
  linear ``<rgb>``);
* ``<default name value>`` defines ``$name`` unless the caller did (``--define name=value``
  wins); every attribute value has its ``$name`` substituted; an undefined ``$name`` is an error;
* ``<include filename>`` (relative to the including file, then to ``<path value>`` folders)
  splices the included ``<scene>``'s children in place; ``<alias id as>`` names an object twice;
* an object (``bsdf``, ``shape``, ``emitter``, ``texture``, ``sensor``, ``film``, ``rfilter``,
  ``sampler``, ``integrator``, ``medium``, ...) with an ``id`` can be used later by ``<ref id>``
  (with ``name``: as a named property), at the top level or nested;
* values: ``float``, ``integer``, ``boolean``, ``string``, ``rgb`` (one number or three, comma-
  or space-separated), ``spectrum`` (a constant; ``wavelength:value`` pairs are averaged, with a
  warning), ``point`` / ``vector`` (``x``/``y``/``z`` or ``value``) and ``transform`` (``translate``,
  ``rotate``, ``scale``, ``matrix``, ``lookat``, each applied after the ones before it).

Malformed input (not XML, a missing or non-numeric attribute, an unknown reference, ...) raises a
:class:`~.builder.SceneFormatError` naming the file and line; elements we do not render warn
(the builder's ``warn``) and are skipped.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from xml.parsers import expat

import numpy as np

from .builder import error_at, look_at_camera_to_world, rotate, scale, translate

OBJECT_TAGS = {"bsdf", "texture", "shape", "emitter", "sensor", "film", "rfilter", "sampler", "integrator",
               "medium", "phase", "volume", "scene"}
VALUE_TAGS = {"float", "integer", "boolean", "string", "rgb", "spectrum", "point", "vector", "transform"}
TRANSFORM_TAGS = {"translate", "rotate", "scale", "matrix", "lookat"}
_PARAM = re.compile(r"\$([A-Za-z_][A-Za-z0-9_]*)")


@dataclass(eq=False)
class Node:
    """One XML element with where it was written."""

    tag: str
    attrs: dict
    file: str
    line: int
    children: list = field(default_factory=list)

    @property
    def pos(self) -> str:
        return f"{self.file}:{self.line}"

    def label(self) -> str:
        """``<tag type="..." name="..." id="...">`` for messages."""
        shown = "".join(f' {k}="{self.attrs[k]}"' for k in ("type", "name", "id") if k in self.attrs)
        return f"<{self.tag}{shown}>"


def parse_xml(path: Path, name: str) -> Node:
    """The element tree of an XML file, every element with its line (expat)."""
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise error_at(name, f"cannot read ({exc.strerror or exc})") from None
    parser = expat.ParserCreate()
    stack: list[Node] = []
    root: list[Node] = []

    def start(tag, attrs):
        node = Node(tag, dict(attrs), name, parser.CurrentLineNumber)
        (stack[-1].children if stack else root).append(node)
        stack.append(node)

    def end(tag):
        stack.pop()

    parser.StartElementHandler = start
    parser.EndElementHandler = end
    try:
        parser.Parse(data, True)
    except expat.ExpatError as exc:
        raise error_at(f"{name}:{exc.lineno}:{exc.offset + 1}",
                       f"not well-formed XML ({expat.ErrorString(exc.code)})") from None
    return root[0]


@dataclass
class Prop:
    """A named property: ``kind`` is the value tag ('float', 'rgb', ..., 'object')."""

    kind: str
    value: object
    node: Node


@dataclass(eq=False)
class MiObject:
    """A plugin object: ``<tag type="...">`` with its named properties and unnamed children."""

    tag: str
    type: str
    id: str | None
    node: Node
    props: dict = field(default_factory=dict)
    children: list = field(default_factory=list)
    used: set = field(default_factory=set)

    def label(self) -> str:
        return f'<{self.tag} type="{self.type}"' + (f' id="{self.id}">' if self.id else ">")

    def has(self, name) -> bool:
        return name in self.props

    def prop(self, name) -> Prop | None:
        self.used.add(name)
        return self.props.get(name)

    def _typed(self, name, kinds, default, what):
        p = self.prop(name)
        if p is None:
            return default
        if p.kind not in kinds:
            raise error_at(p.node.pos, f'{self.label()}: "{name}" must be {what}, got <{p.kind}>')
        return p.value

    def float(self, name, default=None, *, minimum=None, positive=False):
        value = self._typed(name, ("float", "integer"), default, "a <float>")
        if value is not None and (positive and not value > 0 or minimum is not None and value < minimum):
            bound = "> 0" if positive else f">= {minimum:g}"
            raise error_at(self.props[name].node.pos, f'{self.label()}: "{name}" must be {bound}, got {value:g}')
        return None if value is None else float(value)

    def integer(self, name, default=None, *, minimum=None):
        value = self._typed(name, ("integer",), default, "an <integer>")
        if value is not None and minimum is not None and value < minimum:
            raise error_at(self.props[name].node.pos, f'{self.label()}: "{name}" must be >= {minimum}, got {value}')
        return value

    def boolean(self, name, default=None):
        return self._typed(name, ("boolean",), default, "a <boolean>")

    def string(self, name, default=None):
        return self._typed(name, ("string",), default, "a <string>")

    def point(self, name, default=None):
        value = self._typed(name, ("point", "vector"), default, "a <point> or <vector>")
        return None if value is None else np.asarray(value, np.float64)

    def transform(self, name="to_world"):
        value = self._typed(name, ("transform",), None, "a <transform>")
        return None if value is None else np.asarray(value, np.float64)

    def children_of(self, *tags) -> list:
        return [c for c in self.children if c.tag in tags]


class Document:
    """A Mitsuba XML file read into plugin objects (``objects``: the scene's children in order)."""

    def __init__(self, path: Path, name: str, defines: dict | None, warn):
        self.warn = warn
        self.params = {str(k): str(v) for k, v in (defines or {}).items()}
        self.ids: dict[str, MiObject] = {}
        self.search_paths: list[Path] = []
        self.objects: list[MiObject] = []
        self._including: list[Path] = []
        self.version = None
        root = parse_xml(path, name)
        if root.tag != "scene":
            raise error_at(root.pos, f"the root element must be <scene>, not <{root.tag}>")
        self._check_version(root)
        self._scene_children(root, path)

    # -- structure -----------------------------------------------------------------------------

    def _check_version(self, root: Node) -> None:
        version = root.attrs.get("version")
        if version is None:
            raise error_at(root.pos, '<scene> needs a version attribute (e.g. <scene version="3.0.0">)')
        try:
            self.version = tuple(int(p) for p in version.split("."))
        except ValueError:
            raise error_at(root.pos, f'<scene version="{version}">: not a version number like "3.0.0"') from None

    def _upgrade(self, node: Node) -> None:
        """Mitsuba's own upgrade of files older than version 2."""
        if self.version >= (2,):
            return
        if node.tag == "lookAt":
            node.tag = "lookat"
        if node.tag == "srgb":
            node.tag = "rgb"
            node.attrs["_srgb"] = "1"
        n = node.attrs.get("name")
        if n:
            n = n.replace("IOR", "Ior")
            node.attrs["name"] = re.sub(r"(?<=[a-z0-9])([A-Z])", lambda m: "_" + m.group(1).lower(), n)

    def _substitute(self, node: Node) -> None:
        for key, value in node.attrs.items():
            if "$" not in value:
                continue

            def sub(m):
                if m.group(1) not in self.params:
                    raise error_at(node.pos, f"{node.label()}: undefined parameter ${m.group(1)} "
                                             f"(give it a <default> or --define {m.group(1)}=VALUE)")
                return self.params[m.group(1)]

            node.attrs[key] = _PARAM.sub(sub, value)

    def _attr(self, node: Node, key: str) -> str:
        if key not in node.attrs:
            raise error_at(node.pos, f'{node.label()} needs a "{key}" attribute')
        return node.attrs[key]

    def _prepare(self, node: Node) -> None:
        self._upgrade(node)
        if node.tag != "default":
            self._substitute(node)

    def _scene_children(self, scene: Node, path: Path) -> None:
        for child in scene.children:
            self._prepare(child)
            tag = child.tag
            if tag == "default":
                self._substitute(child)
                self.params.setdefault(self._attr(child, "name"), self._attr(child, "value"))
            elif tag == "include":
                self._include(child, path)
            elif tag == "path":
                self.search_paths.append(path.parent / self._attr(child, "value"))
            elif tag == "alias":
                self.ids[self._attr(child, "as")] = self._ref(child, self._attr(child, "id"))
            elif tag in OBJECT_TAGS and tag != "scene":
                self.objects.append(self._object(child, path))
            elif tag == "ref":
                self.objects.append(self._ref(child, self._attr(child, "id")))
            elif tag in VALUE_TAGS:
                self.warn(child.pos, f"{child.label()}: a property of the scene itself; ignored")
            else:
                self.warn(child.pos, f"{child.label()}: unknown element; ignored")

    def resolve(self, path: Path, fname: str, node: Node) -> Path:
        """A file named in the scene: relative to ``path``'s folder, then the <path> folders."""
        candidates = [Path(fname).expanduser()] if Path(fname).is_absolute() else \
            [path.parent / fname] + [p / fname for p in self.search_paths]
        for c in candidates:
            if c.is_file():
                return c
        raise error_at(node.pos, f"{node.label()}: file '{fname}' not found (looked for {candidates[0]})")

    def _include(self, node: Node, path: Path) -> None:
        target = self.resolve(path, self._attr(node, "filename"), node)
        if target.resolve() in self._including:
            raise error_at(node.pos, f"<include>: '{node.attrs['filename']}' includes itself")
        self._including.append(target.resolve())
        root = parse_xml(target, str(target))
        if root.tag != "scene":
            raise error_at(root.pos, f"an included file's root element must be <scene>, not <{root.tag}>")
        self._scene_children(root, target)
        self._including.pop()

    def _ref(self, node: Node, ident: str) -> MiObject:
        if ident not in self.ids:
            raise error_at(node.pos, f'{node.label()}: no object with id="{ident}" defined before it')
        return self.ids[ident]

    # -- objects -------------------------------------------------------------------------------

    def _object(self, node: Node, path: Path) -> MiObject:
        obj = MiObject(node.tag, node.attrs.get("type", ""), node.attrs.get("id"), node)
        if not obj.type:
            raise error_at(node.pos, f'{node.label()} needs a "type" attribute')
        if obj.id is not None:
            if obj.id in self.ids:
                raise error_at(node.pos, f'{node.label()}: id "{obj.id}" is already used '
                                         f"(at {self.ids[obj.id].node.pos})")
            self.ids[obj.id] = obj
        for child in node.children:
            self._prepare(child)
            tag = child.tag
            if tag == "default":
                self.params.setdefault(self._attr(child, "name"), self._attr(child, "value"))
                continue
            if tag == "ref":
                target = self._ref(child, self._attr(child, "id"))
                value = Prop("object", target, child)
            elif tag in OBJECT_TAGS or (tag == "spectrum" and "type" in child.attrs):
                value = Prop("object", self._object(child, path), child)
            elif tag in VALUE_TAGS:
                value = self._value(child)
            else:
                self.warn(child.pos, f"{child.label()} in {obj.label()}: unknown element; ignored")
                continue
            pname = child.attrs.get("name")
            if value.kind == "object" and value.value.tag not in ("texture", "spectrum", "volume"):
                pname = None  # Mitsuba finds a shape's bsdf, a sensor's film ... by class, whatever their name
            if pname is None:
                if value.kind != "object":
                    raise error_at(child.pos, f'{child.label()} in {obj.label()} needs a "name" attribute')
                obj.children.append(value.value)
            elif pname in obj.props:
                raise error_at(child.pos, f'{obj.label()}: property "{pname}" given twice '
                                          f"(first at line {obj.props[pname].node.line})")
            else:
                obj.props[pname] = value
        return obj

    # -- values --------------------------------------------------------------------------------

    def _numbers(self, node: Node, text: str, counts, what: str) -> list:
        parts = [p for p in re.split(r"[,\s]+", text.strip()) if p]
        try:
            values = [float(p) for p in parts]
        except ValueError:
            raise error_at(node.pos, f"{node.label()}: {what} must be numbers, got '{text}'") from None
        if len(values) not in counts or not all(math.isfinite(v) for v in values):
            want = " or ".join(str(c) for c in counts)
            raise error_at(node.pos, f"{node.label()}: {what} must be {want} finite numbers, got '{text}'")
        return values

    def _float_attr(self, node: Node, key: str, default=None) -> float:
        if key not in node.attrs:
            if default is None:
                raise error_at(node.pos, f'{node.label()} needs a "{key}" attribute')
            return default
        return self._numbers(node, node.attrs[key], (1,), f'"{key}"')[0]

    def _xyz(self, node: Node, default: float) -> np.ndarray:
        if "value" in node.attrs:
            v = self._numbers(node, node.attrs["value"], (1, 3), '"value"')
            return np.asarray(v * 3 if len(v) == 1 else v, np.float64)
        return np.array([self._float_attr(node, k, default) for k in "xyz"])

    def _value(self, node: Node) -> Prop:
        tag = node.tag
        if tag == "transform":
            return Prop("transform", self._transform(node), node)
        if tag in ("point", "vector"):
            return Prop(tag, self._xyz(node, 0.0), node)
        text = node.attrs.get("value")
        if tag == "spectrum" and text is None and "filename" in node.attrs:
            self.warn(node.pos, f"{node.label()}: spectra from files are not supported; using 0.5")
            return Prop("rgb", (0.5, 0.5, 0.5), node)
        text = self._attr(node, "value")
        if tag == "float":
            return Prop("float", self._numbers(node, text, (1,), '"value"')[0], node)
        if tag == "integer":
            try:
                return Prop("integer", int(text.strip()), node)
            except ValueError:
                raise error_at(node.pos, f"{node.label()}: \"value\" must be an integer, got '{text}'") from None
        if tag == "boolean":
            low = text.strip().lower()
            if low not in ("true", "false"):
                raise error_at(node.pos, f"{node.label()}: \"value\" must be true or false, got '{text}'")
            return Prop("boolean", low == "true", node)
        if tag == "string":
            return Prop("string", text, node)
        if tag == "rgb":
            v = self._numbers(node, text, (1, 3), '"value"')
            rgb = tuple(v * 3 if len(v) == 1 else v)
            if node.attrs.get("_srgb"):
                from ..textures import srgb_to_linear

                rgb = tuple(float(x) for x in srgb_to_linear(np.clip(rgb, 0, 1)))
            return Prop("rgb", rgb, node)
        # spectrum: a constant, or wavelength:value pairs
        if ":" in text:
            pairs = [p for p in re.split(r"[,\s]+", text.strip()) if p]
            try:
                values = [float(p.split(":")[1]) for p in pairs]
            except (ValueError, IndexError):
                raise error_at(node.pos, f"{node.label()}: \"value\" must be 'wavelength:value' pairs, "
                                         f"got '{text}'") from None
            mean = float(np.mean(values))
            self.warn(node.pos, f"{node.label()}: a spectrum given by wavelengths is rendered as the "
                                f"constant {mean:g} (their mean)")
            return Prop("rgb", (mean,) * 3, node)
        v = self._numbers(node, text, (1, 3), '"value"')
        return Prop("rgb", tuple(v * 3 if len(v) == 1 else v), node)

    def _transform(self, node: Node) -> np.ndarray:
        m = np.eye(4)
        for op in node.children:
            self._prepare(op)
            tag = op.tag
            if tag == "translate":
                step = translate(self._xyz(op, 0.0))
            elif tag == "scale":
                s = self._xyz(op, 1.0)
                if (s == 0).any():
                    raise error_at(op.pos, f"<scale>: a zero scale flattens the shape ({s.tolist()})")
                step = scale(s)
            elif tag == "rotate":
                axis = self._xyz(op, 0.0)
                if not np.linalg.norm(axis) > 0:
                    raise error_at(op.pos, "<rotate> needs a non-zero axis (x, y, z or value)")
                step = rotate(axis, self._float_attr(op, "angle"))
            elif tag == "matrix":
                v = self._numbers(op, self._attr(op, "value"), (9, 16), '"value"')
                step = np.eye(4)
                if len(v) == 9:
                    step[:3, :3] = np.reshape(v, (3, 3))
                else:
                    step = np.reshape(v, (4, 4))
            elif tag == "lookat":
                step = self._lookat(op)
            else:
                self.warn(op.pos, f"<{tag}> in <transform>: unknown transform; ignored")
                continue
            m = step @ m
        return m

    def _lookat(self, op: Node) -> np.ndarray:
        origin = self._numbers(op, self._attr(op, "origin"), (3,), '"origin"')
        target = self._numbers(op, self._attr(op, "target"), (3,), '"target"')
        d = np.subtract(target, origin)
        if not np.linalg.norm(d) > 0:
            raise error_at(op.pos, "<lookat>: origin and target are the same point")
        if "up" in op.attrs:
            up = np.asarray(self._numbers(op, op.attrs["up"], (3,), '"up"'))
        else:  # Mitsuba: any vector perpendicular to the viewing direction
            d = d / np.linalg.norm(d)
            up = np.cross(d, [1.0, 0.0, 0.0] if abs(d[0]) < 0.9 else [0.0, 1.0, 0.0])
        if not np.linalg.norm(np.cross(d / np.linalg.norm(d), up)) > 1e-9:
            raise error_at(op.pos, "<lookat>: 'up' is zero or parallel to the viewing direction")
        return look_at_camera_to_world(origin, target, up)
