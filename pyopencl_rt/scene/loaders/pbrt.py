"""pbrt-v4 scene files (``.pbrt``): the tokenizer and the directives with their parameter lists.

The grammar (pbrt-v4's "File format" documentation): ``#`` starts a comment; a token is a quoted
string (with ``\\"`` escapes), ``[`` or ``]``, or a run of other non-blank characters (numbers,
``true``/``false``, directive names).  A directive is a capitalised word followed by its fixed
arguments (numbers, strings or a bracketed list) and, for most, a parameter list of
``"type name" value`` pairs, where the value is one token or a bracketed list.  ``Include`` and
``Import`` read another file in place (relative to the including file's folder, then the main
file's): as pbrt-v4's parser streams the tokens of its files, the included file's tokens take the
place of the two, so a parameter list may go on after the included file ends.  A file compressed
with gzip (``.pbrt.gz``) is read through it.  :mod:`.pbrt_scene` gives the directives their
meaning.

Every malformed input raises a :class:`~.builder.SceneFormatError` naming the file and line.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from .builder import SceneFormatError, error_at

# ``pyopencl-rt bench pbrt-scenes``'s probe of a scene whose files are not all there: when True, a
# missing file skips what names it (an Include, a directive) with a warning that starts with
# MISSING_SKIPPED, so that what the rest of the scene asks for can be seen.  Never set by a render.
SKIP_MISSING_FILES = False
MISSING_SKIPPED = "missing file skipped: "


class MissingFile(SceneFormatError):
    """A file the scene names that is not there (one error line, as any SceneFormatError)."""


def skipped_missing(exc) -> None:
    """The probe's warning for a missing file it skips (:data:`SKIP_MISSING_FILES`)."""
    import warnings

    from ...errors import one_line

    warnings.warn(MISSING_SKIPPED + one_line(exc), stacklevel=2)

_TOKEN = re.compile(r'[ \t\r\f\v]+|\n|#[^\n]*|"(?:[^"\\\n]|\\.)*"|\[|\]|[^\s\[\]"#]+|"')
_ESCAPES = {"n": "\n", "t": "\t", "b": "\b", "f": "\f", "r": "\r", "\\": "\\", "'": "'", '"': '"'}

# directive -> fixed arguments: 'n<k>' k numbers (or a bracketed list of k), 's' a string,
# 'w' a bare word, 's?' an optional string; then 'p': a parameter list
SIGNATURES = {
    "Identity": "", "Translate": "n3", "Scale": "n3", "Rotate": "n4", "LookAt": "n9",
    "Transform": "n16", "ConcatTransform": "n16", "CoordinateSystem": "s", "CoordSysTransform": "s",
    "TransformTimes": "n2", "ActiveTransform": "w", "ReverseOrientation": "",
    "Camera": "s p", "Sampler": "s p", "Film": "s p", "PixelFilter": "s p", "Integrator": "s p",
    "Accelerator": "s p", "ColorSpace": "s", "Option": "p", "WorldBegin": "", "WorldEnd": "",
    "AttributeBegin": "", "AttributeEnd": "", "TransformBegin": "", "TransformEnd": "",
    "Attribute": "s p", "Shape": "s p", "Material": "s p", "MakeNamedMaterial": "s p", "NamedMaterial": "s",
    "Texture": "s s s p", "LightSource": "s p", "AreaLightSource": "s p", "MakeNamedMedium": "s p",
    "MediumInterface": "s s?", "ObjectBegin": "s", "ObjectEnd": "", "ObjectInstance": "s",
    "Include": "s", "Import": "s",
}
PARAM_TYPES = {"integer", "float", "point2", "vector2", "point3", "vector3", "normal3", "normal", "point",
               "vector", "color", "rgb", "spectrum", "bool", "string", "texture", "blackbody"}


@dataclass
class Token:
    kind: str  # 'str', 'word', '[', ']'
    text: str
    file: str
    line: int

    @property
    def pos(self) -> str:
        return f"{self.file}:{self.line}"


