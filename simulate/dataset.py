"""The dataset type and its CSV form (CONTRACT section 2).

A ``Dataset`` holds raw readings in nT (sensor frame), sample times, the scalar reference magnitude,
optional temperature and heading, and the ground truth when it was simulated (``None`` for real data).
Arrays are copied and made read-only on construction, so no calibrator can change a user's data.
"""
from __future__ import annotations

import io
import json
import math
import re
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

UNIT_FACTORS_NT = {"nT": 1.0, "uT": 1e3, "µT": 1e3, "mG": 100.0, "G": 1e5}
"""Multiply a value in that unit by this factor to get nT."""

FIELD_COLUMNS = ("bx", "by", "bz", "f_ref", "f_meas", "f_meas_before", "f_meas_after")


from magbench.errors import InputError  # noqa: E402  (re-exported: magbench.simulate.InputError)
from magbench.safeio import InputBytes, as_path, atomic_write, check_output, one_line, read_input  # noqa: E402


def real_array(values, what: str, not_numbers: str | None = None) -> np.ndarray:
    """``values`` as a float array, else ``InputError``: ``not_numbers`` (default: ``what`` must be numbers)
    when they are not numbers, and complex values and None refused by name (a cast to float drops their imaginary
    parts with only numpy's warning: a fit of x + iy was answered as if the readings were x; None became NaN)."""
    try:
        arr = np.asarray(values)
    except (TypeError, ValueError):
        raise InputError(not_numbers or f"{what} must be numbers") from None
    if np.iscomplexobj(arr) or (arr.dtype == object and any(isinstance(v, complex) for v in arr.ravel())):
        raise InputError(f"{what} must be real numbers, not complex")
    if arr.dtype == object and any(v is None for v in arr.ravel()):  # a cast makes None a NaN without a word
        raise InputError(f"{what} must be numbers: a value is None")
    try:
        return arr.astype(float, copy=False)
    except (TypeError, ValueError):
        raise InputError(not_numbers or f"{what} must be numbers") from None


def readonly_copy(a, dtype=float, ndim=None, name="array"):
    """A read-only copy of ``a`` (None stays None); ``ndim`` is checked when given.  The one way the project
    freezes an array it keeps (datasets, results, the views a calibrator gets); a float copy of complex
    values is refused (``real_array``)."""
    if a is None:
        return None
    if dtype is float:
        a = real_array(a, name)
    arr = np.array(a, dtype=dtype, copy=True)
    if ndim is not None and arr.ndim != ndim:
        raise InputError(f"{name} must have {ndim} dimension(s), got shape {arr.shape}")
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class Truth:
    """What was simulated: the true correction (canonical form), the sensor as specified, the field."""

    params: Any  # simulate.sensor.ErrorParams: what an ideal calibrator reports
    sensor: Any  # simulate.sensor.SensorModel as simulated
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
        if self.raw_nT is None:
            raise InputError("raw_nT must be readings of shape (n, 3) (bx, by, bz), got None")
        if not isinstance(self.meta, dict):
            raise InputError(f"meta must be a dict, got {type(self.meta).__name__}")
        raw = readonly_copy(self.raw_nT, ndim=2, name="raw_nT")
        if raw.shape[1] != 3:
            raise InputError(f"raw_nT must have 3 columns (bx, by, bz), got {raw.shape[1]}")
        object.__setattr__(self, "raw_nT", raw)
        n = raw.shape[0]
        for name in ("f_ref_nT", "t_s", "temp_C", "heading_deg"):
            value = getattr(self, name)
            if value is None:
                continue
            arr = real_array(value, name)
            if arr.ndim == 0:
                arr = np.full(n, float(arr))
            arr = readonly_copy(arr, ndim=1, name=name)
            if arr.shape[0] != n:
                raise InputError(f"{name} has {arr.shape[0]} rows but raw_nT has {n}")
            bad = np.flatnonzero(~np.isfinite(arr)) if name != "f_ref_nT" else ()
            if len(bad):  # a NaN time would sort last and reorder the judge's time neighbours without a word
                rows = ", ".join(map(str, bad[:5])) + (f" and {len(bad) - 5} more" if len(bad) > 5 else "")
                raise InputError(f"{name} has NaN or infinite values in row(s) {rows}")
            largest = float(np.max(np.abs(arr))) if name != "f_ref_nT" and n else 0.0
            if largest > MAX_ABS_OTHER:  # the reader's own limit
                raise InputError(f"{name} has values beyond {MAX_ABS_OTHER:g} in magnitude (up to {largest:.3g}): a "
                                 f"broken column, not {name}")
            hot = temperature_problem(arr) if name == "temp_C" else None
            if hot is not None:
                raise InputError(f"temp_C in row {hot[0]} is {hot[1]}")
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
        """The readings as a data file (CONTRACT section 2), its metadata as ``# key: value`` lines first: what
        ``pandas.DataFrame.to_csv(index=False, float_format=...)`` writes, byte for byte (tests/test_write_without_pandas.py;
        ``simulate`` then does not import pandas, 0.15-0.3 s of the command)."""
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
        for key, value in self.meta.items():  # a line break in a key or value had forged a line of its own
            buf.write(f"# {one_line(key)}: {one_line(value)}\n")
        buf.write(",".join(cols) + "\n")
        # every column is float64 (``__post_init__``); a NaN as an empty field, as pandas writes it
        text = [[float_format % v if v == v else "" for v in np.asarray(a, dtype=float).tolist()] for a in cols.values()]
        buf.writelines(",".join(row) + "\n" for row in zip(*text))
        atomic_write(path, buf.getvalue(), force=True)


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

    def __post_init__(self):
        """What ``len`` and the readers need, as ``Dataset``'s: f_meas_nT given with rows, ``extra`` and ``meta`` dicts
        (they had been internal errors: TypeError, AttributeError); the values and shapes are checked where they are
        read (``diagnose_scalar``)."""
        try:
            ndim = None if self.f_meas_nT is None else np.ndim(self.f_meas_nT)
        except ValueError:  # rows of different lengths
            ndim = -1
        if ndim is None or ndim < 1:  # more dimensions: the columns' own check says the shape (diagnose_scalar)
            one = "one number" if isinstance(self.f_meas_nT, (int, float, np.number)) else type(self.f_meas_nT).__name__
            raise InputError("f_meas_nT must be one value per row (a 1-D array, nT), got "
                             + {None: "None", -1: "rows of different lengths"}.get(ndim, one))
        for name in ("extra", "meta"):
            if not isinstance(getattr(self, name), dict):
                raise InputError(f"{name} must be a dict, got {type(getattr(self, name)).__name__}")

    def __len__(self) -> int:
        return len(self.f_meas_nT)

    @property
    def has_reference(self) -> bool:
        return self.f_ref_nT is not None

    def with_reference(self, f_ref_nT) -> ScalarSeries:
        """The series with a reference per row (a file without f_ref, given ``--field``, ``--igrf`` or a ``# field_nT:``
        line: had been an internal error, a ``Dataset``'s method asked of a series)."""
        return replace(self, f_ref_nT=f_ref_nT)


