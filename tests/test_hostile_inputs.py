"""A hostile-input corpus: files and options a careless or hostile user gives ``magbench``, each with the
exit status and the message it must get (CONTRACT section 3: 0 success, 2 bad input with one line on
stderr, 3 a calibration that ran but is rejected).  Every case also checks that no traceback is printed,
that stdout stays clean on failure, and that the input file is not changed."""
from __future__ import annotations

import gzip
import hashlib
import io
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest

from magbench.benchmarks.cli import main
from magbench.simulate import attitude
from magbench.simulate.field import ConstantField
from magbench.simulate.scenarios import get_scenario
from magbench.simulate.sensor import ErrorParams, SensorModel

F_NT = 50000.0
FIELD = ConstantField.from_angles(F_NT, 55.0, 3.0)
NINE = ErrorParams(0.012, -0.008, 0.015, (1.021, 0.984, 1.008), (152.0, -218.0, 85.0))
ANGLES_ONLY = ErrorParams(0.012, -0.008, 0.015)


def _sphere(n=300, seed=0, errors=NINE, noise=1.0):
    rng = np.random.default_rng(seed)
    att = attitude.full_sphere(n, rng)
    return SensorModel(errors, noise_nT=noise).measure(att.body_field(np.asarray(FIELD.vector_nT)), rng)


def _plane(n=36, errors=NINE, wobble_deg=0.0, seed=1):
    rng = np.random.default_rng(seed)
    att = attitude.turntable(n, 360.0 / n)
    b = att.body_field(np.asarray(FIELD.vector_nT))
    if wobble_deg:
        from scipy.spatial.transform import Rotation

        tilt = Rotation.from_rotvec(np.radians(wobble_deg) * rng.uniform(-1, 1, (n, 3)) * [1, 1, 0])
        b = tilt.apply(b)
    return SensorModel(errors, noise_nT=1.0).measure(b, rng)


def _csv(raw, f_ref=F_NT, header=("bx", "by", "bz", "f_ref"), sep=",", meta=("# field_nT: 50000",), fmt="{:.4f}",
         newline="\n"):
    cols = [raw[:, 0], raw[:, 1], raw[:, 2]]
    if "f_ref" in [h.lower() for h in header]:
        cols.append(np.broadcast_to(f_ref, (len(raw),)))
    lines = list(meta) + [sep.join(header)]
    lines += [sep.join(fmt.format(v) for v in row) for row in zip(*cols)]
    return newline.join(lines) + newline


def _zipped(text: str) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w") as z:
        z.writestr(zipfile.ZipInfo("data.csv", date_time=(2026, 1, 1, 0, 0, 0)), text)
    return buf.getvalue()


RAW = _sphere()
GOOD = _csv(RAW)


def _edit_row(text, index, new):
    lines = text.splitlines()
    first = next(i for i, ln in enumerate(lines) if not ln.startswith("#")) + 1
    lines[first + index] = new
    return "\n".join(lines) + "\n"


def _spike(raw, rows, size):
    raw = raw.copy()
    raw[rows, 0] += size
    return raw


def _alternating_reference():
    f = np.where(np.arange(len(RAW)) % 2, 45000.0, 50000.0)
    return _csv(RAW, f_ref=f)


def _half_uT():
    raw = RAW.copy()
    raw[::2] /= 1000.0
    return _csv(raw, fmt="{:.6g}")


def _spiked():
    """GOOD with data rows 30, 130 and 230 at 50 times their readings (1 % spikes)."""
    raw = RAW.copy()
    raw[[30, 130, 230]] *= 50.0
    return _csv(raw)


def _quoted(opening, closing):
    """GOOD with a text column ``note``; a quote opens on data row ``opening`` and closes on row ``closing``
    (the same row: balanced; None: never)."""
    lines = GOOD.splitlines()
    first = next(i for i, ln in enumerate(lines) if not ln.startswith("#"))
    lines[first] += ",note"
    for k in range(first + 1, len(lines)):
        row = k - first - 1
        text = "x"
        if row == opening and row == closing:
            text = '"a, quoted note"'
        elif row == opening:
            text = '"opens'
        elif row == closing:
            text = 'closes"'
        lines[k] += "," + text
    return "\n".join(lines) + "\n"


