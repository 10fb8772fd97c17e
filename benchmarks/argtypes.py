"""argparse types shared by the command line's modules (``cli``, ``gradiometer_cli``): one definition of what
a seed or a count is, so that every command checks it alike."""
from __future__ import annotations

import argparse

from magbench.errors import MAX_SEED


def integer(text: str, minimum: int, why: str, maximum: int | None = None, why_above: str = "") -> int:
    """``text`` as an integer of at least ``minimum`` and, when given, at most ``maximum`` (else argparse's
    error, ``why`` or ``why_above`` saying what is wrong)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"{value} {why}")
    if maximum is not None and value > maximum:
        raise argparse.ArgumentTypeError(f"{value} {why_above}")
    return value


def seed(text: str) -> int:
    """argparse type of every --seed: an integer from 0 to 2**64 - 1 (numpy's SeedSequence and nlopt.srand both
    take it; nlopt's is an unsigned 64-bit integer)."""
    return integer(text, 0, "is negative; seeds are non-negative integers", MAX_SEED,
                   "is above 2**64 - 1, the largest seed (NLopt's is 64 bits)")
