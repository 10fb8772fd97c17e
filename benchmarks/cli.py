"""The ``magbench`` command (CONTRACT section 3).

Exit status 0 on success, 2 on bad input or usage (one line on stderr), 1 otherwise.  ``--json``
prints exactly one JSON object on stdout.
"""
from __future__ import annotations

import argparse
import contextlib
import copy
import json
import logging
import math
import os
import re
import sys
import threading
from dataclasses import replace
from pathlib import Path

import numpy as np

import magbench.simulate.dataset as dataset_module
from magbench import __version__
from magbench.benchmarks.argtypes import integer, seed
from magbench.benchmarks.campaign import (
    CHECKPOINT,
    LOCK,
    OWN_SETTINGS,
    Campaign,
    CampaignInterrupted,
    MethodSpec,
    campaign_lock,
    clear_outputs,
    lock_holder,
    run_campaign,
    runs_table_problem,
    start_workers,
    stop_workers,
    stored_manifest,
)
from magbench.benchmarks.gradiometer_cli import add_gradiometer_command
from magbench.benchmarks.metrics import evaluations_label
from magbench.benchmarks.progress import slow_phase
from magbench.benchmarks.runner import run_one
from magbench.benchmarks.tables import to_terminal, warm_latex
from magbench.calibrators import available, make
from magbench.calibrators.artifacts import EXTENSIONS as EXPORT_EXTENSIONS
from magbench.calibrators.artifacts import (
    apply_problems,
    apply_to_csv,
    export,
    export_offset_problem,
    export_path,
    load_calibration,
)
from magbench.calibrators.registry import plugin_errors
from magbench.errors import InputError, with_file_lines
from magbench.paper import ARCSEC_PER_RAD
from magbench.safeio import atomic_output, check_output, os_reason, read_input
from magbench.simulate.dataset import UNIT_FACTORS_NT, read_csv, write_truth
from magbench.simulate.effects import EFFECTS
from magbench.simulate.field import igrf_field
from magbench.simulate.scenarios import get_scenario, scenario_names
from magbench.simulate.sensor import MODELS, PARAM_NAMES

EXIT_OK, EXIT_FAIL, EXIT_USAGE, EXIT_REJECTED = 0, 1, 2, 3
EXIT_STATUS_HELP = """exit status:
  0    success
  2    bad input or usage (one line on stderr; nothing on stdout; the input is never changed)
  3    a calibration ran but its acceptance checks reject it (the cause on stderr; --json still
       prints the whole result with "accepted": false and "rejections"); --accept-any keeps it (exit 0)
  130  interrupted; an interrupted campaign keeps its finished runs: compare ... --resume completes it
  1    anything else (set MAGBENCH_DEBUG=1 for a traceback)"""


class UsageError(InputError):
    pass


# What an option without a help string of its own means (so that every option's --help line says it).
FALLBACK_HELP = {"json": "print one JSON object on stdout and nothing else there",
                 "quiet": "no progress bars on stderr", "force": "overwrite existing output files",
                 "scenario": "scenario name ('magbench list' shows them)",
                 "method": "calibrator name ('magbench list' shows them)",
                 "file": "the data file (CSV, CONTRACT section 2)", "out": "output file or folder",
                 "truth": "also write the ground truth to this JSON file"}


class _HelpFormatter(argparse.RawDescriptionHelpFormatter):
    """Every option's line says what it means and, where it has one, its default."""

    def _format_action(self, action):
        if not action.help and action.dest in FALLBACK_HELP:
            action = copy.copy(action)
            action.help = FALLBACK_HELP[action.dest]
        return super()._format_action(action)

    def _get_help_string(self, action):
        text = action.help or ""
        default = action.default
        if ("%(default)" in text or "default" in text.lower() or default in (None, False, argparse.SUPPRESS)
                or isinstance(action, (argparse._HelpAction, argparse._VersionAction))):
            return text
        shown = " ".join(map(str, default)) if isinstance(default, (list, tuple)) else default
        return f"{text} (default: {shown})".replace("%", "%%").replace("%%(", "%(")


class _Parser(argparse.ArgumentParser):
    """argparse that reports a usage error in one line and exits 2; every option's default in --help."""

    def __init__(self, *args, **kwargs):
        kwargs.setdefault("formatter_class", _HelpFormatter)
        super().__init__(*args, **kwargs)

    def error(self, message):
        # said after "magbench: ": a subcommand's name once ("magbench: calibrate: ..."), the program's not twice
        command = self.prog.removeprefix("magbench").strip()
        raise UsageError(f"{command + ': ' if command else ''}{message} (see {self.prog} --help)")


def _add_reference_options(p: argparse.ArgumentParser) -> None:
    g = p.add_argument_group("reference magnitude and units (CONTRACT section 2)")
    g.add_argument("--units", default="nT", choices=["nT", "uT", "G", "mG"],
                   help="unit of the file's field columns (default nT)")
    g.add_argument("--field", type=float, metavar="NT", help="reference magnitude in nT for every row")
    g.add_argument("--igrf", metavar="LAT,LON,ALT_KM,YYYY-MM-DD",
                   help="reference magnitude from the IGRF-14 model at this place and date")


_BOTH_REFERENCES = "--field and --igrf both give the reference magnitude: give one of them"
"""Both given is refused: --igrf had been ignored beside --field, unread (a malformed --igrf too)."""


def _reference_from_args(args) -> float | None:
    """--field, else --igrf (CONTRACT section 2 order, after the file's own f_ref column); both given is refused."""
    if args.field is not None and args.igrf is not None:
        raise InputError(_BOTH_REFERENCES)
    if args.field is not None:
        if not (math.isfinite(args.field) and args.field > 0):
            raise InputError(f"--field must be a positive number of nT, got {args.field}")
        return args.field
    if args.igrf is not None:  # '' had been no --igrf, silently
        parts = args.igrf.split(",")
        if len(parts) != 4:
            raise InputError(f"--igrf wants LAT,LON,ALT_KM,YYYY-MM-DD, got {args.igrf!r}")
        try:
            lat, lon, alt = (float(v) for v in parts[:3])

            return igrf_field(lat, lon, alt, parts[3].strip()).total_nT
        except ValueError as exc:
            raise InputError(f"--igrf {args.igrf!r}: {exc}") from None
    return None


def load_dataset(args, require_vector: bool = True, file_bytes=None):
    """Read FILE with the reference options; f_ref column > --field > --igrf > '# field_nT:'.  ``file_bytes``: the
    file read already (``safeio.read_input``), when the caller has it."""

    cli_ref = _reference_from_args(args)
    data = read_csv(args.file, units=args.units, require_vector=require_vector, expected_field_nT=cli_ref,
                    source=file_bytes)
    _FIRST_DATA_LINE[0] = data.meta.get("first_data_line")
    ignored = None
    source: str | None
    if data.f_ref_nT is not None:
        source = "the file's f_ref column"
        if cli_ref is not None:
            flag = "--field" if args.field is not None else "--igrf"
            source += f" (it takes precedence over {flag})"
            ignored = f"{flag} was not used: the file's f_ref column comes first (CONTRACT section 2)"
        elif _field_line_apart(data):  # the file says two fields: which one is used is said
            median = float(np.median(data.f_ref_nT))
            ignored = (f"the file's '# field_nT: {data.meta['field_nT']}' line was not used: its f_ref column (median "
                       f"{median:.6g} nT) comes first (CONTRACT section 2)")
    else:
        ref, source = cli_ref, (f"--field {args.field:g}" if args.field is not None else
                                f"--igrf {args.igrf} (IGRF-14)" if args.igrf else None)
        if ref is None and "field_nT" in data.meta:
            ref, source = float(data.meta["field_nT"]), "the file's '# field_nT:' line"  # checked by read_csv
        if ref is not None:
            data = data.with_reference(np.full(len(data), ref))
    if source is not None and hasattr(data, "meta"):
        data = replace(data, meta={**data.meta, "reference_source": source,
                                   **({"reference_ignored": ignored} if ignored else {})})
    return data