def guess_unit(median_magnitude: float, expected_nT: float) -> str:
    """The unit whose conversion puts a typical magnitude nearest (in log) to the expected field."""
    if not (median_magnitude > 0 and math.isfinite(median_magnitude)):
        return "nT"
    best = min(("nT", "uT", "mG", "G"),
               key=lambda u: abs(math.log10(median_magnitude * UNIT_FACTORS_NT[u] / expected_nT)))
    return best


def units_apart(ratio: float, tolerance: float = 0.05, min_exponent: int = 1) -> str | None:
    """What to say when the readings are ``ratio`` times the reference and that ratio is the factor between two units
    (1000 between uT and nT) within ``tolerance`` in log10 and at least 10^``min_exponent``: the two columns were
    written in different units, and one ``units`` reads both (a file of readings in uT beside an f_ref in nT had been
    told to use units='uT', and then refused again)."""
    if not 0 < ratio < math.inf:
        return None
    exponent = round(math.log10(ratio))
    if abs(exponent) < max(min_exponent, 1) or abs(math.log10(ratio) - exponent) > tolerance:
        return None
    factor = 10.0 ** abs(exponent)
    pairs = [f"{a} and {b}" for a, b in (("uT", "nT"), ("mG", "nT"), ("G", "nT"), ("uT", "mG"), ("G", "uT"), ("G", "mG"))
             if UNIT_FACTORS_NT[a] / UNIT_FACTORS_NT[b] == factor]
    if not pairs:  # 10^4, 10^6: no two units are that far apart
        return None
    return (f"a factor of {factor:,.0f}, as between {' or '.join(pairs)}: the readings and f_ref "
            "were written in different units, and the units they are read in (units=) apply to both: write f_ref "
            "in the readings' unit (or the readings in f_ref's)")


MAX_ABS_NT = 1.0e9
"""No reading or reference exceeds 1 T (1e9 nT) in magnitude: a larger number is a broken row, not a field."""
NUMERIC_COLUMNS = FIELD_COLUMNS + ("t", "temp", "heading_deg", "ax", "ay", "az")
"""Columns read as numbers (CONTRACT section 2); any other column is kept as text and ignored."""
MAX_ABS_OTHER = 1.0e12
"""The largest magnitude accepted in the other numeric columns (time in s, temperature, heading)."""
TEMP_RANGE_C = (-273.15, 1000.0)
"""A logged temperature in deg C lies within these: below absolute zero is a missing-value code (-9999) or another
unit, above 1000 C no magnetometer works (a broken cell).  One such cell had wrecked a diagnosis without a word (a
temperature held-out RMS of 677 nT, 'beyond time' -1e15 %); a file in kelvin or Fahrenheit stays within them and is
read (only the temperature's changes are used)."""


def temperature_problem(values: np.ndarray) -> tuple[int, str] | None:
    """(the first row outside ``TEMP_RANGE_C``, why), or None."""
    low, high = TEMP_RANGE_C
    with np.errstate(invalid="ignore"):
        bad = np.flatnonzero(~((values >= low) & (values <= high)))
    if not len(bad):
        return None
    v = float(values[bad[0]])
    why = (f"below absolute zero ({v:g} C: a missing-value code? temperatures are in deg C)" if v < low else
           f"above {high:g} C ({v:g}), where no magnetometer works: a broken cell")
    return int(bad[0]), why


DELIMITERS = (",", ";", "\t")
"""Column separators recognised in the header row (CONTRACT: comma; semicolon and tab are read too)."""
ENCODINGS = ("utf-8-sig",)
"""UTF-8, with or without a byte-order mark (CONTRACT section 2)."""


def writable_path(path, force: bool = False, inputs=()) -> Path:
    """``path`` as a file a command may write: refused (``InputError``) when it is a directory or another
    non-regular file, when its directory does not exist, when it exists and ``force`` is not given, and
    when it is one of ``inputs`` (by inode: hard links count).  The one check every command makes before
    writing an output (``magbench.safeio.check_output``)."""
    return check_output(path, inputs, force)


MAX_LINE_BYTES = 1024 * 1024
"""The longest line read (1 MiB): a data row of a few numbers is a hundred bytes."""
MAX_COLUMNS = 1000
"""The most columns a header may name."""
MAX_META_LINES = 10000
"""The most ``#`` and blank lines before the header."""


@dataclass(frozen=True)
class _Head:
    meta: dict
    skipped: int  # lines before the header
    header: str
    body_start: int  # byte offset of the first line after the header


def _parse_meta(lines: list[str], where: str = "input") -> dict:
    """``# key: value`` lines as a dict; a key given twice with different values is refused (which one
    would be meant is ambiguous)."""
    meta: dict = {}
    for line in lines:
        body = line.lstrip("#").strip()
        if ":" in body:
            key, value = body.split(":", 1)
            key, value = key.strip(), value.strip()
            if key in meta and meta[key] != value:
                raise InputError(f"{where}: conflicting metadata lines '# {key}: {meta[key]}' and '# {key}: {value}': "
                                 "keep one")
            meta[key] = value
    return meta


PACKED_FORMATS = ((b"\x1f\x8b", "gzip-compressed"), (b"PK\x03\x04", "a zip archive (or an .xlsx/.ods workbook)"),
                  (b"BZh", "bzip2-compressed"), (b"\xfd7zXZ\x00", "xz-compressed"), (b"\x28\xb5\x2f\xfd", "zstd-compressed"),
                  (b"MATLAB 5.0 MAT-file", "a MATLAB .mat file"), (b"\x89HDF", "an HDF5 file"))
"""Files a user may give for a CSV, recognized by their first bytes and named in the refusal."""


def newline_lines(data: bytes) -> bytes:
    """A file's bytes with classic Mac OS line endings (carriage returns only, no line feed anywhere) turned into line
    feeds, so that its lines are read as lines (the file itself is not changed); any other file as it is."""
    return data.replace(b"\r", b"\n") if b"\r" in data and b"\n" not in data else data


EXCEL_SEP = re.compile(r"sep=[,;\t|]")
"""The separator hint a spreadsheet writes as a CSV file's first line (Excel's ``sep=,``): not a header, skipped."""


