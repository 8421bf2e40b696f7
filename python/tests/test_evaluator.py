"""Evaluator: the batch evaluator as an objective, for SciPy and ask/tell."""

import struct
import time
import warnings

import numpy as np
import pytest

import mckibben
from conftest import missing


def draw(ev, n, seed=1):
    """n candidates uniform in the evaluator's box."""
    lo, hi = np.array(ev.bounds).T
    return np.random.default_rng(seed).uniform(lo, hi, size=(n, ev.dim))


@pytest.fixture(scope="module")
def ev(stair):
    return mckibben.Evaluator(stair, backend="cpu")


def test_the_box_is_the_fits(ev, small_fit):
    assert ev.names == ["alpha", "loading", "beta_range", "a", "gain", "offset", "x0_range"]
    assert ev.dim == 7 and len(ev.bounds) == 7 and ev.samples == 2000
    assert list(small_fit.search_box["names"]) == ["A", *ev.names[:3], "n", *ev.names[3:]]
    assert ev.param_names == list(small_fit.params)


def test_an_evaluator_scores_the_fits_sse_bit_for_bit(ev, stair, cli, tmp_path):
    fitted = cli("fit", stair.source, "--backend", "cpu", "--seed", "1", "--out", tmp_path)
    params = np.array(list(fitted["params"].values()))
    assert struct.pack("<d", ev.score_params(params)) == struct.pack("<d", fitted["sse"])
    # The same point as search coordinates, one row of a population.
    theta = ev.to_thetas(params)
    assert np.allclose(ev.to_params(theta), params, rtol=1e-12, atol=0)
    population = np.vstack([draw(ev, 5), theta])
    assert ev(population)[-1] == pytest.approx(fitted["sse"], rel=1e-5)
    assert ev.model(theta).params == pytest.approx(fitted["params"], rel=1e-12)
    scores = ev.validate(theta)
    assert scores["val_fit_percent"] == pytest.approx(fitted["val_fit_percent"], rel=1e-6)


def test_any_dtype_layout_or_list_gives_the_same_bits(ev):
    thetas = draw(ev, 64)
    sse = ev(thetas)
    assert sse.shape == (64,) and sse.dtype == np.float64
    assert np.array_equal(ev(np.asfortranarray(thetas)), sse, equal_nan=True)
    assert np.array_equal(ev(thetas.tolist()), sse, equal_nan=True)
    assert np.array_equal(ev(np.vstack([thetas, thetas])[::2]), sse, equal_nan=True)
    single = ev(thetas[3])
    assert isinstance(single, float) and single == sse[3] or np.isnan(single) and np.isnan(sse[3])
    f32 = thetas.astype(np.float32)
    assert np.array_equal(ev(f32), ev(f32.astype(np.float64)), equal_nan=True)


def test_unchecked_is_the_batch_evaluator_alone(stair):
    # In the free box some loops leave the bounded class: the check scores
    # them +inf, where the batch evaluator alone scores them finite.
    checked = mckibben.Evaluator(stair, backend="cpu", loop="free")
    raw = mckibben.Evaluator(stair, backend="cpu", loop="free", checked=False)
    thetas = draw(checked, 2000, seed=2)
    strict, plain = checked(thetas), raw(thetas)
    kept = np.isfinite(strict)
    assert np.array_equal(strict[kept], plain[kept])
    assert np.all(np.isposinf(strict[~kept]))
    assert np.any(np.isfinite(plain[~kept])), "the check rejected nothing the batch kept"


def test_the_gpu_gives_the_cpus_bits(stair, ev):
    try:
        gpu = mckibben.Evaluator(stair, backend="gpu")
    except RuntimeError as e:
        missing(f"no Vulkan adapter for the GPU evaluator ({e})")
    thetas = draw(ev, 300, seed=5)
    for checked in (True, False):
        cpu = mckibben.Evaluator(stair, backend="cpu", checked=checked)
        gpu = mckibben.Evaluator(stair, backend="gpu", checked=checked)
        a, b = cpu(thetas), gpu(thetas)
        assert a.tobytes() == b.tobytes(), (gpu.backend, np.flatnonzero(a != b)[:5])


