"""A fixed sensor gets a time-only answer: the constant |B| - F, its drift, its temperature dependence and
the floor, with the attitude part stated as insufficient_data (not a refusal)."""
import json

import numpy as np
import pandas as pd
import pytest

from magbench.benchmarks.cli import main
from magbench.benchmarks.diagnosis import diagnose
from magbench.errors import InputError
from magbench.simulate.dataset import Dataset

B = np.array([20000.0, 1500.0, 44000.0])
F = float(np.linalg.norm(B))


def fixed(constant_nT=7.0, drift_nT_per_day=4.0, temp_nT_per_C=0.0, noise=0.3, seed=0, n=2000):
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 86400.0, n)
    temp = 20 + 5 * np.sin(2 * np.pi * t / 86400 * 3)  # not a function of a linear drift
    excess = constant_nT + drift_nT_per_day * t / 86400 + temp_nT_per_C * (temp - temp.mean())
    raw = B * (1 + excess[:, None] / F) + rng.normal(0, noise, (n, 3))
    return Dataset(raw, f_ref_nT=np.full(n, F), t_s=t, temp_C=temp)


def test_constant_and_drift_are_recovered():
    r = diagnose(fixed())
    assert r["kind"] == "time_only" and r["attitude"] == "insufficient_data"
    assert r["verdict"] == "field_drift"  # the readings move along their own direction: the magnitude drifts
    to = r["time_only"]
    assert abs(to["constant_nT"] - 9.0) < 0.1  # 7 nT plus half a day of 4 nT/day, at the median
    assert abs(to["drift"]["drift_nT_per_h"] * 24 - 4.0) < 0.1 and to["drift"]["significant"]
    assert 0.2 < to["noise_floor_nT"] < 0.45  # noise 0.3 nT per axis, seen along the field direction
    assert r["time_verdict"] == "drift"


def test_negative_control_no_drift_is_not_called_a_drift():
    r = diagnose(fixed(drift_nT_per_day=0.0, seed=3))
    assert not r["time_only"]["drift"]["significant"] and r["time_verdict"] == "constant"


def test_temperature_beyond_time():
    r = diagnose(fixed(drift_nT_per_day=0.0, temp_nT_per_C=0.8, seed=5))
    tc = r["time_only"]["temperature"]
    assert tc["significant"] and abs(tc["temperature_nT_per_C"] - 0.8) < 0.05
    assert "temperature" in r["time_verdict"]
    assert r["verdict"] == "temperature" and r["time_only"]["temperature"]["named"]  # beyond any smooth trend


def test_a_fixed_sensor_names_temperature_when_it_follows_the_temperature_beyond_time_and_drifts_by_direction():
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from independent_forward import make_case

    for index, expected in ((33, "temperature"), (177, "temperature"), (21, "offset_drift|temperature|field_drift"),
                            (69, "field_drift")):  # temperature, temperature, offset drift, field drift
        case = make_case(index, 2026)
        assert case.category == "fixed"
        r = diagnose(Dataset(case.raw_nT, f_ref_nT=case.f_ref_nT, t_s=case.t_s, temp_C=case.temp_C))
        assert r["verdict"] == expected, (index, case.present, r["time_only"]["temperature"])
        assert r["attitude"] == "insufficient_data"


