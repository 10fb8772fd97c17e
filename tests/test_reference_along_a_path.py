"""A reference that changes smoothly along a path (a model field along a satellite's orbit, sampled with a gap) changes
by several per cent between two rows without jumping: with time stamps, such a step is judged by the reference's own
rate of change around it (``acceptance._smooth_steps``).  A glitch, a switch of units and a reference alternating
between two values are still refused, with or without time stamps."""
import numpy as np
import pytest

from magbench.calibrators import make
from magbench.calibrators.acceptance import reference_problems
from magbench.errors import InputError
from magbench.simulate.dataset import Dataset


def orbit(n=600, seed=0, gap_s=150.0):
    """Readings of an ideal sensor tumbling on a low orbit: the field's magnitude goes from about 25,000 to 55,000 nT
    and back in an orbit (95 min); the sampling has a gap of ``gap_s`` seconds halfway."""
    rng = np.random.default_rng(seed)
    t = np.sort(rng.uniform(0, 5400, n))
    t[n // 2:] += gap_s
    f = 40000 + 15000 * np.sin(2 * np.pi * t / 5700)
    direction = rng.normal(0, 1, (n, 3))
    raw = direction / np.linalg.norm(direction, axis=1, keepdims=True) * f[:, None] + rng.normal(0, 1, (n, 3))
    return raw, f, t


def test_a_gap_along_an_orbit_is_no_jump():
    raw, f, t = orbit()
    assert "jumps" in reference_problems(raw, f)  # without time stamps the step cannot be judged
    assert reference_problems(raw, f, t) is None
    fit = make("lsq").fit(Dataset(raw, f_ref_nT=f, t_s=t))
    assert fit.rms_after_nT < 2.0


@pytest.mark.parametrize("kind", ["glitch", "units", "alternating"])
def test_jumps_are_still_jumps_with_time_stamps(kind):
    raw, f, t = orbit(gap_s=0.0)
    g = f.copy()
    if kind == "glitch":
        g[100] *= 1.05
    elif kind == "units":
        g[400:] *= 1.03
    else:
        g = np.where(np.arange(len(f)) % 2, f, 0.96 * f)
    raw = raw / f[:, None] * g[:, None]
    assert "jumps" in reference_problems(raw, g, t)
    with pytest.raises(InputError, match="jumps"):
        make("lsq").fit(Dataset(raw, f_ref_nT=g, t_s=t))


def test_the_record_s_cache_keeps_the_jump_check_per_time_column():
    """The checks of a record are kept with its readings and reference, and the jump check reads the time stamps too:
    the same orbit's readings and reference fitted with its times (no jump) and then without them (a jump: refused),
    and in the other order, each get their own answer (the cache had answered the second as the first)."""
    from magbench.calibrators.base import _DatasetCache

    raw, f, t = orbit(seed=3)
    for first, second in ((t, None), (None, t)):
        _DatasetCache._entries.clear()
        for times in (first, second):
            data = Dataset(raw, f_ref_nT=f, t_s=times)
            if times is None:
                with pytest.raises(InputError, match="jumps"):
                    make("lsq").fit(data)
            else:
                assert make("lsq").fit(data).rms_after_nT < 2.0
