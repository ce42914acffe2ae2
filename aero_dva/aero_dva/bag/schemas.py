"""Message definitions read from the .msg files: the schema text a bag stores, the typestore
that (de)serializes the messages, and the parsed fields the batch encoder lays out.

This is the one place message layouts come from. The project's own interfaces are the .msg
files under ``interfaces/<pkg>/msg/`` (``dva_msgs`` is a link to ``ros_ws/src/dva_msgs``);
other packages' files are found in ``$AMENT_PREFIX_PATH/<prefix>/share`` and the environment's
``share/`` (the ROS 2 wheels install them there). Serialization is ``rosbags``' typestore
(``Stores.ROS2_JAZZY`` plus every interface file registered with ``get_types_from_msg``).
"""
from __future__ import annotations

import os
import re
import sys
from collections.abc import Sequence
from functools import lru_cache
from pathlib import Path

from rosbags.interfaces import Nodetype
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

__all__ = [
    "INTERFACES",
    "MessageDefinitionNotFound",
    "Nodetype",
    "find_message_file",
    "message_definition",
    "message_fields",
    "message_text",
    "normalize_type_name",
    "parsed_types",
    "schema_typestore",
    "typestore",
    "typestore_of",
]

#: The project's interface packages: ``<pkg>/msg/<Type>.msg``.
INTERFACES = Path(__file__).resolve().parent / "interfaces"

_SEPARATOR = "=" * 80 + "\n"
_PRIMITIVES = frozenset(
    "bool byte char float32 float64 int8 uint8 int16 uint16 int32 uint32 int64 uint64 string "
    "wstring".split()
)
# First token of each line of a .msg file: the field (or constant) type, as rosbag2 parses it.
_FIELD_TYPE = re.compile(r"(?:^|\n)\s*([a-zA-Z0-9_/]+)(?:\[[^\]]*\])?\s+")
_NAME = r"[a-zA-Z][a-zA-Z0-9_]*"
_TYPE_NAME = re.compile(rf"^({_NAME})/(?:(msg)/)?({_NAME})$")


class MessageDefinitionNotFound(LookupError):
    """No .msg file for a message type in any search location, nor a built-in definition."""


def normalize_type_name(type_name: str) -> str:
    """``pkg/Type`` or ``pkg/msg/Type`` -> ``pkg/msg/Type`` (other namespaces are refused)."""
    if not isinstance(type_name, str):
        raise TypeError(f"type_name must be a string, got {type(type_name).__name__}")
    match = _TYPE_NAME.match(type_name)
    if match is None:
        raise ValueError(
            f"type_name must look like 'pkg/msg/Type' or 'pkg/Type', got {type_name!r}"
        )
    return f"{match.group(1)}/msg/{match.group(3)}"


def _split(type_name: str) -> tuple[str, str]:
    pkg, _, name = normalize_type_name(type_name).split("/")
    return pkg, name


def _search_roots(msg_dirs: Sequence[str | os.PathLike]) -> list[Path]:
    roots = [Path(d) for d in msg_dirs]
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix:
            roots.append(Path(prefix) / "share")
    roots.append(INTERFACES)
    roots.append(Path(sys.prefix) / "share")  # ROS 2 wheels: share/ of the environment
    return roots


def find_message_file(type_name: str, msg_dirs: Sequence[str | os.PathLike] = ()) -> Path | None:
    """Locate ``<Type>.msg`` for a type; None if no file exists.

    Search order: each directory of ``msg_dirs`` (as ``<dir>/<pkg>/msg/<Type>.msg``, or
    ``<dir>/<Type>.msg`` if ``dir`` is itself ``.../<pkg>/msg``), then
    ``$AMENT_PREFIX_PATH/<prefix>/share/<pkg>/msg/<Type>.msg``, then :data:`INTERFACES`,
    then ``<sys.prefix>/share``.
    """
    pkg, name = _split(type_name)
    explicit = [Path(d) for d in msg_dirs]
    for root in _search_roots(msg_dirs):
        candidates = [root / pkg / "msg" / f"{name}.msg"]
        if root in explicit and root.name == "msg" and root.parent.name == pkg:
            candidates.append(root / f"{name}.msg")
        for candidate in candidates:
            if candidate.is_file():
                return candidate
    return None


def message_text(type_name: str, msg_dirs: Sequence[str | os.PathLike] = ()) -> str:
    """A type's own definition: its .msg file verbatim, or, for a standard ROS 2 type with no
    file installed, the definition ``rosbags`` generates from its built-in Jazzy types (fields
    and constants without comments).

    Raises
    ------
    MessageDefinitionNotFound
        Neither a file nor a built-in type.
    """
    path = find_message_file(type_name, msg_dirs)
    if path is not None:
        # newline="" keeps the bytes as they are (rosbag2 stores the file verbatim).
        with open(path, encoding="utf-8", newline="") as stream:
            return stream.read()
    full = normalize_type_name(type_name)
    store = _jazzy()
    if full in store.fielddefs:
        return store.gendefhash(full, {}, ros_version=2)[0]
    raise MessageDefinitionNotFound(
        f"no .msg file for {type_name!r}: looked in {[str(p) for p in _search_roots(msg_dirs)]}"
        " (as <root>/<pkg>/msg/<Type>.msg); source the ROS 2 workspace or pass msg_dirs"
    )


