"""Model: the model file the command writes and reads, and simulation."""

import json
import os
import re

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


def test_saving_to_a_folder_says_so(small_fit, tmp_path):
    # The OS said only "Is a directory" or "Not a directory".
    folder = tmp_path / "models"
    folder.mkdir()
    expected = f"{folder} is a folder: give the model file's path (such as {folder}/model.json)"
    with pytest.raises(IsADirectoryError, match="^" + re.escape(expected)):
        small_fit.model.save(folder)
    for path in (f"{folder}/", f"{tmp_path}/new/"):
        expected = f"{path} ends in a separator, so it names a folder: give the model file's path (such as {path}model.json)"
        with pytest.raises(IsADirectoryError, match="^" + re.escape(expected)):
            small_fit.model.save(path)
    assert list(folder.iterdir()) == [] and not (tmp_path / "new").exists()


def test_load_errors(tmp_path):
    # As `open` raises it: the OS's words, and the file in `filename`.
    with pytest.raises(FileNotFoundError, match=r"^\[Errno 2\] No such file or directory: ") as raised:
        mckibben.Model.load(tmp_path / "missing.json")
    assert raised.value.filename == str(tmp_path / "missing.json")
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
    # A Trace runs from its first measured output, as the command runs a CSV.
    assert np.array_equal(model.simulate(stair), y)
    strided = np.repeat(stair.input, 2)[::2]
    assert np.array_equal(model.simulate(list(strided), x0=stair.output[0]), y)
    assert model.simulate([0.1, 0.2, 0.3]).shape == (3,)
    # Without x0 the model starts at rest at the first input: held there,
    # its output does not move.
    held = model.simulate(np.full(300, 0.2))
    assert np.ptp(held) < 1e-3
    with pytest.raises(ValueError, match="x0 must be a finite"):
        model.simulate(stair.input, x0=float("nan"))
    with pytest.raises(ValueError, match="u is empty"):
        model.simulate([])
    # A number is not a series of one sample.
    with pytest.raises(ValueError, match="a single number"):
        model.simulate(0.3)
    # Text or None is not an array: a TypeError naming the argument.
    with pytest.raises(TypeError, match="^u must be an array of numbers .*, got str 'stair.csv'"):
        model.simulate("stair.csv")
    # A Trace in other units of the same kinds runs the model converted
    # into them, with a warning: the run is in the Trace's units.
    in_kpa = mckibben.Trace(stair.input * 1000, stair.output / 1000, stair.dt, input_name="p_kPa", output_name="x_m")
    with pytest.warns(UserWarning, match=r"the model's `pressure` \(MPa\) is read in kPa"):
        metres = model.simulate(in_kpa)
    mm = model.simulate(stair)
    assert np.allclose(metres * 1000, mm, rtol=0, atol=1e-4 * np.ptp(mm))
    # Units of another kind, or another sample time, are refused as
    # `simulate --from` refuses such a file.
    in_volts = mckibben.Trace(stair.input, stair.output, stair.dt, input_name="valve_V")
    with pytest.raises(ValueError, match="the model's input is in MPa .* `valve_V` is in V"):
        model.simulate(in_volts)
    slower = mckibben.Trace(stair.input, stair.output, 2 * stair.dt)
    with pytest.raises(ValueError, match="sampled every 0.02 s, the model every 0.01 s"):
        model.simulate(slower)
    with pytest.raises(TypeError, match="^u must be an array of numbers .*, got None"):
        model.simulate(None)
    with pytest.raises(ValueError, match="at least 2 samples"):
        mckibben.Trace([0.3], [1.0], 0.01)


@pytest.fixture(scope="module")
def creep_model(stair):
    """A model with an effect chain (classic + creep), quickly fitted."""
    return mckibben.fit(stair, pop=40, gens=10, seed=2, effects=["creep"]).model


def test_a_model_with_effects_saves_loads_and_names_its_parameters(creep_model, tmp_path):
    path = tmp_path / "model.json"
    creep_model.save(path)
    again = mckibben.Model.load(path)
    assert again == creep_model and again.effects == ["creep"]
    assert list(again.params)[9:] == ["creep.rho", "creep.kappa", "creep.z0"]
    on_disk = json.loads(path.read_text())
    assert on_disk["format"] == "mckibben-model" and on_disk["version"] == 2
    assert on_disk["effects"] == ["creep"] and on_disk["params"] == again.params
    assert on_disk["search_box"]["names"][-3:] == ["creep.rho", "creep.kappa", "creep.z0"]
    # Saved again, the same bytes: the file keeps its box and provenance.
    again.save(tmp_path / "again.json")
    assert (tmp_path / "again.json").read_bytes() == path.read_bytes()
    assert "classic + creep" in repr(again)
    # Each parameter's unit, in the units the model's columns state.
    assert list(again.units) == list(again.params)
    assert {k: again.units[k] for k in ["alpha", "beta", "b", "x0", "creep.kappa", "creep.z0"]} == {
        "alpha": "1", "beta": "1/mm", "b": "mm/MPa", "x0": "mm", "creep.kappa": "mm/MPa", "creep.z0": "mm"}


