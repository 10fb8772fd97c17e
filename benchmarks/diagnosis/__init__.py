"""The sim-to-real diagnosis (``magbench diagnose``, CONTRACT section 3): where the residual of a
calibration lies, which unmodelled effect causes it, and how far it shrinks once that effect is modelled.

The effects, forward and fitted, are the classes of the one registry ``magbench.simulate.effects``;
this package is the procedure, one concern per module:

* ``model``      the base correction plus one effect's fitted form, fitted by least squares;
* ``localize``   where the residual lies (attitude, time, temperature, distribution);
* ``floor``      the noise floor without any model;
* ``scoring``    cross-validated scoring of each candidate effect;
* ``verdict``    the verdict;
* ``resimulate`` the fitted effect re-simulated and compared with the observation;
* ``vector``     the procedure on a vector dataset (``Diagnosis``);
* ``scalar``     the procedure on a scalar turntable series (seed 000's Table 2);
* ``report``     the human table and the figure;
* ``blind``      the blind check's datasets.
"""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from magbench.calibrators.base import data_problem, one_blas_thread
from magbench.calibrators.core.objective import ScalarObjective, identity_vector
from magbench.calibrators.fisher import coverage
from magbench.errors import MAX_SEED, InputError, check_int
from magbench.numerics import time_column_note, timestamp_glitches
from magbench.simulate.dataset import Dataset, ScalarSeries, read_columns, real_array
from magbench.simulate.sensor import PARAM_NAMES

from .blind import blind_dataset, blind_kinds
from .floor import rail_rows, stale_copies
from .report import diagnosis_figure, diagnosis_text
from .scalar import diagnose_scalar
from .scoring import candidate_effects
from .timeonly import MIN_DISTINCT, time_only
from .vector import DEFAULT_FOLDS, MIN_POINTS_BEYOND_PARAMETERS, Diagnosis, check_folds

__all__ = ["read_gravity", "Diagnosis", "blind_dataset", "blind_kinds", "candidate_effects", "diagnose", "diagnose_scalar",
           "diagnosed_rows", "diagnosis_figure", "diagnosis_text"]


def diagnose(data, base: str = "nine", folds: int = DEFAULT_FOLDS, seed: int = 0, gravity=None,
             progress: bool | None = None) -> dict:
    """Diagnose a vector ``Dataset`` or a scalar turntable ``ScalarSeries`` (``gravity``: optional (n, 3)
    accelerometer directions; ``progress``: a bar on stderr, by default for long records)."""
    # one BLAS thread (calibrators.base.one_blas_thread, as every fit): every product here is a tall-skinny block
    # (65536 x <= 50); a second thread gains nothing, and on a loaded machine spin-waiting BLAS threads made the
    # Gram products up to 100x slower
    folds, seed = check_int(folds, "folds", 2), check_int(seed, "seed", 0)
    if seed > MAX_SEED:
        raise InputError(f"seed must be an integer from 0 to 2**64 - 1, got {seed}")
    if not isinstance(data, (Dataset, ScalarSeries)):
        raise InputError(f"diagnose takes a Dataset (readings, reference, times) or a ScalarSeries, not "
                         f"{type(data).__name__}")
    if gravity is not None and not isinstance(data, ScalarSeries):
        gravity = gravity_problem_free(gravity, len(data))
    check_folds(folds, len(data))  # on every path, also those that do not use them
    glitch = timestamp_glitches(data.t_s)  # every path reads the times
    if glitch:
        raise InputError(glitch)
    with one_blas_thread():
        out = _diagnose(data, base, folds, seed, gravity, progress)
    note = time_column_note(data.t_s)
    if note:
        out["time_column"] = note
    if data.meta.get("input_notes"):  # the reader's (``simulate.dataset.column_notes``)
        out["input_notes"] = str(data.meta["input_notes"])
    return out