def test_the_command_answers_with_exit_0(tmp_path, capsys):
    d = fixed()
    path = tmp_path / "fixed.csv"
    pd.DataFrame({"t": d.t_s, "bx": d.raw_nT[:, 0], "by": d.raw_nT[:, 1], "bz": d.raw_nT[:, 2],
                  "f_ref": d.f_ref_nT}).to_csv(path, index=False)
    assert main(["diagnose", str(path), "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["time_only"]["constant_nT"] > 8 and out["attitude"] == "insufficient_data"


def test_glitches_in_a_fixed_record_are_named_outliers_and_clean_records_have_none():
    rng = np.random.default_rng(11)
    d = fixed(drift_nT_per_day=0.0, seed=5)
    raw = d.raw_nT.copy()
    rows = rng.choice(len(raw), 30, replace=False)
    raw[rows] += rng.normal(0, 1, (30, 3)) * 60.0
    r = diagnose(Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s, temp_C=d.temp_C))
    assert r["verdict"] == "outliers" and r["attitude"] == "insufficient_data"
    assert r["time_only"]["spikes"]["named"] and r["time_verdict"] == "outliers"
    assert abs(r["time_only"]["constant_nT"] - 7.0) < 0.1  # the spikes are left out of the constant and drift
    clean = diagnose(fixed(drift_nT_per_day=0.0, seed=5))  # the control: the same record without them
    assert clean["verdict"] == "insufficient_data" and not clean["time_only"]["spikes"]["named"]


def test_a_few_glitches_in_a_long_fixed_record_are_counted_against_the_noise_not_a_share_of_the_samples():
    """Twelve glitches in 12,000 samples (0.1 %): Gaussian noise gives 0.007 beyond 5 sigma, so their count is
    significant and they are named; Student-t noise (3 degrees of freedom) exceeds 5 robust sigma many times but
    throughout (its rest is heavy-tailed), and is not (negative control)."""
    rng = np.random.default_rng(21)
    d = fixed(drift_nT_per_day=0.0, seed=8, n=12000)
    raw = d.raw_nT.copy()
    rows = rng.choice(len(raw), 12, replace=False)
    raw[rows] += rng.normal(0, 1, (12, 3)) * 60.0
    r = diagnose(Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s, temp_C=d.temp_C))
    assert r["verdict"] == "outliers" and r["time_only"]["spikes"]["count_z"] > 3, r["time_only"]["spikes"]
    heavy = d.raw_nT + rng.standard_t(3, (12000, 3)) * 0.3
    r = diagnose(Dataset(heavy, f_ref_nT=d.f_ref_nT, t_s=d.t_s, temp_C=d.temp_C))
    assert r["time_only"]["spikes"]["n"] > 12 and not r["time_only"]["spikes"]["named"], r["time_only"]["spikes"]


def test_a_burst_in_one_part_of_a_fixed_record_is_not_outliers():
    d = fixed(drift_nT_per_day=0.0, seed=6)
    raw = d.raw_nT.copy()
    rng = np.random.default_rng(2)
    late = rng.choice(np.arange(1500, 2000), 30, replace=False)  # all in the last quarter: a disturbance
    raw[late] += rng.normal(0, 1, (30, 3)) * 60.0
    r = diagnose(Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s, temp_C=d.temp_C))
    assert r["verdict"] == "insufficient_data" and not r["time_only"]["spikes"]["named"]


def test_readings_stuck_at_a_repeated_extreme_are_clipping_not_outliers():
    d = fixed(drift_nT_per_day=0.0, seed=7)
    raw = d.raw_nT.copy()
    raw[::50] = raw.max(axis=0) + 300.0  # forty readings at the converter's limit on every axis
    r = diagnose(Dataset(raw, f_ref_nT=d.f_ref_nT, t_s=d.t_s, temp_C=d.temp_C))
    assert r["verdict"] == "insufficient_data" and r["time_only"]["spikes"]["clipped_share"] == 1.0


