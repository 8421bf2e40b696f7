"""twin: the rig twin's experiments as Traces, the runs `mckibben twin` makes."""

import collections
import subprocess

import numpy as np
import pytest

import mckibben
from conftest import STAIR


def same_samples(a, b):
    """Every sample of every column equal, to the bit, and the same names."""
    assert (a.time_name, a.input_name, a.output_name) == (b.time_name, b.input_name, b.output_name)
    assert np.array_equal(a.t, b.t)
    assert np.array_equal(a.input, b.input) and np.array_equal(a.output, b.output)
    assert list(a.extra) == list(b.extra)
    for name, values in a.extra.items():
        assert np.array_equal(values, b.extra[name]), name


def test_the_default_run_is_the_shipped_stair(stair):
    # data/stair_4.5kg.csv was written by `mckibben twin --experiment stair
    # --load 4.5 --seed 1`, which the defaults are.
    run = mckibben.twin()
    same_samples(run, stair)
    assert run.source == "mckibben twin --experiment stair --load 4.5 --seed 1"
    assert run.source in STAIR.read_text().splitlines()[0]


def test_a_run_with_effects_is_the_commands_file(binary, tmp_path):
    out = tmp_path / "multisine.csv"
    subprocess.run(
        [binary, "twin", "--experiment", "multisine", "--load", "7", "--seed", "3",
         "--effect", "friction=2", "--effect", "creep=1", "--out", out],
        check=True, capture_output=True,
    )
    # Any mapping, its order kept in the command it names.
    effects = collections.OrderedDict([("friction", 2), ("creep", 1.0)])
    run = mckibben.twin("Multisine", load=7, seed=3, effects=effects)
    same_samples(run, mckibben.read_csv(out))
    assert run.source.endswith("--effect friction=2 --effect creep=1")
    # The seed draws the multisine's phases and the noise: another differs.
    other = mckibben.twin("multisine", load=7, seed=4, effects=effects)
    assert not np.array_equal(other.input, run.input)


def test_the_sine_tracks_at_its_frequency():
    run = mckibben.twin("sine", freq=3, load=7)
    assert run.source == "mckibben twin --experiment sine --load 7 --seed 1 --freq 3"
    # Past its settling the reference is 30 + 10·sin(3 t + φ) mm.
    late = run.t >= 10
    t, r = run.t[late], run.extra["reference"][late]
    basis = np.column_stack([np.ones_like(t), np.sin(3 * t), np.cos(3 * t)])
    coef, *_ = np.linalg.lstsq(basis, r, rcond=None)
    assert np.abs(basis @ coef - r).max() < 1e-9
    assert coef[0] == pytest.approx(30) and np.hypot(coef[1], coef[2]) == pytest.approx(10)
    # The muscle follows it under the thesis' PI.
    assert np.ptp(run.output[late]) == pytest.approx(20, rel=0.3)


def test_a_twin_run_is_refused_in_the_arguments_words():
    with pytest.raises(ValueError, match=r"^freq sets the sine's frequency: experiment=\"sine\" \(got experiment=\"stair\"\)"):
        mckibben.twin("stair", freq=2)
    with pytest.raises(ValueError, match="^unknown experiment `steps`: expected stair, sine or multisine"):
        mckibben.twin("steps")
    with pytest.raises(ValueError, match="^unknown effect `fricton`; known: friction, "):
        mckibben.twin(effects={"fricton": 0})
    with pytest.raises(ValueError, match=r"^effect noise: scale must be a finite number ≥ 0 \(got -1\)"):
        mckibben.twin(effects={"noise": -1})
    with pytest.raises(ValueError, match=r"^`load=0`: expected a mass in kg above 0"):
        mckibben.twin(load=0)
    with pytest.raises(ValueError, match=r"^`freq=400`: the twin samples every 0.01 s"):
        mckibben.twin("sine", freq=400)
    # A swing that would leave the muscle slack is outside the twin's physics.
    with pytest.raises(ValueError, match=r"^the load's ringing leaves the muscle slack from 4.110 s on"):
        mckibben.twin(effects={"ringing": 20})
    with pytest.raises(TypeError, match="^effects must be a dict of scales by name"):
        mckibben.twin(effects=["friction=0"])
    with pytest.raises(TypeError, match=r'^effects\["friction"\] must be a number'):
        mckibben.twin(effects={"friction": True})
    with pytest.raises(TypeError, match="^load must be a number"):
        mckibben.twin(load="4.5")