def _diagnose(data, base: str, folds: int, seed: int, gravity, progress: bool | None) -> dict:
    if isinstance(data, ScalarSeries):
        return diagnose_scalar(data, folds=folds, seed=seed)
    problem = data_problem(data)  # before any path (the rotating one, the level vehicle's, the fixed sensor's)
    if problem:  # wrong units, mixed units, a jumping reference: bad input on every path (as the calibrators say)
        raise InputError(problem)
    refusal = attitude_refusal(data, base)
    if refusal is not None and not turned(data):  # a fixed sensor: the time question still has an answer
        return time_only(data, refusal)
    if refusal is None and base in PARAM_NAMES and len(data) <= len(PARAM_NAMES[base]) and not turned(data):
        # too few for the coverage check, and fixed: the rotating sensor's minimum was said ('need at least 19'),
        # while 10 readings get a fixed sensor's answer
        raise InputError(f"{len(data)} readings of a fixed sensor are too few: its time-only answer needs at least "
                         f"{MIN_DISTINCT} different readings (a rotating sensor "
                         f"{len(PARAM_NAMES[base]) + MIN_POINTS_BEYOND_PARAMETERS} with the {base} model)")
    data, gravity, held = without_logger_holds(data, gravity)
    whole, whole_gravity = data, gravity
    data, gravity, clipped = without_rails(data, gravity)
    check_folds(folds, len(data))  # on the readings left: the clipped record's fallback below must not take it
    try:
        out = Diagnosis(data, base, folds, seed, gravity=gravity, progress=progress, degenerate=refusal).run()
    except InputError as exc:
        if clipped is None:
            raise
        # the rest alone cannot be diagnosed: the whole record's figures, clipped readings included, and no name
        try:
            out = Diagnosis(whole, base, folds, seed, gravity=whole_gravity, progress=progress,
                            degenerate=refusal).run()
        except InputError as whole_exc:
            raise InputError(f"{clipped['clipped_statement']}; the record cannot be diagnosed: {whole_exc}") from None
        clipped = dict(clipped, clipped_rows_left_out=0, clipped_statement=clipped_statement(
            clipped["clipped_rows_left_out"], clipped["clipped"], str(exc).splitlines()[0]))
        out["selected"] = []
        if out["verdict"] != "insufficient_data":
            out["verdict"] = "unexplained"
    if refusal is not None:
        out = _few_directions(data, out)
    if held is not None:
        statement = held.pop("held_statement")
        out.update(held)
        out["floor_method"] = out.get("floor_method", "") + statement
    if clipped is not None:
        out.update(clipped)
        out["verdict"] = with_unexplained(out["verdict"])
    return out


def diagnosed_rows(data, result: dict):
    """The rows of ``data`` that the diagnosis ``result`` was made on: without a logger's held rows and readings
    clipped at a rail when it left them out (``held_rows_left_out``, ``clipped_rows_left_out``), so that a figure of
    the residual shows the readings the verdict is about."""
    if not isinstance(data, Dataset):
        return data
    data = without_logger_holds(data, None)[0] if result.get("held_rows_left_out") else data
    return without_rails(data, None)[0] if result.get("clipped_rows_left_out") else data


def with_unexplained(verdict: str) -> str:
    """``verdict`` saying that structure outside the library remains: ``none`` becomes ``unexplained``, named effects
    gain ``+unexplained``; ``unexplained``, ``insufficient_data`` and a verdict that says it already stay."""
    if verdict == "none":
        return "unexplained"
    if verdict in ("unexplained", "insufficient_data") or verdict.endswith("+unexplained"):
        return verdict
    return verdict + "+unexplained"


def without_rails(data: Dataset, gravity):
    """The record without the readings clipped at a converter's rail (``floor.rail_rows``): (data, gravity, what the
    JSON says), or (data, gravity, None) when no axis has a rail.  A clipped reading says only that the field was
    beyond the range there: no model of the library describes it (a nonlinearity's polynomial bends, it does not
    stop), and left in, it is structure at the attitudes nearest the axis, which the naming read as a nonlinearity.
    The rest of the record is diagnosed, and the verdict says ``unexplained`` beside what it names, with the rails
    in ``clipped`` (the readings stay in the file: nothing is changed)."""
    found = rail_rows(np.asarray(data.raw_nT, dtype=float))
    if found is None:
        return data, gravity, None
    mask, rails = found
    data, gravity = _kept_rows(data, gravity, ~mask)
    return data, gravity, {"clipped_rows_left_out": int(mask.sum()), "clipped": rails,
                           "clipped_statement": clipped_statement(int(mask.sum()), rails)}


