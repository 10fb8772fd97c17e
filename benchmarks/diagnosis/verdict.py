"""The verdict of a diagnosis (CONTRACT section 3): the selected effects, strongest first, joined by
``+`` and ending in ``+unexplained`` when a significant remainder is left; with none selected,
``unexplained`` for a significant remainder the tested effects cannot explain, ``none`` when the residual
is consistent with the noise and the tests had the power to see an effect of the stated size, else
``insufficient_data`` (too few points, too little coverage for any effect to be tested)."""
from __future__ import annotations

UNEXPLAINED, NONE, INSUFFICIENT = "unexplained", "none", "insufficient_data"


def verdict(selected: list[str], remainder_significant: bool, powered: bool, untested: dict,
            any_tested: bool = True) -> str:
    """The verdict string.  ``none`` needs the power to see an effect of the stated size and at least one
    effect tested; effects the data could not test are listed beside it (``not_tested``), not hidden in it."""
    if selected:
        return "+".join(selected) + ("+" + UNEXPLAINED if remainder_significant else "")
    if remainder_significant:
        return INSUFFICIENT if untested and not any_tested else UNEXPLAINED
    return NONE if powered and any_tested else INSUFFICIENT
