"""The diagnosis of one record of an independent forward model (tests/independent_forward.py, the first; 2:
tests/independent_forward2.py, 3: tests/independent_forward3.py and 4: tests/independent_forward4.py, whose cases from
DEVELOPMENT_CASES on are held out and not used by tests), shared by the naming tests, and what they read of its
result."""
from __future__ import annotations

import independent_forward
import independent_forward2
import independent_forward3
import independent_forward4
from independent_scoring import parse

from magbench.benchmarks.diagnosis import diagnose
from magbench.simulate.dataset import Dataset

DEVELOPMENT_CASES = 480
"""The second, third and fourth generators' cases 0-479 are their development sets; the rest are held out."""


def run_case(index: int, generator: int = 1) -> tuple[dict, object]:
    """(the diagnosis, the case) of record ``index`` (root seed 2026) of ``generator``."""
    if generator in (2, 3, 4):
        assert index < DEVELOPMENT_CASES, "the second, third and fourth generators' held-out cases are not for tests"
    case = {1: independent_forward, 2: independent_forward2, 3: independent_forward3,
            4: independent_forward4}[generator].make_case(index, 2026)
    data = Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s, temp_C=case.temp_C)
    return diagnose(data, gravity=case.gravity), case


def evidence_row(result: dict, name: str) -> dict:
    """The naming evidence of ``name``."""
    return next(r for r in result["naming"]["evidence"] if r["name"] == name)


def names(verdict: str) -> set[str]:
    """Every effect a verdict names, alone or in a group ``a|b``."""
    groups, _, _ = parse(verdict)
    return {n for g in groups for n in g}
