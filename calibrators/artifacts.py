"""Calibrations as files: the ``magbench.calibration`` JSON schema, loading, and exports to MATLAB's
``magcal`` convention, ArduPilot and PX4.

Python::

    result = make("lsq", model="nine").fit(data)
    text = result.to_json()                      # the schema below, as text
    cal = Calibration.from_json(text)            # or load_calibration("cal.json"), also reads magcal files
    corrected_nT = cal.correct(raw_nT)           # B = M (raw - o)
    export(cal, "cal", "ardupilot")             # -> cal.param (see the formats below)

``magbench calibrate FILE --save CAL [--export json|matlab|ardupilot|px4]`` writes them;
``magbench apply CAL FILE.csv --out OUT.csv`` applies a saved calibration (json, or magcal json/mat).

The schema (``schema: "magbench.calibration"``, ``schema_version: 1``)
------------------------------------------------------------------------
``model``, ``method``, ``magbench_version``; ``parameters``: every one of the nine parameters of CONTRACT
section 1 as ``{"value", "std", "fixed"}`` (``std`` the Cramér-Rao standard deviation at the estimate and
the estimated noise ``noise_nT``; ``fixed`` for the entries the model holds at 0 or 1, with ``std`` null);
``M`` (3x3, row-major, lower triangular) and ``o_nT`` (3) with ``correction: "B = M (raw - o)"`` for column
vectors in nT; ``reference`` (the magnitude used, its source, and ``estimated``/``relative`` with
``--field auto``); ``data`` (``digest``: sha256 of the readings and reference as little-endian float64,
``n_points``); ``rms_before_nT``, ``rms_after_nT``, ``accepted``, ``rejections``, ``warnings``, and
``model_choice`` when the model was ``auto``.  A reader refuses another schema name, a newer version, a
model whose fixed entries are not neutral, and an ``M`` that disagrees with the parameters.

The exports: formulas, units and signs
--------------------------------------
Our correction, for a reading ``raw`` (column vector, nT): ``B = M (raw - o)``, M lower triangular
(CONTRACT section 1).

* ``json``: the schema above; ``B`` exactly (vector and magnitude).
* ``matlab`` (``.mat`` through ``scipy.io.savemat``, or ``.json``): ``A`` (3x3), ``b`` (1x3), ``expmfs``
  (the reference magnitude, nT) as returned by MATLAB's ``[A, b, expmfs] = magcal(D)``, applied as magcal
  documents it to row vectors: ``C = (D - b) * A``.  Hence ``A = M^T`` and ``b = o``, in nT (D in nT);
  ``C`` equals ``B`` as a vector.  A magcal file's own ``A`` (symmetric) is read as given.
* ``ardupilot`` (``.param``, ``NAME,VALUE`` lines as Mission Planner and MAVProxy load them): ArduPilot
  applies, in ``AP_Compass_Backend::correct_field`` (``libraries/AP_Compass/AP_Compass_Backend.cpp``), with
  the field in milligauss::

      mag += offsets;                        // COMPASS_OFS_X/Y/Z (mGauss), ADDED
      mag *= scale_factor;                   // COMPASS_SCALE (applied when within its sanity range)
      mag = S * mag;                         // S = [[DIA_X, ODI_X, ODI_Y], [ODI_X, DIA_Y, ODI_Z],
                                             //      [ODI_Y, ODI_Z, DIA_Z]]  (symmetric)

  i.e. ``corrected_mG = S (COMPASS_SCALE (raw_mG + COMPASS_OFS))``.  Exported: ``COMPASS_OFS = -o / 100``
  (1 mG = 100 nT; the sign flips because ArduPilot adds its offsets), ``COMPASS_SCALE = 1``, and S the
  symmetric positive-definite factor ``S = sqrtm(M^T M)``.  ArduPilot applies it in the board frame, after
  ``COMPASS_ORIENT``/``AHRS_ORIENTATION``: the readings calibrated must be in that frame (for a sensor-frame
  calibration, orientation none).  Motor compensation (``COMPASS_MOT``) is not part of it.
* ``px4`` (``.params``, QGroundControl's tab-separated ``vehicle component name value type`` lines):
  PX4 applies, in ``calibration::Magnetometer::Correct`` (``src/lib/sensor_calibration/Magnetometer.hpp``,
  the matrix built in ``Magnetometer::ParametersUpdate``, ``Magnetometer.cpp``), with the field in gauss::

      corrected = R * (S * ((data + power * CAL_MAG0_COMP) - CAL_MAG0_OFF))

  with ``S = [[XSCALE, XODIAG, YODIAG], [XODIAG, YSCALE, ZODIAG], [YODIAG, ZODIAG, ZSCALE]]`` (symmetric)
  and R the sensor rotation (``CAL_MAG0_ROT``/board rotation; identity for readings in the sensor frame).
  Exported: ``CAL_MAG0_XOFF/YOFF/ZOFF = o / 1e5`` (1 G = 1e5 nT; SUBTRACTED, same sign as ours), the
  scales and off-diagonals from the same ``S = sqrtm(M^T M)``.  ``CAL_MAG0_ID`` (the device id) is not known
  here: set it on the vehicle, or the calibration slot is not matched to the sensor.

ArduPilot and PX4 take a SYMMETRIC soft-iron matrix.  Scalar data fix M only up to a rotation (M = R S for
some rotation R), and ``|S d| = |M d|`` for every d: the exported S gives the same corrected *magnitude*;
the rotation that scalar data cannot see is dropped (as the canonical form of CONTRACT section 1 drops
it), so the corrected *vector* differs from ours by that rotation.  The round trips are tested in
``tests/test_artifacts.py``: each exported file, applied with that system's formula above, gives our
corrected magnitude (and for json and matlab our vector) within 0.01 nT.
"""
from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from magbench import __version__
from magbench.calibrators.acceptance import reference_problems
from magbench.calibrators.core.problem import PHYSICAL_BOX
from magbench.errors import InputError, with_file_lines
from magbench.safeio import InputBytes, as_path, atomic_output, atomic_write, check_output, one_line, read_input
from magbench.simulate.dataset import UNIT_FACTORS_NT, _header, _parse_head, newline_lines, read_csv
from magbench.simulate.sensor import FREE, MODELS, NEUTRAL, NINE_NAMES, ErrorParams, readings_array

