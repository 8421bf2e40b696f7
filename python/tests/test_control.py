"""control: closed-loop tracking on the rig twin, the runs `mckibben control` makes."""

import csv
import json
import os
import pickle
import signal
import subprocess
import threading
import time
import warnings

import numpy as np
import pytest

import mckibben

# A short episode: 1 s at the bias, 4 s of reference, the last 2 s scored.
SHORT = dict(warmup=1, duration=4, steady_from=2)
SHORT_FLAGS = ["--warmup", "1", "--duration", "4", "--steady-from", "2"]
# What a run measures of the machine it ran on, not of the loop.
CLOCKS = {"max_step_time_us", "max_step_cpu_us", "mean_step_time_us", "overrun_steps"}


def without_clocks(document):
    runs = [{k: v for k, v in r.items() if k not in CLOCKS} for r in document["runs"]]
    return {**document, "runs": runs}


def command(binary, *flags):
    out = subprocess.run([binary, "control", *flags, "--json"], check=True, capture_output=True)
    return json.loads(out.stdout), out.stderr.decode()


def test_the_runs_are_the_commands(binary, tmp_path):
    document, _ = command(
        binary, "--controller", "pi,mpc", "--freq", "1,3", "--load", "7", *SHORT_FLAGS,
        "--csv", str(tmp_path),
    )
    result = mckibben.control(["pi", "MPC"], freq=[1, 3], load=7, **SHORT)
    assert without_clocks(result.document) == without_clocks(document)
    assert [(r["controller"], r["freq_rad_s"]) for r in result.runs] == [
        ("pi", 1.0), ("pi", 3.0), ("mpc", 1.0), ("mpc", 3.0)
    ]
    # Each run's samples are the columns its --csv file holds.
    for run in result.runs:
        name = f"control_{run['controller']}_7kg_{run['freq_rad_s']:g}rad"
        with open(tmp_path / f"{name}.csv") as f:
            rows = [r for r in csv.reader(line for line in f if not line.startswith("#"))]
        columns = dict(zip(rows[0], np.array(rows[1:], dtype=float).T))
        for key, column in [("t", "t"), ("pressure", "pressure"), ("displacement", "displacement"),
                            ("valve", "valve_in"), ("reference", "reference")]:
            assert np.array_equal(run[key], columns[column]), (name, key)
        assert run["load_kg"] == 7.0 and run["hysteresis_scale"] == 1.0
    # It pickles whole, so that a worker process can hand it back.
    back = pickle.loads(pickle.dumps(result))
    assert back.document == result.document and repr(back) == "ControlResult(4 runs)"
    assert all(np.array_equal(a["valve"], b["valve"]) for a, b in zip(back.runs, result.runs))
    # The MPC tracks the sine far closer than the thesis' PI.
    rms = {(r["controller"], r["freq_rad_s"]): r["rms_error_mm"] for r in result.document["runs"]}
    assert rms[("mpc", 3.0)] < rms[("pi", 3.0)] / 3


def test_a_model_steers_the_mpc_as_from_its_file(binary, tmp_path):
    # Columns that state no unit, which the controllers take in MPa and mm.
    record = mckibben.twin("multisine", seed=5)
    record = mckibben.Trace(record.input, record.output, record.dt, input_name="u", output_name="y")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        fitted = mckibben.fit(record, pop=200, gens=40).model
    path = tmp_path / "model.json"
    fitted.save(path)
    document, err = command(binary, "--controller", "mpc", "--freq", "2", "--load", "4.5",
                            *SHORT_FLAGS, "--from", str(path))
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = mckibben.control("mpc", freq=2, load=4.5, model=fitted, **SHORT)
    said = [str(w.message) for w in caught]
    # The same design but for where the model came from.
    assert result.document["design"]["source"] == "a Model (Python)"
    assert document["design"]["source"] == str(path)
    for d in (document, result.document):
        d["design"]["source"] = None
    assert without_clocks(result.document) == without_clocks(document)
    # The command's note on a column that states no unit, as a warning
    # naming the argument.
    assert "--from " + str(path) + ": the model's input column `u` states no unit" in err
    assert any(s.startswith("model: the model's input column `u` states no unit") for s in said), said
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        by_path = mckibben.control("mpc", freq=2, load=4.5, model=path, **SHORT)
    assert str(caught[0].message).startswith(f"model {path}: the model's input column `u`")
    assert by_path.document["design"]["source"] == str(path)
    assert without_clocks(by_path.document)["runs"] == without_clocks(result.document)["runs"]


