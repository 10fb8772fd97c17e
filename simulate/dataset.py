"""The dataset type and its CSV form (CONTRACT section 2).

A ``Dataset`` holds raw readings in nT (sensor frame), sample times, the scalar reference magnitude,
optional temperature and heading, and the ground truth when it was simulated (``None`` for real data).
Arrays are copied and made read-only on construction, so no calibrator can change a user's data.
"""
from __future__ import annotations

import io
import json
import math
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

UNIT_FACTORS_NT = {"nT": 1.0, "uT": 1e3, "µT": 1e3, "mG": 100.0, "G": 1e5}
"""Multiply a value in that unit by this factor to get nT."""

FIELD_COLUMNS = ("bx", "by", "bz", "f_ref", "f_meas", "f_meas_before", "f_meas_after")


from magbench.errors import InputError  # noqa: E402  (re-exported: magbench.simulate.InputError)


def readonly_copy(a, dtype=float, ndim=None, name="array"):
    """A read-only copy of ``a`` (None stays None); ``ndim`` is checked when given.  The one way the project
    freezes an array it keeps (datasets, results, the views a calibrator gets)."""
    if a is None:
        return None
    arr = np.array(a, dtype=dtype, copy=True)
    if ndim is not None and arr.ndim != ndim:
        raise InputError(f"{name} must have {ndim} dimension(s), got shape {arr.shape}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class Truth:
    """What was simulated: the true correction (canonical form), the sensor as specified, the field."""

    params: object  # simulate.sensor.ErrorParams: what an ideal calibrator reports
    sensor: object  # simulate.sensor.SensorModel as simulated
    field_ned_nT: tuple[float, float, float]
    scenario: str = ""
    seed: int | None = None
    effects: tuple = ()
    attitude_quat: np.ndarray | None = None  # body -> NED rotation of each sample (scalar-last quaternions)
    raw_without_effects_nT: np.ndarray | None = None  # the same readings (same noise) with no effect on

    def __post_init__(self):
        object.__setattr__(self, "attitude_quat", readonly_copy(self.attitude_quat, ndim=2, name="attitude_quat"))
        object.__setattr__(self, "raw_without_effects_nT",
                           readonly_copy(self.raw_without_effects_nT, ndim=2, name="raw_without_effects_nT"))

    def as_dict(self) -> dict:
        s = self.sensor
        return {
            "scenario": self.scenario,
            "seed": self.seed,
            **self.params.as_dict(),
            "sensor": {
                "convention": s.convention,
                "alpha_rad": s.errors.alpha_rad,
                "beta_rad": s.errors.beta_rad,
                "gamma_rad": s.errors.gamma_rad,
                "scale": list(s.errors.scale),
                "offset_nT": list(s.errors.offset_nT),
                "noise_nT": s.noise_nT,
                "quantization_nT": s.quantization_nT,
            },
            "field_ned_nT": list(self.field_ned_nT),
            "field_total_nT": float(np.linalg.norm(self.field_ned_nT)),
            "effects": [dict(e) for e in self.effects],
        }


@dataclass(frozen=True)
class Dataset:
    """Raw readings (n, 3) in nT with their reference magnitude and optional columns."""

    raw_nT: np.ndarray
    f_ref_nT: np.ndarray | None = None
    t_s: np.ndarray | None = None
    temp_C: np.ndarray | None = None
    heading_deg: np.ndarray | None = None
    truth: Truth | None = None
    meta: dict = field(default_factory=dict)

    def __post_init__(self):
        raw = readonly_copy(self.raw_nT, ndim=2, name="raw_nT")
        if raw.shape[1] != 3:
            raise InputError(f"raw_nT must have 3 columns (bx, by, bz), got {raw.shape[1]}")
        object.__setattr__(self, "raw_nT", raw)
        n = raw.shape[0]
        for name in ("f_ref_nT", "t_s", "temp_C", "heading_deg"):
            value = getattr(self, name)
            if value is None:
                continue
            arr = np.asarray(value, dtype=float)
            if arr.ndim == 0:
                arr = np.full(n, float(arr))
            arr = readonly_copy(arr, ndim=1, name=name)
            if arr.shape[0] != n:
                raise InputError(f"{name} has {arr.shape[0]} rows but raw_nT has {n}")
            object.__setattr__(self, name, arr)
        object.__setattr__(self, "meta", dict(self.meta))

    def __len__(self) -> int:
        return self.raw_nT.shape[0]

    @property
    def has_reference(self) -> bool:
        return self.f_ref_nT is not None

    def with_reference(self, f_ref_nT) -> Dataset:
        return replace(self, f_ref_nT=f_ref_nT)

    # ------------------------------------------------------------------ CSV (CONTRACT section 2)
    def to_csv(self, path, float_format: str = "%.4f") -> None:
        import pandas as pd

        cols = {}
        if self.t_s is not None:
            cols["t"] = self.t_s
        cols["bx"], cols["by"], cols["bz"] = self.raw_nT.T
        if self.f_ref_nT is not None:
            cols["f_ref"] = self.f_ref_nT
        if self.temp_C is not None:
            cols["temp"] = self.temp_C
        if self.heading_deg is not None:
            cols["heading_deg"] = self.heading_deg
        buf = io.StringIO()
        for key, value in self.meta.items():
            buf.write(f"# {key}: {value}\n")
        pd.DataFrame(cols).to_csv(buf, index=False, float_format=float_format, lineterminator="\n")
        Path(path).write_text(buf.getvalue(), encoding="utf-8")


@dataclass(frozen=True)
class ScalarSeries:
    """A scalar-only series (seed 000's Table 2 style): total field per heading, no vector readings."""

    f_meas_nT: np.ndarray
    heading_deg: np.ndarray | None = None
    f_ref_nT: np.ndarray | None = None
    t_s: np.ndarray | None = None
    temp_C: np.ndarray | None = None
    extra: dict = field(default_factory=dict)
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.f_meas_nT)


