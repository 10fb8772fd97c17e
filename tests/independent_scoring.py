"""Scoring of diagnosis verdicts against the independent forward model's truth, wrong names first.

A verdict (docs/CONTRACT.md section 3) is ``none``, ``insufficient_data``, ``unexplained`` or effect names
joined by ``+`` (``a|b`` inside for two the data cannot tell apart), optionally ending in ``+unexplained``.
A *wrong name* is a named effect that is not acceptable for the record, or an ``a|b`` of which neither is;
any name on a clean record is wrong.  Per case: 0 with a wrong name; 1 when every present effect is named
(an ``a|b`` holding it counts when the record cannot separate the pair; an ``a|b|c`` when the record can separate
the present effect from none of the others, each of its pairs with the present effect confoundable),
``+unexplained`` is said exactly when an effect outside the library is present, a clean record is ``none`` and a
too-short one ``insufficient_data``; 0.5 otherwise (partly right).
"""
from __future__ import annotations

from dataclasses import dataclass

from independent_forward import Case

SPECIAL = ("none", "insufficient_data", "unexplained")


@dataclass(frozen=True)
class Score:
    wrong_names: tuple[str, ...]
    named_present: int
    n_present: int
    score: float


def parse(verdict: str) -> tuple[list[tuple[str, ...]], bool, str | None]:
    """(named groups, each a tuple of alternatives; whether '+unexplained' ends it; the special word if the
    verdict is one)."""
    if verdict in SPECIAL:
        return [], verdict == "unexplained", verdict
    parts = verdict.split("+")
    unexplained = parts[-1] == "unexplained"
    if unexplained:
        parts = parts[:-1]
    return [tuple(p.split("|")) for p in parts], unexplained, None


def score(case: Case, verdict: str) -> Score:
    groups, unexplained, special = parse(verdict)
    acceptable = set(case.acceptable)
    wrong = tuple("|".join(g) for g in groups if not (set(g) & acceptable))
    confoundable = {frozenset(p) for p in case.confoundable}
    named = 0
    partial = False
    for effect in case.present:
        holding = [g for g in groups if effect in g]
        if not holding:
            continue
        if any(len(g) == 1 or all(frozenset((effect, other)) in confoundable for other in g if other != effect)
               for g in holding):
            named += 1
        else:
            partial = True  # named only as an ambiguity the record does not have
    if wrong:
        return Score(wrong, named, len(case.present), 0.0)
    if case.too_short:
        return Score((), named, len(case.present), 1.0 if special == "insufficient_data" else 0.5)
    if case.category == "clean":
        return Score((), 0, 0, 1.0 if special == "none" else 0.5)
    complete = named == len(case.present) and not partial and unexplained == case.expect_unexplained
    return Score((), named, len(case.present), 1.0 if complete else 0.5)