SCHEMA = "magbench.calibration"
SCHEMA_VERSION = 1
FORMATS = ("json", "matlab", "ardupilot", "px4")
EXTENSIONS = {"json": ".json", "matlab": ".mat", "ardupilot": ".param", "px4": ".params"}
NT_PER_MILLIGAUSS = 100.0
NT_PER_GAUSS = 1e5


@dataclass(frozen=True)
class Calibration:
    """A saved calibration: the correction ``B = matrix (raw - offset_nT)`` and what it rests on.

    ``matrix`` is M as stored (lower triangular for magbench's own files; a magcal file's ``A^T`` as given);
    ``params`` its canonical nine parameters (CONTRACT section 1)."""

    model: str
    matrix: np.ndarray
    offset_nT: tuple
    params: ErrorParams
    uncertainty: dict = field(default_factory=dict)
    noise_nT: float = float("nan")
    reference: dict = field(default_factory=dict)
    data_digest: str = ""
    n_points: int = 0
    method: str = ""
    accepted: bool = True
    rejections: tuple = ()
    warnings: tuple = ()
    rms_before_nT: float = float("nan")
    rms_after_nT: float = float("nan")
    model_choice: dict | None = None
    magbench_version: str = ""
    origin: str = "magbench"  # or "matlab" (a magcal A, b read from a file)

    def __post_init__(self):
        m = np.array(self.matrix, dtype=float)
        if m.shape != (3, 3) or not np.all(np.isfinite(m)):
            raise InputError("the calibration matrix must be a finite 3x3 matrix")
        m.setflags(write=False)
        object.__setattr__(self, "matrix", m)
        o = tuple(float(v) for v in self.offset_nT)
        if len(o) != 3 or not all(math.isfinite(v) for v in o):
            raise InputError("the calibration offset must be 3 finite numbers (nT)")
        object.__setattr__(self, "offset_nT", o)
        object.__setattr__(self, "rejections", tuple(self.rejections))
        object.__setattr__(self, "warnings", tuple(self.warnings))

    # -- applying ------------------------------------------------------------------------------------
    def correct(self, raw_nT: np.ndarray) -> np.ndarray:
        """B = M (raw - o) for readings (n, 3) in nT."""
        return (readings_array(raw_nT) - np.asarray(self.offset_nT)) @ self.matrix.T

    @property
    def field_nT(self) -> float:
        """The magnitude the corrected field is scaled to (the reference's median; magcal's expmfs)."""
        value = self.reference.get("median_nT")
        return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else float("nan")

    def symmetric_matrix(self) -> np.ndarray:
        """S = sqrtm(M^T M): the symmetric positive-definite soft-iron matrix with |S d| = |M d| (the
        rotation scalar data cannot see dropped), for ArduPilot and PX4."""
        w = self.matrix.T @ self.matrix
        values, vectors = np.linalg.eigh((w + w.T) / 2)
        return (vectors * np.sqrt(np.maximum(values, 0.0))) @ vectors.T

    # -- building --------------------------------------------------------------------------------------
    @classmethod
    def from_result(cls, result) -> Calibration:
        return cls(model=result.model, matrix=result.params.matrix, offset_nT=result.params.offset_nT,
                   params=result.params, uncertainty=dict(result.uncertainty), noise_nT=float(result.noise_nT),
                   reference=dict(result.reference), data_digest=result.data_digest, n_points=int(result.n_points),
                   method=result.method, accepted=bool(result.accepted), rejections=tuple(result.rejections),
                   warnings=tuple(result.warnings), rms_before_nT=float(result.rms_before_nT),
                   rms_after_nT=float(result.rms_after_nT), model_choice=result.model_choice,
                   magbench_version=__version__)

    # -- the schema ----------------------------------------------------------------------------------
    def as_dict(self) -> dict:
        nine = self.params.to_vector("nine")
        free = FREE.get(self.model, tuple(range(9)))
        parameters = {}
        for i, name in enumerate(NINE_NAMES):
            fixed = i not in free
            std = None if fixed else _finite_or_none(self.uncertainty.get(name))
            parameters[name] = {"value": float(nine[i]), "std": std, "fixed": fixed}
        return {
            "schema": SCHEMA,
            "schema_version": SCHEMA_VERSION,
            "magbench_version": self.magbench_version,
            "method": self.method,
            "model": self.model,
            "origin": self.origin,
            "parameters": parameters,
            "M": self.matrix.tolist(),
            "o_nT": list(self.offset_nT),
            "correction": "B = M (raw - o); raw, o and B in nT, column vectors (CONTRACT section 1)",
            "noise_nT": _finite_or_none(self.noise_nT),
            "reference": _jsonable(self.reference),
            "data": {"digest": self.data_digest, "n_points": self.n_points},
            "rms_before_nT": _finite_or_none(self.rms_before_nT),
            "rms_after_nT": _finite_or_none(self.rms_after_nT),
            "accepted": self.accepted,
            "rejections": list(self.rejections),
            "warnings": list(self.warnings),
            **({"model_choice": _jsonable(self.model_choice)} if self.model_choice is not None else {}),
        }

    def to_json(self) -> str:
        return json.dumps(self.as_dict(), indent=2, allow_nan=False) + "\n"

    @classmethod
    def from_dict(cls, d: dict, where: str = "calibration") -> Calibration:
        if not isinstance(d, dict):
            raise InputError(f"{where}: not a calibration (a JSON object is expected)")
        if "schema" not in d and "A" in d and "b" in d:
            return _from_magcal(d, where)
        if d.get("schema") != SCHEMA:
            raise InputError(f"{where}: not a magbench calibration (schema {d.get('schema')!r}, expected {SCHEMA!r})")
        version = d.get("schema_version")
        if not isinstance(version, int) or isinstance(version, bool) or version < 1:
            raise InputError(f"{where}: schema_version {version!r} is not a version number")
        if version > SCHEMA_VERSION:
            raise InputError(f"{where}: schema version {version} is newer than this magbench reads "
                             f"({SCHEMA_VERSION}): upgrade magbench")
        model = d.get("model")
        if model not in MODELS:
            raise InputError(f"{where}: unknown model {model!r} (expected one of {', '.join(MODELS)})")
        try:
            p = d["parameters"]
            nine = np.array([float(p[name]["value"]) for name in NINE_NAMES])
        except (KeyError, TypeError, ValueError) as exc:
            raise InputError(f"{where}: missing or malformed entry {exc}") from None
        matrix, offset = _numbers(d, "M", where), _numbers(d, "o_nT", where)
        if not np.all(np.isfinite(nine)) or matrix.shape != (3, 3) or offset.shape != (3,) \
                or not np.all(np.isfinite(matrix)) or not np.all(np.isfinite(offset)):
            raise InputError(f"{where}: the parameters, M (3x3) and o_nT (3) must be finite numbers")
        params = ErrorParams.from_vector(nine, "nine")
        fixed = [NINE_NAMES[i] for i in range(9) if i not in FREE[model] and nine[i] != NEUTRAL[i]]
        if fixed:
            raise InputError(f"{where}: model mismatch: the {model} model holds {', '.join(fixed)} fixed, "
                             "but the file gives them other values")
        if not (np.allclose(matrix, params.matrix, rtol=1e-9, atol=1e-12)
                and np.allclose(offset, params.offset_nT, rtol=1e-12, atol=1e-9)):
            raise InputError(f"{where}: model mismatch: M and o_nT disagree with the parameters")
        try:
            return cls._rest_of_dict(d, model, matrix, offset, params, p)
        except (TypeError, ValueError, AttributeError) as exc:
            raise InputError(f"{where}: malformed entry ({exc})") from None

    @classmethod
    def _rest_of_dict(cls, d, model, matrix, offset, params, p) -> Calibration:
        uncertainty = {k: float(v["std"]) for k, v in p.items() if isinstance(v, dict) and v.get("std") is not None}
        data = d.get("data") or {}
        return cls(model=model, matrix=matrix, offset_nT=tuple(offset), params=params, uncertainty=uncertainty,
                   noise_nT=_float(d.get("noise_nT")), reference=dict(d.get("reference") or {}),
                   data_digest=str(data.get("digest", "")), n_points=int(data.get("n_points", 0) or 0),
                   method=str(d.get("method", "")), accepted=bool(d.get("accepted", True)),
                   rejections=tuple(d.get("rejections") or ()), warnings=tuple(d.get("warnings") or ()),
                   rms_before_nT=_float(d.get("rms_before_nT")), rms_after_nT=_float(d.get("rms_after_nT")),
                   model_choice=d.get("model_choice"), magbench_version=str(d.get("magbench_version", "")),
                   origin=str(d.get("origin", "magbench")))

    @classmethod
    def from_json(cls, text: str, where: str = "calibration") -> Calibration:
        """Parse ``text`` with a nesting limit (``MAX_JSON_DEPTH``) and bounded numbers (``MAX_JSON_DIGITS``),
        then validate it against the schema (``validate_schema``) before use."""
        d = parse_json(text, where)
        validate_schema(d, where)
        return cls.from_dict(d, where)

    # -- exports -------------------------------------------------------------------------------------
    def magcal(self) -> dict:
        """``A`` (3x3), ``b`` (3), ``expmfs``: ``C = (D - b) * A`` for row vectors D in nT (MATLAB magcal)."""
        return {"A": self.matrix.T.copy(), "b": np.array(self.offset_nT), "expmfs": self.field_nT}

    def ardupilot(self) -> dict:
        """ArduPilot's COMPASS_* parameters (see the module docstring for the formula)."""
        s = self.symmetric_matrix()
        o_mg = np.array(self.offset_nT) / NT_PER_MILLIGAUSS
        return {"COMPASS_OFS_X": -o_mg[0], "COMPASS_OFS_Y": -o_mg[1], "COMPASS_OFS_Z": -o_mg[2],
                "COMPASS_DIA_X": s[0, 0], "COMPASS_DIA_Y": s[1, 1], "COMPASS_DIA_Z": s[2, 2],
                "COMPASS_ODI_X": s[0, 1], "COMPASS_ODI_Y": s[0, 2], "COMPASS_ODI_Z": s[1, 2],
                "COMPASS_SCALE": 1.0}

    def px4(self, instance: int = 0) -> dict:
        """PX4's CAL_MAGn_* parameters (see the module docstring for the formula)."""
        s = self.symmetric_matrix()
        o_g = np.array(self.offset_nT) / NT_PER_GAUSS
        p = f"CAL_MAG{instance}_"
        return {p + "XOFF": o_g[0], p + "YOFF": o_g[1], p + "ZOFF": o_g[2],
                p + "XSCALE": s[0, 0], p + "YSCALE": s[1, 1], p + "ZSCALE": s[2, 2],
                p + "XODIAG": s[0, 1], p + "YODIAG": s[0, 2], p + "ZODIAG": s[1, 2]}