def test_control_is_refused_in_the_arguments_words():
    with pytest.raises(ValueError, match="^unknown controller `pid`: expected pi, pi-tuned, ff-pid or mpc"):
        mckibben.control("pid")
    with pytest.raises(ValueError, match="^`freq` names 1 twice: each run would be made"):
        mckibben.control("pi", freq=[1, 1.0])
    with pytest.raises(ValueError, match="^`hysteresis_scale`: 1 is the nominal model"):
        mckibben.control("mpc", hysteresis_scale=1)
    with pytest.raises(ValueError, match=r"^`horizon=1`: the MPC's horizon must be 2 to 500"):
        mckibben.control("mpc", horizon=1)
    with pytest.raises(ValueError, match=r"^`load=40`: the twin carries at most 15 kg"):
        mckibben.control("pi", load=40)
    with pytest.raises(ValueError, match="^unknown reference `square`: expected sine or steps"):
        mckibben.control("pi", reference="square")
    with pytest.raises(TypeError, match=r"^tuned_gains must be three numbers \(kp, ki, kd\)"):
        mckibben.control("pi-tuned", tuned_gains=(1, 2))
    with pytest.raises(TypeError, match=r"^tuned_gains must be three numbers .* or a dict"):
        mckibben.control("pi-tuned", tuned_gains={"kp": 1, "ki": 2})
    with pytest.raises(TypeError, match=r"^freq\[1\] must be a number"):
        mckibben.control("pi", freq=[1, "2"])
    with pytest.raises(ValueError, match="^`design_columns`: 3 names given; it takes four"):
        mckibben.control("mpc", design_data="rig.csv", design_columns=["t", "u", "p"])


def test_what_no_controller_reads_is_said(tmp_path):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mckibben.control("pi", freq=1, load=4.5, model=tmp_path / "none.json", horizon=30, **SHORT)
    said = [str(w.message) for w in caught]
    # Not read, so not opened: the missing file is no error.
    assert said == [
        "`model` is not read: none of the controllers asked for (pi) uses it; add ff-pid or "
        "mpc to `controller` for one that does",
        "`horizon` is not read: none of the controllers asked for (pi) uses it; add mpc to "
        "`controller` for one that does",
    ], said


def test_given_gains_as_a_list_or_as_a_tunings_dict_run_alike():
    as_list = mckibben.control("pi-tuned", freq=2, load=4.5, tuned_gains=[2.2, 65.5, 0.02], **SHORT)
    gains = as_list.document["tuned"]["gains"]
    assert gains == {"kp": 2.2, "ki": 65.5, "kd": 0.02}
    as_dict = mckibben.control("pi-tuned", freq=2, load=4.5, tuned_gains=gains, **SHORT)
    assert np.array_equal(as_dict.runs[0]["valve"], as_list.runs[0]["valve"])
    assert as_dict.document["tuned"]["given"] is True


def test_a_model_in_kpa_is_read_in_mpa():
    trace = mckibben.twin("multisine")
    kpa = mckibben.Trace(trace.input * 1000, trace.output, trace.dt, input_name="p_kPa", output_name="x_mm")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        model = mckibben.fit(kpa, pop=50, gens=5).model
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        result = mckibben.control("mpc", freq=2, load=4.5, model=model, **SHORT)
    said = [str(w.message) for w in caught]
    assert "model: the model's input (column `p_kPa`, in kPa) is read in MPa, the controllers' unit, its parameters converted" in said, said
    # The design's model is in MPa: its gain a thousand times the kPa one's.
    design = result.document["design"]["model"]["displacement"]
    assert design["params"][-3] == pytest.approx(model.params["b"] * 1000, rel=1e-12)
    # A model with effects too: the creep's gain (mm per kPa) is in mm per MPa.
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        creep = mckibben.fit(kpa, effects=["creep"], pop=50, gens=5).model
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = mckibben.control("mpc", freq=2, load=4.5, model=creep, **SHORT)
    lag = result.document["design"]["model"]["chain"]["lags"][0]
    rho, kappa = creep.params["creep.rho"], creep.params["creep.kappa"]
    assert lag["weight"] == pytest.approx((1 - rho) * kappa * 1000, rel=1e-12)



def test_ctrl_c_stops_the_tuning_and_raises(sigint_raises):
    # The PID's tuning runs for minutes; Ctrl-C stops it after the current
    # generation, with nothing returned.
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    started = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            mckibben.control("pi-tuned", freq=3, load=4.5)
    finally:
        timer.cancel()
    assert time.monotonic() - started < 10