def _spreadsheet_comment(line: str) -> str:
    """A ``#`` line as a spreadsheet exports it, with its row's empty cells after it (``# field_nT: 50000,,,``) or its
    one cell quoted (``"# note: a, b",,,``), as the ``#`` line it is; any other line as it is (such files had been
    refused as a metadata value that is not a number, or as a header without bx, by, bz)."""
    if line.startswith('"#'):  # quoted as a spreadsheet quotes ("" for a quote inside), whatever its separator
        import csv

        for sep in DELIMITERS:
            cells = next(csv.reader([line], delimiter=sep))
            if cells and cells[0].startswith("#") and not any(c.strip() for c in cells[1:]):
                return cells[0]
        return line
    if line.startswith("#"):
        return line.rstrip(",;\t| ")
    return line


def _parse_head(data: bytes, where: str) -> _Head:
    """The ``#`` metadata before the header, the number of lines before it, the header line and where the
    rows start; refuses what is not UTF-8 text, and an overlong header."""
    pos, skipped, meta_lines = 0, 0, []
    for magic, kind in PACKED_FORMATS:
        if data.startswith(magic):
            raise InputError(f"{where} is {kind}, not a CSV text file: unpack it and give the CSV inside")
    if data.startswith(b"\xef\xbb\xbf"):
        pos = 3
    while pos < len(data):
        end = data.find(b"\n", pos)
        end = len(data) if end < 0 else end
        if end - pos > MAX_LINE_BYTES:
            raise InputError(f"{where}: line {skipped + 1} is longer than {MAX_LINE_BYTES:,} bytes (the limit "
                             "of a line): not a data file")
        raw = data[pos:end]
        if b"\x00" in raw:
            raise InputError(f"{where} is not UTF-8 text (it has NUL bytes: UTF-16 or binary?)")
        try:
            line = raw.decode("utf-8").rstrip("\r")
        except UnicodeDecodeError as exc:
            raise InputError(f"{where} is not UTF-8 text ({exc.reason} at byte {pos + exc.start})") from None
        if skipped == 0 and EXCEL_SEP.fullmatch(line):  # a spreadsheet's separator hint ('sep=,') as the first line
            skipped += 1
            pos = end + 1
            continue
        line = _spreadsheet_comment(line)
        if line.startswith("#") or not line.strip():
            if line.startswith("#"):
                meta_lines.append(line)
            skipped += 1
            if skipped > MAX_META_LINES:
                raise InputError(f"{where}: more than {MAX_META_LINES:,} comment or blank lines before the header")
            pos = end + 1
            continue
        return _Head(_parse_meta(meta_lines, where), skipped, line, min(end + 1, len(data)))
    raise InputError(f"{where} has no header row and no data")


def _header(path, line: str) -> tuple[str, list[str]]:
    """The separator and the column names (stripped, lower case); duplicates in any case are refused, and
    more than ``MAX_COLUMNS`` names."""
    sep = max(DELIMITERS, key=line.count)
    if line.count(sep) == 0:
        sep = ","
    if line.count(sep) >= MAX_COLUMNS:
        raise InputError(f"{path}: the header names {line.count(sep) + 1:,} columns, more than the limit of "
                         f"{MAX_COLUMNS:,}")
    names = [c.strip().strip('"').strip().lower() for c in line.split(sep)]
    seen: dict[str, int] = {}
    for name in names:
        seen[name] = seen.get(name, 0) + 1
    dup = sorted(n for n, k in seen.items() if k > 1 and n)
    if dup:
        raise InputError(f"{path}: column(s) {', '.join(dup)} appear more than once in the header "
                         "(names are case-insensitive)")
    return sep, names


def _check_rows(where, data: bytes, offset: int, sep: str, n_names: int, first_line: int) -> tuple[int, bool]:
    """The number of non-blank data lines of ``data[offset:]`` and whether they are consecutive lines (no blank line
    before the last of them: data row i is then line ``first_line + i``); refuses a line longer than
    ``MAX_LINE_BYTES`` and a line whose number of fields differs from the header's (vectorized over the
    positions of line ends and separators, so memory stays a small fraction of the file's; with quoted
    fields, Python's csv module counts instead)."""
    arr = np.frombuffer(data, dtype=np.uint8)[offset:]
    if arr.size == 0:
        return 0, True
    ends = np.flatnonzero(arr == 10)
    if ends.size == 0 or ends[-1] != arr.size - 1:
        ends = np.append(ends, arr.size)
    starts = np.concatenate([[0], ends[:-1] + 1])
    lengths = ends - starts
    if lengths.max() > MAX_LINE_BYTES:
        i = int(np.argmax(lengths > MAX_LINE_BYTES))
        raise InputError(f"{where}: line {first_line + i} is longer than {MAX_LINE_BYTES:,} bytes (the limit of a "
                         "line)")
    first = arr[np.minimum(starts, arr.size - 1)]
    blank = (lengths == 0) | ((lengths == 1) & (first == 13))
    if data.find(b'"', offset) >= 0:
        _check_quoted_rows(where, bytes(memoryview(data)[offset:]), sep, n_names, first_line)
        return _nonblank(arr, starts, ends, blank, np.flatnonzero(~blank & (lengths <= 2 * n_names)))
    fields = np.bincount(np.searchsorted(ends, np.flatnonzero(arr == ord(sep))), minlength=len(ends))[:len(ends)] + 1
    wrong = np.flatnonzero((fields != n_names) & ~blank)
    if wrong.size:
        for i in wrong[:1000]:  # lines of spaces only are blank (the first thousand suspects are enough)
            blank[i] = not bytes(arr[starts[i]:ends[i]]).strip()
        wrong = np.flatnonzero((fields != n_names) & ~blank)
    if wrong.size:
        i = int(wrong[0])
        line = bytes(arr[starts[i]:ends[i]])
        comment = line.lstrip().startswith(b"#")
        split = sep == "," and int(fields[i]) > n_names and _split_numbers(line.decode("utf-8", "replace"), n_names)
        raise InputError(f"{where} is not a readable CSV file: line {first_line + i} has {int(fields[i])} "
                         f"field(s) but the header names {n_names} column(s)"
                         + (f" (and {wrong.size - 1} more such lines)" if wrong.size > 1 else "")
                         + ("; it is a '#' comment: comment and metadata lines go before the header"
                            if comment else "")
                         + ("; its numbers look split at a decimal comma or a thousands comma: write numbers with a "
                            "decimal point and no thousands separators (or separate the columns by semicolons)"
                            if split else ""))
    return _consecutive(blank)


def _split_numbers(line: str, n_names: int) -> bool:
    """Whether a comma-separated ``line`` with more fields than ``n_names`` is numbers written with a decimal comma
    (50000,0 read as two fields) or commas between thousands: every field is digits, and pairs (or groups of three-digit
    fields) joined by commas give ``n_names`` numbers."""
    cells = [c.strip() for c in line.strip().split(",")]
    if not all(re.fullmatch(r"[+-]?\d+(\.\d+)?", c) for c in cells):
        return False
    if len(cells) == 2 * n_names:  # each number split once at its decimal comma
        return True
    return sum(1 for c in cells if not re.fullmatch(r"\d{3}(\.\d+)?", c)) == n_names  # 50,000.0: groups of three