def _float(v) -> float:
    try:
        return float(v) if v is not None else float("nan")
    except (TypeError, ValueError):
        return float("nan")


def _numbers(d: dict, key: str, where: str) -> np.ndarray:
    """``d[key]`` as a float array, or an ``InputError`` that names the entry in the file's terms (numpy's own text about
    'inhomogeneous shapes' had been passed on for a ragged M)."""
    if key not in d:
        raise InputError(f"{where}: missing entry {key!r}")
    try:
        return np.array(d[key], dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"{where}: {key} must be " + ("a 3x3 matrix of numbers (three rows of three)" if key == "M" else
                                                        "three numbers")) from None


def _finite_or_none(v):
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def _jsonable(v):
    if isinstance(v, dict):
        return {str(k): _jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple)):
        return [_jsonable(x) for x in v]
    if isinstance(v, np.ndarray):
        return _jsonable(v.tolist())
    if isinstance(v, (np.floating, np.integer, np.bool_)):
        v = v.item()
    if isinstance(v, float) and not math.isfinite(v):
        return None
    return v


MAX_JSON_BYTES = 1024 * 1024
"""The largest calibration file read (1 MiB; a calibration is about 5 kB)."""
MAX_JSON_DEPTH = 32
"""The deepest nesting of arrays and objects a calibration may have (the schema needs 5)."""
MAX_JSON_DIGITS = 400
"""The most digits a number in a calibration may have (a float64 needs 17, its exponent 3)."""
MAX_MAT_BYTES = 16 * 1024 * 1024
"""The largest .mat calibration read, and the most its compressed parts may inflate to (16 MiB)."""
_STRING = re.compile(r'"(?:[^"\\]|\\.)*"')


