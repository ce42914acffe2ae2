"""Save and load :class:`~aero_dva.control.rbf_network.RBFNetwork` files without pickle.

One ``.npz`` file holds two float64 arrays, ``centres`` (n_neurons, input_dim) and
``output_weights`` (n_neurons,), and ``header``, a JSON string with everything else::

    {"format": "dva_rbf_network", "version": 1, "input_dim": 33,
     "input_names": [...], "input_units": [...], "output_name": "damping",
     "output_unit": "N s/m", "spread": ..., "output_bias": ...,
     "input_scaling": {"offset": [...], "scale": [...],
                       "definition": "x_scaled = (x - offset) / scale"},
     "description": "..."}

Loading uses ``allow_pickle=False`` and checks every field; a problem raises
:class:`RBFFileError` (a ``ValueError``) that names the file and what is wrong.
"""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import numpy as np

from aero_dva import input_ranges as ranges
from aero_dva.atomic_io import atomic_output
from aero_dva.control.rbf_network import InputScaling, RBFNetwork
from aero_dva.safe_files import check_file_header, check_npz, parse_json

__all__ = ["FILE_FORMAT", "FILE_VERSION", "RBFFileError", "load_rbf_network", "save_rbf_network"]

FILE_FORMAT = "dva_rbf_network"
FILE_VERSION = 1
_SCALING_DEFINITION = "x_scaled = (x - offset) / scale"


#: Bounds of a network's spread in scaled input units (inputs are scaled to about [-1, 1]).
MIN_SPREAD, MAX_SPREAD = 1e-6, 1e6


class RBFFileError(ValueError):
    """An RBF network file is missing, unreadable or inconsistent."""


def save_rbf_network(network: RBFNetwork, path, description: str = "") -> Path:
    """Write a network to ``path`` (an ``.npz`` file), atomically.

    Parameters
    ----------
    network : RBFNetwork
        The network to save.
    path : str or os.PathLike
        Destination; ``.npz`` is appended if missing. Written to a temporary file in the same
        directory and renamed, so readers never see a half-written file.
    description : str
        Free text stored in the header (e.g. training data and errors).

    Returns
    -------
    pathlib.Path
        The file written.
    """
    if not isinstance(network, RBFNetwork):
        raise TypeError(f"network must be an RBFNetwork, got {type(network).__name__}")
    if not isinstance(description, str):
        raise TypeError("description must be a string")
    path = Path(path)
    if path.suffix != ".npz":
        path = path.with_name(path.name + ".npz")
    header = {
        "format": FILE_FORMAT,
        "version": FILE_VERSION,
        "input_dim": network.input_dim,
        "n_neurons": network.n_neurons,
        "input_names": list(network.input_names),
        "input_units": list(network.input_units),
        "output_name": network.output_name,
        "output_unit": network.output_unit,
        "spread": network.spread,
        "output_bias": network.output_bias,
        "input_scaling": {
            "offset": network.scaling.offset.tolist(),
            "scale": network.scaling.scale.tolist(),
            "definition": _SCALING_DEFINITION,
        },
        "description": description,
    }
    with atomic_output(path, "wb") as stream:
        np.savez(
            stream,
            header=np.array(json.dumps(header, allow_nan=False)),
            centres=np.ascontiguousarray(network.centres, dtype=np.float64),
            output_weights=np.ascontiguousarray(network.output_weights, dtype=np.float64),
        )
    return path


def _fail(path: Path, what: str) -> RBFFileError:
    return RBFFileError(f"RBF network file {str(path)!r}: {what}")


def _float_array(path: Path, data, key: str, shape: tuple[int, ...]) -> np.ndarray:
    if key not in data.files:
        raise _fail(path, f"array {key!r} is missing (has {sorted(data.files)})")
    try:
        arr = data[key]
    except ValueError as exc:  # object arrays need pickle, which is refused
        raise _fail(path, f"array {key!r} cannot be read without pickle: {exc}") from None
    if arr.dtype != np.float64:
        raise _fail(path, f"array {key!r} has dtype {arr.dtype}, expected float64")
    if arr.shape != shape:
        raise _fail(path, f"array {key!r} has shape {arr.shape}, expected {shape}")
    if not np.all(np.isfinite(arr)):
        raise _fail(path, f"array {key!r} contains NaN or inf")
    return arr


def _header_field(path: Path, header: dict, key: str, kind):
    if key not in header:
        raise _fail(path, f"header field {key!r} is missing")
    value = header[key]
    if kind is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
        if ok and not np.isfinite(value):
            raise _fail(path, f"header field {key!r} must be finite, got {value}")
    elif kind is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    else:
        ok = isinstance(value, kind)
    if not ok:
        raise _fail(path, f"header field {key!r} has type {type(value).__name__}")
    return value