FIELD_LINE_APART = 0.01
"""A file's '# field_nT:' line beside its f_ref column is reported as not used when it differs from the column's median
by more than this share (a simulated file writes both, the column varying with the field by a few per mille)."""


def _field_line_apart(data) -> bool:
    try:
        line = float(data.meta.get("field_nT", "nan"))
    except (TypeError, ValueError):
        return False
    median = float(np.median(data.f_ref_nT))
    return bool(np.isfinite(line) and line > 0 and abs(median - line) > FIELD_LINE_APART * line)


def _positive_int(text: str) -> int:
    return integer(text, 1, "must be at least 1")


def _folds(text: str) -> int:
    return integer(text, 2, "must be at least 2")


def _printable(text: str) -> str:
    """A message safe for a terminal: control characters (escape sequences, carriage returns, NUL) are
    shown escaped, never echoed raw."""
    return "".join(ch if ch.isprintable() or ch == " " else ch.encode("unicode_escape").decode("ascii")
                   for ch in text)


CLI_WORDS = (  # the Python API's words -> the command line's (Python errors speak Python; the CLI translates)
    (re.compile(r"^no reference magnitude: .*"), "no reference magnitude: give an f_ref column, --field NT, "
     "--igrf LAT,LON,ALT_KM,YYYY-MM-DD, or a '# field_nT:' line"),
    (re.compile(r"\bmethod='([\w-]+)'"), r"--method \1"),
    (re.compile(r"\bmodel='(\w+)'"), r"--model \1"),
    (re.compile(r"\bfield='auto'"), "--field auto"),
    (re.compile(r"\bunits='(\w+)'"), r"--units \1"),
    (re.compile(r"\bunits="), "--units"),
    (re.compile(r"\(f_ref_nT= or field=NT\)"), "(--field NT or --igrf)"),
)


def cli_words(message: str) -> str:
    """A message of the Python API in the command line's words (its option names), its data rows (counted from 0,
    as the API counts them) also given as the file's lines when the file read had them on consecutive lines."""
    for pattern, words in CLI_WORDS:
        message = pattern.sub(words, message)
    return _with_lines(message)


_FIRST_DATA_LINE: list[int | None] = [None]
"""The file line of data row 0 of the data file this command read (``load_dataset``), when its rows are consecutive
lines."""


def _with_lines(message: str) -> str:
    """``errors.with_file_lines`` for the data file this command read."""
    return with_file_lines(message, _FIRST_DATA_LINE[0])


def _parse_params(items) -> dict:
    params = {}
    for item in items or []:
        if "=" not in item:
            raise InputError(f"--param wants KEY=VALUE, got {item!r}")
        key, value = item.split("=", 1)
        if not key.strip():
            raise InputError(f"--param {item}: the name before '=' is empty (KEY=VALUE)")
        if key.strip() in OWN_SETTINGS:  # what a campaign sets itself has its own option here too
            raise InputError(f"--param {item}: {key.strip()} has its own option, --{key.strip()}")
        if key.strip() in params:  # the last had silently won
            raise InputError(f"--param {key.strip()} is given twice: give each hyper-parameter once")
        try:
            params[key.strip()] = json.loads(value)
        except json.JSONDecodeError:
            params[key.strip()] = value
    return params


def _emit(args, obj: dict, text: str) -> None:
    if getattr(args, "json", False):
        sys.stdout.write(json.dumps(obj, default=_json_default) + "\n")
    else:
        sys.stdout.write(text.rstrip("\n") + "\n")


def _json_default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, (np.floating, np.integer, np.bool_)):
        return o.item()
    if isinstance(o, float) and not math.isfinite(o):
        return None
    raise TypeError(f"not JSON serializable: {type(o).__name__}")


# ---------------------------------------------------------------------------------------- commands
def cmd_list(args) -> int:

    cals = [{"name": n, "models": list(c.supported_models), "stochastic": c.stochastic, "summary": c.summary,
             "hyperparameters": c._param_names()} for n, c in sorted(available().items())]
    scen = [{"name": n, "model": get_scenario(n).model, "description": get_scenario(n).description}
            for n in scenario_names()]
    effects = list_effects()
    broken = [{"name": n, "reason": why} for n, why in sorted(plugin_errors().items())]
    obj = {"calibrators": cals, "models": [{"name": m, "parameters": list(PARAM_NAMES[m])} for m in MODELS],
           "scenarios": scen, "effects": effects, "unavailable_plugins": broken}
    lines = ["calibrators:"] + [f"  {c['name']:<10} [{', '.join(c['models'])}] {c['summary']}" for c in cals]
    if broken:
        lines += ["plug-ins that did not load:"] + [f"  {b['name']:<10} {_printable(b['reason'])}" for b in broken]
    lines += ["models:"] + [f"  {m['name']:<10} {', '.join(m['parameters'])}" for m in obj["models"]]
    lines += ["scenarios:"] + [f"  {s['name']:<13} ({s['model']}) {s['description']}" for s in scen]
    lines += ["effects:"] + [f"  {e['name']:<13} [needs {', '.join(e['needs']) or 'bx, by, bz, a reference'}"
                             f"{'; optional ' + ', '.join(e['optional']) if e['optional'] else ''}"
                             f"{'' if e['in_library'] else '; outside the fitted library'}] {e['description']}"
                             for e in effects]
    _emit(args, obj, "\n".join(lines))
    return EXIT_OK


def list_effects() -> list[dict]:
    """Effects the simulator can switch on (CONTRACT section 3 names)."""

    return [{"name": name, "in_library": cls.in_library, "needs": list(cls.needs),
             "optional": list(getattr(cls, "optional", ())), "n_parameters": len(cls.fit_params),
             "description": " ".join((cls.__doc__ or "").split())} for name, cls in EFFECTS.items()]


def cmd_simulate(args) -> int:

    scenario = get_scenario(args.scenario)
    check_output(args.out, force=args.force, what="--out file")  # the name as given: '' is no file (Path('') is '.')
    out = Path(args.out)
    if args.truth is not None and not args.truth.strip():  # '' had written no truth, silently
        raise InputError("the --truth file name is empty: give a file name, or leave --truth out")
    if args.truth and (Path(args.truth).resolve() == out.resolve()
                       or (out.exists() and Path(args.truth).exists() and os.path.samefile(out, args.truth))):
        raise InputError(f"--out and --truth name the same file ({out}, by inode): the truth would overwrite the data")
    if args.truth:
        check_output(args.truth, [out], force=args.force, what="--truth file")
    data = scenario.build(args.seed)
    data.to_csv(out)
    if args.truth:
        write_truth(data.truth, args.truth, inputs=[out])
    obj = {"scenario": scenario.name, "seed": args.seed, "out": str(out), "truth": args.truth,
           "n_points": len(data), "model": scenario.model}
    _emit(args, obj, f"wrote {len(data)} samples of scenario {scenario.name} (seed {args.seed}) to {out}"
          + (f"; truth to {args.truth}" if args.truth else ""))
    return EXIT_OK


