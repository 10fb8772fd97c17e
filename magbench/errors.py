"""The errors the command line maps to exit statuses (CONTRACT section 3), and the checks of plain values
that raise them from the library's entry points (seeds, counts, non-negative numbers)."""
from __future__ import annotations

import math
import re
from numbers import Integral


class InputError(ValueError):
    """Bad input or usage: the command line reports it in one line and exits with status 2."""


class FitError(InputError):
    """Readings that do not take the form a closed-form method fits (a quadric that is not an ellipsoid, a gain that
    is not positive, a design the readings leave singular): bad input for that method (status 2), whose cause may lie
    in the readings (too little coverage, spikes: ``Calibrator.fit`` names those beside it)."""


_NUMBER = r"\d+(?:,\d{3})*(?!\d|,\d)"  # 7, 1234 or 1,234 (a list's ", " is not a thousands separator)
_ROWS = re.compile(rf"\b(rows?|row\(s\)) ({_NUMBER}(?:(?:, | and ){_NUMBER}(?! more))*)(?! \(line)")


def with_file_lines(message: str, first_data_line: int | None) -> str:
    """``row 7`` -> ``row 7 (line 11)``, ``rows 0, 2, 4`` -> ``rows 0, 2, 4 (lines 4, 6, 8)``: the library's messages
    count data rows from 0, a file's reader names its lines; both are said once a file has been read whose data row 0
    is on line ``first_data_line`` and whose rows are consecutive lines (None: the message as it is)."""
    if first_data_line is None:
        return message

    def lines(m: re.Match) -> str:
        rows = [int(x.replace(",", "")) for x in re.split(r", | and ", m.group(2))]
        where = ", ".join(f"{first_data_line + r:,}" for r in rows)
        return f"{m.group(0)} (line{'s' if len(rows) > 1 else ''} {where})"

    return _ROWS.sub(lines, message)


def check_nonneg(value, name: str) -> float:
    """``value`` as a finite float >= 0, or ``InputError`` naming ``name``."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise InputError(f"{name} must be a number, got {value!r}") from None
    if not math.isfinite(v) or v < 0:
        raise InputError(f"{name} must be a finite number >= 0, got {value!r}")
    return v


def check_int(value, name: str, minimum: int) -> int:
    """``value`` as an int >= ``minimum`` (a float with an integer value is accepted), or ``InputError``."""
    if isinstance(value, bool) or not isinstance(value, Integral):
        if isinstance(value, float) and value.is_integer():
            value = int(value)
        else:
            raise InputError(f"{name} must be an integer, got {value!r}")
    if value < minimum:
        raise InputError(f"{name} must be at least {minimum}, got {value}")
    return int(value)


MAX_SEED = 2**64 - 1
"""The largest seed: ``nlopt.srand`` takes an unsigned 64-bit integer (a larger one was an OverflowError)."""


def check_seed(value, name: str = "seed") -> int | None:
    """A seed: None (fresh entropy) or an integer from 0 to ``MAX_SEED`` (what ``np.random.default_rng`` and
    ``nlopt.srand`` both take), else ``InputError`` naming ``name`` (not numpy's ValueError or TypeError)."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, Integral) or not 0 <= int(value) <= MAX_SEED:
        raise InputError(f"{name} must be an integer from 0 to 2**64 - 1, or None, got {value!r}")
    return int(value)
