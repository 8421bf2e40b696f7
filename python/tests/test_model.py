"""Model: the model file the command writes and reads, and simulation."""

import json

import numpy as np
import pytest

import mckibben


def test_a_model_saves_and_loads_the_file_the_command_writes(small_fit, tmp_path):
    model = small_fit.model
    path = tmp_path / "model.json"
    model.save(path)
    again = mckibben.Model.load(path)
    assert again == model
    assert again.params == model.params == small_fit.params
    assert list(model.params) == ["A", "alpha", "beta", "gamma", "n", "a", "b", "c", "x0"]
    assert model.effects == []
    assert model.family == "classic" and model.dt == pytest.approx(0.01)
    on_disk = json.loads(path.read_text())
    assert on_disk["family"] == "classic" and len(on_disk["params"]) == 9


def test_load_errors(tmp_path):
    with pytest.raises(FileNotFoundError, match="cannot read"):
        mckibben.Model.load(tmp_path / "missing.json")
    bad = tmp_path / "bad.json"
    bad.write_text('{"family": "classic"}')
    with pytest.raises(ValueError, match="not a model file"):
        mckibben.Model.load(bad)


def test_simulate_takes_any_layout_and_starts_where_asked(small_fit, stair):
    model = small_fit.model
    y = model.simulate(stair.input, x0=stair.output[0])
    assert y.shape == (len(stair),) and y.dtype == np.float64
    # x0 is the measured output at the first sample; the model starts at it
    # plus its start offset, the parameter x0.
    assert y[0] == pytest.approx(stair.output[0] + model.params["x0"], abs=1e-4)
    strided = np.repeat(stair.input, 2)[::2]
    assert np.array_equal(model.simulate(list(strided), x0=stair.output[0]), y)
    assert model.simulate([0.1, 0.2, 0.3]).shape == (3,)
    with pytest.raises(ValueError, match="x0 must be a finite"):
        model.simulate(stair.input, x0=float("nan"))
    with pytest.raises(ValueError, match="u is empty"):
        model.simulate([])