def clipped_statement(n_clipped: int, rails: list[dict], rest_refusal: str | None = None) -> str:
    """What the diagnosis says of ``n_clipped`` readings at the ``rails`` (``floor.rail_rows``): left out, or, when
    without them the rest cannot be diagnosed (``rest_refusal``, its reason), why the whole record's figures are shown
    and nothing is named."""
    where = ", ".join(f"{r['axis']} at {r['level_nT']:.6g} nT ({r['rows']} rows)" for r in rails)
    what = ("left out of the whole diagnosis, and unexplained" if rest_refusal is None else
            f"unexplained; without them the rest cannot be diagnosed ({rest_refusal}), so the figures are the whole "
            "record's, clipped readings included, and no effect is named")
    return (f"{n_clipped} readings sit exactly at an axis's extreme value ({where}): clipped at a converter's rail, "
            f"{what} (no library effect stops the readings at a value)")


def _kept_rows(data: Dataset, gravity, keep: np.ndarray):
    """``data`` and ``gravity`` (None or an (n, 3) array) with only the rows where ``keep``: every per-row column of
    the Dataset, its truth dropped (it describes the whole record)."""
    columns = {name: None if getattr(data, name) is None else getattr(data, name)[keep]
               for name in ("raw_nT", "f_ref_nT", "t_s", "temp_C", "heading_deg")}
    return replace(data, **columns, truth=None), None if gravity is None else gravity[keep]


def without_logger_holds(data: Dataset, gravity):
    """The record without the rows a logger held (``floor.stale_copies``: whole readings that repeat the one before
    them in time, more often than the axes' own repeats give, in continuous readings): (data, gravity, what the JSON
    says), or (data, gravity, None) when there are none.  A held row is a stale copy of an earlier reading written
    at a later time: its attitude, reference and temperature have moved on, so it is no measurement at its time,
    and its residual is the change since (3 to 6 times the noise on clean records of slowly turning gimbals
    with a varying observatory reference).  The floor already came from the distinct samples; the fits, the
    residual and every test now do too, and the reading itself stays in the row it was first written in."""
    if data.t_s is None or np.ptp(data.t_s) <= 0:
        return data, gravity, None
    held = stale_copies(np.asarray(data.raw_nT, dtype=float), np.argsort(data.t_s, kind="stable"))
    if held is None:
        return data, gravity, None
    share = float(held.mean())
    return (*_kept_rows(data, gravity, ~held), {
        "held_rows_left_out": int(held.sum()), "held_sample_fraction": share,
        "held_statement": f"; {int(held.sum())} rows ({100 * share:.1f} %) repeat the reading before them exactly (a "
                          "logger that held its value): stale copies, left out of the whole diagnosis"})


TURNED_RAD = 0.1
"""A record whose readings' directions lie further than this (RMS, in radians) from their mean direction turned: the
sensor was rotated (on a level vehicle, about one axis), though perhaps not enough to determine every parameter of the
base model.  Its diagnosis holds the directions the attitudes leave free with the weak prior on the scales and angles
(a fluxgate's scales within a few percent of 1, its axes within a degree or so of orthogonal) instead of answering the
time question only; a fixed sensor's directions move by the field's own variation, thousandths of a radian."""


MIN_DIRECTIONS = 8
"""A record whose attitudes cannot determine the base model (``attitude_refusal``) and whose readings point in fewer
than this many distinct directions (``distinct_directions``: a sensor moved between a few held positions, not turned
through a band of them) says nothing of the attitude-dependent effects: the base correction's weak prior absorbs
whatever the few positions show.  Its verdict ``none`` is then ``insufficient_data`` (what the time effects show is
still named)."""
DIRECTION_CELL_RAD = 0.0175
"""The cell (about 1 degree) in which ``distinct_directions`` counts the readings' directions."""


def _directions(raw_nT: np.ndarray) -> np.ndarray:
    """The unit directions of the readings whose magnitude is finite and not zero."""
    raw = np.asarray(raw_nT, dtype=float)
    norms = np.linalg.norm(raw, axis=1)
    ok = np.isfinite(norms) & (norms > 0)
    return raw[ok] / norms[ok, None]


