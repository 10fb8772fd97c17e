"""Every registered calibrator on fixed scenarios (lu2014 with the angles model, sphere9 with nine),
saved by pytest-benchmark so that a later run can be compared against it:

    python -m pytest benchmarks/suite/test_bench_calibrators.py --benchmark-autosave
    python -m pytest benchmarks/suite/test_bench_calibrators.py --benchmark-compare
"""
import pytest

from magbench.calibrators import available, make

CASES = [(name, scenario, model) for name, cls in sorted(available().items())
         for scenario, model in (("lu2014", "angles"), ("sphere9", "nine")) if model in cls.supported_models]


@pytest.mark.parametrize("name,scenario,model", CASES, ids=[f"{n}-{s}" for n, s, _ in CASES])
def test_calibrator(benchmark, request, name, scenario, model):
    data = request.getfixturevalue(scenario)
    benchmark.group = f"calibrators on {scenario} ({model})"
    cal = make(name, model=model, seed=0)
    res = benchmark.pedantic(cal.fit, args=(data,), rounds=3, iterations=1)
    benchmark.extra_info.update(evaluations=res.n_evaluations, rms_after_nT=res.rms_after_nT,
                                rms_before_nT=res.rms_before_nT)