def drifting(across_nT=0.0, radial_nT=0.0, step=False, temp_follows=False, noise=0.5, seed=1, n=1500, logged=True):
    """A fixed sensor whose readings drift by ``radial_nT`` along the field and ``across_nT`` across it (a
    raised-cosine in time, or a step at mid-record)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 86400.0, n)
    u = t / t[-1]
    shape = (u >= 0.5).astype(float) if step else 0.5 * (1 - np.cos(np.pi * u))
    temp = 20 + 10 * shape if temp_follows else 20 + 5 * np.sin(2 * np.pi * u * 3)
    b = B / np.linalg.norm(B)
    across = np.cross(b, [0.0, 1.0, 0.0])
    across /= np.linalg.norm(across)
    raw = B + shape[:, None] * (radial_nT * b + across_nT * across) + rng.normal(0, noise, (n, 3))
    return Dataset(raw, f_ref_nT=np.full(n, F), t_s=t, temp_C=temp if logged else None)


def test_a_drift_across_the_readings_cannot_be_told_from_a_turning_field_and_along_them_is_a_field_drift():
    """Across: the offsets drift, or the field's direction changes (a scalar reference follows no direction),
    or (the temperature following time) a temperature coefficient; the JSON says what would separate them."""
    r = diagnose(drifting(across_nT=30.0, radial_nT=5.0))
    assert r["verdict"] == "offset_drift|field_drift", r["time_only"]["drift_direction"]
    assert r["confounded"][0]["alternatives"] == ["offset_drift", "field_drift"]
    assert "vector reference" in r["confounded"][0]["separate_by"]
    r = diagnose(drifting(across_nT=30.0, radial_nT=5.0, temp_follows=True))  # a temperature coefficient as much
    assert r["verdict"] == "offset_drift|temperature|field_drift", r["time_only"]["drift_direction"]
    assert "temperature changes independently of time" in r["confounded"][0]["separate_by"]
    r = diagnose(drifting(radial_nT=30.0))
    assert r["verdict"] == "field_drift" and r["confounded"] == [], r["time_only"]["drift_direction"]


def test_a_drift_across_that_the_wandering_temperature_fits_keeps_temperature_among_the_alternatives():
    """The logged temperature wanders on its own (it does not follow time), and the offsets follow it through a
    thermal lag: the drift across is said with ``temperature`` among its alternatives; the same drift in time
    beside a temperature that wanders otherwise (negative control) is not."""
    from magbench.simulate.effects import first_order_lag
    rng = np.random.default_rng(3)
    n = 3000
    t = np.linspace(0.0, 6 * 3600.0, n)
    u = t / t[-1]
    wander = 20 + 2.0 * u + 1.5 * np.sin(2 * np.pi * 2.3 * u) + 1.0 * np.sin(2 * np.pi * 5.1 * u + 1.0)
    b = B / np.linalg.norm(B)
    across = np.cross(b, [0.0, 1.0, 0.0])
    across /= np.linalg.norm(across)
    core = first_order_lag(t, wander, 600.0)
    raw = B + 4.0 * (core - core.mean())[:, None] * across + rng.normal(0, 0.3, (n, 3))
    r = diagnose(Dataset(raw, f_ref_nT=np.full(n, F), t_s=t, temp_C=wander))
    direction = r["time_only"]["drift_direction"]
    assert direction["temperature_follows_time_r2"] < 0.9 and r["verdict"] in (
        "offset_drift|temperature|field_drift", "temperature"), direction
    other = 20 + 2.0 * u + 1.5 * np.sin(2 * np.pi * 3.7 * u + 2.0) + 1.0 * np.cos(2 * np.pi * 1.3 * u)
    r = diagnose(Dataset(raw, f_ref_nT=np.full(n, F), t_s=t, temp_C=other))
    assert r["verdict"] == "offset_drift|field_drift", r["time_only"]["drift_direction"]


def test_negative_controls_a_switch_and_a_radial_drift_that_follows_the_temperature():
    r = diagnose(drifting(across_nT=30.0, radial_nT=5.0, step=True, logged=False))  # a field switched on: not a drift
    assert r["verdict"] == "insufficient_data", r["time_only"]["drift_direction"]
    assert r["time_only"]["drift_direction"]["step_share"] > 0.9
    assert diagnose(drifting(across_nT=30.0, radial_nT=5.0, logged=False))["verdict"] == "offset_drift|field_drift"
    r = diagnose(drifting(radial_nT=30.0, temp_follows=True))  # the gains' temperature coefficient fits it as well
    assert r["verdict"] == "field_drift|temperature", r["time_only"]["drift_direction"]
    r = diagnose(drifting(across_nT=2.0, radial_nT=30.0))  # neither radial nor clearly across: no name
    assert r["verdict"] == "insufficient_data", r["time_only"]["drift_direction"]


def test_the_text_report_says_which_way_a_fixed_sensor_drifts():
    from magbench.benchmarks.diagnosis import diagnosis_text

    text = diagnosis_text(diagnose(drifting(across_nT=30.0, radial_nT=5.0, logged=False)), "fixed.csv")
    assert "drift direction: the readings drift across their own direction" in text
    assert "verdict: offset_drift|field_drift" in text and "to separate them: a vector reference" in text


def test_a_field_change_the_reference_follows_is_not_a_drift():
    """An observatory's scalar reference follows the field's magnitude: the readings' radial change that it
    follows is the field's own (negative control: the same change with a constant reference is a drift)."""
    n, F = 2000, 48000.0
    rng = np.random.default_rng(5)
    t = np.linspace(0.0, 86400.0, n)
    change = 30.0 * np.sin(2 * np.pi * t / 86400.0)
    b = np.array([0.3, 0.2, 0.93])
    b /= np.linalg.norm(b)
    raw = (F + change)[:, None] * b * 1.01 + np.array([120.0, -80.0, 40.0]) + rng.normal(0, 0.5, (n, 3))
    follows = diagnose(Dataset(raw, f_ref_nT=F + change, t_s=t))
    assert follows["verdict"] == "insufficient_data", follows["time_only"]["drift_direction"]
    constant = diagnose(Dataset(raw, f_ref_nT=np.full(n, F), t_s=t))
    assert constant["verdict"] == "field_drift", constant["time_only"]["drift_direction"]