def distinct_directions(raw_nT: np.ndarray) -> int:
    """How many ~1 degree cells (``DIRECTION_CELL_RAD``) the readings' directions fall in."""
    cells = np.floor(_directions(raw_nT) / DIRECTION_CELL_RAD).astype(np.int64)
    return int(len(np.unique(cells, axis=0))) if len(cells) else 0


def _few_directions(data, out: dict) -> dict:
    """``MIN_DIRECTIONS``: a verdict ``none`` on a record of a few held positions is ``insufficient_data``, said in
    ``attitude`` and ``attitude_reason`` as on the fixed sensor's path."""
    k = distinct_directions(data.raw_nT)
    if k >= MIN_DIRECTIONS:
        return out
    reason = (f"the readings point in {k} distinct direction{'s' if k != 1 else ''} (about 1 degree apart), fewer than "
              f"{MIN_DIRECTIONS}: the base correction's weak prior absorbs what so few positions show, so no effect that "
              "depends on the attitude can be seen; turn the sensor through a band of attitudes")
    out = {**out, "attitude": "insufficient_data", "attitude_reason": reason}
    if out["verdict"] == "none":
        out["verdict"] = "insufficient_data"
    return out


def turned(data) -> bool:
    """Whether the readings' directions spread more than TURNED_RAD (RMS angle from their mean direction)."""
    u = _directions(data.raw_nT)
    if len(u) < 2:
        return False
    mean = u.mean(axis=0)
    mean /= max(float(np.linalg.norm(mean)), 1e-300)
    angle = np.arccos(np.clip(u @ mean, -1.0, 1.0))
    return bool(np.sqrt(np.mean(angle ** 2)) > TURNED_RAD)


def attitude_refusal(data, base: str) -> str | None:
    """Why the attitudes of ``data`` cannot determine the ``base`` model (None when they can, or when the
    record has no reference or too few points: the diagnosis then refuses with its own message)."""
    if not data.has_reference or base not in PARAM_NAMES or len(data) <= len(PARAM_NAMES[base]):
        return None
    report = coverage(ScalarObjective(data.raw_nT, data.f_ref_nT, base), identity_vector(base))
    return report["refusal"]


def gravity_problem_free(gravity, n: int) -> np.ndarray:
    """``gravity`` as an (n, 3) float array of finite, non-zero directions (any unit), else ``InputError``
    saying what is wrong (a wrong shape was an IndexError, NaN rows a LinAlgError with LAPACK on stderr)."""
    g = real_array(gravity, "gravity")
    if g.shape != (n, 3):
        raise InputError(f"gravity must be an (N, 3) array of accelerometer directions, one per reading ({n}), "
                         f"not of shape {g.shape}")
    bad = np.flatnonzero(~np.all(np.isfinite(g), axis=1) | ~(np.einsum("ij,ij->i", g, g) > 0))
    if len(bad):
        raise InputError(f"gravity has {len(bad)} row(s) that are not a direction (NaN, infinite or zero), "
                         f"e.g. row {int(bad[0])}")
    return g


def read_gravity(path, source=None) -> np.ndarray | None:
    """The accelerometer columns ax, ay, az (else gx, gy, gz) of a CSV file, any unit, row for row with the readings
    (``read_columns``: the file read as the readings are, any separator; the header's names in any letter case); None
    without them, ``InputError`` when a row of them is not a direction (NaN, empty, text, zero).  ``source``: the
    file's bytes, when read already for the readings."""
    try:
        found = read_columns(path, ("ax", "ay", "az", "gx", "gy", "gz"), source)
    except InputError:  # unreadable files are refused by the loader with their own message
        return None
    for names in (("ax", "ay", "az"), ("gx", "gy", "gz")):
        if all(n in found for n in names):
            try:  # columns that are there but broken are refused, not silently left out of the diagnosis
                return gravity_problem_free(np.column_stack([found[n] for n in names]), len(found[names[0]]))
            except InputError as exc:
                raise InputError(f"{path}: the accelerometer columns {', '.join(names)}: {exc}") from None
    return None