def json_depth(text: str) -> int:
    """The deepest nesting of ``[`` and ``{`` in JSON text (strings skipped), without recursion."""
    bare = _STRING.sub('""', text).encode("utf-8", "replace")
    arr = np.frombuffer(bare, dtype=np.uint8)
    step = np.isin(arr, (ord("["), ord("{"))).astype(np.int64) - np.isin(arr, (ord("]"), ord("}")))
    return int(np.cumsum(step).max()) if step.size else 0


def _bounded_number(kind):
    def parse(text: str):
        if len(text.lstrip("-")) > MAX_JSON_DIGITS:
            raise InputError(f"a number of {len(text):,} characters (the limit is {MAX_JSON_DIGITS})")
        value = kind(text)
        if kind is float and not math.isfinite(value):  # 1e999: JSON's grammar, beyond any double (read as inf)
            raise InputError(f"the number {text} is beyond the range of a double")
        return value
    return parse


def _unique_keys(pairs: list) -> dict:
    """A JSON object, refused when a key repeats (``{"accepted": false, "accepted": true}`` had kept the last)."""
    out: dict = {}
    for key, value in pairs:
        if key in out:
            raise InputError(f"the key {key!r} appears twice in one object")
        out[key] = value
    return out


def _no_constant(name: str):
    raise InputError(f"{name} is not a number JSON allows")


def parse_json(text: str, where: str = "calibration"):
    """JSON with a depth limit, bounded numbers and no NaN/Infinity; ``InputError`` (one line) otherwise."""
    depth = json_depth(text)
    if depth > MAX_JSON_DEPTH:
        raise InputError(f"{where}: JSON nested {depth:,} deep, more than the limit of {MAX_JSON_DEPTH}")
    try:
        return json.loads(text, parse_int=_bounded_number(int), parse_float=_bounded_number(float),
                          parse_constant=_no_constant, object_pairs_hook=_unique_keys)
    except json.JSONDecodeError as exc:
        raise InputError(f"{where} is not JSON ({exc.msg} at line {exc.lineno})") from None
    except InputError as exc:
        raise InputError(f"{where}: {exc}") from None
    except (ValueError, RecursionError) as exc:
        raise InputError(f"{where}: not a valid JSON calibration ({type(exc).__name__})") from None


_SCHEMA_TYPES: dict[str, Any] = {
                 "schema": str, "schema_version": int, "magbench_version": str, "method": str, "model": str,
                 "origin": str, "parameters": dict, "M": list, "o_nT": list, "correction": str,
                 "noise_nT": (int, float, type(None)), "reference": dict, "data": dict,
                 "rms_before_nT": (int, float, type(None)), "rms_after_nT": (int, float, type(None)),
                 "accepted": bool, "rejections": list, "warnings": list, "model_choice": (dict, type(None))}
"""The type of each top-level entry of the schema (module docstring)."""


def validate_schema(d, where: str = "calibration") -> None:
    """Refuse a magbench calibration whose entries do not have the schema's types (a magcal ``A``/``b`` file
    is checked by its own reader)."""
    if not isinstance(d, dict):
        raise InputError(f"{where}: not a calibration (a JSON object is expected)")
    if "schema" not in d:
        return
    for key, kind in _SCHEMA_TYPES.items():
        if key in d and not isinstance(d[key], kind) or (kind is int and isinstance(d.get(key), bool)):
            raise InputError(f"{where}: entry {key!r} has the wrong type ({type(d[key]).__name__})")
    for key in ("parameters", "M", "o_nT", "accepted"):
        if key not in d:
            raise InputError(f"{where}: missing entry {key!r}")
    median_nT = (d.get("reference") or {}).get("median_nT")
    if median_nT is not None and (isinstance(median_nT, bool) or not isinstance(median_nT, (int, float))
                                  or not median_nT > 0):
        raise InputError(f"{where}: entry reference.median_nT must be a positive number of nT, got {median_nT!r}")
    for key in ("rejections", "warnings"):
        if not all(isinstance(v, str) for v in d.get(key) or ()):
            raise InputError(f"{where}: entry {key!r} must be a list of strings")
    for name, p in d["parameters"].items():
        if not isinstance(p, dict) or not isinstance(p.get("value"), (int, float)) or isinstance(p.get("value"), bool):
            raise InputError(f"{where}: parameter {name!r} must be an object with a numeric 'value'")


def _mat_inflated_size(data: bytes, where: str) -> int:
    """The size a MATLAB v5 file's compressed elements inflate to, counted without keeping more than
    ``MAX_MAT_BYTES`` of it (``InputError`` beyond): a zip bomb is refused before scipy inflates it."""
    import zlib

    if len(data) < 128 or data[126:128] not in (b"IM", b"MI"):
        return len(data)  # not v5 (v4 has no compression; v7.3 is HDF5, refused by scipy)
    order = "<" if data[126:128] == b"IM" else ">"
    total, pos = 0, 128
    while pos + 8 <= len(data):
        kind, nbytes = np.frombuffer(data, dtype=order + "u4", count=2, offset=pos)
        if kind >> 16:  # small data element: 4 bytes of data in the tag
            pos += 8
            continue
        body = data[pos + 8:pos + 8 + int(nbytes)]
        if kind == 15:  # miCOMPRESSED
            inflater = zlib.decompressobj()
            try:
                out = inflater.decompress(body, MAX_MAT_BYTES + 1 - total)
            except zlib.error:
                raise InputError(f"{where} is not a readable .mat file (a compressed part is corrupt)") from None
            total += len(out)
        else:
            total += len(body)
        if total > MAX_MAT_BYTES:
            raise InputError(f"{where}: the .mat file inflates to more than {MAX_MAT_BYTES:,} bytes (the limit)")
        pos += 8 + int(nbytes) + (-int(nbytes) % 8 if kind != 15 else 0)
    return total


