"""The blind check of the diagnosis: simulated datasets, each with a randomly drawn library effect (or
none) that the diagnosis is not told.  The kinds cycle through ``none`` and the registry's library
effects (``simulate.effects``), so a newly registered effect joins the check by itself."""
from __future__ import annotations

import numpy as np

from magbench.simulate.dataset import Dataset
from magbench.simulate.effects import EFFECTS, effect_names
from magbench.simulate.scenarios import get_scenario

BLIND_SEED = 1000
DATA_SEED_RANGE = 2**31  # the data seed is drawn from [0, DATA_SEED_RANGE)
SCENARIO_FOR_BASE = {"angles": "tumble3", "nine": "tumble9q"}  # smooth 10-minute tumbles, quiet field


def blind_kinds() -> tuple[str, ...]:
    """``none`` followed by the library effects, in registry order."""
    return ("none",) + effect_names(in_library=True)


def blind_dataset(i: int) -> tuple[str, str, Dataset]:
    """Dataset i of the blind check: (true effect, base model, data).  Its parameters and the data seed
    are drawn from seed BLIND_SEED + i, at the effect's ``blind_strength``.  Effects the 9-parameter model
    already contains (scale, offset), and every other ``none``, use the angles-only tumble; the rest the
    9-parameter one."""
    rng = np.random.default_rng(BLIND_SEED + i)
    kinds = blind_kinds()
    kind = kinds[i % len(kinds)]
    cls = EFFECTS.get(kind)
    angles_only = "nine" in cls.included_in if cls is not None else bool(i % 2)
    base = "angles" if angles_only else "nine"
    scenario = get_scenario(SCENARIO_FOR_BASE[base])
    if cls is not None:
        scenario = scenario.with_effects(cls.random(rng, cls.blind_strength))
    return kind, base, scenario.build(int(rng.integers(DATA_SEED_RANGE)))