def test_two_wandering_series_do_not_make_a_temperature_effect():
    """A temperature that wanders over tens of minutes and a sensor whose zero wanders in the same band under white
    noise (1/f-like: a small lag-1 correlation, a long memory) correlate by chance; judged on their common memory
    (Bartlett's effective samples) the temperature's z stays a standard normal's, so no temperature is named
    (an AR(1) allowance from the lag-1 correlation gave z up to 6 on these seeds); control: the same temperature
    driving the readings is named every time."""
    n, F = 1500, 50000.0
    t = np.linspace(0.0, 6 * 3600.0, n)
    b = np.array([0.6, 0.0, 0.8])
    freq = np.fft.rfftfreq(n, t[1] - t[0])

    def band(rng):  # periods of 10 to 60 minutes
        spec = np.fft.rfft(rng.standard_normal(n))
        spec[(freq < 1 / 3600) | (freq > 1 / 600)] = 0
        x = np.fft.irfft(spec, n)
        return x / x.std()

    null, driven = [], []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        temp = 20 + 3 * t / t[-1] + 0.4 * band(rng)
        wander = band(rng)
        for drive, out in ((0.0, null), (2.0, driven)):
            change = wander if drive == 0.0 else drive * (temp - temp.mean())
            raw = F * b + change[:, None] * b + rng.normal(0, 1.5, (n, 3))
            out.append(diagnose(Dataset(raw, f_ref_nT=np.full(n, F), t_s=t, temp_C=temp))["time_only"]["temperature"])
    assert not any(c["named"] for c in null) and sum(c["beyond_smooth_time_z"] > 3 for c in null) <= 1, \
        [round(c["beyond_smooth_time_z"], 1) for c in null]
    assert all(c["named"] for c in driven)


def _daily_field(seed: int, n: int = 2000, F: float = 48000.0):
    """A day of a field whose daily variation changes its magnitude by 20 nT and turns it by 30 nT across:
    (times, the variation's shape, the field's direction, the field, 0.5 nT of noise per axis)."""
    rng = np.random.default_rng(seed)
    t = np.linspace(0.0, 86400.0, n)
    wave = np.sin(2 * np.pi * t / 86400.0)
    b = np.array([0.3, 0.2, 0.93])
    b /= np.linalg.norm(b)
    side = np.cross(b, [1.0, 0.0, 0.0])
    side /= np.linalg.norm(side)
    field = (F + 20.0 * wave)[:, None] * b + (30.0 * wave)[:, None] * side
    return t, wave, b, field, rng.normal(0, 0.5, (n, 3))


def test_a_field_that_varies_turns_and_its_turning_is_not_named_a_drift():
    """An observatory's daily variation changes the field's magnitude (which the scalar reference follows) and
    its direction by about as much: a fixed sensor's readings then turn across their direction, which is the
    field's own turning, reported (``field_turning_nT``) and not named.  Negative control: the same turning
    with a reference that varies ten times less exceeds what that variation explains, and is named."""
    t, wave, b, field, noise = _daily_field(11)
    raw = field * 1.01 + np.array([120.0, -80.0, 40.0]) + noise
    varies = diagnose(Dataset(raw, f_ref_nT=np.linalg.norm(field, axis=1), t_s=t))
    direction = varies["time_only"]["drift_direction"]
    assert varies["verdict"] == "insufficient_data", direction
    assert direction["across_trend_rms_nT"] < direction["field_turning_nT"] and "turning" in direction["why"]
    quiet = np.linalg.norm(field, axis=1).mean() + 2.0 * wave  # a reference varying by 2 nT only
    named = diagnose(Dataset(raw, f_ref_nT=quiet, t_s=t))
    assert named["verdict"] == "offset_drift|field_drift", named["time_only"]["drift_direction"]


