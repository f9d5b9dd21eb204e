"""Mitsuba 3 XML scene files (``.xml``): the document.

This module reads the XML the way Mitsuba 3's parser does and hands :mod:`.mitsuba_scene` a list
of plugin objects; that module maps them onto our scene (docs/SCENE_FORMAT.md, "Mitsuba 3 XML").

* ``<scene version="...">`` is the root (files of version < 2, Mitsuba 0.6's, get Mitsuba's own
  upgrade: camelCase names become snake_case, ``<lookAt>`` becomes ``<lookat>``, ``<srgb>`` a
  linear ``<rgb>``);
* ``<default name value>`` defines ``$name`` unless the caller did (``--define name=value``
  wins); every attribute value has its ``$name`` substituted; an undefined ``$name`` is an error;
* file names are found as Mitsuba 3's FileResolver finds them (:meth:`Document.resolve`): a
  relative name is tried in each folder of the search path in turn, which starts as the main
  file's folder and then the current directory, and to whose front each ``<path value>`` adds its
  folder (the latest first); ``<include filename>`` splices the included ``<scene>``'s children
  in place;
* ``<alias id as>`` names an object twice (the object must come first, as in Mitsuba 3);
* an object (``bsdf``, ``shape``, ``emitter``, ``texture``, ``sensor``, ``film``, ``rfilter``,
  ``sampler``, ``integrator``, ``medium``, ...) with an ``id`` can be used by ``<ref id>`` (with
  ``name``: as a named property), at the top level or nested, before or after it is declared:
  as Mitsuba 3 does, references are resolved once the whole file and its includes are read (an
  id that no object has is then one error, at the ``<ref>``);
* values: ``float``, ``integer``, ``boolean``, ``string``, ``rgb`` (one number or three, comma-
  or space-separated), ``spectrum`` (a constant, ``wavelength:value`` pairs or a ``.spd`` file: a
  :class:`~.mitsuba_spectrum.Spectrum`, made RGB where it is used, as Mitsuba's RGB variants do),
  ``point`` / ``vector`` (``x``/``y``/``z`` or ``value``) and ``transform`` (``translate``,
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
from .mitsuba_spectrum import Spectrum, parse_pairs, read_spd

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


def _cwd() -> list[Path]:
    try:
        return [Path.cwd()]
    except OSError:  # the current directory was removed
        return []


@dataclass(eq=False)
class _Ref:
    """A ``<ref id>`` read before the object it names is known."""

    ident: str
    node: Node
    tag: str = "ref"


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

    def choice(self, name, choices, note=""):
        """The <string> ``name``, one of ``choices`` (the first is the default); another is an error,
        its message ended by ``note``."""
        value = self.string(name, choices[0])
        if value not in choices:
            listed = ", ".join(f'"{c}"' for c in choices[:-1]) + f' or "{choices[-1]}"'
            raise error_at(self.props[name].node.pos, f'{self.label()}: {name} must be {listed}, got "{value}"{note}')
        return value

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
        # Mitsuba's FileResolver: the main file's folder, then the current directory (load_file
        # prepends the folder to the process's resolver, which starts with the current directory)
        self.search_path: list[Path] = [path.parent] + _cwd()
        self.objects: list[MiObject] = []
        self._including: list[Path] = [path.resolve()]
        self.version = None
        root = parse_xml(path, name)
        if root.tag != "scene":
            raise error_at(root.pos, f"the root element must be <scene>, not <{root.tag}>")
        self._check_version(root)
        self._pending: list = []  # (its owner, None: the scene; the <ref> placeholder), in document order
        self.referenced: set = set()  # the objects some <ref> or <alias> names
        self._scene_children(root, path)
        self._resolve_references()
        # plugins (meshes, bitmaps, envmaps, ...) resolve their files once the whole document is
        # read, through the main file's search path: an included file's own <path>s have gone
        self.file_search_path = list(self.search_path)

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
                self._add_path(child, path)
            elif tag == "alias":
                self._alias(child)
            elif tag in OBJECT_TAGS and tag != "scene":
                self.objects.append(self._object(child, path))
            elif tag == "ref":
                self.objects.append(self._placeholder(None, child))
            elif tag in VALUE_TAGS:
                self.warn(child.pos, f"{child.label()}: a property of the scene itself; ignored")
            else:
                self.warn(child.pos, f"{child.label()}: unknown element; ignored")

    # -- files: Mitsuba 3's FileResolver (src/core/fresolver.cpp, src/core/parser.cpp) ---------------

    @staticmethod
    def _search(fname: str, folders) -> Path | None:
        """Mitsuba's ``FileResolver::resolve``: an absolute name is itself; a relative one is
        tried in each folder in order, the first that exists wins; None if none does."""
        name = Path(fname)
        if name.is_absolute():
            return name if name.exists() else None
        for folder in folders:
            if (folder / name).exists():
                return folder / name
        return None

    def _not_found(self, node: Node, what: str, fname: str, folders) -> Exception:
        where = "" if Path(fname).is_absolute() else \
            " (searched " + ", ".join(f"{f}{'' if str(f).endswith('/') else '/'}" for f in folders) + ")"
        return error_at(node.pos, f"{node.label()}: {what} '{fname}' not found{where}")

    def resolve(self, fname: str, node: Node) -> Path:
        """A file that a plugin names (a mesh, bitmap, envmap, ...): Mitsuba resolves it when
        the plugin is made, after the whole document is read, through the main file's search
        path (its <path> folders, latest first, then its folder, then the current directory),
        whichever file the plugin is written in."""
        found = self._search(fname, self.file_search_path)
        if found is None:
            raise self._not_found(node, "file", fname, self.file_search_path)
        return found

    def _add_path(self, node: Node, path: Path) -> None:
        """``<path value>``: a relative folder is first looked for beside the file that names
        it, then through the search path; it goes to the front of the search path (of the
        include it is written in, for an included file)."""
        value = self._attr(node, "value")
        folder = Path(value)
        if not folder.is_absolute():
            beside = path.parent / folder
            folder = beside if beside.exists() else (self._search(value, self.search_path) or beside)
        if not folder.exists():
            raise error_at(node.pos, f'<path value="{value}">: folder not found (looked for {folder})')
        self.search_path.insert(0, folder)

    def _include(self, node: Node, path: Path) -> None:
        """Mitsuba parses an included file with a copy of the search path that has the
        including file's folder in front, and drops the copy after it."""
        fname = self._attr(node, "filename")
        outer = self.search_path
        self.search_path = [path.parent] + outer
        try:
            target = self._search(fname, self.search_path)
            if target is None:
                raise self._not_found(node, "file", fname, self.search_path)
            if target.resolve() in self._including:
                raise error_at(node.pos, f"<include>: '{fname}' includes itself")
            self._including.append(target.resolve())
            root = parse_xml(target, str(target))
            if root.tag != "scene":
                raise error_at(root.pos, f"an included file's root element must be <scene>, not <{root.tag}>")
            self._scene_children(root, target)
            self._including.pop()
        finally:
            self.search_path = outer

    # -- references: resolved once the whole document is read, as Mitsuba 3 resolves them ----------

    def _alias(self, node: Node) -> None:
        """``<alias id as>``: ``as`` names the object ``id`` names, which (as in Mitsuba 3) must come
        before it."""
        ident = self._attr(node, "id")
        if ident not in self.ids:
            raise error_at(node.pos, f'{node.label()}: no object with id="{ident}" defined before it '
                                     "(an alias must follow its object)")
        self.ids[self._attr(node, "as")] = self.ids[ident]
        self.referenced.add(self.ids[ident])

    def _placeholder(self, owner, node: Node) -> "_Ref":
        """A ``<ref>`` to fill in once every id is known (:meth:`_resolve_references`)."""
        ref = _Ref(self._attr(node, "id"), node)
        self._pending.append((owner, ref))
        return ref

    def _target(self, ident: str, node: Node) -> MiObject:
        if ident not in self.ids:
            raise error_at(node.pos, f'{node.label()}: no object with id="{ident}" defined in the file or its '
                                     "includes")
        return self.ids[ident]

    def _resolve_references(self) -> None:
        """Every ``<ref>`` replaced by its object, at its place: a top-level one among the scene's
        objects, a nested one as its owner's child or, for a texture, spectrum, volume or medium
        with a ``name``, as that named property (as :meth:`_object` files a nested object)."""
        targets = {}
        for owner, ref in self._pending:
            target = targets[id(ref)] = self._target(ref.ident, ref.node)
            self.referenced.add(target)
            if owner is None:
                continue
            pname = ref.node.attrs.get("name")
            if target.tag not in ("texture", "spectrum", "volume", "medium"):
                pname = None
            k = next(i for i, c in enumerate(owner.children) if c is ref)
            if pname is None:
                owner.children[k] = target
                continue
            del owner.children[k]
            if pname in owner.props:
                raise error_at(ref.node.pos, f'{owner.label()}: property "{pname}" given twice '
                                             f"(first at line {owner.props[pname].node.line})")
            owner.props[pname] = Prop("object", target, ref.node)
        self.objects = [targets[id(o)] if isinstance(o, _Ref) else o for o in self.objects]

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
            if tag == "ref":  # filed where it belongs once its object is known
                obj.children.append(self._placeholder(obj, child))
                continue
            elif tag in OBJECT_TAGS or (tag == "spectrum" and "type" in child.attrs):
                value = Prop("object", self._object(child, path), child)
            elif tag in VALUE_TAGS:
                value = self._value(child)
            else:
                self.warn(child.pos, f"{child.label()} in {obj.label()}: unknown element; ignored")
                continue
            pname = child.attrs.get("name")
            if value.kind == "object" and value.value.tag not in ("texture", "spectrum", "volume", "medium"):
                pname = None  # Mitsuba finds a shape's bsdf, a sensor's film ... by class, whatever their name
            # (a shape's media by name: interior, exterior)
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
        if tag == "spectrum" and "filename" in node.attrs:
            if text is not None:
                raise error_at(node.pos, f'{node.label()}: give "value" or "filename", not both')
            return Prop("spectrum", self._spectrum_file(node), node)
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
        # spectrum: wavelength:value pairs, or a constant (three numbers: an RGB, which Mitsuba 3
        # itself rejects)
        if ":" in text:
            try:
                return Prop("spectrum", parse_pairs(text), node)
            except ValueError as exc:
                raise error_at(node.pos, f"{node.label()}: \"value\" must be 'wavelength:value' pairs in "
                                         f"increasing wavelength: {exc}") from None
        v = self._numbers(node, text, (1, 3), '"value"')
        if len(v) == 3:
            return Prop("rgb", tuple(v), node)
        return Prop("spectrum", Spectrum(None, (v[0],)), node)

    def _spectrum_file(self, node: Node) -> Spectrum:
        """``<spectrum filename>``: Mitsuba reads it while parsing, through the search path of
        the file it is written in."""
        fname = node.attrs["filename"]
        found = self._search(fname, self.search_path)
        if found is None:
            raise self._not_found(node, "spectrum file", fname, self.search_path)
        try:
            return read_spd(found)
        except OSError as exc:
            raise error_at(node.pos, f"{node.label()}: cannot read '{fname}' ({exc.strerror or exc})") from None
        except ValueError as exc:
            raise error_at(node.pos, f"{node.label()}: '{fname}': {exc}") from None

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
                step = rotate(axis, self._float_attr(op, "angle"), normalize=False)  # as Mitsuba: the axis as given
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