def _all_numbers(value) -> bool:
    """Whether ``value`` (JSON lists, or a .mat file's array) holds numbers only: no true/false, no text."""
    if isinstance(value, np.ndarray):
        return value.dtype.kind in "iuf"
    if isinstance(value, (list, tuple)):
        return all(_all_numbers(v) for v in value)
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def _from_magcal(d: dict, where: str, field_nT=None) -> Calibration:
    """A calibration from MATLAB magcal's ``A``, ``b`` (and ``expmfs``): M = A^T, o = b.  ``expmfs`` NaN (what a
    .mat export of a calibration without a reference holds) is none; another non-number, or one not positive, is
    refused (a string had been ignored)."""
    for key in ("A", "b"):
        if key in d and not _all_numbers(d[key]):
            raise InputError(f"{where}: a magcal calibration needs A (3x3) and b (3) numbers ({key} holds "
                             "true/false or text)")
    try:
        a = np.array(d["A"], dtype=float).reshape(3, 3)
        b = np.array(d["b"], dtype=float).reshape(3)
    except (KeyError, TypeError, ValueError):
        raise InputError(f"{where}: a magcal calibration needs A (3x3) and b (3) numbers") from None
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise InputError(f"{where}: A and b must be finite")
    if not np.linalg.det(a) > 0 and not np.linalg.det(a) < 0:
        raise InputError(f"{where}: A is singular")
    expmfs = d.get("expmfs", field_nT)
    if expmfs is not None:
        try:
            if not _all_numbers(expmfs):
                raise ValueError
            expmfs = float(np.asarray(expmfs, dtype=float).reshape(-1)[0])
        except (TypeError, ValueError, IndexError):
            raise InputError(f"{where}: expmfs must be the reference magnitude in nT (a number), got "
                             f"{str(expmfs)[:40]!r}") from None
        if math.isnan(expmfs):
            expmfs = None
        elif not 0 < expmfs < math.inf:
            raise InputError(f"{where}: expmfs must be a positive magnitude in nT, got {expmfs:g}")
    m = a.T
    try:
        params = ErrorParams.from_correction(m, b)
    except np.linalg.LinAlgError:
        raise InputError(f"{where}: A^T A is not positive definite") from None
    reference = {"median_nT": expmfs, "source": "magcal expmfs"} if expmfs is not None else {}
    accepted, rejections = _magcal_verdict(d, where)
    return Calibration(model="nine", matrix=m, offset_nT=tuple(b), params=params, reference=reference,
                       method="magcal", origin="matlab", accepted=accepted, rejections=rejections)


def _magcal_verdict(d: dict, where: str) -> tuple[bool, tuple]:
    """(accepted, rejections) of a magcal-style file that says whether it was accepted (``"accepted": false`` and
    its ``"rejections"``, as magbench's own JSON says it): ``apply`` then refuses it as it refuses magbench's own
    rejected calibrations (it had been applied silently).  Without the entry it is accepted (MATLAB's magcal
    says nothing of it); one that is not true or false is refused, as the schema's own ``accepted`` is."""
    value = d.get("accepted", True)
    if (isinstance(value, np.ndarray) and value.size == 1 and value.dtype.kind in "biuf"
            and value.item() in (0, 1)):
        value = bool(value.item())  # a .mat file's logical, or a 0/1 scalar (MATLAB's doubles included)
    if not isinstance(value, bool):
        raise InputError(f"{where}: entry 'accepted' must be true or false, got {str(value)[:40]!r}")
    reasons = d.get("rejections")
    if reasons is None or (isinstance(reasons, (np.ndarray, list, tuple)) and len(np.ravel(reasons)) == 0):
        reasons = ()
    elif isinstance(reasons, str):
        reasons = (reasons,)
    elif isinstance(reasons, np.ndarray) and reasons.dtype.kind in "USO":  # a .mat file's char or cell array
        flat = [r.item() if isinstance(r, np.ndarray) and r.size == 1 else r for r in reasons.ravel()]
        reasons = tuple(str(r).strip() if isinstance(r, (str, np.str_)) else r for r in flat)
    if not isinstance(reasons, (list, tuple)) or not all(isinstance(r, str) for r in reasons):
        raise InputError(f"{where}: entry 'rejections' must be a list of strings")
    return value, tuple(reasons)


def load_calibration(path, source: InputBytes | None = None) -> Calibration:
    """Read a calibration file: magbench's schema (``.json``) or MATLAB magcal's ``A``/``b`` (``.mat`` or
    ``.json``).  Refuses (``InputError``, one line) what is neither, another schema or a newer version, a
    special file, a file over ``MAX_JSON_BYTES`` (``MAX_MAT_BYTES`` for .mat, inflated size included),
    JSON nested deeper than ``MAX_JSON_DEPTH`` or with numbers longer than ``MAX_JSON_DIGITS``.  The
    file is read once (``source``: bytes read already)."""
    path = as_path(path, "calibration file")
    if path.suffix.lower() in (".param", ".params"):  # exports for a flight controller, never read back
        raise InputError(f"{path}: an ArduPilot .param or PX4 .params file is an export for the flight controller, "
                         "not read back; apply reads magbench JSON or MATLAB magcal (.mat, .json)")
    mat = path.suffix.lower() == ".mat"
    src = source or read_input(path, "calibration file", MAX_MAT_BYTES if mat else MAX_JSON_BYTES)
    if mat:
        import io

        from scipy.io import loadmat

        _mat_inflated_size(src.data, str(path))
        try:
            d = loadmat(io.BytesIO(src.data))
        except MemoryError:
            raise InputError(f"{path}: not enough memory to read this .mat file") from None
        except Exception as exc:  # scipy raises several kinds for a broken file
            raise InputError(f"{path} is not a readable .mat file ({type(exc).__name__})") from None
        return _from_magcal({k: v for k, v in d.items() if not k.startswith("__")}, str(path))
    try:
        text = src.data.decode("utf-8-sig")
    except UnicodeDecodeError:
        raise InputError(f"{path} is not a calibration file (not UTF-8 text; .mat files need the .mat "
                         "extension)") from None
    return Calibration.from_json(text, str(path))


MAX_CONDITION = 100.0
"""The largest condition number of M that ``apply`` uses: a physical sensor (scales 0.5..2, angles within
0.5 rad) has at most about 8; beyond 100 the calibration collapses a direction."""
DETERMINANT_RANGE = (1e-2, 1e2)
"""|det M| of a physical sensor lies in about 0.05..8 (scales 0.5..2): outside 0.01..100 it is not one."""