def _parse_meta(lines: list[str]) -> dict:
    meta = {}
    for line in lines:
        body = line.lstrip("#").strip()
        if ":" in body:
            key, value = body.split(":", 1)
            meta[key.strip()] = value.strip()
    return meta


def guess_unit(median_magnitude: float, expected_nT: float) -> str:
    """The unit whose conversion puts a typical magnitude nearest (in log) to the expected field."""
    if not (median_magnitude > 0 and math.isfinite(median_magnitude)):
        return "nT"
    best = min(("nT", "uT", "mG", "G"),
               key=lambda u: abs(math.log10(median_magnitude * UNIT_FACTORS_NT[u] / expected_nT)))
    return best


MAX_ABS_NT = 1.0e9
"""No reading or reference exceeds 1 T (1e9 nT) in magnitude: a larger number is a broken row, not a field."""
NUMERIC_COLUMNS = FIELD_COLUMNS + ("t", "temp", "heading_deg", "ax", "ay", "az")
"""Columns read as numbers (CONTRACT section 2); any other column is kept as text and ignored."""
MAX_ABS_OTHER = 1.0e12
"""The largest magnitude accepted in the other numeric columns (time in s, temperature, heading)."""
DELIMITERS = (",", ";", "\t")
"""Column separators recognised in the header row (CONTRACT: comma; semicolon and tab are read too)."""
ENCODINGS = ("utf-8-sig",)
"""UTF-8, with or without a byte-order mark (CONTRACT section 2)."""


def writable_path(path, force: bool = False) -> Path:
    """``path`` as a file a command may write: refused (``InputError``) when it is a directory, when its
    directory does not exist, or when it exists and ``force`` is not given.  The one check every command
    makes before writing an output."""
    path = Path(path)
    if path.is_dir():
        raise InputError(f"{path} is a directory, not a file")
    if not path.parent.exists():
        raise InputError(f"directory {path.parent} does not exist")
    if path.exists() and not force:
        raise InputError(f"{path} exists; refusing to overwrite it (use --force)")
    return path