def _evaluations_text(result) -> str:
    if result.evaluation_mode == "closed-form":
        return f"closed-form ({result.n_evaluations} counted evaluations)" if result.n_evaluations else "closed-form"
    return f"{result.n_evaluations} evaluations"


def _field_value(text: str):
    """argparse type of calibrate's --field: a number of nT, or 'auto' (estimated from the readings)."""
    if text.strip().lower() == "auto":
        return "auto"
    try:
        return float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is neither a number of nT nor 'auto'") from None


SAVE_FORMATS = {".json": ("json", "matlab"), ".mat": ("matlab",), ".param": ("ardupilot",), ".params": ("px4",)}
"""The formats a --save name's extension may hold (matlab's magcal also as JSON text); without --export the first is
the format written."""


def _save_target(args) -> tuple[Path | None, str]:
    """The calibration file --save/--export will write and its format, checked before the fit ((None, '') without
    --save).  Without --export the format is the extension's (``SAVE_FORMATS``; json for another or none); an
    --export that the extension contradicts (JSON text in a .mat file, ArduPilot's parameters in a .json) is
    refused."""
    if args.save is None:
        if args.export is not None:
            raise InputError("--export picks the format of --save PATH: give --save too")
        return None, ""
    if not os.fspath(args.save).strip():
        raise InputError("--save: the file name is empty")
    suffix = Path(os.fspath(args.save)).suffix.lower()
    allowed = SAVE_FORMATS.get(suffix)
    fmt = args.export or (allowed[0] if allowed else "json")
    if allowed and fmt not in allowed:
        raise InputError(f"--save {args.save}: a {suffix} file does not hold --export {fmt} (that writes "
                         f"{EXPORT_EXTENSIONS[fmt]}): give a {EXPORT_EXTENSIONS[fmt]} name, or --export {allowed[0]}")
    path = export_path(args.save, fmt)
    return check_output(path, [args.file], args.force, what="--save file"), fmt


def _calibration_lines(result, n_points: int) -> list[str]:
    """The human-readable summary of a calibration result (``calibrate`` without --json)."""
    p = result.params
    lines = [f"{result.method} ({result.model} model), {n_points} points, {result.status}: {result.message}"]
    if result.model_choice:
        lines.append(f"  model auto -> {result.model}: {result.model_choice['reason']}")
    if result.model in ("angles", "nine"):
        lines.append(f"  alpha  {p.alpha_rad: .6e} rad   beta {p.beta_rad: .6e} rad   gamma {p.gamma_rad: .6e} rad")
    if result.model in ("diag", "nine"):
        lines.append("  scale  " + "  ".join(f"{k:.6f}" for k in p.scale)
                     + "    offset " + "  ".join(f"{o:.2f}" for o in p.offset_nT) + " nT")
    elif result.model == "offset":
        lines.append("  offset " + "  ".join(f"{o:.2f}" for o in p.offset_nT) + " nT")
    if result.uncertainty:
        lines.append(f"  Cramér-Rao std at noise {result.noise_nT:.3g} nT: "
                     + ", ".join(f"{k} {v:.2g}" for k, v in result.uncertainty.items()))
    lines.append(f"  total-field RMS {result.rms_before_nT:.3f} -> {result.rms_after_nT:.3f} nT; "
                 f"{_evaluations_text(result)}, "
                 f"{result.runtime_s * 1e3:.1f} ms"
                 + (f" (and {result.extra['one_time_s']:.2f} s of one-time setup: its solver's imports, compiles "
                    "or cache loads, once per process)" if result.extra.get("one_time_s") else "")
                 + f", seed {result.seed}")
    return lines + [f"  warning: {cli_words(w)}" for w in result.warnings]


ONE_BLAS_THREAD_ROWS = 100_000
"""``calibrate`` of a longer record runs BLAS on one thread unless ``--blas-threads`` says otherwise: its
products are long and thin (9 x 32,768 blocks), which a second thread hardly speeds up on an idle machine
and slows several-fold on a busy one (2e6 rows on a loaded 2-core host: 8-15 s with the library's threads,
4-6 s with one)."""


def cmd_calibrate(args) -> int:

    params = _parse_params(args.param)
    if args.algorithm is not None:  # '' had been no algorithm at all, silently: the default one ran
        if "algorithm" in params:  # --param algorithm=Y beside --algorithm X had silently run X
            raise InputError(f"--algorithm {args.algorithm} and --param algorithm={params['algorithm']} both set the "
                             "NLopt algorithm: give it once")
        params["algorithm"] = args.algorithm
    if args.field is not None and args.igrf is not None:  # before 'auto' is turned into no --field below
        raise InputError(_BOTH_REFERENCES)
    if args.blas_threads:
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=args.blas_threads)
    field_auto = args.field == "auto"
    if field_auto:
        args.field = None  # the reference options below then only read the file
    cal = make(args.method, model=args.model, seed=args.seed, **params)  # an unknown method before reading
    target, fmt = _save_target(args)

    talk = not getattr(args, "json", False)
    with slow_phase(f"reading {args.file}", talk):
        data = load_dataset(args)
    if not args.blas_threads and len(data) > ONE_BLAS_THREAD_ROWS:
        from threadpoolctl import threadpool_limits

        threadpool_limits(limits=1)
    with slow_phase(f"calibrating {len(data):,} readings ({args.method}, then the acceptance checks)", talk):
        result = cal.fit(data, field="auto") if field_auto else cal.fit(data)
    if target is not None and not result.accepted and args.accept_any and fmt != "json":
        # magbench's JSON keeps "accepted": false (apply then refuses it unless --accept-any); the other formats have
        # no field for it, so a rejected answer would reach MATLAB, a flight controller or apply as a good one
        raise InputError(f"calibration rejected ({cli_words(result.rejections[0])}); not saved to {target}: a {fmt} "
                         "file cannot say it was rejected, and whatever reads it would take it for a good one; save it "
                         "as magbench JSON (--export json), which keeps the rejection")
    beyond = export_offset_problem(result.calibration(), fmt) if target is not None else None
    if beyond is not None and beyond[0] and (result.accepted or args.accept_any):  # before any line: exit 2 is one
        raise InputError(f"{beyond[1]}; not saved to {target} (--export json or matlab keeps it)")
    obj = result.as_dict()
    obj["input_sha256"] = data.meta.get("file_sha256")  # the bytes the readings were parsed from
    ref = result.reference
    if ref.get("estimated"):
        unit = getattr(args, "units", "nT") or "nT"
        factor = UNIT_FACTORS_NT.get(unit) if unit != "nT" else None
        in_unit = f" = {ref['median_nT'] / factor:.6g} {unit}" if factor else ""
        sys.stderr.write(f"magbench: reference {ref['median_nT']:.6g} nT{in_unit} estimated from the readings "
                         "(--field auto; MATLAB magcal's expmfs); the overall gain is relative to it\n")
    else:
        sys.stderr.write(f"magbench: reference {ref['median_nT']:.6g} nT (median) from {ref['source']}\n")
    lines = _calibration_lines(result, len(data))
    saved = None
    if target is not None and (result.accepted or args.accept_any):
        saved = export(result.calibration(), target, fmt, force=args.force, inputs=[args.file], warn=False)
        lines.append(f"  saved {fmt} calibration to {saved}")
        if beyond is not None:  # offsets the flight controller takes with a setting changed, or a warning of its own
            sys.stderr.write(f"magbench: warning: {beyond[1]}\n")
            obj["warnings"] = obj["warnings"] + [beyond[1]]
            lines.append(f"  warning: {beyond[1]}")
    obj["saved"] = str(saved) if saved else None
    if result.accepted:
        _emit(args, obj, "\n".join(lines))
        return EXIT_OK
    if args.accept_any:
        lines += [f"  warning (rejection kept by --accept-any): {r}" for r in result.rejections]
        obj["warnings"] = obj["warnings"] + [f"rejection kept by --accept-any: {r}" for r in result.rejections]
        _emit(args, obj, "\n".join(lines))
        return EXIT_OK
    lines += [f"  REJECTED: {cli_words(r)}" for r in result.rejections]
    _emit(args, obj, "\n".join(lines))
    more = f" (+{len(result.rejections) - 1} more)" if len(result.rejections) > 1 else ""
    unsaved = f"; not saved to {target}" if target is not None else ""
    sys.stderr.write(f"magbench: calibration rejected: {cli_words(result.rejections[0])}{more}{unsaved}; "
                     "--accept-any keeps it\n")
    return EXIT_REJECTED