def _consecutive(blank: np.ndarray) -> tuple[int, bool]:
    """(lines not blank, whether no blank line comes before the last of them)."""
    kept = np.flatnonzero(~blank)
    return int(kept.size), bool(kept.size == 0 or kept[-1] == kept.size - 1)


def _nonblank(arr, starts, ends, blank, suspects) -> tuple[int, bool]:
    """``_consecutive`` of the lines, the ``suspects`` (short lines) checked for whitespace only."""
    blank = blank.copy()
    for i in suspects:
        blank[i] = not bytes(arr[starts[i]:ends[i]]).strip()
    return _consecutive(blank)


def _check_quoted_rows(where, body: bytes, sep: str, n_names: int, first_line: int) -> None:
    """With quoted fields (rare in data files): the records read by Python's csv module, which knows
    quoting; a field that spans lines (an unbalanced quote, or a quoted line break) and a record whose
    number of fields differs from the header's are refused, naming the line."""
    import csv

    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError as exc:
        raise InputError(f"{where} is not UTF-8 text ({exc.reason})") from None
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=sep, skipinitialspace=True, strict=False)
    line = first_line
    try:
        for record in reader:
            start, line = line, first_line + reader.line_num
            if not record or all(not f.strip() for f in record) and len(record) <= 1:
                continue
            if line - start > 1 or any("\n" in f or "\r" in f for f in record):
                raise InputError(f"{where}: a quoted field starting on line {start} spans {line - start} lines: an "
                                 "unbalanced quote (\") joins lines into one field, or a field holds a line break")
            if len(record) != n_names:
                raise InputError(f"{where} is not a readable CSV file: line {start} has {len(record)} field(s) but "
                                 f"the header names {n_names} column(s)")
        tail = text.rsplit("\n", 1)[-1]
        if tail.strip() and _open_at_end(tail, sep):  # the csv module closes a quote left open at the file's end
            raise InputError(f"{where}: a quote (\") on line {line - 1 if line > first_line else line}, the last, "
                             "never closes: an unbalanced quote")
    except csv.Error as exc:
        if "field limit" in str(exc):  # a quote never closed: the field runs on to the file's end
            raise InputError(f"{where}: a quoted field starting on line {line} runs on past {csv.field_size_limit():,} "
                             "characters: an unbalanced quote (\") joins lines into one field") from None
        raise InputError(f"{where} is not a readable CSV file: {exc} (line {line})") from None


def _open_at_end(last_line: str, sep: str) -> bool:
    """Whether a file's last line (without a line end) leaves a quoted field open: a quote at a field's start that
    never closes, which the csv module's lenient reader closes silently (a stray quote inside a field, 12"3, is
    text, not a quote)."""
    import csv

    try:
        list(csv.reader([last_line], delimiter=sep, skipinitialspace=True, strict=True))
    except csv.Error as exc:
        return "unexpected end of data" in str(exc)
    return False


SMALL_TABLE_BYTES = 2 * 1024 * 1024
"""Files whose data rows are at most this many bytes (about 36,000 rows of t, bx, by, bz, f_ref) are parsed by Python's
csv module instead of pandas, whose import alone costs a one-off command 0.15-0.5 s: measured in fresh processes on
this project's 2-core host, 5,000 rows 0.04 against 0.5-0.7 s, 40,000 rows (2.1 MB) 0.36-0.58 against 0.60-0.69 s,
80,000 rows 0.77-0.99 against 0.60-0.90 s; the numbers read are the same (tests/test_dataset.py)."""


def _small_table(path, body: bytes, sep: str, names: list[str], numeric: list[str]) -> dict[str, np.ndarray]:
    """The data rows of a small file by the csv module, with pandas' reading of them: blank lines skipped,
    spaces after a separator ignored, quoted fields unquoted; a numeric column whose every value parses is
    float64, any other column text (object)."""
    import csv

    try:
        text = body.decode(ENCODINGS[0])
    except UnicodeDecodeError as exc:
        raise InputError(f"{path} is not UTF-8 text ({exc.reason})") from None
    reader = csv.reader(io.StringIO(text, newline=""), delimiter=sep, skipinitialspace=True)
    try:
        records = [r for r in reader if r and not (len(r) == 1 and not r[0].strip())]
    except csv.Error as exc:
        raise InputError(f"{path} is not a readable CSV file: {exc}") from None
    columns = list(zip(*records)) if records else [() for _ in names]
    out: dict[str, np.ndarray] = {}
    for name, values in zip(names, columns):
        if name in numeric:
            try:
                if any("_" in v for v in values):  # Python reads 1_000 as a number; pandas and C do not
                    raise ValueError
                floats = np.array([float(v) for v in values], dtype=np.float64)
                if np.isfinite(floats).all():  # else kept as text: the refusal then quotes the cell as written
                    out[name] = floats
                    continue
            except ValueError:
                pass
        out[name] = np.array(values, dtype=object)
    return out


def _table(path, data: bytes, head: _Head, sep: str, names: list[str],
           numeric: list[str]) -> tuple[dict[str, np.ndarray], bool]:
    """The data rows as ``{column: array}`` and whether they are consecutive lines (``_check_rows``): the numeric
    columns parsed straight to float64 (the fast path: two million rows in about a second by pandas' C parser, no
    string objects; small files by the csv module, without importing pandas); a column that does not parse as text
    (object), so that the bad value can be named by ``_numeric``.  Parsed from the bytes already read; the row count
    is checked against the line count, so a quote that swallows rows (or a quoted line break) is refused."""
    body = memoryview(data)[head.body_start:]
    n_lines, consecutive = _check_rows(path, data, head.body_start, sep, len(names), head.skipped + 2)
    if len(body) <= SMALL_TABLE_BYTES:
        table = _small_table(path, bytes(body), sep, names, numeric)
    else:
        table = _pandas_table(path, body, sep, names, numeric)
    n_rows = len(next(iter(table.values()))) if table else 0
    if n_rows == 0:
        raise InputError(f"{path} has a header but no data rows")
    if n_rows != n_lines:
        raise InputError(f"{path}: {n_lines} data lines but {n_rows} rows parsed: an unbalanced quote "
                         "(\") joins lines into one field")
    for c, values in table.items():
        if values.dtype != object:
            continue
        has_break = np.array(["\r" in str(v) or "\n" in str(v) for v in values], dtype=bool)
        if has_break.any():
            row = head.skipped + 2 + int(np.flatnonzero(has_break)[0])
            raise InputError(f"{path}: column {c or '(unnamed)'} holds a line break inside quotes (row starting "
                             f"on line {row}): fields may not span lines")
    return table, consecutive