def apply_problems(cal: Calibration) -> list[str]:
    """Why ``cal`` should not be applied: it was rejected when made, or M is ill-conditioned (condition
    number above ``MAX_CONDITION`` or determinant outside ``DETERMINANT_RANGE``)."""
    out = []
    if not cal.accepted:
        first = cal.rejections[0] if cal.rejections else "no reason recorded"
        out.append(f"the calibration was rejected by its acceptance checks when it was made ({first})")
    with np.errstate(all="ignore"):
        cond = float(np.linalg.cond(cal.matrix))
        signed = float(np.linalg.det(cal.matrix))
        det = abs(signed)
    if not cond <= MAX_CONDITION or not DETERMINANT_RANGE[0] <= det <= DETERMINANT_RANGE[1]:
        out.append(f"the calibration matrix is ill-conditioned (condition number {cond:.3g}, |determinant| "
                   f"{det:.3g}; the limits are a condition number of {MAX_CONDITION:g} and a determinant within "
                   f"{DETERMINANT_RANGE[0]:g}..{DETERMINANT_RANGE[1]:g})")
    elif signed < 0:  # the magnitude is unchanged, so no check on the readings would say it
        out.append(f"the calibration matrix has a negative determinant ({signed:.3g}): it mirrors the readings (an "
                   "axis's sign flipped), which no sensor's calibration does")
    else:
        out += _unphysical(cal)
    return out


FRAME_ROTATION_MAX_RAD = 0.5
"""The largest rotation ``apply`` takes beyond the sensor model's own matrix (M times the inverse of the matrix its
parameters give): none for magbench's files, a few degrees for a magcal file's symmetric A; a 90-degree turn of the
axes had been applied without a word (the magnitude is unchanged)."""


def _unphysical(cal: Calibration) -> list[str]:
    """Why ``cal``'s matrix is no sensor's correction: it turns the axes by more than FRAME_ROTATION_MAX_RAD beyond
    its parameters' matrix, or its angles lie outside the box every calibrator's answer must lie in (within 0.5 rad,
    ``PHYSICAL_BOX``; the scales are judged by the corrected magnitudes against the data's reference, which says by
    how much, and by DETERMINANT_RANGE; offsets are not limited here, a phone's hard iron is several fields)."""
    p = cal.params
    out = []
    with np.errstate(all="ignore"):
        turn = cal.matrix @ np.linalg.inv(p.matrix)
    angle = float(np.arccos(np.clip((np.trace(turn) - 1.0) / 2.0, -1.0, 1.0)))
    if not angle <= FRAME_ROTATION_MAX_RAD:
        out.append(f"the calibration matrix turns the axes by {np.degrees(angle):.3g} degrees beyond its own angles and "
                   "scales (axes swapped or rotated: no sensor's calibration)")
    limit = PHYSICAL_BOX["angle_range_rad"]
    angles = {"alpha_rad": p.alpha_rad, "beta_rad": p.beta_rad, "gamma_rad": p.gamma_rad}
    wild = [f"{k} {v:.3g}" for k, v in angles.items() if not abs(v) <= limit]
    if wild:
        out.append(f"the calibration's {', '.join(wild)} lie outside what a sensor can have (angles within {limit:g} "
                   "rad, the box every calibrator's answer must lie in)")
    return out


ARDUPILOT_OFFS_MAX_DEFAULT_MG = 1800.0
"""ArduPilot's default COMPASS_OFFS_MAX (``AP_COMPASS_OFFSETS_MAX_DEFAULT``, libraries/AP_Compass/AP_Compass.cpp):
the pre-arm check (``AP_Arming::compass_checks``: ``offsets.length() > _compass.get_offsets_max()``, 'Compass
offsets too high') refuses to arm with a COMPASS_OFS vector longer than it, and the onboard calibrator
(``CompassCalibrator::fit_acceptable``) refuses a fit with an axis beyond it.  (COMPASS_OFS_X/Y/Z's own
``@Range: -400 400`` is the ground station's advice, not enforced.)"""
ARDUPILOT_OFFS_MAX_LIMIT_MG = 3000.0
"""The largest COMPASS_OFFS_MAX can be set to (its ``@Range: 500 3000``, AP_Compass.cpp): offsets longer than this
fail the pre-arm check whatever the setting."""
PX4_MAG_MAX_OFFSET_G = 1.3
"""PX4's ``MAG_MAX_OFFSET_LEN`` (src/modules/commander/mag_calibration.cpp): an offset beyond 1.3 G on an axis gets
'Warning: mag with large offsets' from PX4's own calibration ('the maximum measurement range is ~1.9 Ga, the earth
field is ~0.6 Ga, so an offset larger than ~1.3 Ga means the mag will saturate in some directions'); PX4 stores
it all the same."""


def export_offset_problem(cal: Calibration, fmt: str) -> tuple[bool, str] | None:
    """(refused, why) when ``cal``'s offsets lie beyond what the flight controller of ``fmt`` takes, else None:
    ArduPilot's COMPASS_OFS longer than the largest COMPASS_OFFS_MAX (refused: no setting lets the vehicle arm)
    or than its default (a warning: COMPASS_OFFS_MAX must be raised); a PX4 CAL_MAG0_*OFF beyond
    ``PX4_MAG_MAX_OFFSET_G`` (a warning, as PX4's own calibration gives).  They had been written without a word."""
    if fmt == "ardupilot":
        ofs = np.array([cal.ardupilot()[f"COMPASS_OFS_{a}"] for a in "XYZ"])
        length = float(np.linalg.norm(ofs))
        axes = ", ".join(f"{a} {v:.0f}" for a, v in zip("XYZ", ofs))
        if length > ARDUPILOT_OFFS_MAX_LIMIT_MG:
            return True, (f"COMPASS_OFS would be {length:.0f} mG long ({axes}), beyond the largest COMPASS_OFFS_MAX "
                          f"ArduPilot takes ({ARDUPILOT_OFFS_MAX_LIMIT_MG:.0f} mG): its pre-arm check ('Compass offsets "
                          "too high') refuses it whatever the setting")
        if length > ARDUPILOT_OFFS_MAX_DEFAULT_MG:
            return False, (f"COMPASS_OFS is {length:.0f} mG long ({axes}), beyond ArduPilot's default "
                           f"COMPASS_OFFS_MAX of {ARDUPILOT_OFFS_MAX_DEFAULT_MG:.0f} mG: its pre-arm check ('Compass "
                           f"offsets too high') refuses to arm until COMPASS_OFFS_MAX (at most "
                           f"{ARDUPILOT_OFFS_MAX_LIMIT_MG:.0f}) is raised")
    elif fmt == "px4":
        off = np.array(cal.offset_nT) / NT_PER_GAUSS
        wide = [f"CAL_MAG0_{a}OFF {v:.3g} G" for a, v in zip("XYZ", off) if abs(v) > PX4_MAG_MAX_OFFSET_G]
        if wide:
            verb = "is" if len(wide) == 1 else "are"
            return False, (f"{', '.join(wide)} {verb} beyond the {PX4_MAG_MAX_OFFSET_G:g} G at which PX4's own "
                           "calibration warns of large offsets (the sensor saturates in some directions)")
    return None


