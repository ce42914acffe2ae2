"""Parse the YAML, JSON and .npz files users give, within limits checked before any work.

Every loader of the project reads through here (with :func:`~aero_dva.text_input.
read_text_input` for the bytes), so a file that cannot be used is refused in one sentence that
names it and the limit, never with a RecursionError, an OverflowError or an allocation of
terabytes. The limits (:data:`LIMITS`, quoted in docs/reliability.md):

* text files (YAML, JSON): at most ``MAX_TEXT_BYTES`` (4 MiB), UTF-8, no NUL byte;
* nesting: at most :data:`MAX_DEPTH` levels of lists/mappings (the deepest shipped file has 3);
* YAML aliases: at most :data:`MAX_ALIASES` (a file of aliases of aliases expands without end);
* integers: magnitude below 2**63 (a 400-digit integer is no physical quantity or seed);
* JSON numbers: finite (NaN, Infinity and 1e999 are refused where they are read);
* .npz/.npy arrays: the shape declared in each header must fit in the bytes stored for it.
"""
from __future__ import annotations

import json
import re
import zipfile
from pathlib import Path

import numpy as np
import yaml

from aero_dva.text_input import MAX_TEXT_BYTES, InputFileError, read_text_input

__all__ = ["LIMITS", "MAX_ALIASES", "MAX_ABS_INT", "MAX_DEPTH", "check_file_header",
           "check_npz", "finite_float",
           "parse_json", "parse_yaml", "read_json", "read_yaml"]

#: Deepest nesting of lists and mappings read (the deepest shipped file has 3 levels).
MAX_DEPTH = 32
#: Most YAML aliases (``*name``) read in one file.
MAX_ALIASES = 64
#: Integers of this magnitude or more are refused (they do not fit in 64 bits).
MAX_ABS_INT = 2**63
#: The limits in one sentence, for ``--help`` texts and error hints.
LIMITS = (f"YAML and JSON files at most {MAX_TEXT_BYTES // 2**20} MiB of UTF-8 text, "
          f"{MAX_DEPTH} levels of nesting, {MAX_ALIASES} aliases, integers below 2**63, "
          "finite JSON numbers")

_HEADER_READERS = {(1, 0): np.lib.format.read_array_header_1_0,
                   (2, 0): np.lib.format.read_array_header_2_0}
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')
_BRACKET = re.compile(r"[\[\]{}]")


def _where(path, what: str) -> str:
    return f"{what} {str(path)!r}"