def _pandas_table(path, body: memoryview, sep: str, names: list[str], numeric: list[str]) -> dict[str, np.ndarray]:
    import warnings

    import pandas as pd

    options = dict(sep=sep, header=None, names=names, encoding=ENCODINGS[0],
                   skipinitialspace=True, comment=None, engine="c", skip_blank_lines=True, index_col=False)
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            try:
                frame = pd.read_csv(io.BytesIO(body), dtype={n: np.float64 for n in numeric}, na_filter=False,
                                    **options)
                if not all(np.isfinite(frame[n].to_numpy()).all() for n in numeric if n in frame):
                    raise ValueError  # a NaN or infinite cell (refused): read as text, so that the refusal quotes it
            except ValueError:
                frame = pd.read_csv(io.BytesIO(body), dtype=str, na_filter=False, **options)
    except UnicodeDecodeError as exc:
        raise InputError(f"{path} is not UTF-8 text ({exc.reason})") from None
    except MemoryError:
        raise InputError(f"{path}: not enough memory to read it") from None
    except Exception as exc:  # pandas raises several parser errors
        text = str(exc).strip()
        why = text.splitlines()[0] if text else type(exc).__name__
        raise InputError(f"{path} is not a readable CSV file: {why}") from None
    return {c: frame[c].to_numpy() for c in frame.columns}


UNIT_META_KEYS = ("units", "unit")
"""Metadata lines that state the unit of the field columns (``# units: uT``)."""
COUNT_META_KEYS = ("gain", "gain_nt_per_count", "nt_per_count", "lsb_nt", "counts_per_nt", "counts_per_ut",
                   "counts_per_gauss", "lsb_per_gauss", "resolution_nt_per_lsb", "adc_gain")
"""Metadata lines that say the readings are ADC counts with a conversion factor."""
COUNT_UNITS = ("counts", "count", "lsb", "adc", "raw", "digits")


def _check_meta_units(where, meta: dict, units: str) -> None:
    """Refuse a file whose metadata says its readings are in another unit than they are read in, or in
    ADC counts (with a gain line): the unit is then stated, never guessed."""
    lower = {k.strip().lower(): k for k in meta}
    gain = next((lower[k] for k in COUNT_META_KEYS if k in lower), None)
    stated = next((meta[lower[k]] for k in UNIT_META_KEYS if k in lower), None)
    if gain is not None or (stated is not None and stated.strip().lower() in COUNT_UNITS):
        line = f"'# {gain}: {meta[gain]}'" if gain is not None else f"'# units: {stated}'"
        raise InputError(f"{where}: the readings are ADC counts ({line}), not {units}: convert them to nT with "
                         "the gain first (counts x nT per count)")
    if stated is not None:
        canon = {"nt": "nT", "ut": "uT", "µt": "uT", "mg": "mG", "g": "G", "gauss": "G", "milligauss": "mG",
                 "nanotesla": "nT", "microtesla": "uT"}.get(stated.strip().lower())
        if canon is None:
            raise InputError(f"{where}: metadata line '# units: {stated}' names no unit magbench reads "
                             "(nT, uT, mG, G)")
        if canon != units:
            raise InputError(f"{where}: the file says its readings are in {canon} ('# units: {stated}') but they "
                             f"are read as {units}: read it with units {canon}")


def _as_floats(values: np.ndarray) -> np.ndarray:
    """Text values as floats, NaN where one does not parse (pandas' ``to_numeric(errors='coerce')``)."""
    out = np.empty(len(values), dtype=float)
    for i, v in enumerate(values):
        try:
            if "_" in str(v):
                raise ValueError
            out[i] = float(str(v).strip())
        except ValueError:
            out[i] = np.nan
    return out


DECIMAL_COMMA = re.compile(r"^[+-]?(\d+|\d{1,3}(\.\d{3})+),\d+$")
"""A number written with a decimal comma (a spreadsheet's export in many locales), with or without dots between its
thousands (50.000,0)."""
THOUSANDS_COMMA = re.compile(r"^[+-]?\d{1,3}(,\d{3})+(\.\d+)?$")
"""A number written with commas between its thousands (50,000.0, quoted in a comma-separated file)."""


def _numeric(path: Path, table: dict[str, np.ndarray], name: str, first_line: int) -> np.ndarray:
    """A column as finite floats within +-MAX_ABS_NT; refuses a bad value naming its line."""
    text = table[name]
    values = text if text.dtype == np.float64 else _as_floats(text)
    is_field = name in FIELD_COLUMNS
    limit = MAX_ABS_NT if is_field else MAX_ABS_OTHER
    with np.errstate(invalid="ignore"):
        bad = np.flatnonzero(~(np.abs(values) <= limit))
    if bad.size:
        rows = ", ".join(str(first_line + i) for i in bad[:5])
        more = f" and {bad.size - 5} more" if bad.size > 5 else ""
        raw_value = text[bad[0]]
        raw_value = raw_value.item() if isinstance(raw_value, np.generic) else raw_value
        absurd = "beyond any magnetic field (1e9 nT)" if is_field else f"beyond any plausible value ({limit:g})"
        why = absurd if np.isfinite(values[bad[0]]) else "missing, non-numeric or non-finite"
        text_value = raw_value.strip() if isinstance(raw_value, str) else ""
        hint = ("; it has a decimal comma: write numbers with decimal points and no thousands separators (and separate "
                "columns by commas, semicolons or tabs)" if DECIMAL_COMMA.match(text_value) else
                "; it has commas between thousands: write numbers without thousands separators"
                if THOUSANDS_COMMA.match(text_value) else "")
        hint = hint or (_epoch_hint(values[bad[0]]) if name == "t" else "") or _line_hint(table, int(bad[0]))
        raise InputError(f"{path}: column {name} has a value {why} ({raw_value!r}) on line {rows}{more}{hint}")
    hot = temperature_problem(values) if name == "temp" else None
    if hot is not None:
        raise InputError(f"{path}: column temp on line {first_line + hot[0]} is {hot[1]}")
    return values


EPOCH_UNITS = (("milliseconds", 1e3, "1000"), ("microseconds", 1e6, "10^6"), ("nanoseconds", 1e9, "10^9"))
"""Units a logger writes Unix times in, beside seconds, for the hint of a t value beyond MAX_ABS_OTHER."""