def export_path(path, fmt: str) -> Path:
    """PATH with the format's extension added when it has none (json .json, matlab .mat, ardupilot .param,
    px4 .params)."""
    if fmt not in FORMATS:
        raise InputError(f"unknown export format {fmt!r}: use one of {', '.join(FORMATS)}")
    text = os.fspath(path)
    if text.endswith(("/", os.sep)) or Path(text).is_dir():  # the extension would land beside the directory
        what = "is a directory" if Path(text).is_dir() else "ends in a separator: it names a directory"
        raise InputError(f"{text} {what}: give a file name in it (e.g. "
                         f"{Path(text) / ('calibration' + EXTENSIONS[fmt])})")
    path = Path(text)
    return path if path.suffix else path.with_name(path.name + EXTENSIONS[fmt])


def export_text(cal: Calibration, fmt: str, path: Path) -> str | None:
    """The file's text for the text formats (None for a .mat file)."""
    if fmt == "json":
        return cal.to_json()
    if fmt == "matlab":
        if path.suffix.lower() == ".mat":
            return None
        mc = cal.magcal()
        return json.dumps({"A": mc["A"].tolist(), "b": mc["b"].tolist(), "expmfs": _finite_or_none(mc["expmfs"]),
                           "convention": "C = (D - b) * A for row vectors D (MATLAB magcal); D, b, C in nT",
                           "source": f"magbench {cal.magbench_version} {cal.method} ({cal.model} model)",
                           "data_digest": cal.data_digest}, indent=2) + "\n"
    head = [f"magbench {cal.magbench_version} calibration ({cal.method}, {cal.model} model, data {cal.data_digest})"]
    if fmt == "ardupilot":
        lines = ["# " + head[0],
                 "# ArduPilot AP_Compass_Backend::correct_field: corrected_mG = S * (COMPASS_SCALE * (raw_mG + COMPASS_OFS)),",
                 "# S = [[DIA_X, ODI_X, ODI_Y], [ODI_X, DIA_Y, ODI_Z], [ODI_Y, ODI_Z, DIA_Z]]; offsets in milligauss, added.",
                 "# S = sqrtm(M^T M): same corrected magnitude; the rotation scalar data cannot see is dropped."]
        lines += [f"{k},{v:.10g}" for k, v in cal.ardupilot().items()]
        return "\n".join(lines) + "\n"
    lines = ["# " + head[0],
             "# PX4 calibration::Magnetometer::Correct: corrected = R * (S * (data_G - CAL_MAG0_OFF)),",
             "# S = [[XSCALE, XODIAG, YODIAG], [XODIAG, YSCALE, ZODIAG], [YODIAG, ZODIAG, ZSCALE]];",
             "# offsets in gauss, subtracted.",
             "# S = sqrtm(M^T M): same corrected magnitude; the rotation scalar data cannot see is dropped.",
             "# CAL_MAG0_ID (the device id) must be set on the vehicle.",
             "# Vehicle-Id Component-Id Name Value Type"]
    lines += [f"1\t1\t{k}\t{v:.10g}\t9" for k, v in cal.px4().items()]  # 9: MAV_PARAM_TYPE_REAL32
    return "\n".join(lines) + "\n"


def export(cal: Calibration, path, fmt: str = "json", force: bool = False, inputs=(), warn: bool = True) -> Path:
    """Write ``cal`` to PATH (extension added when it has none) in ``fmt``, atomically (a temporary file in
    the same folder, renamed); refuses to overwrite an existing file unless ``force``, and any of
    ``inputs`` (paths or ``InputBytes``, compared by inode) even with it.  Offsets beyond what the flight
    controller takes (``export_offset_problem``) are refused, or, when it takes them with a setting changed or a
    warning of its own, warned of (``warnings.warn``; not with ``warn=False``, whose caller says it).  Returns the
    path written."""
    path = check_output(export_path(path, fmt), inputs, force)
    problem = export_offset_problem(cal, fmt)
    if problem is not None and problem[0]:
        raise InputError(f"{problem[1]}; not saved to {path} (--export json or matlab keeps it)")
    if problem is not None and warn:
        import warnings

        warnings.warn(problem[1], UserWarning, stacklevel=2)
    text = export_text(cal, fmt, path)
    if text is not None:
        return atomic_write(path, text, inputs, force)
    from scipy.io import savemat

    mc = cal.magcal()
    with atomic_output(path, inputs, force) as tmp:
        savemat(str(tmp), {"A": mc["A"], "b": mc["b"][None, :],
                           "expmfs": np.nan if mc["expmfs"] is None else mc["expmfs"]})
    return path


CAL_COLUMNS = ("bx_cal", "by_cal", "bz_cal", "f_cal")
"""Columns ``apply`` adds: the corrected field and its magnitude, in the unit of the input's field columns."""


def zero_readings(raw_nT: np.ndarray) -> str | None:
    """Why readings of exactly 0 on all three axes cannot be calibrated or corrected (a dropout, or a missing value a
    logger wrote as 0: no direction, and no field a calibration could give back), naming the rows; None without
    any."""
    zero = ~np.any(raw_nT, axis=1)
    if not zero.any():
        return None
    rows = np.flatnonzero(zero)
    return (f"raw readings are exactly 0 on all three axes in {len(rows)} row(s) (row{'s' if len(rows) > 1 else ''} "
            f"{', '.join(map(str, rows[:5]))}"
            f"{', ...' if len(rows) > 5 else ''}): a dropout or a missing value written as 0, not a reading of a "
            "field; remove those rows")