def tokenize(text: str, name: str) -> list[Token]:
    tokens, line = [], 1
    for m in _TOKEN.finditer(text):
        t = m.group()
        if t == "\n":
            line += 1
        elif t[0] in " \t\r\f\v#":
            continue
        elif t[0] == '"':
            if len(t) < 2 or not t.endswith('"'):
                raise error_at(f"{name}:{line}", "unterminated string (a '\"' without its closing '\"')")
            tokens.append(Token("str", re.sub(r"\\(.)", lambda e: _ESCAPES.get(e.group(1), e.group(1)), t[1:-1]),
                                name, line))
        elif t in "[]":
            tokens.append(Token(t, t, name, line))
        else:
            tokens.append(Token("word", t, name, line))
    return tokens


@dataclass
class Param:
    type: str
    name: str
    values: list
    pos: str
    used: bool = False


@dataclass
class Params:
    """A directive's parameter list; accessors mark what was read so the rest can be warned about."""

    items: dict = field(default_factory=dict)

    def __contains__(self, name) -> bool:
        return name in self.items

    def get(self, name) -> Param | None:
        p = self.items.get(name)
        if p is not None:
            p.used = True
        return p

    def _values(self, name, types, n=None):
        p = self.get(name)
        if p is None:
            return None, None
        if p.type not in types:
            raise error_at(p.pos, f'"{p.type} {name}": expected a {" or ".join(sorted(types))} parameter')
        if n is not None and len(p.values) != n:
            raise error_at(p.pos, f'"{p.type} {name}" needs {n} value{"s" if n > 1 else ""}, got {len(p.values)}')
        return p.values, p

    def numbers(self, name, types=("float",), n=None, default=None):
        values, p = self._values(name, set(types) | ({"float"} if "integer" in types else set()), n)
        if values is None:
            return default
        if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
            raise error_at(p.pos, f'"{p.type} {name}" needs numbers')
        return values

    def float(self, name, default=None):
        v = self.numbers(name, ("float", "integer"), 1)
        return default if v is None else float(v[0])

    def integer(self, name, default=None):
        v = self.numbers(name, ("integer",), 1)
        if v is not None and not float(v[0]).is_integer():
            raise error_at(self.items[name].pos, f'"integer {name}" needs an integer, got {v[0]}')
        return default if v is None else int(v[0])

    def boolean(self, name, default=None):
        values, p = self._values(name, {"bool"}, 1)
        if values is None:
            return default
        v = values[0]
        if isinstance(v, str) and v in ("true", "false"):
            v = v == "true"
        if not isinstance(v, bool):
            raise error_at(p.pos, f'"bool {name}" needs true or false, got {v!r}')
        return v

    def string(self, name, default=None, types=("string",)):
        values, p = self._values(name, set(types), 1)
        if values is None:
            return default
        if not isinstance(values[0], str):
            raise error_at(p.pos, f'"{p.type} {name}" needs a quoted string')
        return values[0]

    def unused(self) -> list[Param]:
        return [p for p in self.items.values() if not p.used]


def one_line_at(pos, what) -> str:
    return str(error_at(pos, what))


@dataclass
class Directive:
    name: str
    args: list
    params: Params
    pos: str


def pbrt_path(pos: str, folder: Path, fname: str, what: str) -> Path:
    """``folder / fname`` (``folder``: the scene file's), which must be a file: otherwise an error at
    ``pos`` that ``what`` (the directive, such as 'Shape "plymesh"') names."""
    path = folder / fname
    if not path.is_file():
        raise MissingFile(one_line_at(pos, f"{what}: file '{fname}' not found (looked for {path})"))
    return path


def pbrt_file(d: Directive, folder: Path, what: str, needs: str | None = None) -> tuple[str, Path]:
    """The directive ``d``'s "string filename" and its :func:`pbrt_path`; without the parameter, an
    error that ``needs`` (``what`` if not given) needs it."""
    fname = d.params.string("filename")
    if fname is None:
        raise error_at(d.pos, f'{needs or what} needs "string filename"')
    return fname, pbrt_path(d.pos, folder, fname, what)


