"""Many serialized messages of one type decoded at once: the batch CDR encoder read backwards.

Messages of one type with the same sequence lengths and strings share one byte layout
(:class:`~aero_dva.bag.batch_cdr.CdrLayout`): constant bytes with the numeric fields at fixed
offsets. :func:`decode_batch` takes the layout from the first message (decoded by ``rosbags``
with the bag's own schema), checks that every message of the batch has exactly the layout's
constant bytes (string and sequence lengths, strings, padding) and that the first and last
messages decode to the same numbers both ways, then reads every numeric field of all messages
as numpy columns: no Python work per message. A batch that does not pass returns None, and the
caller decodes it message by message. Pure: no ROS imports, no file I/O.
"""
from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from aero_dva.bag.batch_cdr import cdr_layout
from aero_dva.bag.schemas import Nodetype, message_fields, normalize_type_name, schema_typestore

__all__ = ["decode_batch"]


def _shape(msg, type_name: str, prefix: str, lengths: dict, strings: dict) -> None:
    """Sequence lengths and strings of a decoded message, by field path (as cdr_layout)."""
    for name, (kind, args) in message_fields(type_name):
        path, value = prefix + name, getattr(msg, name)
        if kind == Nodetype.NAME:
            _shape(value, args, path + ".", lengths, strings)
        elif kind == Nodetype.SEQUENCE:
            lengths[path] = len(value)
        elif kind == Nodetype.BASE and args[0] == "string":
            strings[path] = value


def _value(msg, path: str):
    for name in path.split("."):
        msg = getattr(msg, name)
    return msg


def decode_batch(raw: Sequence[bytes] | np.ndarray, type_name: str, schema_text: str,
                 fields: Sequence[str]) -> dict[str, np.ndarray] | None:
    """Numeric ``fields`` (paths such as ``"header.stamp.sec"``, ``"plunge"``) of the
    serialized messages ``raw`` (byte strings, or a (k, length) uint8 matrix, one message per
    row), all of ``type_name``; None if they do not share one layout.

    Returns ``{path: array}``, shape (k,) for a scalar and (k, n) for a sequence of n.
    """
    if len(raw) == 0:
        return None
    matrix = isinstance(raw, np.ndarray)
    full = normalize_type_name(type_name)
    store = schema_typestore(full, schema_text)  # the bag's own definition
    try:
        first = store.deserialize_cdr(bytes(raw[0]), full)
        lengths, strings = {}, {}
        _shape(first, full, "", lengths, strings)
        layout = cdr_layout(full, lengths, strings)
    except Exception:  # noqa: BLE001 - a damaged message or a layout not covered here:
        return None  # the caller's per-message path reports or decodes it
    size = layout.size
    if any(f not in layout.fields for f in fields):
        return None
    if matrix:
        if raw.ndim != 2 or raw.shape[1] != size:
            return None
        data = np.ascontiguousarray(raw, dtype=np.uint8)
    else:
        if any(len(r) != size for r in raw):
            return None
        data = np.frombuffer(b"".join(raw), dtype=np.uint8).reshape(len(raw), size)
    constant = np.ones(size, dtype=bool)
    for offset, dtype, shape in layout.fields.values():
        constant[offset:offset + dtype.itemsize * int(np.prod(shape, dtype=int))] = False
    template = np.frombuffer(layout.template, dtype=np.uint8)
    if not np.array_equal(data[:, constant], np.broadcast_to(template[constant],
                                                              (len(raw), constant.sum()))):
        return None
    view = data.reshape(-1).view(layout.dtype())
    out = {f: np.array(view[f]) for f in fields}
    try:
        last = store.deserialize_cdr(bytes(raw[-1]), full)
    except Exception:  # noqa: BLE001 - as above
        return None
    for msg, row in ((first, 0), (last, len(raw) - 1)):
        for f in fields:
            if not np.array_equal(np.asarray(_value(msg, f)), out[f][row]):
                return None  # the bag's definition lays the fields out otherwise
    return out
