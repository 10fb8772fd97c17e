"""cmaes maps its population into the box itself (``into_box``) instead of handing pycma the bounds, which
mapped and looked up each solution in Python (40 % of a fit's time on 300 readings).  The search must be the
same to the last bit: the map against pycma's own transformation, and whole fits against the former code
(pycma given ``bounds=[0, 1]`` and told the phenotypes), kept here as the reference."""
import numpy as np
import pytest
from cma.transformations import BoxConstraintsLinQuadTransformation

from magbench.calibrators import make
from magbench.calibrators.core import loop
from magbench.calibrators.core.problem import SolveOutput
from magbench.calibrators.methods.cmaes import CMAES, into_box
from magbench.simulate import simulate
from magbench.simulate.scenarios import get_scenario


def test_into_box_is_pycmas_map_to_the_last_bit():
    rng = np.random.default_rng(5)
    # inside, in both margins, beyond the reflections and many periods away
    y = np.concatenate([rng.uniform(-0.2, 1.2, (400, 9)), rng.normal(0.5, 3.0, (400, 9)),
                        rng.normal(0.5, 300.0, (50, 9)), np.array([[0.0, 1.0, 0.05, 0.95, -0.05, 1.05, -0.6, 1.6,
                                                                     0.5]])])
    tf = BoxConstraintsLinQuadTransformation([[0.0, 1.0]])
    expected = np.array([tf(row.copy()) for row in y])
    got = into_box(y)
    assert np.array_equal(got, expected)
    assert np.all((got >= 0) & (got <= 1))


def test_into_box_changes_the_folded_values_only():
    """Negative control: the identity inside [0.05, 0.95], not elsewhere (a map that did nothing would
    pass the bounds check above only by luck)."""
    inner = np.linspace(0.05, 0.95, 91)[None, :]
    assert np.array_equal(into_box(inner), inner)
    outer = np.array([[-0.3, 1.3, 0.01, 0.99]])
    assert not np.any(into_box(outer) == outer)


class _BoundedReference(CMAES):
    """cmaes as it was: pycma given the bounds, told the phenotypes it returned."""

    def _solve(self, problem):
        import cma

        lo, hi = problem.lower, problem.upper
        span = hi - lo
        rng = problem.rng
        options = {"bounds": [0.0, 1.0], "maxfevals": int(problem.termination.max_evaluations or self.max_evaluations),
                   "tolfun": self.tolfun, "tolx": self.tolx, "verbose": -9, "seed": np.nan, "signals_filename": "",
                   "randn": lambda lam, n: rng.standard_normal((lam, n))}
        es = cma.CMAEvolutionStrategy(np.clip((problem.x0 - lo) / span, 0.0, 1.0), self.sigma0, options)
        generations, bests, stop = 0, [], ""
        window = 10 + int(np.ceil(30 * len(lo) / es.popsize))
        while not es.stop():
            u = np.asarray(es.ask())
            f = yield loop.values(lo + u * span)
            es.tell(list(u), f.tolist())
            generations += 1
            bests.append(f.min())
            flat = np.inf
            if generations > window:
                recent = bests[-window:]
                spread, best = max(f.max() - f.min(), max(recent) - min(recent)), abs(min(bests))
                flat = spread / best if best else (0.0 if spread == 0 else np.inf)
            stop = yield loop.iteration(flat)
            if stop:
                break
        stops = ["tolfun_rel"] if stop == "converged" else ["maxfevals"] if stop else list(es.stop())
        return SolveOutput(problem.best_x, status="max_evaluations" if "maxfevals" in stops else "converged",
                           message=f"{generations} generations of {es.popsize}; stop: {', '.join(stops)}",
                           nit=generations, extra={"generations": generations, "population": es.popsize})


@pytest.mark.parametrize("scenario, data_seed, seed", [("sphere9", 0, 0), ("cap9", 1, 3), ("vehicle9", 2, 7),
                                                       ("lu2014", 3, 1)])
def test_fit_is_the_bounded_pycma_search(scenario, data_seed, seed):
    data = simulate(scenario, data_seed)
    model = get_scenario(scenario).model
    ours = make("cmaes", model=model, seed=seed).fit(data)
    ref = _BoundedReference(model=model, seed=seed).fit(data)
    assert ours.n_evaluations == ref.n_evaluations and ours.nit == ref.nit and ours.status == ref.status
    assert np.array_equal(ours.params.to_vector(model), ref.params.to_vector(model))