def cmd_apply(args) -> int:

    check_output(args.out, [args.calibration, args.file], args.force, what="--out file")
    cal = load_calibration(args.calibration)
    problems = apply_problems(cal)
    if problems and not args.accept_any:
        raise InputError(f"{args.calibration}: {problems[0]}: refusing to apply it (--accept-any applies it anyway)")
    info = apply_to_csv(cal, args.file, args.out, units=args.units, force=args.force,
                        cal_name=Path(args.calibration).name, inputs=[args.calibration], accept_any=args.accept_any)
    info.update(calibration=str(args.calibration), method=cal.method, model=cal.model, data_digest=cal.data_digest,
                warnings=[f"applied by --accept-any: {p}" for p in problems] + info["warnings"])
    text = (f"wrote {info['n_rows']} rows to {info['out']}: {', '.join(info['columns_added'])} added ({info['units']}; "
            f"{cal.method or cal.origin} {cal.model} calibration from {args.calibration})")
    if "rms_f_cal_minus_f_ref_nT" in info:
        text += f"\n  total-field RMS against the file's f_ref: {info['rms_f_cal_minus_f_ref_nT']:.3f} nT"
    text += "".join(f"\n  warning: {w}" for w in info["warnings"])
    _emit(args, info, text)
    return EXIT_OK


def cmd_demo(args) -> int:
    import pandas as pd

    rows = []
    for name in ("lu2014", "sphere9"):
        scenario = get_scenario(name)
        data = scenario.build(args.seed)
        for method in sorted(available()):
            rows.append(run_one(data, method, scenario.model, seed=args.seed, scenario=name))
    frame = pd.DataFrame(rows)
    if args.json:
        _emit(args, {"seed": args.seed, "rows": frame.replace({np.nan: None}).to_dict(orient="records")}, "")
        return EXIT_OK
    lines = [f"magbench demo (seed {args.seed}): Lu et al. 2014's turntable experiment (lu2014, 3 angles) and a "
             "full-sphere 9-parameter sensor (sphere9), every registered calibrator.", ""]
    for name, part in frame.groupby("scenario", sort=False):
        lines.append(f"== {name}: {get_scenario(name).description}")
        before = pd.to_numeric(part.get("rms_before_nT", pd.Series(dtype=float)), errors="coerce").dropna()
        if len(before):  # the same readings for every method: said once, not in a column of equal numbers
            lines.append(f"   total-field RMS before calibration: {before.median():.3g} nT")
        table = pd.DataFrame({
            "method": part["method"],
            "d_alpha\"": part.get("alpha_err_rad", np.nan) * ARCSEC_PER_RAD,
            "d_beta\"": part.get("beta_err_rad", np.nan) * ARCSEC_PER_RAD,
            "d_gamma\"": part.get("gamma_err_rad", np.nan) * ARCSEC_PER_RAD,
            "rms_after_nT": part.get("rms_after_nT", np.nan),
            "evals": [evaluations_label(m, n) for m, n in zip(part.get("evaluation_mode", pd.Series("counted", index=part.index)),
                                                              part.get("n_evaluations", pd.Series(np.nan, index=part.index)))],
            "ms": part.get("runtime_s", np.nan) * 1e3,
            "accepted": ["-" if not isinstance(a, (bool, np.bool_)) else ("yes" if a else "REJECTED")
                         for a in part.get("accepted", pd.Series(None, index=part.index, dtype=object))],
        })
        if "scale_err_max" in part and part["scale_err_max"].notna().any():
            table.insert(4, "max_d_scale", part["scale_err_max"])
            table.insert(5, "max_d_offset_nT", part["offset_err_max_nT"])
        # milliseconds as whole numbers from 100 on: a run of 1040 ms on a loaded machine had printed '1.04e+03' and
        # widened the table past its 110 columns
        ms = {"ms": lambda v: "-" if not np.isfinite(v) else (f"{v:.0f}" if v >= 100 else f"{v:.3g}")}
        lines.append(table.to_string(index=False, float_format=lambda v: f"{v:.3g}", na_rep="-", formatters=ms))
        for _, r in part[part["error"] != ""].iterrows():
            lines.append(f"  {r['method']}: not run: {cli_words(r['error'])}")
        rejected = part[(part["error"] == "") & (part.get("accepted", pd.Series(True, index=part.index)) == False)]  # noqa: E712
        for _, r in rejected.iterrows():
            reasons = [t for t in str(r.get("rejections", "") or "").split("; ") if t]
            more = f" (+{len(reasons) - 1} more)" if len(reasons) > 1 else ""
            lines.append(f"  {r['method']} REJECTED: {cli_words(reasons[0]) if reasons else 'no reason recorded'}{more}")
        lines.append("")
    lines.append("d_*: estimate minus truth (angles in arc-seconds); max_d_scale, max_d_offset_nT: the largest over the "
                 "three axes; rms_after_nT: total-field residual against the reference after calibration; "
                 "accepted: whether the calibration passes its acceptance checks (a finished fit can be rejected; "
                 "the first reason is under the table).")
    _emit(args, {}, "\n".join(lines))
    return EXIT_OK


def _at_budgets(specs, budgets, calibrators):
    """Every iterative configuration once per evaluation budget (``ga budget=1000``, ``ga budget=10000``),
    so that fixed-budget tables compare like with like; closed-form methods, which have no evaluations to
    budget, appear once."""
    if any(b < 1 for b in budgets):
        raise InputError("--budgets must be positive numbers of evaluations")
    out = []
    for spec in specs:
        cls = calibrators.get(spec.name)
        if cls is None or cls.closed_form or any(k == "budget" for k, _ in spec.params):
            out.append(spec)
            continue
        out += [MethodSpec(spec.name, spec.params + (("budget", int(b)),)) for b in budgets]
    return tuple(out)