def _epoch_hint(value: float) -> str:
    """'; it looks like a Unix time in milliseconds ...' when ``value`` (a t beyond MAX_ABS_OTHER) is a Unix time in
    one of EPOCH_UNITS between the years 2001 and 2100 (t is in seconds: the column is refused, not rescaled)."""
    if not np.isfinite(value):
        return ""
    for unit, per_second, factor in EPOCH_UNITS:
        if 1e9 <= value / per_second <= 4.1e9:
            return f"; it looks like a Unix time in {unit} (t is in seconds: divide the column by {factor})"
    return ""


def _line_hint(table: dict[str, np.ndarray], i: int) -> str:
    """What a refused line ``i`` is, when it is a line of another kind: the header again (files joined end to
    end), or a '#' comment after the header."""
    cells = {name: col[i].item() if isinstance(col[i], np.generic) else col[i] for name, col in table.items()}
    text = {name: str(v).strip() for name, v in cells.items() if isinstance(v, str)}
    if text and all(v.lower() == name for name, v in text.items()) and len(text) == len(cells):
        return "; that line repeats the header (files joined end to end?): keep one header line"
    if any(v.startswith("#") for v in text.values()):
        return "; it is a '#' comment: comment and metadata lines go before the header"
    if text and all(v.strip("[]()").lower() in UNIT_WORDS for v in text.values()):
        return ("; that line is a row of units: units go in --units (or a '# units:' line), temperatures in deg C, "
                "times in s; remove the row")
    return ""


UNIT_WORDS = frozenset({"nt", "ut", "µt", "mg", "g", "gauss", "t", "tesla", "s", "sec", "ms", "c", "degc", "°c", "k",
                        "f", "degf", "°f", "deg", "°", "degrees", "rad", "g0", "m/s2", "m/s^2", "counts", ""})
"""Cells of a units row under the header (``_line_hint``)."""


def _header_hint(names: list[str], missing: list[str]) -> str:
    """What a header without the wanted columns is, when it is something else: names separated by spaces (one column
    read), or numbers (a file without a header row)."""
    if len(names) == 1 and all(m in names[0].lower().split() for m in missing):
        return "; its columns are separated by spaces: separate them by commas, semicolons or tabs"
    try:
        [float(n) for n in names]
    except ValueError:
        return ""
    return "; its first line is numbers: the file needs a header row naming its columns (t,bx,by,bz,f_ref, ...)"


def _non_ascii(names: list[str], missing: list[str]) -> str:
    """'; column NAME has a non-ASCII character (U+XXXX NAME) ...' for a column name that is a ``missing`` name
    with non-ASCII letters in its place (``bх``, Cyrillic: it prints exactly like the name it is not), else ''."""
    import unicodedata

    for want in missing:
        for name in names:
            odd = [a for a, b in zip(name.lower(), want) if a != b]
            if len(name) == len(want) and odd and all(ord(a) > 127 for a in odd):
                return (f"; column {name!r} has a non-ASCII character (U+{ord(odd[0]):04X} "
                        f"{unicodedata.name(odd[0], 'unnamed')}) where {want!r} has {want[name.lower().index(odd[0])]!r}: "
                        "write the names in ASCII")
    return ""


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


def read_csv(path, units: str = "nT", require_vector: bool = True, expected_field_nT: float | None = None,
             source: InputBytes | None = None):
    """Read a data file (CONTRACT section 2) into a ``Dataset`` (or a ``ScalarSeries`` when the file has
    ``f_meas`` instead of bx, by, bz and ``require_vector`` is false).

    ``units`` applies to every field column of the file (bx, by, bz, f_ref, f_meas); the ``# field_nT:``
    metadata line is in nT by its name.  Refuses, with an ``InputError`` naming the line, non-numeric,
    non-finite or absurd values (beyond 1 T), duplicate column names in any letter case, a directory,
    FIFO or device, an unreadable or non-UTF-8 file, lines longer than ``MAX_LINE_BYTES``, more than
    ``MAX_COLUMNS`` columns, rows whose field count differs from the header's, a quote that joins lines,
    conflicting metadata lines, metadata that states another unit or ADC counts, and a file whose
    magnitudes look like another unit than ``units`` (compared with ``expected_field_nT``, else the
    file's ``# field_nT:``, else the geomagnetic range).

    The file is read once (``magbench.safeio.read_input``; or ``source``, bytes read already) and parsed
    from those bytes by pandas' C parser (two million rows in about a second); the metadata records its
    sha256 (``file_sha256``).
    """
    path = as_path(path, "data file")
    if not isinstance(units, str) or units not in UNIT_FACTORS_NT:
        raise InputError(f"unknown unit {units!r}: use one of nT, uT, mG, G")
    src, data, head, sep, names = _opened(path, source)
    _check_meta_units(path, head.meta, units)
    numeric = [c for c in names if c in NUMERIC_COLUMNS]
    has_vector = all(c in names for c in ("bx", "by", "bz"))
    scalar_col = next((c for c in ("f_meas", "f_meas_before") if c in names), None)
    if not has_vector and (require_vector or scalar_col is None):
        missing = [c for c in ("bx", "by", "bz") if c not in names]
        extra = " (it is a scalar-only series: use 'magbench diagnose')" if scalar_col else ""
        raise InputError(f"{path} lacks column(s) {', '.join(missing)}{extra} (its columns: "
                         f"{', '.join(names[:12])}{', ...' if len(names) > 12 else ''}; units go in --units or a "
                         f"'# units:' line, not in the column names){_non_ascii(names, missing)}"
                         f"{_header_hint(names, missing)}")
    frame, consecutive = _table(path, data, head, sep, names, numeric)
    first_line = head.skipped + 2
    meta = head.meta
    if consecutive:  # data row i is line first_line + i (the command line names rows by their lines too)
        meta = {**meta, "first_data_line": first_line}

    def column(name):
        return _numeric(path, frame, name, first_line) if name in names else None

    factor = UNIT_FACTORS_NT[units]
    f_ref = column("f_ref")
    if f_ref is not None and np.any(f_ref <= 0):
        row = first_line + int(np.flatnonzero(f_ref <= 0)[0])
        raise InputError(f"{path}: f_ref must be a positive magnitude, not {f_ref[f_ref <= 0][0]:g} (line {row})")
    field_meta = _meta_field_nT(path, meta)
    if expected_field_nT is None:
        expected_field_nT = field_meta
    raw: np.ndarray | None = None
    scalar: np.ndarray | None = None  # the scalar column, parsed once: the unit checks and the series read it
    if has_vector:
        raw = np.column_stack([column(c) for c in ("bx", "by", "bz")])
        magnitude = float(np.median(np.sqrt(np.einsum("ij,ij->i", raw, raw))))
    else:
        scalar = _numeric(path, frame, str(scalar_col), first_line)
        magnitude = float(np.median(np.abs(scalar)))
    if raw is not None:
        check_thousands_dots(raw, str(path))
    if f_ref is not None:  # the two columns against each other first: each alone can look like another unit
        check_columns_agree(magnitude, float(np.median(f_ref)), str(path))
    if f_ref is not None and not expected_field_nT:
        check_reference_units(float(np.median(f_ref)), units, where=str(path))
    f_ref = f_ref * factor if f_ref is not None else None

    temp_C = _temperature_C(path, meta, column("temp"))
    common = dict(t_s=column("t"), temp_C=temp_C, heading_deg=column("heading_deg"))
    meta = {**meta, "source_file": str(path), "units_read": units, "file_sha256": src.sha256}
    if "temp_unit" in meta:  # the temperatures are in deg C now (a file written from this dataset says so)
        meta["temp_unit_read"], meta["temp_unit"] = meta["temp_unit"], "C"
    notes = column_notes(names, meta, temp_C)
    if notes:
        meta["input_notes"] = notes
    check_units(magnitude, units, expected_field_nT, where=str(path))
    if raw is not None:
        return Dataset(raw * factor, f_ref_nT=f_ref, meta=meta, **common)
    others = {c: column(c) * factor for c in FIELD_COLUMNS if c in names and c not in ("f_ref",)}
    assert scalar is not None  # no vector readings: a scalar column (checked above)
    return ScalarSeries(scalar * factor, f_ref_nT=f_ref, extra=others, meta={**meta, "f_meas_column": scalar_col},
                        **common)


