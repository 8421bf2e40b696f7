"""Type stubs of the `mckibben` extension module (docs/PYTHON.md)."""

import os
from typing import Any, Callable, Literal, Mapping, Sequence, final, overload

import numpy as np
import numpy.typing as npt

__version__: str
__all__ = [
    "__version__",
    "Trace",
    "Model",
    "FitResult",
    "Diagnosis",
    "ControlResult",
    "Identification",
    "Evaluator",
    "ScipyObjective",
    "read_csv",
    "fit",
    "diagnose",
    "identify",
    "twin",
    "control",
]

_ArrayLike = npt.ArrayLike
_Bound = tuple[float, float] | float
_Path = str | bytes | os.PathLike[str] | os.PathLike[bytes]

@final
class Trace:
    """One recorded experiment on a uniform time base."""

    def __new__(
        cls,
        input: _ArrayLike,
        output: _ArrayLike,
        dt: float,
        input_name: str = "pressure",
        output_name: str = "displacement",
        source: str = "python",
        time_name: str = "t",
    ) -> Trace: ...
    @property
    def source(self) -> str: ...
    @property
    def t(self) -> npt.NDArray[np.float64]: ...
    @property
    def input(self) -> npt.NDArray[np.float64]: ...
    @property
    def output(self) -> npt.NDArray[np.float64]: ...
    @property
    def time_name(self) -> str: ...
    @property
    def input_name(self) -> str: ...
    @property
    def output_name(self) -> str: ...
    @property
    def dt(self) -> float: ...
    @property
    def extra(self) -> dict[str, npt.NDArray[np.float64]]: ...
    def __len__(self) -> int: ...

@overload
def read_csv(
    path: _Path,
    input: str = "pressure",
    output: str = "displacement",
    time: str | None = None,
    resample: float | None = None,
    split_gaps: Literal[False] = False,
    dt: float | None = None,
) -> Trace: ...
@overload
def read_csv(
    path: _Path,
    input: str = "pressure",
    output: str = "displacement",
    time: str | None = None,
    resample: float | None = None,
    *,
    split_gaps: Literal[True],
    dt: float | None = None,
) -> list[Trace]: ...
@overload
def read_csv(
    path: _Path,
    input: str = "pressure",
    output: str = "displacement",
    time: str | None = None,
    resample: float | None = None,
    split_gaps: bool = False,
    dt: float | None = None,
) -> Trace | list[Trace]: ...

@final
class Model:
    """A fitted hysteresis model, a family and its effect chain: the model
    file `mckibben fit` and `diagnose --out` write."""

    @staticmethod
    def load(path: _Path) -> Model: ...
    def save(self, path: _Path) -> None: ...
    def simulate(self, u: _ArrayLike | Trace, x0: float | None = None) -> npt.NDArray[np.float64]:
        """Free-run output on `u`; `x0` is the measured output at the first
        sample (default: at rest at the first input; for a `Trace`, its
        first measured output). A `Trace` in other pressure or length units
        runs the model converted into them, with a `UserWarning`; one in
        units of another kind, or at another sample time than the model's,
        raises `ValueError`."""
    @property
    def params(self) -> dict[str, float]:
        """The family's parameters in canonical order, then the effects' as `effect.param`."""
    @property
    def units(self) -> dict[str, str]:
        """Each parameter's unit, by the names `params` holds (`"mm/MPa"`; `"1"`: a pure number)."""
    @property
    def effects(self) -> list[str]:
        """The effect stages after the family, in chain order."""
    @property
    def family(self) -> Literal["linear", "classic", "generalized"]: ...
    @property
    def stable_step(self) -> float | None:
        """The largest output step a sample within which the hysteresis update settles."""
    @property
    def dt(self) -> float: ...
    @property
    def input_mean(self) -> float: ...
    @property
    def output_mean(self) -> float: ...
    @property
    def input_name(self) -> str: ...
    @property
    def output_name(self) -> str: ...
    def __eq__(self, other: object, /) -> bool: ...

@final
class FitResult:
    """What `fit` returns: `mckibben fit --json`'s fields, the model, the history."""

    model: Model | None
    params: dict[str, float]
    sse: float
    val_rmse: float | None
    val_fit_percent: float | None
    linear_val_fit_percent: float | None
    linear_largest_pole: float | None
    records: list[dict[str, Any]]
    columns: dict[str, Any] | None
    notes: list[dict[str, str]]
    stable_step: float | None
    largest_step: float | None
    start_sse: float | None
    start_val_fit_percent: float | None
    built: dict[str, float | bool] | None
    switching: dict[str, float | bool] | None
    evaluations: int
    generations: int
    seconds: float
    backend: str
    family: str
    effects: list[str]
    algo: str
    flow: str
    overshoot: Literal["allow", "refuse"]
    seed: int
    population: int
    tries: int
    try_population: int
    try_sizes: list[dict[str, int]]
    agreement: dict[str, Any] | None
    refining: dict[str, Any] | None
    std_errors: dict[str, float | None]
    units: dict[str, str]
    undetermined: list[str]
    diverging_probes: list[str]
    stop: Literal["completed", "target-sse", "time-budget", "interrupted"]
    interrupted: bool
    stages: list[dict[str, Any]]
    on_edge: list[dict[str, Any]]
    widened: list[dict[str, Any]]
    search_box: dict[str, Any]
    history: dict[str, Any]