def test_scipy_differential_evolution_runs_vectorized(ev, stair):
    try:
        import scipy.optimize as optimize
    except ImportError as e:
        missing(f"SciPy is not installed ({e})")
    start = time.perf_counter()
    result = optimize.differential_evolution(
        ev.for_scipy,
        ev.bounds,
        vectorized=True,
        updating="deferred",
        seed=1,
        maxiter=40,
        popsize=10,
        tol=0,
        polish=False,
    )
    seconds = time.perf_counter() - start
    assert np.isfinite(result.fun) and result.x.shape == (ev.dim,)
    assert ev(result.x) == pytest.approx(result.fun)
    fit = ev.model(result.x).simulate(stair.input, x0=stair.output[0])
    assert np.isfinite(fit).all()
    print(f"scipy DE: SSE {result.fun:.6g} after {result.nfev} evaluations in {seconds:.2f} s")


def test_an_ask_tell_loop(ev):
    # Ask a population, tell its SSEs, keep the best, ask around it.
    rng = np.random.default_rng(7)
    lo, hi = np.array(ev.bounds).T
    asked = draw(ev, 64, seed=7)
    first_best = np.nanmin(ev(asked))
    best, best_sse = None, np.inf
    for _ in range(10):
        told = ev(asked)
        told = np.where(np.isnan(told), np.inf, told)
        i = int(np.argmin(told))
        if told[i] < best_sse:
            best, best_sse = asked[i], told[i]
        asked = np.clip(best + rng.normal(scale=0.02, size=(32, ev.dim)) * (hi - lo), lo, hi)
    # The loop moved: what it kept scores lower than the first population's
    # best, and scoring it again gives the SSE it was told.
    assert best_sse < first_best
    assert ev(best) == best_sse


@pytest.mark.parametrize(
    "thetas, error, message",
    [
        (np.zeros((3, 5)), ValueError, r"an \(N, 7\) array"),
        (np.zeros((0, 7)), ValueError, "no candidate"),
        (np.full((2, 7), np.nan), ValueError, r"thetas\[0, 0\] is NaN"),
        (np.zeros((2, 2, 7)), ValueError, r"got shape \(2, 2, 7\)"),
        (np.zeros((2, 7), dtype=complex), TypeError, "expected real numbers"),
        ([["a"] * 7], TypeError, "expected real numbers"),
        ("thetas", TypeError, "^thetas must be an array of numbers .*, got str 'thetas'"),
        (None, TypeError, "^thetas must be an array of numbers .*, got None"),
    ],
)
def test_bad_candidates_raise_the_named_exception(ev, thetas, error, message):
    with pytest.raises(error, match=message):
        ev(thetas)


@pytest.mark.parametrize(
    "column, value, message",
    [
        (2, 1e308, r"^params\[1\] maps to a non-finite search coordinate: loading \(column 1\) is inf"),
        (4, 1e308, r"^params\[1\]: n is 1e308, where this Evaluator's box holds it at 1"),
        (7, -1e308, r"^params\[1\] maps to a non-finite search coordinate: offset \(column 5\) is -inf"),
    ],
)
def test_parameters_too_large_for_the_box_are_refused(ev, column, value, message):
    # They mapped to inf or NaN coordinates, silently.
    params = np.tile([1.0, 0.9, 0.001, -0.001, 1.0, 0.99, -0.0025, -1.3, 8.3], (2, 1))
    assert np.all(np.isfinite(ev.to_thetas(params)))
    params[1, column] = value
    with pytest.raises(ValueError, match=message):
        ev.to_thetas(params)


def test_parameters_the_box_holds_elsewhere_are_refused(stair):
    # They mapped to coordinates that score the hold (n = 1), silently.
    params = np.tile([1.0, 0.9, 0.001, -0.001, 1.0, 0.99, -0.0025, -1.3, 8.3], (2, 1))
    params[1, 4] = 1.5
    held = mckibben.Evaluator(stair, backend="cpu")
    with pytest.raises(ValueError, match=r"^params\[1\]: n is 1.5, where this Evaluator's box "
                       r"holds it at 1 \(free_n=False\): .*; free_n=True searches it$"):
        held.to_thetas(params)
    free = mckibben.Evaluator(stair, backend="cpu", free_n=True)
    assert free.to_params(free.to_thetas(params))[1, 4] == pytest.approx(1.5, rel=1e-12)
    params[1, 4] = 1e308
    with pytest.raises(ValueError, match=r"^params\[1\] maps to a non-finite search coordinate: "
                       r"loading \(column 1\) is NaN"):
        free.to_thetas(params)
    held_at_two = mckibben.Evaluator(stair, backend="cpu", free_n=True, bounds={"n": (2.0, 2.0)})
    with pytest.raises(ValueError, match=r"^params\[0\]: n is 1, where .* holds it at 2 "
                       r"\(`bounds`\): .* would use 2$"):
        held_at_two.to_thetas(params)


