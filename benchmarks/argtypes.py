"""argparse types shared by the command line's modules (``cli``, ``gradiometer_cli``): one definition of what
a seed or a count is, so that every command checks it alike."""
from __future__ import annotations

import argparse

from magbench.errors import MAX_SEED


def integer(text: str, minimum: int, why: str) -> int:
    """``text`` as an integer of at least ``minimum`` (else argparse's error, ``why`` saying what is wrong)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < minimum:
        raise argparse.ArgumentTypeError(f"{value} {why}")
    return value


def seed(text: str) -> int:
    """argparse type of every --seed: an integer from 0 to 2**64 - 1 (numpy's SeedSequence and nlopt.srand both
    take it; nlopt's is an unsigned 64-bit integer)."""
    value = integer(text, 0, "is negative; seeds are non-negative integers")
    if value > MAX_SEED:
        raise argparse.ArgumentTypeError(f"{value} is above 2**64 - 1, the largest seed (NLopt's is 64 bits)")
    return value