TEMP_UNITS = {"c": 0, "degc": 0, "celsius": 0, "k": 1, "kelvin": 1, "f": 2, "degf": 2, "fahrenheit": 2}
"""``# temp_unit:`` values: the temp column in deg C (the contract's unit), kelvin or deg F (converted to deg C)."""
TEMP_MAYBE_F_C = (45.0, 200.0)
"""A temp column read as deg C whose median lies between these is hot for a magnetometer in deg C and room to desert
temperatures in deg F: ``column_notes`` says how to declare deg F (the per-degree coefficients are per deg C)."""
TIME_LIKE = ("time", "time_s", "t_s", "t_ms", "time_ms", "t_us", "timestamp", "time_stamp", "seconds", "secs",
             "elapsed", "elapsed_s", "datetime", "date_time", "epoch", "unix_time", "millis", "ms")
TEMP_LIKE = ("temperature", "temp_c", "temp_f", "temp_k", "t_c", "t_degc", "temperature_c", "temperature_f",
             "sensor_temp", "temp_sensor")


def _temperature_C(path: Path, meta: dict, values: np.ndarray | None) -> np.ndarray | None:
    """The temp column in deg C: as written, or converted from the unit of a ``# temp_unit:`` line (K, F)."""
    stated = meta.get("temp_unit")
    if stated is None:
        return values
    kind = TEMP_UNITS.get(stated.strip().lower().replace("°", "").replace(" ", ""))
    if kind is None:
        raise InputError(f"{path}: metadata line '# temp_unit: {stated}' names no temperature unit (C, K or F)")
    if values is None or kind == 0:
        return values
    converted = values - 273.15 if kind == 1 else (values - 32.0) * (5.0 / 9.0)
    hot = temperature_problem(converted)
    if hot is not None:
        raise InputError(f"{path}: column temp (in {stated.strip()}) on data row {hot[0]} is {hot[1]}")
    return converted


def column_notes(names: list[str], meta: dict, temp_C: np.ndarray | None) -> str:
    """What a reader of this file should know that no refusal says (``meta['input_notes']``; calibrate warns,
    diagnose says it in ``input_notes``): a time or temperature column under another name than ``t`` or ``temp``
    (not read: a fixed sensor's drift had been given per row, and a verdict changed, without a word), and a temp column
    read as deg C whose median could be deg F."""
    notes = []
    lower = [n.lower() for n in names]
    if "t" not in lower:
        timeish = [n for n in names if n.lower() in TIME_LIKE]
        if timeish:
            notes.append(f"column {timeish[0]!r} is not read: the time column is named t, in seconds (rename it, "
                         "converted to seconds, for the time-based checks)")
    if "temp" not in lower:
        tempish = [n for n in names if n.lower() in TEMP_LIKE]
        if tempish:
            notes.append(f"column {tempish[0]!r} is not read: the temperature column is named temp, in deg C (a "
                         "'# temp_unit: K' or '# temp_unit: F' line converts)")
    if temp_C is not None and meta.get("temp_unit") is None and len(temp_C):
        middle = float(np.median(temp_C))
        if TEMP_MAYBE_F_C[0] < middle < TEMP_MAYBE_F_C[1]:
            notes.append(f"the temp column's median is {middle:.4g}, read as deg C: if it is in deg F, say so with a "
                         "'# temp_unit: F' line (per-degree temperature coefficients are per deg C, 1.8 times those "
                         "per deg F)")
    return "; ".join(notes)


def _opened(path: Path, source: InputBytes | None) -> tuple[InputBytes, bytes, _Head, str, list[str]]:
    """A data file's bytes (``source`` when read already), its lines' bytes, its head, separator and column names."""
    src = source if source is not None else read_input(path, "data file")
    data = newline_lines(src.data)
    head = _parse_head(data, str(path))
    sep, names = _header(path, head.header)
    return src, data, head, sep, names


def read_columns(path, wanted, source: InputBytes | None = None) -> dict[str, np.ndarray]:
    """The columns of ``wanted`` (lower-case names) that a data file has, read as ``read_csv`` reads the file (its
    separator, metadata lines, quoting and rows, so row i is ``read_csv``'s row i): float arrays, NaN where a cell does
    not parse.  For columns ``read_csv`` does not keep (the accelerometer's ax, ay, az or gx, gy, gz), read without
    pandas where ``read_csv`` does; ``{}`` when the file has none of them.  ``source``: the file's bytes, when the
    caller read them for ``read_csv`` already (read once)."""
    _, data, head, sep, names = _opened(as_path(path, "data file"), source)
    present = [c for c in wanted if c in names]
    if not present:
        return {}
    table, _ = _table(path, data, head, sep, names, present)
    return {c: table[c] if table[c].dtype == np.float64 else _as_floats(table[c]) for c in present}


GEOMAGNETIC_NT = (20000.0, 70000.0)
"""The geomagnetic field's magnitude, widened a little (22,000 to 67,000 nT at the surface): without a known field, an
f_ref whose median lies outside it and another unit brings inside it is refused (``check_reference_units``)."""


THOUSANDS_INT_OVER_FRACTION = 5.0
"""``check_thousands_dots``: readings written with a dot as the thousands separator (47.717 for 47,717 nT; -295 with no
dot) read as whole numbers of hundreds where the field's components are small and as fractions of 1 to 999 elsewhere,
so the whole numbers' median magnitude is many times the fractions' (about 500 against 30); in a file of decimals
(uT written to 0.1) the two share one distribution."""