def fit(
    u: _ArrayLike | Trace | Sequence[Trace | tuple[_ArrayLike, _ArrayLike, float]],
    y: _ArrayLike | None = None,
    dt: float | None = None,
    model: Literal["classic", "generalized"] | None = None,
    effects: Sequence[str] | None = None,
    algo: Literal["de", "ga", "mfa", "pso"] = "de",
    pop: int | None = None,
    gens: int | None = None,
    seed: int = 1,
    backend: Literal["auto", "cpu", "gpu"] = "cpu",
    bounds: Mapping[str, _Bound] | None = None,
    progress: Callable[[dict[str, Any]], object] | None = None,
    *,
    free_n: bool = False,
    loop: Literal["bounded", "free"] = "bounded",
    switch: Literal["search", "starts", "mean", "zero"] | None = None,
    overshoot: Literal["refuse", "allow"] | None = None,
    thesis_flow: bool = False,
    target_sse: float | None = None,
    time_budget: float | None = None,
    stall: int | None = None,
    start: Model | _Path | None = None,
    carry: Model | _Path | None = None,
    refine_rounds: int | None = None,
) -> FitResult: ...

@final
class Evaluator:
    """The batch evaluator as an objective over the fit's search box."""

    def __new__(
        cls,
        u: _ArrayLike | Trace,
        y: _ArrayLike | None = None,
        dt: float | None = None,
        model: Literal["classic", "generalized"] = "classic",
        backend: Literal["auto", "cpu", "gpu"] = "auto",
        *,
        bounds: Mapping[str, _Bound] | None = None,
        free_n: bool = False,
        loop: Literal["bounded", "free"] = "bounded",
        checked: bool = True,
    ) -> Evaluator: ...
    def __call__(self, thetas: _ArrayLike) -> npt.NDArray[np.float64] | float:
        """N SSEs for an (N, d) array of candidates; a float for one vector of d."""
    @property
    def for_scipy(self) -> ScipyObjective: ...
    @property
    def bounds(self) -> list[tuple[float, float]]: ...
    @property
    def names(self) -> list[str]: ...
    @property
    def dim(self) -> int: ...
    @property
    def param_names(self) -> list[str]: ...
    @property
    def backend(self) -> str: ...
    @property
    def samples(self) -> int: ...
    @property
    def checked(self) -> bool: ...
    def to_params(self, thetas: _ArrayLike) -> npt.NDArray[np.float64]: ...
    def to_thetas(self, params: _ArrayLike) -> npt.NDArray[np.float64]: ...
    def score_params(self, params: _ArrayLike) -> npt.NDArray[np.float64] | float: ...
    def model(self, theta: _ArrayLike) -> Model: ...
    def validate(self, theta: _ArrayLike) -> dict[str, float]:
        """`val_rmse` and `val_fit_percent` of one candidate, as `fit` scores its own."""

@final
class ScipyObjective:
    """An Evaluator in SciPy's (d, S) layout."""

    def __call__(self, x: _ArrayLike) -> npt.NDArray[np.float64] | float: ...
    @property
    def evaluator(self) -> Evaluator: ...

def diagnose(
    datasets: Trace | Sequence[Trace | tuple[_ArrayLike, _ArrayLike, float]],
    baseline: Literal["classic", "generalized"] | None = None,
    effects: Sequence[str] | None = None,
    seed: int = 1,
    seeds: int | None = None,
    generations: int | None = None,
    scratch_seeds: int | None = None,
    backend: Literal["auto", "cpu", "gpu"] = "cpu",
    max_effects: int | None = None,
    start: Model | _Path | None = None,
    blocks: int | None = None,
    transfer: Trace | Sequence[Trace | tuple[_ArrayLike, _ArrayLike, float]] | None = None,
    repeat: int = 1,
) -> Diagnosis: ...

@final
class Diagnosis:
    """What `diagnose` returns: `mckibben diagnose --json`'s document and the
    models `diagnose --out` writes."""

    document: dict[str, Any]
    model: Model
    baseline: Model

def twin(
    experiment: Literal["stair", "sine", "multisine"] = "stair",
    load: float = 4.5,
    seed: int = 1,
    freq: float | None = None,
    effects: Mapping[str, float] | None = None,
) -> Trace:
    """An experiment on the rig twin, the recording `mckibben twin` writes."""

def control(
    controller: str | Sequence[str] | None = None,
    freq: float | Sequence[float] | None = None,
    load: float | Sequence[float] | None = None,
    *,
    seed: int = 1,
    model: Model | _Path | None = None,
    design_data: _Path | None = None,
    design_columns: Sequence[str] | None = None,
    design_load: float | None = None,
    hysteresis_scale: float | Sequence[float] | None = None,
    robustness: bool = False,
    tuned_gains: Sequence[float] | Mapping[str, float] | None = None,
    algo: Literal["ga", "mfa", "pso", "de"] | None = None,
    pop: int | None = None,
    gens: int | None = None,
    horizon: int | None = None,
    r_move: float | None = None,
    reference: Literal["sine", "steps"] = "sine",
    warmup: float | None = None,
    duration: float | None = None,
    steady_from: float | None = None,
    effects: Mapping[str, float] | None = None,
) -> ControlResult:
    """Closed-loop tracking on the rig twin, as `mckibben control` runs it."""

@final
class ControlResult:
    """What `control` returns: `mckibben control --json`'s document and each
    run's samples."""

    document: dict[str, Any]
    runs: list[dict[str, Any]]

def identify(
    u: Trace | _ArrayLike | Sequence[Trace | tuple[_ArrayLike, _ArrayLike, float]],
    y: _ArrayLike | None = None,
    dt: float | None = None,
    *,
    na: int = 1,
    nb: int = 1,
    nk: int = 1,
) -> Identification:
    """The thesis' ARX identification, as `mckibben identify --json` gives it."""

@final
class Identification:
    """What `identify` returns: `mckibben identify --json`'s document and,
    for the first order, its model."""

    document: dict[str, Any]
    model: Model | None