def test_a_chain_simulates_as_the_command_does(creep_model, stair, cli, tmp_path):
    creep_model.save(tmp_path / "model.json")
    out = tmp_path / "sim.csv"
    cli("simulate", "--from", tmp_path / "model.json", "--input", stair.source, "--out", out)
    lines = [l for l in out.read_text().splitlines() if not l.startswith("#")]
    column = lines[0].split(",").index("displacement")
    expected = np.array([float(l.split(",")[column]) for l in lines[1:]])
    y = creep_model.simulate(stair.input, x0=stair.output[0])
    assert np.array_equal(y, expected)
    # The chain changes the run: the baseline alone gives another output.
    assert not np.array_equal(y, mckibben.Model.load(tmp_path / "model.json").simulate(stair.input))


def test_a_version_1_file_still_loads(small_fit, tmp_path):
    m = small_fit.model
    legacy = {
        "family": "classic",
        "params": list(m.params.values()),
        "input_mean": m.input_mean,
        "output_mean": m.output_mean,
        "dt": m.dt,
        "input_name": m.input_name,
        "output_name": m.output_name,
    }
    path = tmp_path / "v1.json"
    path.write_text(json.dumps(legacy))
    assert mckibben.Model.load(path) == m


def test_a_model_fitted_in_python_names_its_time_column_for_the_command(stair, cli, tmp_path):
    rows = [f"{t:.17g},{p:.17g},{y:.17g}" for t, p, y in zip(stair.t[:600], stair.input[:600], stair.output[:600])]
    data = tmp_path / "rig.csv"
    data.write_text("time_s,pressure,displacement\n" + "\n".join(rows) + "\n")
    trace = mckibben.read_csv(data, time="time_s")
    path = tmp_path / "model.json"
    mckibben.fit(trace, pop=20, gens=5, seed=1).model.save(path)
    assert json.loads(path.read_text())["provenance"]["read"]["time"] == "time_s"
    # `simulate --from` reads the file as the model's data were read.
    assert cli("simulate", "--from", path, "--input", data)["samples"] == 600


def test_a_model_fitted_in_python_on_resampled_data_resamples_for_the_command(stair, cli, tmp_path):
    # A logger's clock: every sample up to 1 ms late, so the file is not
    # uniform and reads only resampled.
    late = 0.001 * (np.arange(600) % 3) / 2
    t = stair.t[:600] + late
    rows = [f"{a:.17g},{p:.17g},{y:.17g}" for a, p, y in zip(t, stair.input[:600], stair.output[:600])]
    data = tmp_path / "logger.csv"
    data.write_text("t,pressure,displacement\n" + "\n".join(rows) + "\n")
    with pytest.raises(ValueError, match="resample"):
        mckibben.read_csv(data)
    trace = mckibben.read_csv(data, resample=0.01)
    path = tmp_path / "model.json"
    mckibben.fit(trace, pop=20, gens=5, seed=1).model.save(path)
    read = json.loads(path.read_text())["provenance"]["read"]
    assert (read["time"], read["resample"], read["split_gaps"]) == ("t", 0.01, False)
    # `simulate --from` resamples the file as the model's data were.
    assert cli("simulate", "--from", path, "--input", data)["samples"] == len(trace)


def test_a_value_of_the_wrong_type_names_its_argument(small_fit):
    with pytest.raises(TypeError, match=r"^x0 must be a number \(an int or a float\), got str '1'"):
        small_fit.model.simulate([0.1, 0.2], x0="1")
    with pytest.raises(TypeError, match="^x0 must be a number .*, got bool True"):
        small_fit.model.simulate([0.1, 0.2], x0=True)
    with pytest.raises(TypeError, match="^path must be a file's path .*, got int 3"):
        mckibben.Model.load(3)
    with pytest.raises(TypeError, match="^path must be a file's path .*, got None"):
        small_fit.model.save(None)


def test_a_model_path_may_be_bytes(small_fit, stair, tmp_path):
    # As open() takes it (Model.load refused bytes).
    path = os.fsencode(tmp_path / "model.json")
    small_fit.model.save(path)
    assert mckibben.Model.load(path) == small_fit.model
    warm = mckibben.fit(stair, pop=20, gens=2, start=path)
    assert warm.start_sse is not None