def test_a_magnitude_drift_beyond_a_varying_reference_is_named_beside_the_fields_turning():
    """The field turns with its daily variation (not named), and besides, the magnitude here drifts by 12 nT that
    the reference does not follow (a local change, or the offsets drifting along the field): the radial trend
    beyond the reference is ``offset_drift|field_drift``.  Controls: without the local drift, nothing is named;
    a reference whose shape differs from the local variation by 1 % of it (a reference elsewhere) names nothing."""
    t, wave, b, field, noise = _daily_field(12)
    local = 12.0 * (t / 86400.0) ** 2  # a slow change of the magnitude here, not in the reference
    field = field + local[:, None] * b
    raw = field * 1.01 + np.array([120.0, -80.0, 40.0]) + noise
    reference = np.linalg.norm(field - local[:, None] * b, axis=1)
    r = diagnose(Dataset(raw, f_ref_nT=reference, t_s=t))
    direction = r["time_only"]["drift_direction"]
    assert r["verdict"] == "offset_drift|field_drift", direction
    assert "beyond the reference" in direction["why"] and r["confounded"][0]["alternatives"] == ["offset_drift", "field_drift"]
    still = field - local[:, None] * b
    assert diagnose(Dataset(still * 1.01 + np.array([120.0, -80.0, 40.0]) + noise, f_ref_nT=reference,
                            t_s=t))["verdict"] == "insufficient_data"
    elsewhere = reference + 0.2 * np.sin(4 * np.pi * t / 86400.0)  # 1 % of the variation's 14 nT RMS
    assert diagnose(Dataset(still * 1.01 + np.array([120.0, -80.0, 40.0]) + noise, f_ref_nT=elsewhere,
                            t_s=t))["verdict"] == "insufficient_data"


def _hold(data: Dataset, share: float, seed: int = 4) -> Dataset:
    """The record as a logger that repeats its last reading on about ``share`` of the rows writes it."""
    raw = np.array(data.raw_nT, dtype=float)
    held = np.random.default_rng(seed).random(len(raw)) < share
    for i in np.flatnonzero(held[1:]) + 1:
        raw[i] = raw[i - 1]
    return Dataset(raw, f_ref_nT=data.f_ref_nT, t_s=data.t_s, temp_C=data.temp_C)


def test_held_samples_do_not_pull_a_fixed_sensors_floor_down():
    """A held sample interpolates perfectly from its twin: the floor comes from the distinct samples, as the
    vector floor's does.  Negative control: the record without held samples reports none and the same floor."""
    clean = diagnose(fixed(noise=1.0, n=3000))["time_only"]
    held = diagnose(_hold(fixed(noise=1.0, n=3000), 0.3))["time_only"]
    assert clean["held_sample_fraction"] == 0.0 and "held" not in clean["floor_method"]
    assert 0.25 < held["held_sample_fraction"] < 0.35 and "distinct samples" in held["floor_method"]
    assert abs(held["noise_floor_nT"] / clean["noise_floor_nT"] - 1) < 0.1


def test_a_stuck_sensor_and_a_reference_that_does_not_belong_are_refused(tmp_path, capsys):
    """Every reading identical (a stuck logger), or readings a twelfth of the reference (wrong units), on a fixed
    sensor: exit status 2 with one line, not a time-only answer (a floor of 0, a |B| - F of the units' error)."""
    n = 400
    t = np.arange(n, dtype=float)
    for name, raw, ref, says in (("stuck", np.tile(B, (n, 1)), F, "stuck sensor"),
                                 ("units", np.tile(B, (n, 1)) / 12 + np.random.default_rng(1).normal(0, 0.3, (n, 3)), F,
                                  "times the reference")):
        path = tmp_path / f"{name}.csv"
        pd.DataFrame({"t": t, "bx": raw[:, 0], "by": raw[:, 1], "bz": raw[:, 2], "f_ref": ref}).to_csv(path, index=False)
        assert main(["diagnose", str(path)]) == 2
        err = capsys.readouterr().err.strip()
        assert says in err and len(err.splitlines()) == 1


