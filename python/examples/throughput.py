"""docs/PYTHON.md's throughput check: Evaluator called from Python at
N = 10^5 (on canonical rows, as bench scores them, and on search
coordinates, which adds the map to canonical rows that the engine also
makes) beside `mckibben bench` on the same 2000 samples (the shipped
stair's estimation half, which Evaluator scores, written as its own file
for `bench`). Both on the CPU path, median of 5 calls after a warm-up;
five rounds, alternating, since other jobs share the machine.

    python python/examples/throughput.py [MCKIBBEN_BINARY]   # from the repository root
"""

import json
import statistics
import subprocess
import sys
import tempfile
import time

import numpy as np

import mckibben

N = 100_000
binary = sys.argv[1] if len(sys.argv) > 1 else "target/release/mckibben"
stair = mckibben.read_csv("data/stair_4.5kg.csv")
ev = mckibben.Evaluator(stair, backend="cpu", checked=False)
half = ev.samples
# The population `bench` draws (eval::workload::mixed_population): even rows
# uniform over the box (nearly all diverge), odd rows within ±5 % of the
# box's width around a good model (here the fit's; bench's: the thesis'),
# so that every 32-lane batch runs its whole length.
lo, hi = np.array(ev.bounds).T
rng = np.random.default_rng(1)
centre = ev.to_thetas(list(mckibben.fit(stair, seed=1).params.values()))
thetas = rng.uniform(lo, hi, size=(N, ev.dim))
near = centre + rng.uniform(-0.05, 0.05, size=(N // 2, ev.dim)) * (hi - lo)
thetas[1::2] = np.clip(near, lo, hi)

with tempfile.NamedTemporaryFile("w", suffix=".csv", delete=False) as f:
    f.write("t,pressure,displacement\n")
    for t, u, y in zip(stair.t[:half].tolist(), stair.input[:half].tolist(), stair.output[:half].tolist()):
        f.write(f"{t!r},{u!r},{y!r}\n")
    first_half = f.name


params = ev.to_params(thetas)


def python_rate(call, population):
    call(population)  # warm-up
    times = []
    for _ in range(5):
        start = time.perf_counter()
        call(population)
        times.append(time.perf_counter() - start)
    return N * half / statistics.median(times)


def bench_rate():
    out = subprocess.run(
        [binary, "bench", first_half, "--backend", "cpu", "--pop", str(N), "--repeats", "5", "--json"],
        check=True, capture_output=True, text=True,
    )
    row = json.loads(out.stdout)["rows"][0]
    assert row["samples"] == half
    return row["candidate_samples_per_s"]


diverged = np.mean(~np.isfinite(ev(thetas)))
print(f"{ev.backend}; N = {N}, {half} samples, {100 * diverged:.0f} % diverged")
print("candidate-samples/s: bench | ev.score_params (canonical rows, as bench) | ev(thetas) (search coordinates)")
rates = []
for round in range(5):
    rates.append((bench_rate(), python_rate(ev.score_params, params), python_rate(ev, thetas)))
    b, p, c = rates[-1]
    print(f"round {round + 1}: {b:.3e} | {p:.3e} ({p / b:.3f}) | {c:.3e} ({c / b:.3f})")
b, p, c = (statistics.median(r) for r in zip(*rates))
print(f"median: {b:.3e} | {p:.3e} ({p / b:.3f}) | {c:.3e} ({c / b:.3f})")
