"""``magbench gradiometer``: seed 001's experiment on the command line.  Kept apart from
``benchmarks/gradiometer.py`` so that building the ``magbench`` parser (and ``magbench --help``) does
not import the simulator and the calibrators."""
from __future__ import annotations

import argparse
import json

from magbench import paper
from magbench.benchmarks.argtypes import seed


def _cmd_gradiometer(args) -> int:
    from magbench.benchmarks.gradiometer import format_report, run_gradiometer

    r = run_gradiometer(seed=args.seed, n_points=args.points, fluctuation_nT=args.fluctuation_nT,
                        noise_nT=args.noise_nT)
    print(json.dumps(r) if args.json else format_report(r))
    return 0


def add_gradiometer_command(subparsers) -> argparse.ArgumentParser:
    """Add ``gradiometer`` (seed 001's experiment) to an argparse subparsers object; ``func(args)`` prints
    the table (or one JSON object with ``--json``) and returns 0; bad values raise ``InputError``."""
    p = subparsers.add_parser(
        "gradiometer", help="Jin, Zhuang & Wang (2024): calibrate a two-fluxgate gradiometer by GA under a fluctuating field",
        description="Simulate the gradiometer of Jin, Zhuang & Wang (2024) (two tri-axial fluxgates on one "
                    "rigid body, 24 parameters) "
                    "in a field fluctuating in time, calibrate it by single-sensor ellipsoid fits and by the "
                    "paper's three 6-gene GAs, and report the per-axis gradient residual (paper: 1.85 nT).")
    p.add_argument("--seed", type=seed, default=0, help="random seed, a non-negative integer (default 0)")
    p.add_argument("--points", type=int, default=paper.GRADIOMETER_POINTS,
                   help=f"number of attitudes in the record (default {paper.GRADIOMETER_POINTS})")
    p.add_argument("--fluctuation-nT", dest="fluctuation_nT", type=float, default=paper.GRADIOMETER_FLUCTUATION_NT,
                   help="largest deviation of the ambient field in time, nT "
                        f"(default {paper.GRADIOMETER_FLUCTUATION_NT:g})")
    p.add_argument("--noise-nT", dest="noise_nT", type=float, default=paper.GRADIOMETER_NOISE_NT,
                   help=f"white noise per axis of each sensor, nT (default {paper.GRADIOMETER_NOISE_NT})")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(func=_cmd_gradiometer)
    return p