def _dependencies(text: str, package: str) -> list[str]:
    deps = set()
    for match in _FIELD_TYPE.finditer(text):
        field_type = match.group(1)
        if field_type in _PRIMITIVES:
            continue
        deps.add(field_type if "/" in field_type else f"{package}/{field_type}")
    return sorted(deps)  # rosbag2 keeps them in a std::set: byte order


def message_definition(type_name: str, msg_dirs: Sequence[str | os.PathLike] = ()) -> str:
    """Full ``ros2msg`` schema text of a type, as rosbag2 stores it in MCAP.

    The type's own text (:func:`message_text`) comes first, unchanged (comments and constants
    included). Each dependency follows once, depth first, in sorted order of the names as
    written in the .msg files: ``"\\n" + "=" * 80 + "\\nMSG: pkg/Type\\n" + text``.

    Raises
    ------
    MessageDefinitionNotFound
        If a definition is found nowhere.
    """
    seen: set[str] = set()

    def expand(name: str, depth: int) -> str:
        if depth > 50:
            raise ValueError(f"message definitions nest too deeply below {type_name!r}")
        text = message_text(name, msg_dirs)
        out = text
        for dep in _dependencies(text, _split(name)[0]):
            if dep not in seen:
                seen.add(dep)
                out += "\n" + _SEPARATOR + f"MSG: {dep}\n" + expand(dep, depth + 1)
        return out

    return expand(type_name, 0)


@lru_cache(maxsize=1)
def _jazzy():
    return get_typestore(Stores.ROS2_JAZZY)


def _interface_types() -> dict:
    types: dict = {}
    for path in sorted(INTERFACES.glob("*/msg/*.msg")):
        name = f"{path.parent.parent.name}/msg/{path.stem}"
        types.update(get_types_from_msg(path.read_text(encoding="utf-8"), name))
    return types


@lru_cache(maxsize=1)
def typestore():
    """The project's ``rosbags`` typestore: ROS 2 Jazzy's types and every .msg file under
    :data:`INTERFACES` (cached; do not register other types in it)."""
    store = get_typestore(Stores.ROS2_JAZZY)
    store.register(_interface_types())
    return store


@lru_cache(maxsize=64)
def schema_typestore(type_name: str, schema_text: str):
    """A typestore that knows ``type_name`` as a bag's ``ros2msg`` schema text defines it.

    The project's store when it already holds that type; otherwise Jazzy's types plus the
    schema (or the schema alone, if it redefines a Jazzy type differently).
    """
    full = normalize_type_name(type_name)
    store = typestore()
    if full in store.fielddefs and message_definition_matches(store, full, schema_text):
        return store
    parsed = get_types_from_msg(schema_text, full)
    store = get_typestore(Stores.ROS2_JAZZY)
    try:
        store.register(parsed)
    except Exception:  # noqa: BLE001 - a schema that redefines a Jazzy type: use it alone
        store = get_typestore(Stores.EMPTY)
        store.register(parsed)
    return store


def message_definition_matches(store, type_name: str, schema_text: str) -> bool:
    """Whether ``schema_text`` defines ``type_name`` and its dependencies with the fields
    ``store`` has (comments, constants' spelling and field order of the text aside)."""
    try:
        parsed = get_types_from_msg(schema_text, type_name)
    except Exception:  # noqa: BLE001 - an unparsable text matches nothing
        return False
    for name, (_, fields) in parsed.items():
        have = store.fielddefs.get(name)
        if have is None or [(f, d) for f, d in have[1]] != [(f, d) for f, d in fields]:
            return False
    return True


@lru_cache(maxsize=128)
def parsed_types(type_name: str) -> dict:
    """``rosbags``' parse of a type's full schema text (:func:`message_definition`): the type
    and every dependency, ``{pkg/msg/Type: (constants, fields)}``."""
    full = normalize_type_name(type_name)
    return get_types_from_msg(message_definition(full), full)


def message_fields(type_name: str) -> list[tuple[str, tuple]]:
    """Parsed fields of a type, in order: ``(name, (Nodetype, args))`` as ``rosbags`` gives
    them (``args`` of a primitive: ``(type, bound)``; of a nested type: its name; of an array
    or sequence: ``((Nodetype, args), length)``). Parses the .msg text only: no typestore."""
    full = normalize_type_name(type_name)
    return list(parsed_types(full)[full][1])


@lru_cache(maxsize=16)
def typestore_of(*type_names: str):
    """A small typestore of just these types and their dependencies, parsed from their .msg
    texts: a few milliseconds to make, where :func:`typestore` loads all of Jazzy (about
    0.1 s), for a process that serializes only a few known types (the batch recorder)."""
    store = get_typestore(Stores.EMPTY)
    types: dict = {}
    for name in type_names:
        types.update(parsed_types(name))
    store.register(types)
    return store