def _campaign_from_args(args):
    """The campaign and output folder ``compare`` was asked for, refused (InputError) before anything in
    ``--out`` is touched: unknown scenarios or methods, bad counts, a non-empty folder without --force or
    --resume."""
    scenarios = tuple(s for item in args.scenarios for s in item.split(",") if s)
    for s in scenarios:
        get_scenario(s)
    methods = [m for item in args.methods for m in (item.split(",") if ":" not in item else [item]) if m]
    if not scenarios or not methods:  # only commas or empty names: a campaign of no runs
        raise InputError(f"--{'scenarios' if not scenarios else 'methods'} names none: give at least one name")
    if methods == ["all"]:
        methods = sorted(available())
    if args.trials < 1 or args.jobs < 1:
        raise InputError("--trials and --jobs must be at least 1")
    if args.dask in (None, "local"):  # a remote Dask cluster has its own workers
        args.jobs = local_workers(args.jobs)
    if args.force and args.resume:
        raise InputError("--force starts the campaign over and --resume continues it: give one of them")
    if not str(args.out).strip():  # Path('') is '.': with --force the campaign had cleared and filled the working folder
        raise InputError("the --out folder name is empty: give a folder for the campaign")
    out = Path(args.out)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out} exists and is not a directory")
    holder = lock_holder(out) if out.is_dir() else None
    if holder is not None:
        raise InputError(f"{out} is in use by another campaign ({holder}); wait for it to end, or use another --out")
    if out.exists() and any(p.name != LOCK for p in out.iterdir()) and not (args.force or args.resume):
        if _campaign_complete(out):
            hint = ("it holds a complete campaign: --resume with more methods runs only those, --force starts over, "
                    "or give another --out")
        elif (out / CHECKPOINT).exists():
            hint = f"it holds an interrupted campaign ({CHECKPOINT}): use --resume to complete it or --force to start over"
        else:
            hint = "use --resume to complete its campaign or --force to overwrite it"
        raise InputError(f"{out} exists and is not empty; refusing to overwrite it ({hint})")
    specs = tuple(MethodSpec.parse(m) for m in methods)
    if args.budgets:
        specs = _at_budgets(specs, args.budgets, available())
    campaign = Campaign(scenarios, specs, trials=args.trials, seed=args.seed)
    campaign.tasks()  # bad methods are refused before anything in --out is touched
    for spec in specs:  # and bad hyper-parameters (ga:pc=2 had failed in the first run, leaving a partial campaign)
        make(spec.name, **dict(spec.params))
    return campaign, out


def cmd_compare(args) -> int:
    import shlex

    figure_options = [a.split("=")[0] for a in args._argv if a.split("=")[0] in ("--format", "--dpi")]
    if args.no_figures and figure_options:
        raise InputError(f"{' and '.join(dict.fromkeys(figure_options))} set{'s' if len(set(figure_options)) == 1 else ''} "
                         "the figures, which --no-figures leaves out: give one or the other")
    campaign, out = _campaign_from_args(args)
    command = "magbench " + shlex.join(args._argv)
    created = not out.exists()
    try:
        with campaign_lock(out, command):  # one campaign per folder; held until the report is written
            if not (args.force or args.resume) and any(p.name != LOCK for p in out.iterdir()):
                raise InputError(f"{out} was filled by another process meanwhile; refusing to overwrite it")
            return _compare_locked(args, campaign, out, command)
    except BaseException:
        if created:  # the folder the lock made, left empty (a Dask scheduler out of reach): not left behind
            with contextlib.suppress(OSError):
                out.rmdir()  # only an empty one
        raise


def _campaign_complete(out: Path) -> bool:
    """Whether ``out`` holds a campaign its manifest calls complete (a damaged manifest: not known, so no)."""
    try:
        man = stored_manifest(out)
    except OSError:
        return False
    return man is not None and man.get("complete") is True


def _compare_locked(args, campaign, out: Path, command: str) -> int:
    import shlex

    if args.force:
        clear_outputs(out)
    progress = not args.json and not args.quiet
    cluster = _local_dask_cluster(args.jobs, progress) if args.dask == "local" else None
    # a fresh campaign on local workers: they start (and warm up) now, while this process imports what its
    # tables, figures and report need (pandas, matplotlib), which it would otherwise do on a core of its own; the
    # imports run in a thread beside the runs (this process only waits for the workers' results meanwhile): done
    # before the runs, they had left the warmed workers idle for the second they outlasted the warm-ups
    pool = start_workers(campaign, args.jobs) if args.jobs > 1 and not args.dask and not args.resume else None
    imports = threading.Thread(target=_warm_output_tools, name="magbench-output-imports", daemon=True) if pool else None
    try:
        if imports is not None:
            imports.start()
        runs = run_campaign(campaign, out, jobs=args.jobs, command=command, progress=progress, resume=args.resume,
                            dask_address=cluster.scheduler_address if cluster is not None else args.dask, pool=pool)
    except CampaignInterrupted as stop:
        argv = [a for a in args._argv if a != "--force"] + ([] if args.resume else ["--resume"])
        sys.stderr.write(f"magbench: interrupted: {stop.n_done} of {stop.n_total} runs finished, kept in {out} "
                         f"(tables of those written, manifest marked incomplete); to run the {stop.n_missing} "
                         f"missing: magbench {shlex.join(argv)}\n")
        if args.json:
            _emit(args, {"out": str(out), "complete": False, "n_runs": stop.n_done, "n_missing": stop.n_missing,
                         "resume": "magbench " + shlex.join(argv)}, "")
        return stop.exit_status
    finally:
        stop_workers(pool)
        if cluster is not None:
            cluster.close()
    if imports is not None:
        imports.join()
    return _compare_outputs(args, runs, out, progress)


def _warm_output_tools() -> None:
    """``_output_tools(warm=True)`` in a thread beside the runs, best effort: what fails here fails again, and is
    reported, where this process then imports and uses them (a thread's exception would print a traceback)."""
    with contextlib.suppress(Exception):
        _output_tools(warm=True)


def _output_tools(warm: bool = False):
    """The comparison's tables, the figures and the report: (write_comparison, make_figures, write_report);
    ``warm``: the campaign tables' LaTeX templates compiled too (``tables.warm_latex``)."""
    from magbench.benchmarks.comparison import write_comparison
    from magbench.benchmarks.figures import make_figures
    from magbench.benchmarks.report import write_report

    if warm:
        warm_latex()

    return write_comparison, make_figures, write_report


def _compare_outputs(args, runs, out: Path, progress: bool) -> int:
    """After the runs: the comparison, figures and report, then the summary (or one JSON object)."""
    attrs = runs.attrs
    figures = not args.no_figures and (not attrs.get("already_complete") or not (out / "report.html").is_file())
    comparison = len(runs) and runs["configuration"].nunique() >= 2  # a comparison needs two methods
    prepare = None
    if comparison and not attrs.get("already_complete"):
        write_comparison = _output_tools()[0]

        def prepare():  # the comparison's tables; its figures are drawn with the others, in parallel
            write_comparison(out, figures=False)
    if figures:
        _, make_figures, write_report = _output_tools()
        images: dict = {}  # the report embeds the figures drawn here at screen resolution
        make_figures(out, formats=tuple(args.format), dpi=args.dpi, images=images, progress=progress,
                     jobs=max(1, args.jobs or 1), prepare=prepare)
        write_report(out, images=images)
    elif prepare is not None:
        prepare()
    failed = int((runs["error"] != "").sum())
    obj = {"out": str(out), "n_runs": len(runs), "n_failed": failed, "complete": True,
           "n_new": int(attrs.get("n_new", len(runs))), "n_resumed": int(attrs.get("n_resumed", 0)),
           "summary": str(out / "summary.md"),
           "comparison": str(out / "comparison.md") if (out / "comparison.md").is_file() else None,
           "report": str(out / "report.html") if (out / "report.html").is_file() and not args.no_figures else None}
    if attrs.get("already_complete"):
        note = (f"\ncampaign in {out} was already complete ({len(runs)} runs, {failed} failed): nothing new to run"
                + ("; report.html written" if figures else ", nothing rewritten"))
    elif attrs.get("n_resumed"):
        note = (f"\n{len(runs)} runs ({failed} failed) in {out}: {attrs['n_resumed']} from the checkpoint, "
                f"{attrs['n_new']} run now")
    else:
        note = f"\n{len(runs)} runs ({failed} failed) in {out}"
    import pandas as pd

    summary = pd.read_csv(out / "summary.csv", keep_default_na=False, na_values=[""]) \
        if (out / "summary.csv").is_file() else None
    table = to_terminal(summary) if summary is not None and len(summary) else (out / "summary.md").read_text()
    _emit(args, obj, table + "fin: the solver ended normally; acc: the answer passed the acceptance checks; max angle: "
                             "the largest median error of α, β, γ\n"
                             f"every column: {out / 'summary.md'}" + note)
    return EXIT_OK