def finite_float(value, name: str, error: type[ValueError] = InputFileError) -> float:
    """``value`` (an int or float, not a bool) as a finite float; ``error`` naming ``name``
    otherwise (a 400-digit integer is refused here, not left to raise OverflowError)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise error(f"{name} must be a number, got {value!r}"[:200])
    if isinstance(value, int) and abs(value) >= MAX_ABS_INT:
        raise error(f"{name}: an integer of {len(str(abs(value)))} digits is out of range "
                    "(at most 2**63)")
    number = float(value)
    if not np.isfinite(number):
        raise error(f"{name} must be finite, got {number}")
    return number


def _check_tree(node, where: str, error) -> None:
    """Integers out of range anywhere in a parsed document (iteratively: depth is bounded)."""
    stack, seen = [node], set()
    while stack:
        item = stack.pop()
        if isinstance(item, (dict, list)):
            if id(item) in seen:  # an alias: a node met twice (or a list holding itself)
                continue
            seen.add(id(item))
            stack.extend([*item.keys(), *item.values()] if isinstance(item, dict) else item)
        elif isinstance(item, int) and not isinstance(item, bool) and abs(item) >= MAX_ABS_INT:
            raise error(f"{where}: an integer of {len(str(abs(item)))} digits is out of range "
                        "(integers must be below 2**63)")


#: libyaml's parser when PyYAML was built with it (the wheels are): the same safe types as
#: ``yaml.SafeLoader``, parsed in C (a bag's metadata.yaml took about 0.1 s in pure Python).
_SAFE_LOADER = getattr(yaml, "CSafeLoader", yaml.SafeLoader)


def parse_yaml(text: str, where: str, error: type[ValueError] = InputFileError):
    """The YAML document ``text`` (safe types only), its nesting and aliases checked on the
    event stream before any object is built; ``error`` starting with ``where`` otherwise."""
    open_anchors: list = []  # anchor of each list/mapping being read, outermost first
    aliases = 0
    try:
        for event in yaml.parse(text, Loader=_SAFE_LOADER):
            if isinstance(event, (yaml.SequenceStartEvent, yaml.MappingStartEvent)):
                open_anchors.append(event.anchor)
                if len(open_anchors) > MAX_DEPTH:
                    raise error(f"{where}: nested more than {MAX_DEPTH} levels deep (line "
                                f"{event.start_mark.line + 1}); at most {MAX_DEPTH} are read")
            elif isinstance(event, (yaml.SequenceEndEvent, yaml.MappingEndEvent)):
                open_anchors.pop()
            elif isinstance(event, yaml.AliasEvent):
                aliases += 1
                if aliases > MAX_ALIASES:
                    raise error(f"{where}: more than {MAX_ALIASES} aliases (*name); at most "
                                f"{MAX_ALIASES} are read")
                if event.anchor in open_anchors:
                    raise error(f"{where}: the alias *{event.anchor} (line "
                                f"{event.start_mark.line + 1}) is inside the node it names; "
                                "a value cannot contain itself")
        data = yaml.load(text, Loader=_SAFE_LOADER)  # a safe loader
    except yaml.YAMLError as exc:
        detail = " ".join(str(exc).split())  # the parser's message spans several lines
        raise error(f"{where}: not valid YAML ({detail[:300]})") from None
    except (ValueError, OverflowError) as exc:
        if isinstance(exc, error):
            raise
        # e.g. an integer of more than 4300 digits, a date out of range
        raise error(f"{where}: a value cannot be read ({str(exc)[:200]})") from None
    _check_tree(data, where, error)
    return data


def _json_depth(text: str) -> int:
    """Deepest bracket nesting of a JSON text, strings left out (no recursion, no parse)."""
    brackets = _BRACKET.findall(_STRING.sub("", text))
    if not brackets:
        return 0
    steps = np.array([1 if b in "[{" else -1 for b in brackets], dtype=np.int64)
    return int(np.cumsum(steps).max())


def parse_json(text: str, where: str, error: type[ValueError] = InputFileError, *,
               nonfinite: bool = False):
    """The JSON document ``text``: nesting at most :data:`MAX_DEPTH`, integers below 2**63,
    every number finite (``nonfinite``: NaN, Infinity and 1e999 are left to the caller, which
    checks each field by name); ``error`` starting with ``where`` otherwise."""
    depth = _json_depth(text)
    if depth > MAX_DEPTH:
        raise error(f"{where}: nested {depth} levels deep; at most {MAX_DEPTH} are read")

    def integer(token: str) -> int:
        if len(token.lstrip("-")) > 19 or abs(int(token)) >= MAX_ABS_INT:
            raise error(f"{where}: the integer {token[:20]}... ({len(token)} digits) is out "
                        "of range (integers must be below 2**63)")
        return int(token)

    def real(token: str) -> float:
        number = float(token)
        if not nonfinite and not np.isfinite(number):
            raise error(f"{where}: the number {token[:30]} is out of the float range")
        return number

    def constant(token: str):
        if nonfinite:
            return float(token)
        raise error(f"{where}: {token} is not a finite number (JSON has none)")

    try:
        return json.loads(text, parse_int=integer, parse_float=real, parse_constant=constant)
    except json.JSONDecodeError as exc:
        raise error(f"{where}: not valid JSON ({exc})") from None


def check_file_header(data, fail, file_format: str, version: int, units: dict | None = None,
                      *, what: str = "the top level") -> None:
    """Check the header fields of a project file read as a JSON object.

    ``fail(text)`` returns the exception to raise (it names the file); ``what`` names the
    object in the message. ``units``: checked when given.
    """
    if not isinstance(data, dict):
        raise fail(f"{what} is not a JSON object")
    if data.get("format") != file_format:
        raise fail(f"format is {data.get('format')!r}, expected {file_format!r}")
    if data.get("version") != version:
        raise fail(f"version {data.get('version')!r} is not {version}")
    if units is not None and data.get("units") != units:
        raise fail(f"units are {data.get('units')!r}, expected {units!r}")


def read_yaml(path, what: str = "file", error: type[ValueError] = InputFileError):
    """Read and parse the YAML file ``path`` (:func:`read_text_input` then :func:`parse_yaml`)."""
    return parse_yaml(read_text_input(path, what, error=error), _where(path, what), error)


def read_json(path, what: str = "file", error: type[ValueError] = InputFileError):
    """Read and parse the JSON file ``path`` (:func:`read_text_input` then :func:`parse_json`)."""
    return parse_json(read_text_input(path, what, error=error), _where(path, what), error)


def check_npz(path, what: str = "file", error: type[ValueError] = InputFileError,
              max_bytes: int = 1 << 30) -> dict[str, tuple[tuple[int, ...], np.dtype]]:
    """Shape and dtype of every array of the .npz archive ``path``, read from the headers
    only; each declared array must fit in the bytes stored for it (so loading it allocates
    no more than the file holds) and in ``max_bytes``. Object arrays are refused."""
    where = _where(path, what)
    path = Path(path)
    if not path.is_file():
        raise error(f"{where}: no such file")
    found = {}
    try:
        with zipfile.ZipFile(path) as archive:
            for info in archive.infolist():
                if not info.filename.endswith(".npy"):
                    continue
                name = info.filename[:-4]
                with archive.open(info) as member:
                    version = np.lib.format.read_magic(member)
                    if version not in _HEADER_READERS:
                        raise error(f"{where}: array {name!r} has .npy format version "
                                    f"{version}; versions 1 and 2 are read")
                    shape, _, dtype = _HEADER_READERS[version](member)
                    header_bytes = member.tell()
                if dtype.hasobject:
                    raise error(f"{where}: array {name!r} holds Python objects (refused "
                                "without pickle: only numbers and text are read)")
                needed = int(np.prod(shape, dtype=object)) * dtype.itemsize
                stored = info.file_size - header_bytes
                # an empty axis makes an empty array, but numpy still refuses the other axes'
                # product past its index range: bound that too
                spanned = int(np.prod([max(n, 1) for n in shape], dtype=object))
                if needed > stored or max(needed, spanned) > max_bytes:
                    raise error(f"{where}: array {name!r} declares shape {shape} "
                                f"({needed:,} bytes) but {stored:,} bytes are stored (at most "
                                f"{max_bytes:,} read)")
                found[name] = (shape, dtype)
    except Exception as exc:  # numpy's header parser fails on damaged bytes in many ways
        if isinstance(exc, error):
            raise
        raise error(f"{where}: not a readable .npz archive ({str(exc)[:200]})") from None
    return found