class _Stream:
    """The tokens of a file and of the files it includes, as one stream (pbrt-v4's parser reads
    them so: an ``Include``d file's tokens take the place of the directive, and a directive's
    parameter list may go on after the included file ends).  Indexed from the start of the
    directive being read (:meth:`drop` forgets what was read); ``None`` past the end."""

    def __init__(self, tokens):
        self._source = tokens
        self._buffer: list[Token] = []

    def __getitem__(self, i):
        while len(self._buffer) <= i:
            tok = next(self._source, None)
            if tok is None:
                return None
            self._buffer.append(tok)
        return self._buffer[i]

    def drop(self, n: int) -> None:
        del self._buffer[:n]


class Parser:
    """Directives of a pbrt file and the files it includes, in order (:meth:`directives`)."""

    def __init__(self, path: Path, name: str):
        self.main_dir = path.parent
        self.path, self.name = path, name

    def directives(self):
        stream = _Stream(self._tokens(self.path, self.name, []))
        while stream[0] is not None:
            tok = stream[0]
            if tok.kind != "word" or not tok.text[:1].isalpha():
                raise error_at(tok.pos, f"expected a directive (such as Shape or AttributeBegin), got {_show(tok)}")
            if tok.text not in SIGNATURES:
                raise error_at(tok.pos, f"unknown directive '{tok.text}'")
            d, i = self._directive(stream, 0)
            stream.drop(i)
            yield d

    def _read(self, path: Path, name: str) -> list[Token]:
        """The tokens of one file; a gzip-compressed one (``.gz``, or the gzip magic number) is
        read through gzip, as pbrt-v4 reads ``.pbrt.gz``."""
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise error_at(name, f"cannot read ({exc.strerror or exc})") from None
        if data[:2] == b"\x1f\x8b" or path.suffix.lower() == ".gz":
            data = gunzip(data, name)
        return tokenize(data.decode("utf-8", errors="replace"), name)

    def _tokens(self, path: Path, name: str, stack: list):
        """The tokens of ``path`` with each ``Include``/``Import "file"`` replaced by that file's."""
        tokens = self._read(path, name)
        i = 0
        while i < len(tokens):
            tok = tokens[i]
            if tok.kind == "word" and tok.text in ("Include", "Import"):
                if i + 1 >= len(tokens) or tokens[i + 1].kind != "str":
                    got = _show(tokens[i + 1]) if i + 1 < len(tokens) else "the end of the file"
                    raise error_at(tok.pos, f"{tok.text} needs a quoted string, got {got}")
                fname = tokens[i + 1].text
                try:
                    target = self._locate(fname, path, tok.pos)
                except MissingFile as exc:
                    if not SKIP_MISSING_FILES:
                        raise
                    skipped_missing(exc)
                    i += 2  # and the parameters that went on after the missing file's last directive
                    while i < len(tokens) and not (tokens[i].kind == "word" and tokens[i].text[:1].isalpha()
                                                   and tokens[i].text not in ("true", "false")):
                        i += 1
                    continue
                if target.resolve() in stack + [path.resolve()]:
                    raise error_at(tok.pos, f"{tok.text} '{fname}': the file includes itself")
                yield from self._tokens(target, str(target), stack + [path.resolve()])
                i += 2
                continue
            yield tok
            i += 1

    def _locate(self, fname: str, path: Path, pos: str) -> Path:
        for base in (path.parent, self.main_dir):
            candidate = base / fname
            if candidate.is_file():
                return candidate
        raise MissingFile(one_line_at(pos, f"file '{fname}' not found (looked for {path.parent / fname})"))

    def _directive(self, tokens, i):
        head = tokens[i]
        i += 1
        args = []
        for spec in SIGNATURES[head.text].split():
            if spec == "p":
                continue
            if spec.startswith("n"):
                n = int(spec[1:])
                values, i = self._numbers(tokens, i, n, head)
                args.append(values)
            elif spec in ("s", "s?"):
                if tokens[i] is not None and tokens[i].kind == "str" and not _is_decl(tokens, i):
                    args.append(tokens[i].text)
                    i += 1
                elif spec == "s":
                    got = _show(tokens[i]) if tokens[i] is not None else "the end of the file"
                    raise error_at(head.pos, f"{head.text} needs a quoted string, got {got}")
            elif spec == "w":
                if tokens[i] is None or tokens[i].kind != "word":
                    raise error_at(head.pos, f"{head.text} needs a word")
                args.append(tokens[i].text)
                i += 1
        params = Params()
        if SIGNATURES[head.text].endswith("p"):
            while tokens[i] is not None and tokens[i].kind == "str":
                param, i = self._param(tokens, i)
                if param.name in params.items:
                    raise error_at(param.pos, f'parameter "{param.name}" given twice')
                params.items[param.name] = param
        return Directive(head.text, args, params, head.pos), i

    def _numbers(self, tokens, i, n, head):
        bracket = tokens[i] is not None and tokens[i].kind == "["
        if bracket:
            i += 1
        values = []
        while len(values) < n and tokens[i] is not None and tokens[i].kind == "word" and tokens[i].text not in SIGNATURES:
            values.append(_number(tokens[i], f"{head.text} needs {n} numbers"))
            i += 1
        if len(values) != n:
            raise error_at(head.pos, f"{head.text} needs {n} numbers, got {len(values)}")
        if bracket:
            if tokens[i] is None or tokens[i].kind != "]":
                raise error_at(head.pos, f"{head.text}: expected ']' after {n} numbers")
            i += 1
        return values, i

    def _param(self, tokens, i):
        decl = tokens[i]
        parts = decl.text.split()
        if len(parts) != 2:
            raise error_at(decl.pos, f'bad parameter declaration "{decl.text}" (expected "type name")')
        ptype, pname = parts
        if ptype not in PARAM_TYPES:
            raise error_at(decl.pos, f'unknown parameter type "{ptype}" in "{decl.text}"')
        i += 1
        if tokens[i] is None:
            raise error_at(decl.pos, f'"{decl.text}" has no value')
        raw = []
        if tokens[i].kind == "[":
            i += 1
            while tokens[i] is not None and tokens[i].kind != "]":
                if tokens[i].kind == "[" or tokens[i].text in SIGNATURES:
                    raise error_at(decl.pos, f'"{decl.text}": a \'[\' without its \']\'')
                raw.append(tokens[i])
                i += 1
            if tokens[i] is None:
                raise error_at(decl.pos, f'"{decl.text}": a \'[\' without its \']\'')
            i += 1
        elif tokens[i].kind in ("str", "word"):
            raw.append(tokens[i])
            i += 1
        else:
            raise error_at(tokens[i].pos, f'"{decl.text}": expected a value, got {_show(tokens[i])}')
        values = []
        for t in raw:
            if t.kind == "str":
                values.append(t.text)
            elif t.text in ("true", "false"):
                values.append(t.text == "true")
            else:
                values.append(_number(t, f'"{decl.text}": expected numbers'))
        return Param(ptype, pname, values, decl.pos), i


def gunzip(data: bytes, name: str) -> bytes:
    """The contents of gzip-compressed ``data`` (one error line naming ``name`` when it is not)."""
    import gzip
    import zlib

    try:
        return gzip.decompress(data)
    except (OSError, EOFError, zlib.error) as exc:
        raise error_at(name, f"not a valid gzip file ({exc})") from None


def _is_decl(tokens, i) -> bool:
    """Whether the string at i starts a parameter ("type name" followed by a value)."""
    parts = tokens[i].text.split()
    return len(parts) == 2 and parts[0] in PARAM_TYPES


def _number(tok: Token, what: str):
    try:
        v = float(tok.text)
    except ValueError:
        raise error_at(tok.pos, f"{what}, got {_show(tok)}") from None
    if v != v or v in (float("inf"), float("-inf")):
        raise error_at(tok.pos, f"{what}, got {_show(tok)}")
    return int(v) if re.fullmatch(r"[+-]?\d+", tok.text) else v


def _show(tok: Token) -> str:
    return f"'{tok.text}'" if tok.kind != "str" else f'"{tok.text}"'