def test_a_fixed_sensor_below_its_resolution_gets_a_floor_from_its_lattice_not_a_collapsed_mad():
    """Readings rounded to 1 nT under 0.3 nT of noise repeat on each axis (not a logger's holds: whole rows repeat
    no more often than the axes' own repeats together give); the interpolation errors take lattice values whose
    median absolute deviation fell to 0.02 nT (and 58 % of its rows, taken for a logger's holds, were dropped).
    Their trimmed RMS gives about the noise.  Negative control: the same record at 0.01 nT resolution keeps the MAD
    and every row."""
    d = fixed(drift_nT_per_day=0.0, noise=0.3, n=3000, seed=7)
    coarse = Dataset(np.round(d.raw_nT), f_ref_nT=d.f_ref_nT, t_s=d.t_s, temp_C=d.temp_C)
    fine = Dataset(np.round(d.raw_nT, 2), f_ref_nT=d.f_ref_nT, t_s=d.t_s, temp_C=d.temp_C)
    c, f = diagnose(coarse)["time_only"], diagnose(fine)["time_only"]
    assert c["held_sample_fraction"] > 0.3 and "grid" in c["floor_method"] and "distinct" not in c["floor_method"]
    assert 0.2 < c["noise_floor_nT"] < 0.5, c["noise_floor_nT"]
    assert "grid" not in f["floor_method"] and 0.2 < f["noise_floor_nT"] < 0.4, f


def test_without_a_clock_the_drift_is_per_row_not_per_hour():
    """No t column, or one time on every row: the rows' order is the time axis, and the drift is given per row
    (it had been reported in nT/h as if the rows were one second apart); with the clock the same readings give
    nT/h (the control)."""
    timed = fixed(seed=7)  # 4 nT a day over 2000 rows
    per_h = diagnose(timed)["time_only"]
    assert per_h["time_axis"] == "the t column" and abs(per_h["drift"]["drift_nT_per_h"] * 24 - 4.0) < 0.2
    assert per_h["drift"]["drift_nT_per_row"] is None and per_h["span_rows"] is None  # the same keys either way
    for t, said in ((None, "no t column"), (np.zeros(len(timed)), "one time for every row")):
        to = diagnose(Dataset(timed.raw_nT, f_ref_nT=timed.f_ref_nT, t_s=t, temp_C=timed.temp_C))["time_only"]
        assert said in to["time_axis"] and to["span_h"] is None and to["span_rows"] == len(timed) - 1
        assert to["drift"]["drift_nT_per_h"] is None
        assert abs(to["drift"]["drift_nT_per_row"] * (len(timed) - 1) - 4.0) < 0.2 and to["drift"]["significant"]


def test_the_command_says_a_drift_per_row_and_the_folds_out_of_range_and_the_reference_not_used(tmp_path, capsys):
    d = fixed(seed=8, n=600)
    path = tmp_path / "fixed.csv"
    pd.DataFrame({"bx": d.raw_nT[:, 0], "by": d.raw_nT[:, 1], "bz": d.raw_nT[:, 2], "f_ref": d.f_ref_nT}).to_csv(
        path, index=False)
    assert main(["diagnose", str(path)]) == 0
    out = capsys.readouterr().out
    assert "nT per 1000 rows" in out and "nT/h" not in out and "no t column" in out
    assert main(["diagnose", str(path), "--folds", "1000"]) == 2  # a fixed sensor uses no folds: still refused
    assert "--folds must be at most 100 for 600 readings" in capsys.readouterr().err
    assert main(["diagnose", str(path), "--field", "50000", "--json"]) == 0
    assert "--field was not used" in json.loads(capsys.readouterr().out)["reference_ignored"]
    assert main(["diagnose", str(path), "--json"]) == 0  # the control: nothing given beside f_ref, nothing said
    assert "reference_ignored" not in json.loads(capsys.readouterr().out)