def mixed_units(raw_nT: np.ndarray) -> str | None:
    """Why the readings are not all in one unit (some rows a factor of 30 or more off the others), or None:
    the calibrators' own check (``acceptance.reference_problems``) against a constant reference, so that a
    file without ``f_ref`` is checked too (the median magnitude's plausibility is ``read_csv``'s)."""
    typical = float(np.median(np.sqrt(np.einsum("ij,ij->i", raw_nT, raw_nT))))
    return reference_problems(raw_nT, np.full(len(raw_nT), typical if typical > 0 else 1.0))


CORRECTED_RATIO_RANGE = (0.5, 2.0)
"""``apply``: the corrected magnitudes' median over the file's reference (else over the raw readings' median
magnitude) within which a calibration can belong to the readings: a fluxgate's or a vehicle's correction changes the
magnitude by per cent, not by a factor (a matrix four times too large had written 200,000 nT against a reference of
50,000 nT, exit 0)."""


def correction_misfit(f_cal_nT: np.ndarray, raw_nT: np.ndarray, f_ref_nT: np.ndarray | None) -> str | None:
    """Why corrected magnitudes cannot be the field these readings measured, or None (``CORRECTED_RATIO_RANGE``)."""
    if f_ref_nT is not None:
        against, what = float(np.median(f_ref_nT)), "the file's reference f_ref"
    else:
        against, what = float(np.median(np.sqrt(np.einsum("ij,ij->i", raw_nT, raw_nT)))), "the raw readings'"
    ratio = float(np.median(f_cal_nT)) / against if against > 0 else math.inf
    if CORRECTED_RATIO_RANGE[0] <= ratio <= CORRECTED_RATIO_RANGE[1]:
        return None
    return (f"the corrected magnitudes (median {np.median(f_cal_nT):.6g} nT) are {ratio:.3g} times {what} (median "
            f"{against:.6g} nT): the calibration is not for these readings (another sensor or unit, or a changed "
            "matrix)")


def apply_to_csv(cal: Calibration, src, out, units: str = "nT", force: bool = False, cal_name: str = "",
                 inputs=(), accept_any: bool = False) -> dict:
    """Write ``out``: the data file ``src`` with the corrected field ``bx_cal, by_cal, bz_cal`` and its
    magnitude ``f_cal`` added as the last columns (in ``units``, the unit of the file's field columns);
    every other line and column of ``src`` is copied byte for byte, its ``#`` metadata lines too, with
    two lines added after them (``# calibration:`` and ``# cal_units:``).  ``src`` is read once: the rows
    corrected and the lines copied come from the same bytes.  Refuses (``InputError``) an ``out`` that is
    ``src`` or one of ``inputs`` (by inode, hard links included) or exists (unless ``force``), a file that
    already has those columns, readings whose magnitude does not fit the calibration's reference
    (wrong ``units``), rows in mixed units (``mixed_units``) and readings of exactly 0 on every axis
    (``zero_readings``), a reference that does not belong to the readings (``acceptance.reference_problems``: f_ref in
    uT beside readings in nT), and, unless ``accept_any`` (then ``info["warnings"]`` says it), corrected magnitudes
    that cannot be the measured field (``correction_misfit``).  ``out`` is written atomically."""
    src, out = Path(src), Path(out)
    check_output(out, [src, *inputs], force)
    source = read_input(src, "data file")
    field = cal.field_nT if math.isfinite(cal.field_nT) and cal.field_nT > 0 else None
    data = read_csv(src, units=units, require_vector=True, expected_field_nT=field, source=source)
    mixed = mixed_units(data.raw_nT) or zero_readings(data.raw_nT)
    if not mixed and data.f_ref_nT is not None:
        mixed = reference_problems(data.raw_nT, data.f_ref_nT, data.t_s)
    if mixed:
        raise InputError(f"{src}: {with_file_lines(mixed, data.meta.get('first_data_line'))}")
    head = _parse_head(newline_lines(source.data), str(src))
    sep, names = _header(src, head.header)
    clash = [c for c in CAL_COLUMNS if c in names]
    if clash:
        raise InputError(f"{src} already has column(s) {', '.join(clash)}: it was calibrated already "
                         "(apply the calibration to the raw file)")
    factor = UNIT_FACTORS_NT[units]
    corrected = cal.correct(data.raw_nT)
    magnitude = np.linalg.norm(corrected, axis=1)
    misfit = correction_misfit(magnitude, data.raw_nT, data.f_ref_nT)
    if misfit and not accept_any:
        raise InputError(f"{src}: {misfit}; nothing written (--accept-any writes it anyway)")
    values = np.column_stack([corrected, magnitude]) / factor
    lines = source.data.decode("utf-8-sig").splitlines(keepends=True)
    skipped = head.skipped
    head_lines, body = lines[:skipped], lines[skipped:]
    header, rows = body[0], body[1:]
    eol = header[len(header.rstrip("\r\n")):] or "\n"
    digits = ".4f" if units == "nT" else ".10g"
    written, k = [], 0
    for line in rows:
        text = line.rstrip("\r\n")
        if not text.strip():
            written.append(line)
            continue
        if k >= len(values):
            raise InputError(f"{src}: more data lines than rows read ({len(values)}): quoted line breaks are not "
                             "supported")
        ending = line[len(text):] or eol
        written.append(text + sep + sep.join(format(v, digits) for v in values[k]) + ending)
        k += 1
    if k != len(values):
        raise InputError(f"{src}: {k} data lines but {len(values)} rows read: quoted line breaks are not supported")
    note = [f"# calibration: {one_line(cal_name or 'calibration')} ({one_line(cal.method or cal.origin)}, "
            f"{one_line(cal.model)} model, data {one_line(cal.data_digest or 'unknown')}){eol}", f"# cal_units: {units}{eol}"]
    if head_lines and not head_lines[-1].endswith(("\n", "\r")):
        head_lines[-1] += eol
    text = "".join(head_lines + note + [header.rstrip("\r\n") + sep + sep.join(CAL_COLUMNS) + eol] + written)
    atomic_write(out, text, [source, *inputs], force)
    f_cal_nT = values[:, 3] * factor
    info = {"out": str(out), "n_rows": int(len(values)), "columns_added": list(CAL_COLUMNS), "units": units,
            "input_sha256": source.sha256, "warnings": [f"written by --accept-any: {misfit}"] if misfit else []}
    if data.f_ref_nT is not None:
        info["rms_f_cal_minus_f_ref_nT"] = float(np.sqrt(np.mean((f_cal_nT - data.f_ref_nT) ** 2)))
    return info