def check_thousands_dots(raw: np.ndarray, where: str = "input") -> None:
    """Refuse readings that a dot as thousands separator explains (a spreadsheet in a European locale wrote 47.717 for
    47,717 nT and -295 for -295 nT: read as they stand they look like uT, and read so, the rows of small components are
    1000 times too large): every value has at most three decimals, at least half are fractions, none of them below 1 in
    magnitude (a thousands group follows a digit from 1 to 999), at least two whole numbers lie between 100 and 999 in
    magnitude, and the whole numbers' median magnitude is THOUSANDS_INT_OVER_FRACTION times the fractions'."""
    def three_decimals(a: np.ndarray) -> bool:
        milli = a * 1000.0
        return bool(np.all(np.abs(milli - np.round(milli)) <= 1e-6 * np.maximum(milli, 1.0)))

    if not three_decimals(np.abs(raw[:1000][np.isfinite(raw[:1000])])):  # most files: decided on their first rows
        return
    v = np.abs(raw[np.isfinite(raw)])
    if v.size < 6 or not three_decimals(v):
        return
    whole = v == np.round(v)
    fractions, wholes = v[~whole], v[whole]
    if (2 * fractions.size < v.size or np.any(fractions < 1.0)
            or np.count_nonzero((wholes >= 100) & (wholes <= 999)) < 2
            or np.median(wholes) < THOUSANDS_INT_OVER_FRACTION * np.median(fractions)):
        return
    big = float(fractions[np.argmax(fractions)])
    small = float(wholes[(wholes >= 100) & (wholes <= 999)][0])
    raise InputError(f"{where}: the readings look written with a dot as the thousands separator ({big:.3f} beside {small:.0f}: "
                     f"{big:.3f} for {big * 1000:,.0f}, while readings below 1,000 have no dot): write the numbers "
                     "without thousands separators, with a decimal point")


COLUMNS_APART_TOLERANCE = 0.3
"""Readings whose median magnitude is a power of ten of at least 100 times f_ref's (or its inverse) within this much in
log10 (a factor of 2 either way: an uncalibrated sensor's scale errors and hard iron move its magnitude by tens of
per cent) were written in another unit than f_ref (``check_columns_agree``)."""


def check_columns_agree(readings_median: float, f_ref_median: float, where: str = "input") -> None:
    """Refuse a file whose readings and f_ref columns are written in two units (readings in nT beside f_ref in uT):
    ``units`` reads both, so no unit given can make them agree.  Asked before each column's own unit check, which had
    sent such a file from units='uT' to units='nT' and back."""
    if not (readings_median > 0 and f_ref_median > 0):
        return
    ratio = readings_median / f_ref_median
    apart = units_apart(ratio, tolerance=COLUMNS_APART_TOLERANCE, min_exponent=2)
    if apart:
        raise InputError(f"{where}: the readings' magnitude (median {readings_median:.4g}) is {ratio:.4g} times f_ref's "
                         f"(median {f_ref_median:.4g}), about {apart}")


def check_reference_units(f_ref_median: float, units: str, where: str = "input") -> None:
    """Refuse an f_ref column (its median ``f_ref_median`` in ``units``) that ``units`` puts outside the geomagnetic
    field and another unit inside it: the unit given wrongly for readings and f_ref alike (a file in uT read as mG,
    whose readings then agree with their reference, had been calibrated with offsets 10 times off and accepted).
    Asked only where no field is known (``--field``, ``--igrf``, a ``# field_nT:`` line: a laboratory field says so
    there).  The reference, not the readings: an uncalibrated sensor's hard iron can put the readings' magnitude
    far outside the geomagnetic field (a phone's 200 uT) while the field is geomagnetic."""
    nt = f_ref_median * UNIT_FACTORS_NT[units]
    if GEOMAGNETIC_NT[0] <= nt <= GEOMAGNETIC_NT[1] or not 1.0e3 <= nt <= 1.0e7:
        return  # geomagnetic; or no field at all, which the readings' and the reference's own checks refuse
    other = next((u for u in ("nT", "uT", "mG", "G") if u != units and
                  GEOMAGNETIC_NT[0] <= f_ref_median * UNIT_FACTORS_NT[u] <= GEOMAGNETIC_NT[1]), None)
    if other is not None:
        raise InputError(f"{where}: f_ref (median {f_ref_median:.4g} {units}) is {nt:.4g} nT, outside the geomagnetic "
                         f"field's {GEOMAGNETIC_NT[0]:,.0f} to {GEOMAGNETIC_NT[1]:,.0f} nT; it looks like {other} "
                         f"({f_ref_median * UNIT_FACTORS_NT[other]:.4g} nT): read with units='{other}', or, for a "
                         f"laboratory field of {nt:.4g} nT, say so with a '# field_nT:' line (or --field)")


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
        converted = magnitude * UNIT_FACTORS_NT[guess]
        # a unit is named only where it brings the readings within the factor 5 of a plausible reference; readings
        # plausible in their own unit against an implausible reference (--field 1e300) are the reference's fault
        fits = 1.0e3 <= reference <= 1.0e7 and 0.2 <= converted / reference <= 5.0
        if guess != units and fits:
            hint = f"they look like {guess}: read with units='{guess}'"
        elif expected_field_nT and 1.0e3 <= nt <= 1.0e7 and not 1.0e3 <= expected_field_nT <= 1.0e7:
            ref_unit = guess_unit(expected_field_nT, nt)  # the unit the reference was perhaps given in
            in_nt = expected_field_nT * UNIT_FACTORS_NT[ref_unit]
            hint = (f"the reference is in nT: {expected_field_nT:g} {ref_unit} would be {in_nt:g} nT"
                    if ref_unit != "nT" and 0.2 <= in_nt / nt <= 5.0 else
                    f"the reference is no geomagnetic or laboratory field (plausible: {1.0e3:g} to {1.0e7:g} nT): "
                    "check it")
        elif 1.0e3 <= nt * 1.0e9 / UNIT_FACTORS_NT[units] <= 1.0e7:
            hint = "they look like tesla: convert them to nT (x 1e9) and read with units='nT'"
        else:
            hint = "check the file and the reference"
        ref = f" against a reference of {expected_field_nT:.6g} nT" if expected_field_nT else ""
        raise InputError(f"{where}: median field magnitude {magnitude:.4g} {units} is implausible{ref}; {hint}")


def write_truth(truth: Truth, path, inputs=()) -> None:
    """The truth as JSON, written atomically (never over one of ``inputs``)."""
    atomic_write(path, json.dumps(truth.as_dict(), indent=2) + "\n", inputs=inputs, force=True)
