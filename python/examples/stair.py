"""docs/PYTHON.md's worked example: fit the shipped stair with mckibben.fit,
then with SciPy's differential evolution over the same batch evaluator, and
plot both loops over the measured one.

    python python/examples/stair.py [FIGURE]   # from the repository root

FIGURE defaults to docs/figures/python/stair_loop.svg.
"""

import sys
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from scipy.optimize import differential_evolution  # noqa: E402

import mckibben  # noqa: E402

stair = mckibben.read_csv("data/stair_4.5kg.csv")

# 1. The staged fit of `mckibben fit` (same defaults, same seed, same bits).
result = mckibben.fit(stair, seed=1)
assert result.model is not None, "every candidate diverged"
print(result)
print({k: round(v, 6) for k, v in result.params.items()})

# 2. SciPy's differential evolution on the same objective, a whole
#    population per call (SciPy passes (d, S) arrays: `for_scipy`).
ev = mckibben.Evaluator(stair, backend="cpu")
start = time.perf_counter()
de = differential_evolution(
    ev.for_scipy, ev.bounds, vectorized=True, updating="deferred",
    popsize=100, maxiter=300, tol=0, polish=False, seed=1,
)
scipy_seconds = time.perf_counter() - start
scipy_model = ev.model(de.x)
# popsize · d candidates a generation, the initial population included.
candidates = (de.nit + 1) * 100 * ev.dim
print(f"scipy: SSE {de.fun:.6g}, {candidates} candidates, {scipy_seconds:.2f} s")

scipy_val = ev.validate(de.x)  # scored as fit scores its own
print(f"scipy: validation fit {scipy_val['val_fit_percent']:.4f} %")

# 3. The loop: displacement against pressure, measured and fitted.
y = stair.output
fig, ax = plt.subplots(figsize=(6, 4.5))
ax.plot(stair.input, y, ".", ms=2, color="0.6", label="measured", rasterized=True)
ax.plot(stair.input, result.model.simulate(stair.input, x0=y[0]), lw=1.2,
        label=f"mckibben.fit ({result.val_fit_percent:.1f} %)")
ax.plot(stair.input, scipy_model.simulate(stair.input, x0=y[0]), lw=1, ls="--",
        label=f"SciPy DE on Evaluator ({scipy_val['val_fit_percent']:.1f} %)")
ax.set_xlabel(f"{stair.input_name} (MPa)")
ax.set_ylabel(f"{stair.output_name} (mm)")
ax.set_title("Shipped 4.5 kg stair: hysteresis loop (validation fit %)")
ax.legend(loc="upper left")
fig.tight_layout()
fig.savefig(sys.argv[1] if len(sys.argv) > 1 else "docs/figures/python/stair_loop.svg",
            dpi=150, metadata={"Date": None})