def _string_list(path: Path, header: dict, key: str, length: int) -> tuple[str, ...]:
    values = _header_field(path, header, key, list)
    if len(values) != length or not all(isinstance(v, str) for v in values):
        raise _fail(path, f"header field {key!r} must be {length} strings")
    return tuple(values)


def _vector(path: Path, scaling: dict, key: str, length: int) -> np.ndarray:
    values = scaling.get(key)
    if not isinstance(values, list) or len(values) != length:
        raise _fail(path, f"input_scaling.{key} must be a list of {length} numbers")
    if not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        raise _fail(path, f"input_scaling.{key} must hold numbers only")
    arr = np.array(values, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise _fail(path, f"input_scaling.{key} contains NaN or inf")
    return arr


def load_rbf_network(path, expected_input_dim: int | None = None) -> RBFNetwork:
    """Load and validate a network written by :func:`save_rbf_network`.

    Parameters
    ----------
    path : str or os.PathLike
        The ``.npz`` file.
    expected_input_dim : int, optional
        Required number of inputs (33 for the spectrum-based controller,
        :data:`~aero_dva.control.rbf_network.SPECTRUM_INPUT_DIM`).

    Returns
    -------
    RBFNetwork

    Raises
    ------
    RBFFileError
        If the file is missing, not an npz archive, from another format or version, or has
        arrays or header fields of the wrong type, shape or value.
    """
    path = Path(path)
    if not path.is_file():
        raise _fail(path, "no such file")
    if zipfile.is_zipfile(path):  # every array's declared shape must fit in the file
        check_npz(path, "RBF network file", RBFFileError)
    try:
        data = np.load(path, allow_pickle=False)
    except Exception as exc:  # numpy's header parser fails on damaged bytes in many ways
        raise _fail(path, f"not a readable .npz archive ({type(exc).__name__}: {exc})") from None
    if not isinstance(data, np.lib.npyio.NpzFile):
        raise _fail(path, "not an .npz archive (a single .npy array)")
    with data:
        try:
            if "header" not in data.files:
                raise _fail(path, f"the 'header' entry is missing (has {sorted(data.files)})")
            raw = data["header"]
            if raw.dtype.kind != "U" or raw.shape != ():
                raise _fail(path, "the 'header' entry is not a JSON string")
            header = parse_json(str(raw), f"RBF network file {str(path)!r}: the header",
                                RBFFileError, nonfinite=True)  # fields checked by name
            check_file_header(header, lambda text: _fail(path, text), FILE_FORMAT,
                              FILE_VERSION, what="the header")
            dim = _header_field(path, header, "input_dim", int)
            n_neurons = _header_field(path, header, "n_neurons", int)
            if dim < 1 or n_neurons < 0:
                raise _fail(path, f"input_dim {dim} / n_neurons {n_neurons} out of range")
            if expected_input_dim is not None and dim != expected_input_dim:
                raise _fail(path, f"input_dim is {dim}, the controller needs {expected_input_dim}")
            centres = _float_array(path, data, "centres", (n_neurons, dim))
            weights = _float_array(path, data, "output_weights", (n_neurons,))
        except RBFFileError:
            raise
        except (OSError, ValueError, zipfile.BadZipFile, EOFError) as exc:
            raise _fail(path, f"an archive member is unreadable ({exc})") from None
    scaling = _header_field(path, header, "input_scaling", dict)
    spread = _header_field(path, header, "spread", float)
    if not MIN_SPREAD <= spread <= MAX_SPREAD:
        # inputs are scaled to about [-1, 1]: a spread outside these bounds makes every
        # neuron a spike or a constant (and 1/spread^2 overflows long before 1e-300)
        raise _fail(path, f"spread must be within [{MIN_SPREAD:g}, {MAX_SPREAD:g}] (scaled "
                          f"input units), got {spread}")
    offset = _vector(path, scaling, "offset", dim)
    scale = _vector(path, scaling, "scale", dim)
    bias = _header_field(path, header, "output_bias", float)
    try:
        ranges.check_number(bias, "output_bias", ranges.NETWORK["output_bias"])
        ranges.check_numbers(offset.tolist(), "input_scaling.offset", ranges.NETWORK["offset"])
        ranges.check_numbers(scale.tolist(), "input_scaling.scale", ranges.NETWORK["scale"])
    except ValueError as exc:
        raise _fail(path, str(exc)) from None
    return RBFNetwork(
        centres=centres,
        output_weights=weights,
        output_bias=float(bias),
        spread=float(spread),
        scaling=InputScaling(offset, scale),
        input_names=_string_list(path, header, "input_names", dim),
        input_units=_string_list(path, header, "input_units", dim),
        output_name=_header_field(path, header, "output_name", str),
        output_unit=_header_field(path, header, "output_unit", str),
    )