def _file_head(path: Path) -> tuple[dict, int, str]:
    """The metadata of the ``#`` lines before the header, the number of lines before the header, and the
    header line; refuses what is not a readable UTF-8 text file."""
    if path.is_dir():
        raise InputError(f"{path} is a directory, not a data file")
    if not path.exists():
        raise InputError(f"no such file: {path}")
    meta_lines, skipped = [], 0
    try:
        with path.open("r", encoding=ENCODINGS[0], newline="") as handle:
            for line in handle:
                if line.startswith("#") or not line.strip():
                    if line.startswith("#"):
                        meta_lines.append(line.rstrip("\r\n"))
                    skipped += 1
                    continue
                if "\x00" in line:
                    raise InputError(f"{path} is not UTF-8 text (it has NUL bytes: UTF-16 or binary?)")
                return _parse_meta(meta_lines), skipped, line.rstrip("\r\n")
    except UnicodeDecodeError as exc:
        raise InputError(f"{path} is not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except OSError as exc:
        raise InputError(f"cannot read {path}: {exc.strerror or exc}") from None
    raise InputError(f"{path} has no header row and no data")


def _header(path: Path, line: str) -> tuple[str, list[str]]:
    """The separator and the column names (stripped, lower case); duplicates in any case are refused."""
    sep = max(DELIMITERS, key=line.count)
    if line.count(sep) == 0:
        sep = ","
    names = [c.strip().strip('"').strip().lower() for c in line.split(sep)]
    seen: dict[str, int] = {}
    for name in names:
        seen[name] = seen.get(name, 0) + 1
    dup = sorted(n for n, k in seen.items() if k > 1 and n)
    if dup:
        raise InputError(f"{path}: column(s) {', '.join(dup)} appear more than once in the header "
                         "(names are case-insensitive)")
    return sep, names


def _table(path: Path, skipped: int, sep: str, names: list[str], numeric: list[str]):
    """The data rows: the numeric columns parsed straight to floats (the fast path: two million rows in
    about a second, no string objects); when that fails, everything as text so that the bad value can be
    named by ``_numeric``."""
    import pandas as pd

    options = dict(sep=sep, skiprows=skipped + 1, header=None, names=names, encoding=ENCODINGS[0],
                   skipinitialspace=True, comment=None, engine="c", skip_blank_lines=True, index_col=False)
    try:
        try:
            frame = pd.read_csv(path, dtype={n: np.float64 for n in numeric}, na_filter=False, **options)
        except ValueError:
            frame = pd.read_csv(path, dtype=str, na_filter=False, **options)
    except Exception as exc:  # pandas raises several parser errors
        raise InputError(f"{path} is not a readable CSV file: {str(exc).splitlines()[0]}") from None
    if len(frame) == 0:
        raise InputError(f"{path} has a header but no data rows")
    return frame


def _numeric(path: Path, frame, name: str, first_line: int) -> np.ndarray:
    """A column as finite floats within +-MAX_ABS_NT; refuses a bad value naming its line."""
    import pandas as pd

    text = frame[name]
    if text.dtype == np.float64:
        values = text.to_numpy()
    else:
        values = pd.to_numeric(text.astype(str).str.strip(), errors="coerce").to_numpy(dtype=float)
    is_field = name in FIELD_COLUMNS
    limit = MAX_ABS_NT if is_field else MAX_ABS_OTHER
    with np.errstate(invalid="ignore"):
        bad = np.flatnonzero(~(np.abs(values) <= limit))
    if bad.size:
        rows = ", ".join(str(first_line + i) for i in bad[:5])
        more = f" and {bad.size - 5} more" if bad.size > 5 else ""
        raw_value = text.iloc[bad[0]]
        absurd = "beyond any magnetic field (1e9 nT)" if is_field else f"beyond any plausible value ({limit:g})"
        why = absurd if np.isfinite(values[bad[0]]) else "missing, non-numeric or non-finite"
        raise InputError(f"{path}: column {name} has a value {why} ({raw_value!r}) on line {rows}{more}")
    return values


def _meta_field_nT(path: Path, meta: dict) -> float | None:
    text = meta.get("field_nT")
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{path}: metadata line 'field_nT: {text}' is not a number") from None
    if not (math.isfinite(value) and 0 < value <= MAX_ABS_NT):
        raise InputError(f"{path}: metadata line 'field_nT: {text}' must be a positive number of nT")
    return value


def read_csv(path, units: str = "nT", require_vector: bool = True, expected_field_nT: float | None = None):
    """Read a data file (CONTRACT section 2) into a ``Dataset`` (or a ``ScalarSeries`` when the file has
    ``f_meas`` instead of bx, by, bz and ``require_vector`` is false).

    ``units`` applies to every field column of the file (bx, by, bz, f_ref, f_meas); the ``# field_nT:``
    metadata line is in nT by its name.  Refuses, with an ``InputError`` naming the line, non-numeric,
    non-finite or absurd values (beyond 1 T), duplicate column names in any letter case, a directory,
    an unreadable or non-UTF-8 file, and a file whose magnitudes look like another unit than ``units``
    (compared with ``expected_field_nT``, else the file's ``# field_nT:``, else the geomagnetic range).
    The file is read once by pandas' C parser (two million rows in about a second).
    """
    path = Path(path)
    if units not in UNIT_FACTORS_NT:
        raise InputError(f"unknown unit {units!r}: use one of nT, uT, mG, G")
    meta, skipped, header_line = _file_head(path)
    sep, names = _header(path, header_line)
    numeric = [c for c in names if c in NUMERIC_COLUMNS]
    frame = _table(path, skipped, sep, names, numeric)
    first_line = skipped + 2
    has_vector = all(c in names for c in ("bx", "by", "bz"))
    scalar_col = next((c for c in ("f_meas", "f_meas_before") if c in names), None)
    if not has_vector and (require_vector or scalar_col is None):
        missing = [c for c in ("bx", "by", "bz") if c not in names]
        extra = " (it is a scalar-only series: use 'magbench diagnose')" if scalar_col else ""
        raise InputError(f"{path} lacks column(s) {', '.join(missing)}{extra}")

    def column(name):
        return _numeric(path, frame, name, first_line) if name in names else None

    factor = UNIT_FACTORS_NT[units]
    f_ref = column("f_ref")
    if f_ref is not None and np.any(f_ref <= 0):
        row = first_line + int(np.flatnonzero(f_ref <= 0)[0])
        raise InputError(f"{path}: f_ref must be a positive magnitude, not {f_ref[f_ref <= 0][0]:g} (line {row})")
    f_ref = f_ref * factor if f_ref is not None else None
    field_meta = _meta_field_nT(path, meta)
    if expected_field_nT is None:
        expected_field_nT = field_meta

    common = dict(t_s=column("t"), temp_C=column("temp"), heading_deg=column("heading_deg"))
    meta = {**meta, "source_file": str(path), "units_read": units}
    if has_vector:
        raw = np.column_stack([column(c) for c in ("bx", "by", "bz")])
        magnitude = float(np.median(np.sqrt(np.einsum("ij,ij->i", raw, raw))))
    else:
        raw = None
        magnitude = float(np.median(column(scalar_col)))
    check_units(magnitude, units, expected_field_nT, where=str(path))
    if has_vector:
        return Dataset(raw * factor, f_ref_nT=f_ref, meta=meta, **common)
    extra = {c: column(c) * factor for c in FIELD_COLUMNS if c in names and c not in ("f_ref",)}
    return ScalarSeries(column(scalar_col) * factor, f_ref_nT=f_ref, extra=extra, meta=meta, **common)


def check_units(magnitude: float, units: str, expected_field_nT: float | None = None, where: str = "input") -> None:
    """Refuse magnitudes that look like another unit than the one given.

    With a known field the median magnitude, converted to nT, must lie within a factor 5 of it; without
    one, between 1,000 and 10,000,000 nT (Earth's field is 22,000 to 67,000 nT; hard-iron offsets and
    lab coils widen that).  The message names the unit the numbers look like.
    """
    nt = magnitude * UNIT_FACTORS_NT[units]
    reference = expected_field_nT if expected_field_nT else 50000.0
    ok = 1.0e3 <= nt <= 1.0e7
    if expected_field_nT:
        ok = ok and 0.2 <= nt / expected_field_nT <= 5.0
    if not ok:
        guess = guess_unit(magnitude, reference)
        hint = f"they look like {guess}: read with --units {guess}" if guess != units else \
            "check the file and the reference"
        ref = f" against a reference of {expected_field_nT:.6g} nT" if expected_field_nT else ""
        raise InputError(f"{where}: median field magnitude {magnitude:.4g} {units} is implausible{ref}; {hint}")


def write_truth(truth: Truth, path) -> None:
    Path(path).write_text(json.dumps(truth.as_dict(), indent=2) + "\n", encoding="utf-8")