def test_bad_construction_raises(stair):
    with pytest.raises(ValueError, match="unknown model family"):
        mckibben.Evaluator(stair, model="bouc")
    with pytest.raises(ValueError, match="linear model"):
        mckibben.Evaluator(stair, model="linear")
    with pytest.raises(ValueError, match="differ in length"):
        mckibben.Evaluator(stair.input, stair.output[:10], 0.01)
    # What is missing is named, not both; a list of Traces is one too many.
    with pytest.raises(ValueError, match="^give the sample time dt with the arrays u and y"):
        mckibben.Evaluator(stair.input, stair.output)
    with pytest.raises(ValueError, match="^give the output y with the input u and dt"):
        mckibben.Evaluator(stair.input, dt=0.01)
    with pytest.raises(ValueError, match="^u is a list of Traces, and this takes one experiment"):
        mckibben.Evaluator([stair, stair])
    # fit takes a list, each Trace with its own output and sample time.
    with pytest.raises(ValueError, match="^u is a list of Traces, each with its own output"):
        mckibben.fit([stair], stair.output, pop=20, gens=2)
    with pytest.raises(ValueError, match="no parameter `zeta`"):
        mckibben.Evaluator(stair, bounds={"zeta": 1.0})
    # An effect's parameter: the family's box has none (it was left out).
    with pytest.raises(ValueError, match="`creep.rho` names an effect's parameter"):
        mckibben.Evaluator(stair, bounds={"creep.rho": 0.5})
    # A wrong type names its argument (PyO3 names it only in a note).
    with pytest.raises(TypeError, match="^checked must be True or False, got int 1"):
        mckibben.Evaluator(stair, checked=1)
    with pytest.raises(TypeError, match="^model must be a str, got None"):
        mckibben.Evaluator(stair, model=None)
    with pytest.raises(TypeError, match="^dt must be a number .*, got bool True"):
        mckibben.Evaluator(stair.input, stair.output, True)


def test_a_box_with_nothing_free_is_refused_as_fit_refuses_it(stair, ev):
    # Every search coordinate held: the evaluator panicked on a call, or
    # scored three rows of nothing as no SSE at all.
    held = {name: (lo + hi) / 2 for name, (lo, hi) in zip(ev.names, ev.bounds)}
    with pytest.raises(ValueError, match="the search space has no free parameter"):
        mckibben.Evaluator(stair, backend="cpu", bounds=held)
    with pytest.raises(ValueError, match="the search space has no free parameter"):
        mckibben.fit(stair, bounds=held, pop=20, gens=2)


def test_coordinates_outside_the_box_are_warned_of(stair):
    # A model fitted with another box came back as coordinates this box does
    # not hold, without a word.
    # The default fit's model (docs/JSON.md), alpha moved to 0.9.
    params = np.array([1.0, 0.9, 2.76575e-05, 0.00610709, 1.0, 0.976411, 4.75674, -3.59365, 1.51339])
    narrow = mckibben.Evaluator(stair, backend="cpu", bounds={"alpha": (0.0, 0.5)})
    with pytest.warns(UserWarning, match=r"^params\[0\]: alpha is 0.9 in the search coordinates, "
                      r"outside this Evaluator's box \[0, 0.5\]: scoring the coordinates, or "
                      r"`to_params`, takes it to the box's edge, 0.5"):
        theta = narrow.to_thetas(params)
    # As the warning says: the coordinates stand for the model at the edge.
    assert narrow.to_params(theta)[1] == 0.5
    edge = params.copy()
    edge[1] = 0.5
    assert narrow(theta[None, :])[0] == narrow.score_params(edge)
    wide = mckibben.Evaluator(stair, backend="cpu")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        wide.to_thetas(params)