# (id, file content (str or bytes) or None for no file, extra arguments, expected status, message fragment)
CASES = [
    # encodings
    ("utf8-bom", "\ufeff" + GOOD, [], 0, ""),
    ("crlf", GOOD.replace("\n", "\r\n"), [], 0, ""),
    ("utf16", GOOD.encode("utf-16"), [], 2, "not UTF-8"),
    ("latin1-comment", ("# site: Zürich\n" + GOOD).encode("latin-1"), [], 2, "not UTF-8"),
    ("binary-garbage", bytes(range(256)) * 4, [], 2, "not UTF-8"),
    # packed files a user gives for the CSV: said what they are (they were 'NUL bytes: UTF-16 or binary?')
    ("gzip", gzip.compress(GOOD.encode(), mtime=0), [], 2, "is gzip-compressed, not a CSV text file: unpack it"),
    # a spreadsheet's export in a decimal-comma locale, and units written into the column names
    ("decimal-comma", _csv(RAW, sep=";").replace(".", ","), [], 2, "it has a decimal comma: write numbers with decimal"),
    ("units-in-header", GOOD.replace("bx,by,bz", "Bx (nT),By (nT),Bz (nT)"), [], 2,
     "units go in --units or a '# units:' line"),
    ("zip", _zipped(GOOD), [], 2, "is a zip archive (or an .xlsx/.ods workbook)"),
    # delimiters and layout
    ("semicolon", _csv(RAW, sep=";"), [], 0, ""),
    ("tab", _csv(RAW, sep="\t"), [], 0, ""),
    ("header-comma-rows-semicolon", _csv(RAW, sep=";").replace("bx;by;bz;f_ref", "bx,by,bz,f_ref"), [], 2,
     "has 1 field(s) but the header names 4"),
    ("extra-field-in-a-row", _edit_row(GOOD, 5, "1,2,3,50000,9"), [], 2, "not a readable CSV"),
    ("spaces-around-values", GOOD.replace(",", " , "), [], 0, ""),
    ("quoted-header", GOOD.replace("bx,by,bz,f_ref", '"bx","by","bz","f_ref"'), [], 0, ""),
    ("blank-lines", GOOD.replace("\n", "\n\n", 20), [], 0, ""),
    # columns
    ("duplicate-any-case", GOOD.replace("bx,by,bz,f_ref", "BX,bx,bz,f_ref"), [], 2, "more than once"),
    ("duplicate-same-case", GOOD.replace("bx,by,bz,f_ref", "bx,by,bx,f_ref"), [], 2, "more than once"),
    ("missing-bz", GOOD.replace("bx,by,bz,f_ref", "bx,by,bq,f_ref"), [], 2, "lacks column"),
    # a look-alike letter prints exactly like the name it is not: said which character it is
    ("cyrillic-x-in-bx", GOOD.replace("bx,by,bz,f_ref", "b\u0445,by,bz,f_ref"), [], 2,
     "has a non-ASCII character (U+0445 CYRILLIC SMALL LETTER HA)"),
    # files joined end to end (the header again), and a comment line after the header
    ("header-repeated", GOOD + "\n".join(ln for ln in GOOD.splitlines() if not ln.startswith("#")) + "\n", [], 2,
     "that line repeats the header (files joined end to end?)"),
    ("comment-after-header", _edit_row(GOOD, 5, "# moved the sensor"), [], 2,
     "it is a '#' comment: comment and metadata lines go before the header"),
    ("comment-with-commas-after-header", _edit_row(GOOD, 5, "# moved, the, sensor, here"), [], 2,
     "it is a '#' comment: comment and metadata lines go before the header"),
    ("no-header", "\n".join(GOOD.splitlines()[2:]) + "\n", [], 2, "lacks column"),
    ("extra-columns", GOOD.replace("\n", ",x\n").replace("bx,by,bz,f_ref,x", "bx,by,bz,f_ref,comment")
     .replace("# field_nT: 50000,x", "# field_nT: 50000"), [], 0, ""),
    ("upper-case-names", GOOD.replace("bx,by,bz,f_ref", "BX,BY,BZ,F_REF"), [], 0, ""),
    ("other-order", _csv(RAW[:, [2, 0, 1]], header=("bz", "bx", "by", "f_ref")), [], 0, ""),
    # units, ADC counts, references
    ("uT-read-as-nT", _csv(RAW / 1000.0, f_ref=50.0, fmt="{:.6g}", meta=()), [], 2, "look like uT"),
    ("uT-with-units", _csv(RAW / 1000.0, f_ref=50.0, fmt="{:.6g}", meta=()), ["--units", "uT"], 0, ""),
    ("gauss-with-units", _csv(RAW / 1e5, f_ref=0.5, fmt="{:.8g}", meta=()), ["--units", "G"], 0, ""),
    ("nT-read-as-uT", GOOD, ["--units", "uT"], 2, "implausible"),
    # a unit given wrongly with an f_ref in the same unit: the magnitudes stay within 1,000 .. 10^7 nT (a laboratory
    # field's range) and agree with the reference, but another unit makes them the geomagnetic field (had been
    # calibrated with offsets 10 and 100 times off, exit 0)
    ("uT-read-as-mG", _csv(RAW / 1000.0, f_ref=50.0, fmt="{:.6g}", meta=()), ["--units", "mG"], 2,
     "f_ref (median 50 mG) is 5000 nT, outside the geomagnetic field's 20,000 to 70,000 nT; it looks like uT"),
    ("uT-read-as-G", _csv(RAW / 1000.0, f_ref=50.0, fmt="{:.6g}", meta=()), ["--units", "G"], 2, "it looks like uT"),
    ("nT-read-as-mG", _csv(RAW, meta=()), ["--units", "mG"], 2, "it looks like nT"),
    ("mG-read-as-uT", _csv(RAW / 100.0, f_ref=500.0, fmt="{:.6g}", meta=()), ["--units", "uT"], 2, "it looks like mG"),
    # the reference, not the readings, is held to the geomagnetic range: an uncalibrated phone's hard iron (180 uT)
    # puts the readings' magnitude at 200 uT, and mG would bring that inside (had been refused as units): judged
    # by the calibration (outside a fluxgate's physical range), not refused as a unit
    ("uT-with-a-phone's-hard-iron", _csv((RAW + [180000.0, -90000.0, 50000.0]) / 1000.0, f_ref=50.0, fmt="{:.6g}",
                                          meta=()), ["--units", "uT"], 3, "outside a fluxgate's physical range"),
    ("lab-field-in-mG-said", _csv(RAW / 1000.0, f_ref=50.0, fmt="{:.6g}", meta=()), ["--units", "mG", "--field", "5000"],
     0, ""),
    ("lab-field-in-mG-metadata", _csv(RAW / 1000.0, f_ref=50.0, fmt="{:.6g}", meta=("# field_nT: 5000",)),
     ["--units", "mG"], 0, ""),
    ("uT-beside-f-ref-in-nT", _csv(RAW / 1000.0, f_ref=F_NT, fmt="{:.6g}", meta=()), ["--units", "uT"], 2,
     "a factor of 1,000, as between uT and nT or G and mG: the readings and f_ref were written in different units"),
    # spikes make the closed-form scalar calibrations' quadrics indefinite: said beside their reason (the reason
    # alone had blamed the attitude coverage of a full sphere)
    ("spikes-merayo", _spiked(), ["--method", "merayo"], 2, "3 of 300 readings (rows 30, 130, 230 (lines 33, 133, 233)) "
     "have magnitudes far from the others'"),
    ("spikes-twostep", _spiked(), ["--method", "twostep"], 2, "if they are spikes, this method fits them as they are"),
    # spreadsheet exports: Excel's separator hint, and '#' lines with their row's empty cells or quoted
    ("excel-sep-line", "\ufeffsep=,\r\n" + GOOD.replace("\n", "\r\n"), [], 0, ""),
    ("excel-sep-line-semicolon", "sep=;\n" + _csv(RAW, sep=";"), [], 0, ""),
    ("comment-with-empty-cells", GOOD.replace("# field_nT: 50000", "# field_nT: 50000,,,"), [], 0, ""),
    ("comment-quoted", GOOD.replace("# field_nT: 50000", '"# field_nT: 50000",,,'), [], 0, ""),
    ("comment-quoted-with-quotes", '"# note: say ""hi""",,,\n' + GOOD, [], 0, ""),
    ("sep-line-not-first", "# field_nT: 50000\nsep=,\n" + "\n".join(GOOD.splitlines()[1:]) + "\n", [], 2,
     "lacks column"),
    ("adc-counts", _csv(np.round(RAW / 3.0517578125), meta=(), fmt="{:.0f}"), [], 2, "times the reference"),
    ("f-ref-ten-times-off", _csv(RAW, f_ref=5000.0, meta=()), [], 2, "times the reference"),
    ("field-option-ten-times-off", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--field", "5000"], 2,
     "implausible"),
    ("half-rows-in-uT", _half_uT(), [], 2, "mixes units"),
    ("reference-alternating", _alternating_reference(), [], 2, "reference jumps"),
    ("f-ref-zero-row", _edit_row(GOOD, 7, "1000,2000,3000,0"), [], 2, "positive"),
    # the calibrators count data rows from 0, the reader names file lines: the command line says both (GOOD's data
    # row 0 is its line 3)
    ("readings-zero-row", _edit_row(GOOD, 7, "0,0,0,50000"), [], 2, "in 1 row(s) (row 7 (line 10))"),
    # near zero but not exactly: the coverage check's eigenvalues had not converged (an internal error, exit 1)
    ("readings-tiny-row", _edit_row(GOOD, 4, "1e-300,0,0,50000"), [], 2,
     "1 row(s) (row 4 (line 7)) have a magnitude less than 1/1000 of the others'"),
    ("reference-steps-once", _csv(RAW, f_ref=np.where(np.arange(len(RAW)) < 150, F_NT, 0.9 * F_NT)), [], 2,
     "at row 150 (line 153)"),
    ("f-ref-negative", _csv(RAW, f_ref=-50000.0), [], 2, "positive"),
    ("meta-field-negative", _csv(RAW, header=("bx", "by", "bz"), meta=("# field_nT: -50000",)), [], 2,
     "positive number"),
    ("meta-field-text", _csv(RAW, header=("bx", "by", "bz"), meta=("# field_nT: fifty",)), [], 2, "not a number"),
    ("meta-field-zero", _csv(RAW, header=("bx", "by", "bz"), meta=("# field_nT: 0",)), [], 2, "positive number"),
    ("meta-field-inf", _csv(RAW, header=("bx", "by", "bz"), meta=("# field_nT: inf",)), [], 2, "positive number"),
    ("no-reference", _csv(RAW, header=("bx", "by", "bz"), meta=()), [], 2, "no reference"),
    # model auto said it once per candidate model, in the Python API's words (f_ref_nT=, field=)
    ("no-reference-model-auto", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--model", "auto"], 2,
     "no reference magnitude: give an f_ref column, --field NT"),
    ("meta-field-used", _csv(RAW, header=("bx", "by", "bz")), [], 0, ""),
    ("field-option-used", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--field", "50000"], 0, ""),
    ("field-option-negative", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--field", "-3"], 2, "positive"),
    ("field-option-nan", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--field", "nan"], 2, "positive"),
    # a reference given in another unit is said so (the readings' unit was named: 'they look like G')
    ("field-option-in-gauss", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--field", "0.5"], 2,
     "the reference is in nT: 0.5 G would be 50000 nT"),
    ("field-option-absurd", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--field", "1e300"], 2,
     "the reference is no geomagnetic or laboratory field"),
    # classic Mac OS line endings (carriage returns only) are lines: the file was 'no header row and no data'
    ("cr-only-line-ends", GOOD.replace("\n", "\r"), [], 0, ""),
    # --save refused before the fit, in one line (a folder that takes no file was found after it, under the
    # reference's notice), and never a file whose name says another format than the one written
    ("save-into-proc", GOOD, ["--save", "/proc/magbench-cal.json"], 2, "cannot write /proc/magbench-cal.json"),
    ("save-empty-name", GOOD, ["--save", ""], 2, "--save: the file name is empty"),
    ("save-mat-as-json", GOOD, ["--save", "cal.mat", "--export", "json"], 2,
     "a .mat file does not hold --export json (that writes .json)"),
    ("save-json-as-ardupilot", GOOD, ["--save", "cal.json", "--export", "ardupilot"], 2,
     "a .json file does not hold --export ardupilot"),
    ("param-empty-name", GOOD, ["--param", "=1"], 2, "the name before '=' is empty"),
    # a reference 30 % high puts lsq's scales at 0.77 (a warning); the GA's box cannot reach them: said so, not that its
    # search stopped short
    ("reference-30pct-high-ga", _csv(RAW, f_ref=1.3 * F_NT), ["--method", "ga"], 3,
     "the optimum lies outside ga's search box (kx, ky, kz ended on its bound)"),
    # attitude coverage
    ("plane-36", _csv(_plane(36)), [], 2, "degenerate attitude coverage"),
    ("plane-3600", _csv(_plane(3600)), [], 2, "degenerate attitude coverage"),
    ("plane-wobbling-2deg", _csv(_plane(360, wobble_deg=2.0)), [], 3, "is not determined by these data"),
    ("plane-wobbling-12deg", _csv(_plane(360, wobble_deg=12.0)), [], 0, ""),
    ("plane-angles-model", _csv(_plane(36, errors=ANGLES_ONLY)), ["--model", "angles"], 0, ""),
    ("one-attitude-repeated", _csv(np.repeat(RAW[:1], 50, axis=0)), [], 2, "only 1 distinct reading in 50 rows"),
    ("hemisphere", _csv(get_scenario("cap9").build(0).raw_nT), [], 0, ""),
    # spikes and outliers
    ("spike-5e6-ellipsoid", _csv(_spike(RAW, [17], 5e6)), ["--method", "ellipsoid"], 3, "outliers"),
    ("spike-5e6-lsq", _csv(_spike(RAW, [17], 5e6)), [], 3, "ransac"),
    ("spike-5e6-ransac", _csv(_spike(RAW, [17], 5e6)), ["--method", "ransac"], 0, ""),
    ("spikes-500nT-10pct-lsq", _csv(_spike(RAW, np.arange(0, 300, 10), 500.0)), [], 3, "points are outliers"),
    ("spikes-500nT-10pct-ransac", _csv(_spike(RAW, np.arange(0, 300, 10), 500.0)), ["--method", "ransac"], 0, ""),
    # broken values
    ("overflow-1e300", _edit_row(GOOD, 9, "1e300,1,1,50000"), [], 2, "beyond any magnetic field"),
    ("absurd-1e12", _edit_row(GOOD, 9, "1e12,1,1,50000"), [], 2, "beyond any magnetic field"),
    ("nan-value", _edit_row(GOOD, 3, "nan,1,1,50000"), [], 2, "non-finite"),
    ("empty-cell", _edit_row(GOOD, 3, ",1,1,50000"), [], 2, "missing"),
    ("text-value", _edit_row(GOOD, 3, "abc,1,1,50000"), [], 2, "non-numeric"),
    ("inf-value", _edit_row(GOOD, 3, "inf,1,1,50000"), [], 2, "non-finite"),
    # empty and tiny
    ("empty-file", "", [], 2, "no header"),
    ("comments-only", "# field_nT: 50000\n# nothing else\n", [], 2, "no header"),
    ("header-only", "bx,by,bz,f_ref\n", [], 2, "no data rows"),
    ("five-rows", _csv(RAW[:5]), [], 2, "too few"),
    ("one-row", _csv(RAW[:1]), [], 2, "too few"),
    # options
    ("seed-negative", GOOD, ["--seed", "-5"], 2, "negative"),
    ("seed-text", GOOD, ["--seed", "x"], 2, "not an integer"),
    # NLopt's srand takes 64 bits: a larger seed was an internal error (OverflowError)
    ("seed-above-64-bits", GOOD, ["--method", "nlopt", "--seed", str(2**64)], 2, "is above 2**64 - 1"),
    ("param-not-int", GOOD, ["--method", "aga", "--param", "population=abc"], 2, "population must be an int in [2, 1000000]"),
    ("param-no-equals", GOOD, ["--param", "population"], 2, "KEY=VALUE"),
    ("param-unknown", GOOD, ["--param", "colour=3"], 2, "no hyper-parameter"),
    ("param-bool-as-int", GOOD, ["--param", "bounded=1"], 2, "bounded must be a bool"),
    ("method-unknown", GOOD, ["--method", "nope"], 2, "unknown calibrator"),
    ("model-unknown", GOOD, ["--model", "ten"], 2, "invalid choice"),
    ("units-unknown", GOOD, ["--units", "kT"], 2, "invalid choice"),
    ("igrf-1850", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--igrf", "34.26,108.94,0.4,1850-01-01"], 2,
     "outside IGRF-14"),
    ("igrf-2035", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--igrf", "34.26,108.94,0.4,2035-01-01"], 2,
     "outside IGRF-14"),
    ("igrf-altitude", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--igrf", "34.26,108.94,50000,2013-06-27"], 2,
     "implausible"),
    ("igrf-latitude", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--igrf", "95,108.94,0.4,2013-06-27"], 2,
     "latitude"),
    ("igrf-malformed", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--igrf", "34.26;108.94"], 2, "--igrf"),
    ("igrf-bad-date", _csv(RAW, header=("bx", "by", "bz"), meta=()), ["--igrf", "34.26,108.94,0.4,2013-13-45"], 2,
     "--igrf"),
    ("directory", "DIRECTORY", [], 2, "is a directory"),
    ("missing-file", None, [], 2, "no such file"),
    # ambiguous input: metadata, quotes, field counts, units
    ("conflicting-field-meta", _csv(RAW, header=("bx", "by", "bz"), meta=("# field_nT: 50000", "# field_nT: 57000")),
     [], 2, "conflicting metadata lines '# field_nT: 50000' and '# field_nT: 57000'"),
    ("same-field-meta-twice", _csv(RAW, header=("bx", "by", "bz"), meta=("# field_nT: 50000", "# field_nT: 50000")),
     [], 0, ""),
    ("quote-swallows-rows", _quoted(20, 290), [], 2, "unbalanced quote"),
    ("quote-to-end-of-file", _quoted(20, None), [], 2, "starting on line 23 spans 280 lines: an unbalanced quote"),
    ("header-missing-a-column-quoted", _quoted(20, 20).replace("bx,by,bz,f_ref,note", "bx,by,bz,note"), [], 2,
     "has 5 field(s) but the header names 4"),
    ("quoted-line-break", _quoted(20, 21), [], 2, "unbalanced quote"),
    ("balanced-quotes", _quoted(20, 20), [], 0, ""),
    ("header-missing-a-column", GOOD.replace("bx,by,bz,f_ref", "bx,by,bz"), [], 2,
     "has 4 field(s) but the header names 3"),
    ("row-missing-a-field", _edit_row(GOOD, 11, "1,2,50000"), [], 2, "line 14 has 3 field(s)"),
    ("counts-with-gain-line", _csv(np.round(RAW / 3.0517578125), meta=("# gain_nT_per_count: 3.0517578125",),
                                   fmt="{:.0f}"), [], 2, "ADC counts ('# gain_nT_per_count: 3.0517578125')"),
    ("units-counts-line", _csv(np.round(RAW / 3.0517578125), meta=("# units: counts",), fmt="{:.0f}"), [], 2,
     "ADC counts ('# units: counts')"),
    ("units-line-disagrees", _csv(RAW / 1000.0, f_ref=50.0, fmt="{:.6g}", meta=("# units: uT",)), [], 2,
     "read as nT: read it with units uT"),
    ("units-line-agrees", _csv(RAW / 1000.0, f_ref=50.0, fmt="{:.6g}", meta=("# units: uT",)), ["--units", "uT"], 0,
     ""),
    ("units-line-unknown", _csv(RAW, meta=("# units: furlongs",)), [], 2, "names no unit"),
    # bounded reads
    ("overlong-line", _edit_row(GOOD, 4, "1," * 600_000 + "1"), [], 2, "longer than 1,048,576 bytes"),
    ("overlong-header", "#\n" + "a," * 2_000_000 + "bx\n1\n", [], 2, "longer than 1,048,576 bytes"),
    ("too-many-columns", ",".join(["bx", "by", "bz", "f_ref"] + [f"c{i}" for i in range(5000)]) + "\n1,2,3,4\n",
     [], 2, "more than the limit of 1,000"),
]


def _bad_igrf_is_an_ordinary_reference():
    """Sanity: a valid --igrf date gives a reference in the geomagnetic range (the IGRF cases above fail
    on their date, place or form, not on the mechanism)."""
    from magbench.simulate.field import igrf_field

    return igrf_field(34.26, 108.94, 0.4, "2013-06-27").total_nT


def test_a_non_ascii_name_is_pointed_at_only_where_it_stands_for_a_missing_one(tmp_path, capsys):
    """Negative control of the look-alike hint: a non-ASCII name of another column (a temperature in French)
    beside a missing bx is not blamed for it."""
    path = tmp_path / "d.csv"
    path.write_text(GOOD.replace("bx,by,bz,f_ref", "bq,by,bz,f_ref").replace("\n", ",20\n")
                    .replace("bq,by,bz,f_ref,20", "bq,by,bz,f_ref,temp\u00e9rature")
                    .replace("# field_nT: 50000,20", "# field_nT: 50000"), encoding="utf-8")
    assert main(["calibrate", str(path), "--method", "lsq"]) == 2
    err = capsys.readouterr().err
    assert "lacks column(s) bx" in err and "non-ASCII" not in err


def test_the_corpus_is_large_enough():
    assert len(CASES) >= 60
    assert len({c[0] for c in CASES}) == len(CASES)
    assert 45000 < _bad_igrf_is_an_ordinary_reference() < 56000


def _input_file(tmp_path, content):
    """The case's input at tmp_path/input.csv (a directory for DIRECTORY, nothing for None), and its SHA-256."""
    path = tmp_path / "input.csv"
    if content == "DIRECTORY":
        path.mkdir()
    elif content is not None:
        path.write_bytes(content if isinstance(content, bytes) else content.encode("utf-8"))
    return path, hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None


@pytest.mark.parametrize("ident,content,extra,status,fragment", CASES, ids=[c[0] for c in CASES])
def test_hostile_input(tmp_path, capsys, ident, content, extra, status, fragment):
    path, before = _input_file(tmp_path, content)
    args = ["calibrate", str(path)] + (["--method", "lsq"] if "--method" not in extra else []) + extra
    code = main(args)
    out, err = capsys.readouterr()
    assert code == status, f"{ident}: exit {code}, expected {status}; stderr: {err.strip()}"
    assert "Traceback" not in err + out
    lines = [ln for ln in err.splitlines() if ln.strip()]
    if status == 2:
        assert len(lines) == 1, f"{ident}: bad input must give one line on stderr, got {lines}"
        assert out == "", f"{ident}: nothing on stdout on bad input"
    if status == 3:
        causes = [ln for ln in lines if ln.startswith("magbench: calibration rejected:")]
        assert len(causes) == 1 and len(lines) <= 2, lines
    if status == 0:
        assert "REJECTED" not in out
    assert fragment in err, f"{ident}: {fragment!r} not in {err.strip()!r}"
    if before is not None:
        assert hashlib.sha256(path.read_bytes()).hexdigest() == before, "the input file was changed"


def test_json_output_of_a_rejection_is_whole_and_stdout_is_one_object(tmp_path, capsys):
    import json

    path = tmp_path / "spike.csv"
    path.write_text(_csv(_spike(RAW, [17], 5e6)))
    assert main(["calibrate", str(path), "--method", "lsq", "--json"]) == 3
    out, err = capsys.readouterr()
    obj = json.loads(out)
    assert obj["accepted"] is False and any("outliers" in r for r in obj["rejections"])
    assert obj["reference"]["source"] == "the file's f_ref column"
    for key in ("method", "model", "alpha_rad", "beta_rad", "gamma_rad", "scale", "offset_nT", "matrix",
                "rms_before_nT", "rms_after_nT", "runtime_s", "n_evaluations", "seed", "warnings"):
        assert key in obj
    assert main(["calibrate", str(path), "--method", "lsq", "--json", "--accept-any"]) == 0
    obj = json.loads(capsys.readouterr().out)
    assert obj["accepted"] is False and any("accept-any" in w for w in obj["warnings"])


def test_simulate_refuses_out_equal_to_truth_and_keeps_the_data(tmp_path, capsys):
    out = tmp_path / "x.csv"
    assert main(["simulate", "--scenario", "sphere9", "--out", str(out)]) == 0
    before = out.read_bytes()
    assert main(["simulate", "--scenario", "sphere9", "--out", str(out), "--truth", str(tmp_path / "." / "x.csv"),
                 "--force"]) == 2
    assert "same file" in capsys.readouterr().err
    assert out.read_bytes() == before


def test_simulate_out_empty_or_a_folder_is_refused_by_what_it_is(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main(["simulate", "--scenario", "sphere9", "--out", ""]) == 2
    assert "the --out file name is empty" in capsys.readouterr().err  # had been ". is a directory, not a file"
    assert main(["simulate", "--scenario", "sphere9", "--out", str(tmp_path)]) == 2
    assert "is a directory, not a file" in capsys.readouterr().err
    assert list(tmp_path.iterdir()) == []


TABLE2 = (Path(__file__).resolve().parents[1] / "simulate" / "data" / "lu2014_table2.csv").read_text()


def _table2(edit=None, drop_f_ref=False):
    lines = TABLE2.splitlines()
    if edit is not None:
        row, column, value = edit
        first = next(i for i, ln in enumerate(lines) if not ln.startswith("#")) + 1
        cells = lines[first + row].split(",")
        cells[column] = value
        lines[first + row] = ",".join(cells)
    if drop_f_ref:
        lines = [ln if ln.startswith("#") else ln.rsplit(",", 1)[0] for ln in lines]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("content,extra,status,fragment", [
    # a scalar series without f_ref, given its field: had been an internal error (a Dataset's method asked of it)
    (_table2(drop_f_ref=True), [], 0, ""),
    (_table2(drop_f_ref=True), ["--field", "51978.74"], 0, ""),
    # the reference's rows as a vector record's: had been diagnosed (a residual of 1.8e7 nT reported)
    (_table2(edit=(5, 6, "1.04e8")), [], 2, "f_ref_nT in row(s) 5 (line 9) is more than 1000 times the median"),
    (_table2(edit=(2, 6, "60000")), [], 2, "the reference jumps 2 time(s)"),
    (_table2(edit=(3, 2, "0.01")), [], 2, "f_meas_before in row(s) 3 (line 7) is less than 1/1000 of the median"),
], ids=["no-f-ref-field-line", "no-f-ref-field-option", "f-ref-spike", "f-ref-jump", "f-meas-tiny"])
def test_scalar_series_rows_and_references(tmp_path, capsys, content, extra, status, fragment):
    path = tmp_path / "scalar.csv"
    path.write_text(content)
    code = main(["diagnose", str(path), *extra])
    out, err = capsys.readouterr()
    assert code == status, err
    assert "internal error" not in err and fragment in err
    if status == 0:
        assert "residual RMS 57.812 nT on the fit" in out  # Table 2's diagnosis, as with its f_ref column


def test_empty_output_names_are_refused_before_anything_is_written(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    (tmp_path / "keep.txt").write_text("mine")
    assert main(["compare", "--scenarios", "sphere9", "--methods", "lsq", "--trials", "1", "--out", "", "--force"]) == 2
    assert "the --out folder name is empty" in capsys.readouterr().err  # '' had been '.': cleared and filled
    assert [p.name for p in tmp_path.iterdir()] == ["keep.txt"]
    data = tmp_path / "keep.csv"
    data.write_text(GOOD)
    assert main(["diagnose", str(data), "--figure", ""]) == 2  # had been no figure, without a word
    assert "--figure: the file name is empty" in capsys.readouterr().err


def test_control_characters_in_names_are_not_echoed_raw(tmp_path, capsys):
    name = str(tmp_path / "evil\x1b[31mred\rname.csv")
    assert main(["calibrate", name, "--method", "lsq"]) == 2
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\r" not in err and "\\x1b" in err


@pytest.mark.parametrize("where", ["file-name", "column-name"])
def test_a_line_break_in_a_name_is_shown_escaped_and_the_reason_kept(tmp_path, capsys, where):
    """One line on stderr with the whole reason: a line break in a file or column name is escaped, not cut there
    (the message had ended at it: 'magbench: /tmp/a' and nothing more)."""
    if where == "file-name":
        path = tmp_path / "a\nb.csv"
        path.write_text(_edit_row(GOOD, 7, "nan,1,2,50000"))
        reason = "column bx has a value missing, non-numeric or non-finite ('nan') on line 10"
    else:
        path = tmp_path / "c.csv"
        path.write_text(GOOD.replace("bx,by,bz,f_ref", '"b\rx",by,bz,f_ref'))
        reason = "units go in --units or a '# units:' line"
    assert main(["calibrate", str(path), "--method", "lsq"]) == 2
    err = capsys.readouterr().err
    lines = err.splitlines()
    assert len(lines) == 1 and "\r" not in err and reason in lines[0]
    assert ("a\\nb.csv" if where == "file-name" else "b\\rx") in lines[0]


def test_igrf_warnings_never_reach_stdout(tmp_path, capsys):
    path = tmp_path / "v.csv"
    path.write_text(_csv(RAW, header=("bx", "by", "bz"), meta=()))
    code = main(["calibrate", str(path), "--method", "lsq", "--json", "--igrf", "34.26,108.94,0.4,1850-01-01"])
    out, err = capsys.readouterr()
    assert code == 2 and out == ""


# ------------------------------------------------------------------ the second hostile corpus
def _run(capsys, args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    assert "Traceback" not in out + err
    return code, out, err


def _refused(capsys, args, fragment):
    """Exit 2, one line on stderr holding ``fragment``, nothing on stdout."""
    code, out, err = _run(capsys, args)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert code == 2, f"exit {code}: {err}"
    assert len(lines) == 1, lines
    assert out == ""
    assert fragment in err, err
    return err


def _digest(path):
    return hashlib.sha256(open(path, "rb").read()).hexdigest()


def _smooth_record(n=2000, seed=0, step_nT=None, pink_nT=0.0, noise=3.0):
    """A record in time (a smooth tumble, 3 nT noise), optionally with the offsets stepping halfway by
    ``step_nT`` (a vector) or with 1/f noise of RMS ``pink_nT`` added to every axis."""
    rng = np.random.default_rng(seed)
    att = attitude.tumble(n, rng)
    raw = np.array(SensorModel(NINE, noise_nT=noise).measure(att.body_field(np.asarray(FIELD.vector_nT)), rng))
    if step_nT is not None:
        raw[n // 2:] += step_nT
    if pink_nT:
        spec = np.fft.rfft(rng.normal(size=(n, 3)), axis=0)
        f = np.maximum(np.arange(spec.shape[0]), 1)
        pink = np.fft.irfft(spec / np.sqrt(f)[:, None], n=n, axis=0)
        raw += pink_nT * pink / pink.std(axis=0)
    lines = ["t,bx,by,bz,f_ref"] + [f"{t:.3f},{x:.4f},{y:.4f},{z:.4f},{F_NT:.1f}" for t, (x, y, z) in zip(att.t_s, raw)]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("method", ["lsq", "ellipsoid"])
def test_a_step_in_the_offsets_is_rejected_and_located(tmp_path, capsys, method):
    path = tmp_path / "step.csv"
    path.write_text(_smooth_record(step_nT=np.array([700.0, -350.0, 210.0])))
    before = _digest(path)
    code, out, err = _run(capsys, ["calibrate", path, "--method", method])
    assert code == 3, err
    assert "a step in the residual at row 1,000" in err and "times the noise estimated independently" in err
    assert "offsets jump by about" in out
    assert _digest(path) == before


@pytest.mark.parametrize("pink", [0.0, 5.0, 15.0], ids=["white", "pink-5nT", "pink-15nT"])
def test_clean_records_are_accepted_with_white_or_1_over_f_noise(tmp_path, capsys, pink):
    """Negative controls of the step test: the same record without the step passes."""
    path = tmp_path / "clean.csv"
    path.write_text(_smooth_record(pink_nT=pink))
    code, out, err = _run(capsys, ["calibrate", path, "--method", "lsq", "--json"])
    assert code == 0, err
    import json

    obj = json.loads(out)
    assert obj["accepted"] and not [w for w in obj["warnings"] if "independently" in w]
    assert obj["input_sha256"] == _digest(path)  # the digest of the bytes read, recorded


def test_without_time_or_repeats_the_warning_says_the_noise_is_not_independent(tmp_path, capsys):
    path = tmp_path / "plain.csv"
    path.write_text(GOOD)
    code, out, err = _run(capsys, ["calibrate", path, "--method", "lsq"])
    assert code == 0 and "the noise could not be estimated independently of the fit" in out


def _vehicle_csv(tilt_deg=5.0, n=720, seed=3):
    rng = np.random.default_rng(seed)
    att = attitude.vehicle(n, rng, pitch_roll_deg=tilt_deg, turns=2.0)
    raw = SensorModel(NINE, noise_nT=3.0).measure(att.body_field(np.asarray(FIELD.vector_nT)), rng)
    lines = ["t,bx,by,bz,f_ref"] + [f"{t:.1f},{x:.4f},{y:.4f},{z:.4f},{F_NT:.1f}" for t, (x, y, z) in zip(att.t_s, raw)]
    return "\n".join(lines) + "\n"


def _three_attitudes_csv(n_each=100, seed=1):
    from scipy.spatial.transform import Rotation

    rot = Rotation.random(3, random_state=seed)[np.repeat(np.arange(3), n_each)]
    b = rot.apply(np.tile(FIELD.vector_nT, (3 * n_each, 1)), inverse=True)
    raw = SensorModel(NINE, noise_nT=3.0).measure(b, np.random.default_rng(seed))
    return _csv(raw)


@pytest.mark.parametrize("content", [_vehicle_csv(), _three_attitudes_csv()], ids=["planar-5deg", "three-attitudes"])
def test_model_auto_never_accepts_an_unidentifiable_offset_model(tmp_path, capsys, content):
    import json

    path = tmp_path / "auto.csv"
    path.write_text(content)
    before = _digest(path)
    code, out, err = _run(capsys, ["calibrate", path, "--method", "lsq", "--model", "auto", "--json"])
    assert code == 3, err
    obj = json.loads(out)
    assert obj["accepted"] is False and obj["rejections"][0].startswith("model auto:")
    assert "not determined" in obj["rejections"][0]
    assert "calibration rejected: model auto" in err
    assert _digest(path) == before


def test_model_auto_on_a_sphere_still_chooses_and_accepts(tmp_path, capsys):
    """Negative control: full coverage gives an accepted choice."""
    path = tmp_path / "sphere.csv"
    path.write_text(GOOD)
    code, out, err = _run(capsys, ["calibrate", path, "--method", "lsq", "--model", "auto"])
    assert code == 0 and "model auto -> nine" in out


def test_a_header_field_ten_percent_low_warns_about_the_mean_scale(tmp_path, capsys):
    path = tmp_path / "low.csv"
    path.write_text(_csv(RAW, header=("bx", "by", "bz"), meta=("# field_nT: 45000",)))
    code, out, err = _run(capsys, ["calibrate", path, "--method", "lsq"])
    assert code == 0 and "the mean scale factor is 1.1" in out and "units are likely wrong" in out
    path.write_text(_csv(RAW, header=("bx", "by", "bz")))  # the right field: no such warning
    code, out, err = _run(capsys, ["calibrate", path, "--method", "lsq"])
    assert code == 0 and "mean scale factor" not in out


# special files and bombs: refused at once, without reading them
def test_a_fifo_is_refused_without_blocking(tmp_path, capsys):
    import os
    import time

    fifo = tmp_path / "pipe.csv"
    os.mkfifo(fifo)
    t0 = time.monotonic()
    _refused(capsys, ["calibrate", fifo, "--method", "lsq"], "is a FIFO (named pipe), not a data file")
    assert time.monotonic() - t0 < 5


def test_a_symlink_to_dev_zero_is_refused_at_once(tmp_path, capsys):
    import os
    import time

    link = tmp_path / "zero.csv"
    os.symlink("/dev/zero", link)
    t0 = time.monotonic()
    _refused(capsys, ["calibrate", link, "--method", "lsq"], "is a character device, not a data file")
    _refused(capsys, ["apply", link, GOOD_PATH(tmp_path), "--out", tmp_path / "o.csv"], "character device")
    assert time.monotonic() - t0 < 5


def GOOD_PATH(tmp_path):  # noqa: N802 - a constant-like helper
    path = tmp_path / "good.csv"
    if not path.exists():
        path.write_text(GOOD)
    return path


def _saved_calibration(tmp_path, capsys, *extra):
    cal = tmp_path / "cal.json"
    code, _, err = _run(capsys, ["calibrate", GOOD_PATH(tmp_path), "--method", "lsq", "--save", cal, *extra])
    assert code == 0, err
    return cal


def test_json_bombs_are_refused(tmp_path, capsys):
    deep = tmp_path / "deep.json"
    deep.write_text("[" * 200_000 + "]" * 200_000)
    _refused(capsys, ["apply", deep, GOOD_PATH(tmp_path), "--out", tmp_path / "o.csv"], "nested 200,000 deep")
    digits = tmp_path / "digits.json"
    digits.write_text('{"schema": "magbench.calibration", "schema_version": 1' + "0" * 5000 + "}")
    _refused(capsys, ["apply", digits, GOOD_PATH(tmp_path), "--out", tmp_path / "o.csv"],
             "a number of 5,001 characters")
    wrong = tmp_path / "wrong.json"
    obj = __import__("json").loads(_saved_calibration(tmp_path, capsys).read_text())
    obj["accepted"] = "yes"
    wrong.write_text(__import__("json").dumps(obj))
    _refused(capsys, ["apply", wrong, GOOD_PATH(tmp_path), "--out", tmp_path / "o.csv"],
             "'accepted' has the wrong type")
    assert not (tmp_path / "o.csv").exists()


def test_a_mat_bomb_is_refused_before_it_inflates(tmp_path, capsys):
    from scipy.io import savemat

    bomb = tmp_path / "bomb.mat"
    savemat(bomb, {"A": np.eye(3), "b": np.zeros((1, 3)), "pad": np.zeros((3000, 1000))}, do_compression=True)
    assert bomb.stat().st_size < 200_000
    _refused(capsys, ["apply", bomb, GOOD_PATH(tmp_path), "--out", tmp_path / "o.csv"],
             "inflates to more than 16,777,216")
    ok = tmp_path / "ok.mat"  # negative control: a small compressed magcal file is read
    savemat(ok, {"A": np.eye(3), "b": np.zeros((1, 3)), "expmfs": F_NT}, do_compression=True)
    code, out, err = _run(capsys, ["apply", ok, GOOD_PATH(tmp_path), "--out", tmp_path / "o.csv"])
    assert code == 0, err


def test_a_memory_error_without_text_is_one_line(tmp_path, capsys, monkeypatch):
    import pandas as pd

    def no_memory(*args, **kwargs):
        raise MemoryError()

    from magbench.simulate import dataset

    monkeypatch.setattr(pd, "read_csv", no_memory)
    monkeypatch.setattr(dataset, "SMALL_TABLE_BYTES", 0)  # the large-file path (pandas)
    _refused(capsys, ["calibrate", GOOD_PATH(tmp_path), "--method", "lsq"], "not enough memory")


# outputs: never over an input (hard links included), atomic, OSError as exit 2
def test_save_onto_a_hard_link_of_the_input_is_refused(tmp_path, capsys):
    import os

    src = GOOD_PATH(tmp_path)
    link = tmp_path / "link.json"
    os.link(src, link)
    before = _digest(src)
    _refused(capsys, ["calibrate", src, "--method", "lsq", "--save", link, "--force"], "is the input file")
    assert _digest(src) == before and _digest(link) == before


def test_simulate_truth_onto_a_hard_link_of_out_is_refused(tmp_path, capsys):
    import os

    out = tmp_path / "x.csv"
    assert main(["simulate", "--scenario", "sphere9", "--out", str(out)]) == 0
    capsys.readouterr()
    link = tmp_path / "truth.json"
    os.link(out, link)
    before = _digest(out)
    _refused(capsys, ["simulate", "--scenario", "sphere9", "--out", out, "--truth", link, "--force"], "same file")
    assert _digest(out) == before


def test_apply_out_onto_its_inputs_is_refused(tmp_path, capsys):
    import os

    cal = _saved_calibration(tmp_path, capsys)
    src = GOOD_PATH(tmp_path)
    link = tmp_path / "link.csv"
    os.link(src, link)
    before, cal_before = _digest(src), _digest(cal)
    _refused(capsys, ["apply", cal, src, "--out", link, "--force"], "is the input file")
    _refused(capsys, ["apply", cal, src, "--out", cal, "--force"], "is the input file")
    assert _digest(src) == before and _digest(cal) == cal_before


@pytest.mark.parametrize("target,fragment", [("/dev/full", "is a character device"),
                                             ("/proc/magbench-out.csv", "cannot write /proc/magbench-out.csv")])
def test_unwritable_outputs_are_exit_2_with_the_reason(tmp_path, capsys, target, fragment):
    cal = _saved_calibration(tmp_path, capsys)
    before = _digest(GOOD_PATH(tmp_path))
    _refused(capsys, ["apply", cal, GOOD_PATH(tmp_path), "--out", target, "--force"], fragment)
    _refused(capsys, ["simulate", "--scenario", "sphere9", "--out", target, "--force"], fragment)
    assert _digest(GOOD_PATH(tmp_path)) == before


def test_a_full_disk_leaves_no_truncated_or_empty_output(tmp_path, capsys, monkeypatch):
    import errno
    import io

    from magbench import safeio

    cal = _saved_calibration(tmp_path, capsys)
    old = tmp_path / "old.csv"
    old.write_text("the previous output\n")

    class Full(io.FileIO):
        def write(self, b):
            super().write(bytes(b)[:10])
            raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(safeio, "open", lambda path, mode="rb": Full(path, mode.replace("b", "")), raising=False)
    _refused(capsys, ["apply", cal, GOOD_PATH(tmp_path), "--out", old, "--force"], "No space left on device")
    assert old.read_text() == "the previous output\n"
    _refused(capsys, ["simulate", "--scenario", "sphere9", "--out", tmp_path / "new.csv"], "No space left")
    assert not (tmp_path / "new.csv").exists()
    assert not [p.name for p in tmp_path.iterdir() if ".tmp" in p.name], "a temporary file was left behind"


# apply: guards and one read
def test_apply_refuses_a_rejected_calibration_unless_accept_any(tmp_path, capsys):
    import json

    spike = tmp_path / "spike.csv"
    spike.write_text(_csv(_spike(RAW, [17], 5e6)))
    cal = tmp_path / "rejected.json"
    code, _, _ = _run(capsys, ["calibrate", spike, "--method", "lsq", "--save", cal, "--accept-any"])
    assert code == 0 and json.loads(cal.read_text())["accepted"] is False
    out = tmp_path / "o.csv"
    _refused(capsys, ["apply", cal, GOOD_PATH(tmp_path), "--out", out], "was rejected by its acceptance checks")
    assert not out.exists()
    code, text, err = _run(capsys, ["apply", cal, GOOD_PATH(tmp_path), "--out", out, "--accept-any"])
    assert code == 0 and "warning: applied by --accept-any" in text and out.exists()


def test_apply_refuses_an_ill_conditioned_calibration(tmp_path, capsys):
    import json

    cal = tmp_path / "flat.json"
    cal.write_text(json.dumps({"A": [[1, 0, 0], [0, 1, 0], [0, 0, 1e-30]], "b": [0, 0, 0], "expmfs": F_NT}))
    out = tmp_path / "o.csv"
    _refused(capsys, ["apply", cal, GOOD_PATH(tmp_path), "--out", out],
             "ill-conditioned (condition number 1e+30, |determinant| 1e-30; the limits are a condition number of 100")
    good = _saved_calibration(tmp_path, capsys)  # negative control
    code, _, err = _run(capsys, ["apply", good, GOOD_PATH(tmp_path), "--out", out])
    assert code == 0, err


def test_apply_reads_the_data_file_once(tmp_path, capsys, monkeypatch):
    import builtins

    from magbench import safeio
    from magbench.calibrators import artifacts

    cal = _saved_calibration(tmp_path, capsys)
    src = GOOD_PATH(tmp_path)
    before = _digest(src)
    reads, real_read, real_open = [], safeio.read_input, builtins.open

    def counting(path, *args, **kwargs):
        reads.append(str(path))
        return real_read(path, *args, **kwargs)

    def no_second_open(path, *args, **kwargs):
        assert str(path) != str(src), "the data file was opened a second time"
        return real_open(path, *args, **kwargs)

    monkeypatch.setattr(artifacts, "read_input", counting)
    monkeypatch.setattr(builtins, "open", no_second_open)
    code, out, err = _run(capsys, ["apply", cal, src, "--out", tmp_path / "o.csv", "--json"])
    assert code == 0, err
    assert reads.count(str(src)) == 1
    assert __import__("json").loads(out)["input_sha256"] == before


DIAGNOSE_ANSWERS = {"plane-36", "plane-3600"}  # a level turntable: the diagnosis's weak prior answers it (exit 0)
CALIBRATE_ONLY = ("--method", "--save", "--accept-any", "--param", "--model")


def _fixed(n=400, seed=2):
    """A fixed sensor's readings (one attitude), the noise its only change."""
    b = np.asarray(FIELD.vector_nT, dtype=float)
    return b + np.random.default_rng(seed).normal(0.0, 0.5, (n, 3))


DIAGNOSE_CASES = [
    ("fixed-stuck", _csv(np.tile(np.asarray(FIELD.vector_nT), (400, 1))), "stuck sensor"),
    ("fixed-uT", _csv(_fixed() / 1000.0), "uT"),
    ("fixed-gain", _csv(_fixed() / 2.5), "times the reference"),
    ("fixed-reference-jumps", _csv(_fixed(), f_ref=np.where(np.arange(400) < 200, F_NT, 0.9 * F_NT)), "jumps"),
    ("level-reference-tenfold", _csv(_plane(400, wobble_deg=0.5), f_ref=10 * F_NT), "times the reference"),
]


BAD_FOR_DIAGNOSE = [c for c in CASES if c[3] == 2 and c[0] not in DIAGNOSE_ANSWERS
                    and not any(e.startswith(CALIBRATE_ONLY) for e in c[2])]


def test_most_of_the_corpus_is_bad_input_for_diagnose_too():
    assert len(BAD_FOR_DIAGNOSE) >= 60


@pytest.mark.parametrize("ident,content,extra,status,fragment", BAD_FOR_DIAGNOSE, ids=[c[0] for c in BAD_FOR_DIAGNOSE])
def test_diagnose_refuses_the_bad_input_calibrate_refuses(tmp_path, capsys, ident, content, extra, status, fragment):
    """The diagnosis reads the same files: what is bad input to ``calibrate`` is bad input to ``diagnose``, with one
    line and exit 2 (its level-vehicle and fixed-sensor paths answer where the calibrators refuse the attitudes
    only, and must not answer on wrong units or a wrong reference)."""
    path, before = _input_file(tmp_path, content)
    code = main(["diagnose", str(path), *extra])
    out, err = capsys.readouterr()
    assert code == 2, f"{ident}: exit {code}; stdout: {out[:300]}"
    assert "Traceback" not in err + out and out == ""
    assert len([ln for ln in err.splitlines() if ln.strip()]) == 1
    if before is not None:
        assert hashlib.sha256(path.read_bytes()).hexdigest() == before


@pytest.mark.parametrize("ident,content,fragment", DIAGNOSE_CASES, ids=[c[0] for c in DIAGNOSE_CASES])
def test_diagnose_refuses_a_stuck_sensor_and_a_reference_that_does_not_belong(tmp_path, capsys, ident, content,
                                                                              fragment):
    """The paths that answer where the calibrators refuse the attitudes (a fixed sensor's time question, a level
    vehicle's weak prior) refuse what is bad input: a stuck sensor, readings in other units, a reference that jumps
    or does not belong (they answered with a floor of 0, or |B| - F of the units' error, at exit 0)."""
    path = tmp_path / "input.csv"
    path.write_text(content)
    code = main(["diagnose", str(path)])
    out, err = capsys.readouterr()
    assert code == 2 and out == "" and fragment in err and len(err.strip().splitlines()) == 1, (ident, code, err, out[:200])


def test_diagnose_answers_the_fixed_and_level_records_of_those_negative_controls(tmp_path, capsys):
    """Negative controls: the same fixed and level records with their own reference are answered (exit 0)."""
    for name, raw in (("fixed", _fixed()), ("level", _plane(400, wobble_deg=0.5))):
        path = tmp_path / f"{name}.csv"
        path.write_text(_csv(raw))
        assert main(["diagnose", str(path)]) == 0, (name, capsys.readouterr().err)
        capsys.readouterr()


@pytest.mark.parametrize("extra,fragment", [
    (["--figure", "{tmp}/fig.txt"], "the name must end in .png, .svg, .pdf"),
    (["--figure", "{tmp}/fig"], "the name must end in .png, .svg, .pdf"),
    (["--folds", "1000"], "--folds must be at most 100 for 300 readings"),
])
def test_diagnose_refuses_options_it_cannot_honour_before_diagnosing(tmp_path, capsys, extra, fragment):
    """A figure name without a known format was an internal error (exit 1) after the whole diagnosis;
    --folds 1000 on 300 readings ran (700 empty folds) and reported 1000 folds."""
    path = tmp_path / "good.csv"
    path.write_text(GOOD)
    argv = ["diagnose", str(path), *[a.format(tmp=tmp_path) for a in extra]]
    assert main(argv) == 2
    out, err = capsys.readouterr()
    assert out == "" and fragment in err and len(err.strip().splitlines()) == 1, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["good.csv"]


def test_diagnose_writes_a_figure_named_in_capitals_and_takes_the_most_folds(tmp_path, capsys):
    """The negative controls: .PNG is a PNG, and --folds at its limit (100 for 300 readings) runs."""
    path = tmp_path / "good.csv"
    path.write_text(GOOD)
    assert main(["diagnose", str(path), "--figure", str(tmp_path / "fig.PNG"), "--folds", "100"]) == 0
    assert (tmp_path / "fig.PNG").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("dpi,fragment", [("5", "5 is below 20"), ("100000", "100000 is above 1200")])
def test_compare_refuses_a_resolution_it_cannot_draw_before_any_run(tmp_path, capsys, dpi, fragment):
    """--dpi 5 was an internal error (FreeType) and --dpi 100000 'not enough memory', both after the runs."""
    out = tmp_path / "c"
    assert main(["compare", "--scenarios", "sphere9", "--methods", "lsq", "--trials", "1", "--out", str(out),
                 "--quiet", "--dpi", dpi]) == 2
    err = capsys.readouterr().err
    assert fragment in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


def test_compare_calls_a_complete_campaign_complete(tmp_path, capsys):
    """A finished campaign's folder was refused as 'an interrupted campaign (runs.partial.jsonl)'."""
    out = tmp_path / "c"
    argv = ["compare", "--scenarios", "sphere9", "--methods", "lsq", "--trials", "1", "--out", str(out), "--quiet",
            "--no-figures"]
    assert main(argv) == 0
    capsys.readouterr()
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert "it holds a complete campaign" in err and "interrupted" not in err


def test_an_unreachable_dask_scheduler_is_named(tmp_path, capsys, monkeypatch):
    """--dask with no scheduler there said 'cannot read or write OSError' (exit 2) after 20 s."""
    from magbench.benchmarks import campaign

    monkeypatch.setattr(campaign, "DASK_CONNECT_S", 1)
    code = main(["compare", "--scenarios", "sphere9", "--methods", "lsq", "--trials", "1", "--out",
                 str(tmp_path / "c"), "--quiet", "--no-figures", "--dask", "tcp://127.0.0.1:9"])
    err = capsys.readouterr().err
    assert code == 2 and "cannot reach the Dask scheduler at tcp://127.0.0.1:9 within 1 s" in err, err
    assert len(err.strip().splitlines()) == 1


def test_diagnose_refuses_broken_accelerometer_columns(tmp_path, capsys):
    """A file whose ax, ay, az had an empty row was diagnosed without its gravity, saying nothing."""
    lines = GOOD.splitlines()
    header = [i for i, ln in enumerate(lines) if not ln.startswith("#")][0]
    body = [ln + (",0,0,9.8" if i != header + 6 else ",,,") for i, ln in enumerate(lines[header + 1:], header + 1)]
    bad = tmp_path / "bad.csv"
    bad.write_text("\n".join(lines[:header] + [lines[header] + ",ax,ay,az"] + body) + "\n")
    assert main(["diagnose", str(bad)]) == 2
    err = capsys.readouterr().err
    assert "accelerometer columns ax, ay, az" in err and "not a direction" in err and len(err.strip().splitlines()) == 1
    good = tmp_path / "good.csv"
    good.write_text(bad.read_text().replace(",,,", ",0,0,9.8"))
    assert main(["diagnose", str(good)]) == 0


def test_more_jobs_than_cpus_runs_as_many_workers_as_cpus(tmp_path, capsys, monkeypatch):
    """--jobs 200 on a 2-core machine forked 200 workers, each importing and warming up."""
    import os

    monkeypatch.setattr(os, "cpu_count", lambda: 2)
    out = tmp_path / "c"
    assert main(["compare", "--scenarios", "sphere9", "--methods", "lsq", "--trials", "4", "--jobs", "200", "--out",
                 str(out), "--quiet", "--no-figures"]) == 0
    err = capsys.readouterr().err
    assert "--jobs 200 is more than this machine's 2 CPUs: running 2 workers" in err
    assert json.loads((out / "manifest.json").read_text())["jobs"] == 2
    assert main(["compare", "--scenarios", "sphere9", "--methods", "lsq", "--trials", "4", "--jobs", "2", "--out",
                 str(tmp_path / "d"), "--quiet", "--no-figures"]) == 0  # the control: no notice
    assert "CPUs" not in capsys.readouterr().err


@pytest.mark.parametrize("rows", [4000, 300], ids=["past-the-field-limit", "control-short"])
def test_a_quote_never_closed_in_a_long_file_is_named(tmp_path, capsys, rows):
    """A quote that never closes in a long file runs past the csv module's field limit (131,072 characters): said as
    the unbalanced quote it is, with its line, not as the parser's 'field larger than field limit'; the control, a
    short file, is refused by the line count as before."""
    rng = np.random.default_rng(rows)
    u = rng.normal(size=(rows, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    lines = ["bx,by,bz,f_ref"] + [f"{a:.3f},{b:.3f},{c:.3f},50000" for a, b, c in (u * 5e4).tolist()]
    lines[5] = lines[5].replace(",", ',"', 1)
    path = tmp_path / "q.csv"
    path.write_text("\n".join(lines) + "\n")
    fragment = ("a quoted field starting on line 6 runs on past 131,072 characters: an unbalanced quote" if rows == 4000
                else "starting on line 6 spans")
    _refused(capsys, ["calibrate", path, "--method", "lsq"], fragment)


@pytest.mark.parametrize("last, status", [(',"50000', 2), (',"50000"', 0), (',50000,12"3', 0)],
                         ids=["quote-open-at-the-end", "control-closed", "control-inch-mark"])
@pytest.mark.parametrize("rows", [300, 6000], ids=["small", "1-MB"])
def test_a_quote_left_open_on_the_last_line_is_refused(tmp_path, capsys, last, status, rows):
    """A file whose last line (no line end after it) opens a quote that never closes had been read without a word
    (the csv module closes it at the end of the data); refused with its line.  Controls: the quote closed, and a
    stray inch mark inside a text field (text, not a quote)."""
    rng = np.random.default_rng(rows)
    u = rng.normal(size=(rows, 3))
    u /= np.linalg.norm(u, axis=1)[:, None]
    note = last.count(",") == 2
    lines = ["bx,by,bz,f_ref" + (",note" if note else "")] + [
        f"{a:.3f},{b:.3f},{c:.3f},50000" + (",x" if note else "") for a, b, c in (u * 5e4).tolist()]
    a, b, c = (u[-1] * 5e4).tolist()
    lines[-1] = f"{a:.3f},{b:.3f},{c:.3f}" + last
    path = tmp_path / "q.csv"
    path.write_text("\n".join(lines))  # no line end after the last line
    if status == 2:
        _refused(capsys, ["calibrate", path, "--method", "lsq"], f"a quote (\") on line {rows + 1}, the last, never "
                                                                   "closes: an unbalanced quote")
    else:
        code, _, err = _run(capsys, ["calibrate", path, "--method", "lsq"])
        assert code in (0, 3), err