DIAGNOSIS_FIGURE_FORMATS = ("png", "svg", "pdf")
"""What ``diagnose --figure`` writes, by the name's extension (checked before the diagnosis: an unknown one
was an internal error after it)."""


def cmd_diagnose(args) -> int:
    from magbench.benchmarks.diagnosis import diagnose, diagnosed_rows, diagnosis_figure, diagnosis_text, read_gravity

    talk = not getattr(args, "json", False)
    with slow_phase(f"reading {args.file}", talk):
        file_bytes = read_input(args.file, "data file")  # once: the readings and the accelerometer columns
        data = load_dataset(args, require_vector=False, file_bytes=file_bytes)
    if args.figure is not None and not args.figure.strip() and not args.no_figure:  # '' had been no figure, silently
        raise InputError("--figure: the file name is empty (give PATH.png, .svg or .pdf)")
    figure = Path(args.figure) if args.figure and not args.no_figure else None
    if figure is not None:
        if figure.suffix.lower().lstrip(".") not in DIAGNOSIS_FIGURE_FORMATS:
            raise InputError(f"--figure {figure}: the name must end in "
                             f"{', '.join('.' + f for f in DIAGNOSIS_FIGURE_FORMATS)} (its format)")
        if figure.exists() and not args.force and not figure.is_dir():
            raise InputError(f"{figure} exists; refusing to overwrite it (use another --figure PATH or --force)")
        check_output(figure, [args.file], args.force, what="--figure file")
    with slow_phase(f"diagnosing {len(data):,} readings (fits of every candidate effect, blocked in time and "
                    "attitude)", talk):
        result = diagnose(data, base=args.model, folds=args.folds, seed=args.seed, gravity=read_gravity(args.file, file_bytes))
    if figure is not None:
        with atomic_output(figure, [args.file], args.force, what="--figure file") as tmp:
            diagnosis_figure(diagnosed_rows(data, result), result, tmp)
    result["figure"] = str(figure) if figure else None
    ignored = (getattr(data, "meta", None) or {}).get("reference_ignored")
    if ignored:  # --field or --igrf beside the file's f_ref column: said, as calibrate says it
        result["reference_ignored"] = ignored
    _emit(args, result, diagnosis_text(result, args.file))
    return EXIT_OK


def cmd_report(args) -> int:
    from magbench.benchmarks.figures import make_figures
    from magbench.benchmarks.report import MANIFEST_UNKNOWNS, read_manifest, write_report

    d = Path(args.dir)
    if not (d / "runs.csv").is_file():
        raise InputError(f"{d} is not a campaign directory (no runs.csv): run 'magbench compare' first")
    problem = runs_table_problem(d / "runs.csv")
    if problem:
        raise InputError(f"{problem}; running its campaign again with --resume rebuilds the tables from its "
                         f"{CHECKPOINT}, when it has one")
    if read_manifest(d / "manifest.json") is None:  # a damaged one: refused (InputError) before the figures
        sys.stderr.write(f"magbench: warning: {d / 'manifest.json'} is missing: {MANIFEST_UNKNOWNS}\n")
    images: dict = {}
    progress = not args.json and not args.quiet
    written = make_figures(d, formats=tuple(args.format or ()), dpi=args.dpi, images=images, progress=progress,
                           jobs=local_workers(args.jobs))
    path = write_report(d, images=images)
    _emit(args, {"report": str(path), "figures": [str(p) for p in written]},
          f"wrote {path}" + (f" and {len(written)} figure files in {d / 'figures'}" if written else ""))
    return EXIT_OK


def cmd_reproduce(args) -> int:
    from magbench.benchmarks.reproduce import reproduce

    written = reproduce(Path(args.out), quick=args.quick, jobs=local_workers(args.jobs),
                        progress=not (args.json or args.quiet))
    _emit(args, {"out": args.out, "written": [str(p) for p in written]},
          "\n".join(f"wrote {p}" for p in written))
    return EXIT_OK


def _add_figure_options(p: argparse.ArgumentParser, default, help_text: str | None = None) -> None:
    p.add_argument("--format", nargs="+", choices=["png", "svg", "pdf"], default=default, metavar="FMT",
                   help=help_text or "figure file formats, one or more of png, svg, pdf")
    p.add_argument("--dpi", type=_dpi, default=300,
                   help=f"resolution of PNG figures, {DPI_RANGE[0]} to {DPI_RANGE[1]} (print: 300)")


DPI_RANGE = (20, 1200)
"""The PNG resolutions ``--dpi`` takes: below 20 the fonts fail (FreeType refused 5 dpi, an internal error
after the campaign), above 1200 a figure is hundreds of megabytes (100000 ran out of memory after it)."""


def _dpi(text: str) -> int:
    return integer(text, DPI_RANGE[0], f"is below {DPI_RANGE[0]}: figures need at least {DPI_RANGE[0]} dpi",
                   DPI_RANGE[1], f"is above {DPI_RANGE[1]}: a figure at that resolution takes hundreds of megabytes")


def local_workers(jobs: int) -> int:
    """``--jobs`` as a number of local worker processes: at most this machine's CPUs, with a one-line notice
    when fewer than asked (--jobs 200 on 2 cores forked 200 workers, each importing and warming up)."""
    cpus = os.cpu_count() or 1
    if jobs > cpus:
        sys.stderr.write(f"magbench: --jobs {jobs} is more than this machine's {cpus} CPUs: running {cpus} workers\n")
        return cpus
    return jobs


def _local_dask_cluster(workers: int, progress: bool):
    """``--dask local``: a Dask cluster on this machine, scheduler and workers bound to 127.0.0.1 (no
    dashboard), one single-threaded worker process per --jobs; closed when the campaign ends."""
    try:
        from distributed import LocalCluster
    except ImportError:
        raise InputError("--dask local needs Dask's distributed package: pip install 'magbench[dask]'") from None
    if progress:
        sys.stderr.write(f"magbench: starting a local Dask cluster ({workers} worker{'s' if workers != 1 else ''}, "
                         "127.0.0.1)\n")
    return LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, host="127.0.0.1",
                        dashboard_address=None, silence_logs=logging.ERROR)


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(prog="magbench", description="Simulate tri-axial fluxgate magnetometers and benchmark "
                     "their calibration algorithms.", epilog=EXIT_STATUS_HELP,
                     formatter_class=_HelpFormatter)

    parser.add_argument("--version", action="version", version=f"magbench {__version__}")
    sub = parser.add_subparsers(dest="command", parser_class=_Parser)

    _add_list_parser(sub)
    _add_data_parser(sub)
    _add_simulate_parser(sub)
    _add_calibrate_parser(sub)
    _add_apply_parser(sub)
    _add_diagnose_parser(sub)
    _add_compare_parser(sub)
    add_gradiometer_command(sub)
    _add_report_parser(sub)
    _add_reproduce_parser(sub)
    _add_demo_parser(sub)
    parser.set_defaults(command_names=tuple(sub.choices))  # what a bare ``magbench`` names
    return parser


