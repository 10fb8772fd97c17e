"""argparse types shared by the command line's modules (``cli``, ``gradiometer_cli``): one definition of what
a seed or a count is, so that every command checks it alike."""
from __future__ import annotations

import argparse


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
    """argparse type of every --seed: a non-negative integer (numpy's SeedSequence and nlopt.srand need one)."""
    return integer(text, 0, "is negative; seeds are non-negative integers")