def test_a_clock_needs_ten_different_times_and_a_sample_index_is_no_clock():
    """Two different times (most rows sharing one) or a t column the file calls a sample index give the drift per
    row; their 'drift' in nT/h had come from two time points, or had taken samples for seconds."""
    d = fixed(seed=9, n=600)
    two = np.where(np.arange(600) < 300, 0.0, 1.0)
    to = diagnose(Dataset(d.raw_nT, f_ref_nT=d.f_ref_nT, t_s=two))["time_only"]
    assert "only 2 different times" in to["time_axis"] and to["drift"]["drift_nT_per_h"] is None
    indexed = Dataset(d.raw_nT, f_ref_nT=d.f_ref_nT, t_s=np.arange(600.0), meta={"t_note": "t is the sample index"})
    to = diagnose(indexed)["time_only"]
    assert "counts samples" in to["time_axis"] and to["drift"]["drift_nT_per_h"] is None
    to = diagnose(Dataset(d.raw_nT, f_ref_nT=d.f_ref_nT, t_s=np.arange(600.0)))["time_only"]  # control: 1 Hz seconds
    assert to["time_axis"] == "the t column" and to["drift"]["drift_nT_per_h"] is not None


def test_a_drift_over_a_tiny_time_span_keeps_its_standard_error():
    """A t column spanning 1e-9 h had fallen below the pseudo-inverse's cutoff: a standard error of 0 and a
    'significant' drift.  The drift and its error scale with the time unit together."""
    d = fixed(seed=10, n=600)
    base = diagnose(d)["time_only"]["drift"]
    tiny = diagnose(Dataset(d.raw_nT, f_ref_nT=d.f_ref_nT, t_s=d.t_s / 1e11, temp_C=d.temp_C))["time_only"]["drift"]
    assert tiny["drift_se_nT_per_h"] > 0
    assert abs(tiny["drift_nT_per_h"] / tiny["drift_se_nT_per_h"] - base["drift_nT_per_h"] / base["drift_se_nT_per_h"]) < 0.05


def test_a_glitched_timestamp_is_refused_and_a_gap_is_not(tmp_path, capsys):
    """One row's time far from both neighbours' (0 among Unix seconds) had hidden a 20 nT/h drift ('not
    significant', a span of 47,000 h) and, on a rotating record, failed the lag's derivatives (an internal error);
    a record whose time jumps and stays (a gap) is diagnosed."""
    d = fixed(seed=11, n=600)
    t = 1.7e9 + d.t_s
    glitched = t.copy()
    glitched[100] = 0.0
    path = tmp_path / "glitch.csv"
    pd.DataFrame({"t": glitched, "bx": d.raw_nT[:, 0], "by": d.raw_nT[:, 1], "bz": d.raw_nT[:, 2],
                  "f_ref": d.f_ref_nT}).to_csv(path, index=False)
    assert main(["diagnose", str(path)]) == 2
    err = capsys.readouterr().err
    assert "glitched time: row 100 (line 102) reads 0 s" in err and err.count("\n") == 1
    gap = t.copy()
    gap[300:] += 1e7  # the logger paused for four months
    assert diagnose(Dataset(d.raw_nT, f_ref_nT=d.f_ref_nT, t_s=gap))["kind"] == "time_only"


def test_a_few_readings_written_again_in_turn_are_refused():
    d = fixed(seed=12, n=600)
    cycled = d.raw_nT[np.arange(600) % 3]  # three readings, never the same twice in a row
    with pytest.raises(InputError, match="only 3 different values"):
        diagnose(Dataset(cycled, f_ref_nT=d.f_ref_nT, t_s=d.t_s))


def test_too_few_readings_of_a_fixed_sensor_are_refused_with_the_fixed_sensors_minimum():
    """Nine readings had been told a rotating sensor's minimum ('need at least 19') while ten get an answer."""
    d = fixed(seed=13, n=10)
    with pytest.raises(InputError, match="9 readings of a fixed sensor are too few: its time-only answer needs at least 10"):
        diagnose(Dataset(d.raw_nT[:9], f_ref_nT=d.f_ref_nT[:9], t_s=d.t_s[:9]))
    assert diagnose(d)["kind"] == "time_only"  # the control: ten
