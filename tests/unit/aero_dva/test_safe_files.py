"""The limits of aero_dva.safe_files: each is refused in one line naming the input; files
within them parse as plain yaml/json would."""
from __future__ import annotations

import io
import json
import zipfile

import numpy as np
import pytest
import yaml

from aero_dva.safe_files import (
    MAX_DEPTH,
    check_npz,
    finite_float,
    parse_json,
    parse_yaml,
)
from aero_dva.text_input import InputFileError

WHERE = "wing file 'w.yaml'"


@pytest.mark.parametrize("text, match", [
    ("a: " + "[" * 3000 + "1" + "]" * 3000, "nested more than 32 levels"),
    ("a: " + "{b: " * 40 + "1" + "}" * 40, "nested more than 32 levels"),
    ("a: " + "9" * 400, "integer of 400 digits"),
    ("a: [-" + "9" * 30 + "]", "integer of 30 digits"),
    ("a: " + "9" * 5000, "cannot be read"),
    ("&a [*a]", "inside the node it names"),
    ("a: &x 1\n" + "".join(f"b{i}: *x\n" for i in range(70)), "more than 64 aliases"),
    ("a: [1", "not valid YAML"),
])
def test_yaml_beyond_the_limits_is_refused(text, match):
    with pytest.raises(InputFileError, match=match) as caught:
        parse_yaml(text, WHERE)
    assert str(caught.value).startswith(WHERE) and "\n" not in str(caught.value)


def test_yaml_within_the_limits_parses_as_safe_load():
    inner = MAX_DEPTH - 1  # the top mapping is the first level
    text = "a: " + "[" * inner + "1" + "]" * inner + "\nb: &x {c: 2}\nd: *x\ne: 1e308\n"
    assert parse_yaml(text, WHERE) == yaml.safe_load(text)


@pytest.mark.parametrize("text, match", [
    ("[" * 3000 + "]" * 3000, "nested 3000 levels deep"),
    ('{"a": ' + "9" * 400 + "}", "out of range"),
    ('{"a": NaN}', "NaN is not a finite number"),
    ('{"a": -Infinity}', "-Infinity is not a finite number"),
    ('{"a": 1e999}', "out of the float range"),
    ('{"a": 1', "not valid JSON"),
])
def test_json_beyond_the_limits_is_refused(text, match):
    with pytest.raises(InputFileError, match=match):
        parse_json(text, WHERE)


def test_json_brackets_inside_strings_are_not_nesting():
    text = json.dumps({"a": "[" * 100, "b": [[1.5, -2]], "c": 2**62})
    assert parse_json(text, WHERE) == json.loads(text)


def test_finite_float():
    assert finite_float(3, "mass") == 3.0
    for bad in (10**400, float("nan"), float("inf"), True, "1"):
        with pytest.raises(InputFileError, match="mass"):
            finite_float(bad, "mass")


def _npz(tmp_path, member: bytes):
    path = tmp_path / "a.npz"
    with zipfile.ZipFile(path, "w") as archive:
        archive.writestr("x.npy", member)
    return path


def test_npz_shapes_are_checked_against_the_stored_bytes(tmp_path):
    buffer = io.BytesIO()
    np.save(buffer, np.arange(6.0).reshape(2, 3))
    ok = _npz(tmp_path, buffer.getvalue())
    assert check_npz(ok)["x"][0] == (2, 3)
    header = io.BytesIO()
    np.lib.format.write_array_header_1_0(header, {"descr": "<f8", "fortran_order": False,
                                                  "shape": (600_000, 600_000)})
    huge = _npz(tmp_path, header.getvalue() + b"\0" * 48)
    with pytest.raises(InputFileError, match=r"declares shape \(600000, 600000\)"):
        check_npz(huge)