EXAMPLE_PREFIX = "example:"
"""``example:NAME`` stands for the recording ``NAME.csv`` shipped with the package (``magbench data``)."""


def example_recordings() -> dict[str, tuple[Path, str]]:
    """The recordings shipped in ``magbench.simulate.data``: name -> (path, title from its provenance)."""

    root = Path(dataset_module.__file__).resolve().parent / "data"  # package data, installed with the wheel
    out = {}
    for csv in sorted(root.glob("*.csv")):
        prov = next((p for p in (root / f"{csv.stem}.PROVENANCE.md", root / f"{csv.stem.split('_')[0]}.PROVENANCE.md")
                     if p.is_file()), None)
        title = prov.read_text(encoding="utf-8").splitlines()[0].lstrip("# ").strip() if prov else ""
        out[csv.stem] = (csv, title)
    return out


def resolve_example(text: str) -> str:
    """``example:NAME`` as the path of that shipped recording (any other text unchanged)."""
    if not text.startswith(EXAMPLE_PREFIX):
        return text
    name = text[len(EXAMPLE_PREFIX):].strip().removesuffix(".csv")
    known = example_recordings()
    if name not in known:
        raise InputError(f"no example recording {name!r}; 'magbench data' lists them ({', '.join(known)})")
    return str(known[name][0])


def cmd_data(args) -> int:
    known = example_recordings()
    obj = {name: {"path": str(path), "title": title} for name, (path, title) in known.items()}
    width = max(map(len, known), default=0)
    lines = ["Recordings shipped with magbench (real data, each with its provenance and licence beside it); use",
             "one from any folder as example:NAME, e.g. magbench calibrate example:sap6_BB --units uT", ""]
    lines += [f"  {name:<{width}}  {title}" for name, (_, title) in known.items()]
    lines += ["", f"folder: {next(iter(known.values()))[0].parent}" if known else "no recordings installed"]
    _emit(args, obj, "\n".join(lines))
    return EXIT_OK


def _add_data_parser(sub) -> None:
    p = sub.add_parser("data", help="the example recordings shipped with magbench (use them as example:NAME)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_data)


def _add_list_parser(sub) -> None:
    p = sub.add_parser("list", help="calibrators, models, scenarios, effects")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_list)


def _add_simulate_parser(sub) -> None:
    p = sub.add_parser("simulate", help="simulate a scenario to a CSV file and its truth to JSON")
    p.add_argument("--scenario", required=True)
    p.add_argument("--seed", type=seed, default=0, help="random seed, a non-negative integer (default 0)")
    p.add_argument("--out", required=True, metavar="FILE.csv", help="the data file to write (CSV, CONTRACT section 2)")
    p.add_argument("--truth", metavar="FILE.json")
    p.add_argument("--force", action="store_true", help="overwrite existing output files")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_simulate)


def _add_calibrate_parser(sub) -> None:
    p = sub.add_parser("calibrate", help="calibrate a data file with one method")
    p.add_argument("file", metavar="FILE.csv")
    p.add_argument("--method", required=True)
    p.add_argument("--model", default="nine", choices=["offset", "diag", "angles", "nine", "auto"],
                   help="offset (3 offsets), diag (+3 scales), angles (the 3 angles of Lu et al. 2014), nine (angles, scales, "
                        "offsets), auto (the simplest identifiable model within noise of the best held-out residual; "
                        "default nine)")
    p.add_argument("--seed", type=seed, default=0, help="random seed, a non-negative integer (default 0)")
    p.add_argument("--algorithm", help="NLopt algorithm name (method nlopt)")
    p.add_argument("--blas-threads", type=_positive_int, metavar="N",
                   help="limit BLAS/OpenMP to N threads for this fit (default: one for records of more than "
                        "100,000 rows, whose long thin products a second thread hardly speeds up, else the library's "
                        "own; campaigns always use one per worker)")
    p.add_argument("--accept-any", action="store_true",
                   help="keep a calibration that fails its acceptance checks (exit 0, the causes as warnings) "
                        "instead of exit status 3")
    p.add_argument("--param", action="append", metavar="KEY=VALUE", help="a hyper-parameter (repeatable)")
    p.add_argument("--save", metavar="PATH", help="write the calibration to PATH (the extension of --export is added "
                   "when PATH has none); an accepted calibration only, unless --accept-any")
    p.add_argument("--export", choices=["json", "matlab", "ardupilot", "px4"],
                   help="format of --save: json (magbench's schema), matlab (A, b, expmfs: .mat, or .json; "
                        "corrected = (D - b) * A), ardupilot (COMPASS_* .param), px4 (CAL_MAG0_* .params); by default "
                        "the --save name's extension says it (.mat matlab, .param ardupilot, .params px4), else json")
    p.add_argument("--force", action="store_true", help="overwrite the --save file")
    p.add_argument("--json", action="store_true")
    _add_reference_options(p)
    for action in p._actions:  # calibrate's --field also takes 'auto' (magcal's expmfs)
        if action.dest == "field":
            action.type, action.metavar = _field_value, "NT|auto"
            action.help = ("reference magnitude in nT for every row, or 'auto': estimated from the readings (the "
                           "fitted sphere's or ellipsoid's radius, as magcal's expmfs; the overall gain then stays "
                           "relative to it)")
    p.set_defaults(func=cmd_calibrate)


def _add_apply_parser(sub) -> None:
    p = sub.add_parser("apply", help="apply a saved calibration to a data file: corrected columns added")
    p.add_argument("calibration", metavar="CAL", help="a calibration file: magbench json, or magcal's A, b (.mat/.json)")
    p.add_argument("file", metavar="FILE.csv")
    p.add_argument("--out", required=True, metavar="OUT.csv",
                   help="the output: FILE's lines and columns as they are, plus bx_cal, by_cal, bz_cal, f_cal")
    p.add_argument("--force", action="store_true", help="overwrite OUT.csv")
    p.add_argument("--accept-any", action="store_true",
                   help="apply a calibration that was rejected when it was made, or whose matrix is ill-conditioned "
                        "(condition number above 100, determinant outside 0.01..100); refused otherwise (exit 2)")
    p.add_argument("--units", default="nT", choices=["nT", "uT", "G", "mG"],
                   help="unit of the file's field columns (default nT); the added columns are in it too")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_apply)


def _add_diagnose_parser(sub) -> None:
    p = sub.add_parser("diagnose", help="where the calibration residual lies and which unmodelled effect causes it")
    p.add_argument("file", metavar="FILE.csv")
    p.add_argument("--model", default="nine", choices=["angles", "nine"], help="the base calibration model")
    p.add_argument("--folds", type=_folds, default=5, help="cross-validation folds (at least 2; default 5)")
    p.add_argument("--seed", type=seed, default=0, help="random seed, a non-negative integer (default 0)")
    p.add_argument("--figure", metavar="PATH.png", help="write the figure of the residual before/after the selected "
                   "effects to PATH (no figure without it)")
    p.add_argument("--no-figure", action="store_true", help="no figure even with --figure (kept for old scripts)")
    p.add_argument("--force", action="store_true", help="overwrite the figure")
    p.add_argument("--json", action="store_true")
    _add_reference_options(p)
    p.set_defaults(func=cmd_diagnose)


def _add_compare_parser(sub) -> None:
    p = sub.add_parser("compare", help="a campaign: scenarios x calibrators x trials -> tables, figures, report")
    p.add_argument("--scenarios", nargs="+", required=True, metavar="NAME",
                   help="scenarios to simulate ('magbench list' shows them); space- or comma-separated")
    p.add_argument("--methods", nargs="+", default=["all"], metavar="NAME[:KEY=VALUE...]",
                   help="calibrators, optionally with hyper-parameters (nlopt:algorithm=GN_ISRES); 'all' = every one")
    p.add_argument("--trials", type=int, default=10, help="trials (data sets) per scenario; every calibrator "
                   "sees the same data in a trial; efficiencies need about 30")
    p.add_argument("--budgets", type=_positive_int, nargs="+", metavar="N",
                   help="run every iterative method at each of these evaluation budgets (fixed-budget comparison); "
                        "closed-form methods run once")
    p.add_argument("--seed", type=seed, default=0,
                   help="root seed, a non-negative integer; every run's seed follows from it and the run's identity "
                        "(scenario, trial, configuration), never from list positions (default 0)")
    p.add_argument("--out", required=True, metavar="DIR", help="campaign folder: tables, figures, report.html")
    p.add_argument("--jobs", type=int, default=1, help="local worker processes (with --dask local: Dask workers)")
    p.add_argument("--dask", metavar="ADDRESS|local",
                   help="run on a Dask cluster: a scheduler's address (tcp://127.0.0.1:8786), or 'local' to start "
                        "a local cluster of --jobs workers bound to 127.0.0.1 for this campaign (default: no Dask)")
    p.add_argument("--no-figures", action="store_true", help="tables only")
    _add_figure_options(p, ["png", "svg"])
    p.add_argument("--force", action="store_true",
                   help="start over in a non-empty directory: first delete the campaign outputs there (tables, "
                        "manifest, checkpoint, figures, report.html), nothing else")
    p.add_argument("--resume", action="store_true",
                   help="complete an interrupted campaign in --out: same arguments, only the missing runs are run "
                        "(every finished run is kept in DIR/runs.partial.jsonl as it completes)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_compare)


def _add_report_parser(sub) -> None:
    p = sub.add_parser("report", help="one self-contained HTML page of a campaign directory")
    p.add_argument("dir", metavar="DIR", help="a campaign folder written by 'magbench compare'")
    _add_figure_options(p, None, "also write the figures to DIR/figures in these formats (default: none; the "
                                 "report embeds its own)")
    p.add_argument("--jobs", type=_positive_int, default=1, help="processes drawing the figures")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_report)


def _add_reproduce_parser(sub) -> None:
    p = sub.add_parser("reproduce", help="regenerate everything committed in results/")
    p.add_argument("--out", default="results", metavar="DIR", help="folder to write everything to")
    p.add_argument("--jobs", type=_positive_int, default=2, help="local worker processes")
    p.add_argument("--quick", action="store_true", help="few trials (a smoke test, not the committed results)")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_reproduce)


def _add_demo_parser(sub) -> None:
    p = sub.add_parser("demo", help="simulate Lu et al. 2014's experiment and a sphere, compare every calibrator")
    p.add_argument("--seed", type=seed, default=0, help="random seed, a non-negative integer (default 0)")
    p.add_argument("--json", action="store_true")
    p.set_defaults(func=cmd_demo)


def _first_line(exc: BaseException) -> str:
    """The first non-empty line of an exception's text, or its type's name (a MemoryError has no text)."""
    lines = [ln for ln in str(exc).splitlines() if ln.strip()]
    return _printable(lines[0].strip()) if lines else type(exc).__name__


def _usage_error(exc: BaseException) -> str | None:
    """The one-line message of an exception that is bad input, not our fault (None otherwise): an
    ``InputError``, an ``OSError`` (a path and the system's reason), memory or nesting beyond the machine's."""
    if isinstance(exc, InputError):  # ours: all of it on one line (a line break in a file or column name it quotes is
        # shown escaped, not cut there: the reason after it had been lost)
        text = str(exc).strip()
        return cli_words(_printable(text)) if text else type(exc).__name__
    if isinstance(exc, OSError):
        where = f"{exc.filename}: " if getattr(exc, "filename", None) else ""
        return _printable(f"cannot read or write {where}{os_reason(exc)}")
    if isinstance(exc, MemoryError):
        return "not enough memory for this input (it is too large, or not what it claims to be)"
    if isinstance(exc, RecursionError):
        return "the input is nested too deeply to read"
    return None


def main(argv=None) -> int:
    import warnings

    parser = build_parser()
    caught: list = []
    _FIRST_DATA_LINE[0] = None  # this command's data file, once read, says where its rows are
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            args = parser.parse_args(argv)
            args._argv = list(argv) if argv is not None else sys.argv[1:]
            if isinstance(getattr(args, "file", None), str):
                args.file = resolve_example(args.file)
            if not getattr(args, "command", None):  # a usage error: one line, as every other (CONTRACT section 3)
                raise InputError(f"a command is needed: {', '.join(args.command_names)} (magbench --help says what "
                                 "each does)")
            status = args.func(args)
        _show_warnings(caught)
        return status
    except (InputError, OSError, MemoryError, RecursionError) as exc:  # bad input: one line, no library warnings
        sys.stderr.write(f"magbench: {_usage_error(exc)}\n")
        return EXIT_USAGE
    except KeyboardInterrupt as exc:  # 130 for Ctrl-C (128 + SIGINT); 143 for a SIGTERM turned into one
        sys.stderr.write("magbench: interrupted\n")
        return getattr(exc, "exit_status", 128 + 2)
    except Exception as exc:  # anything else is our fault: one line, status 1, traceback on request
        if os.environ.get("MAGBENCH_DEBUG"):
            raise
        sys.stderr.write(f"magbench: internal error: {type(exc).__name__}: {_first_line(exc)} "
                         "(set MAGBENCH_DEBUG=1 for a traceback)\n")
        return EXIT_FAIL


def run() -> int:
    """The ``magbench`` command as a process (the console script and ``python -m magbench``): ``main``, then
    everything still alive frozen out of the collector's sight (``gc.freeze``), so that the interpreter's
    teardown does not run its collections over the heap that matplotlib, pandas, SciPy and numba leave
    (0.15 s of a serial campaign's exit, 0.3 s of one on two workers); the memory goes back to the system
    with the process either way.  In-process callers (the tests) use ``main``, which leaves the collector alone."""
    import gc

    status = main()
    gc.freeze()
    return status


LIBRARY_WARNINGS = (RuntimeWarning, DeprecationWarning, PendingDeprecationWarning, FutureWarning)
"""Warnings of numpy, pandas and scipy about their own internals: never shown to a user (the checks of
magbench say what matters, in its own words)."""


def _show_warnings(caught) -> None:
    """After a command that did not fail on bad input: the warnings it raised, except the libraries' own."""
    import warnings

    for w in caught:
        if not issubclass(w.category, LIBRARY_WARNINGS) and not type(w.message).__module__.startswith("pandas"):
            warnings.showwarning(w.message, w.category, w.filename, w.lineno)


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
