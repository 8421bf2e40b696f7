"""fit: the command's staged engine, bit for bit; progress, Ctrl-C, the GIL."""

import json
import os
import signal
import struct
import subprocess
import sys
import threading
import time
import warnings

import pathlib

import numpy as np
import pytest

import mckibben
from conftest import REPO, STAIR


def bits(x):
    return struct.pack("<d", x)


def test_fit_gives_the_commands_parameters_bit_for_bit(stair, cli, tmp_path):
    expected = cli("fit", stair.source, "--backend", "cpu", "--seed", "1", "--out", tmp_path)
    result = mckibben.fit(stair, seed=1)
    assert list(result.params) == list(expected["params"])
    assert [bits(v) for v in result.params.values()] == [bits(v) for v in expected["params"].values()]
    assert bits(result.sse) == bits(expected["sse"])
    assert result.std_errors == expected["std_errors"]
    assert result.undetermined == expected["undetermined"] == []
    assert result.diverging_probes == expected["diverging_probes"] == []
    assert result.std_errors["A"] is None and result.std_errors["b"] > 0
    assert result.units == expected["units"] == result.model.units
    assert (result.units["b"], result.units["alpha"]) == ("mm/MPa", "1")
    assert result.val_fit_percent == expected["val_fit_percent"]
    assert result.linear_val_fit_percent == expected["linear_val_fit_percent"]
    assert result.linear_largest_pole == expected["linear_largest_pole"]
    assert result.columns == expected["columns"]
    assert result.columns["output"] == {"column": "displacement", "unit": "mm"}
    assert (result.stable_step, result.largest_step) == (expected["stable_step"], expected["largest_step"])
    assert result.stable_step > result.largest_step > 0
    assert result.model.stable_step == result.stable_step
    assert result.stop == expected["stop"] == "completed" and not result.interrupted
    assert [s["best_cost"] for s in result.stages] == [s["best_cost"] for s in expected["stages"]]
    assert all(0 < s["evaluator_seconds"] <= s["seconds"] for s in result.stages)
    assert (result.population, result.algo, result.flow) == (1000, "de", "joint")
    assert result.on_edge == expected["on_edge"] and result.widened == expected["widened"]
    assert list(result.search_box["names"]) == expected["search_box"]["names"]
    h = result.history
    assert h["params"].shape == (len(h["generation"]), 9) and h["names"][-1] == "x0"
    assert np.array_equal(h["params"][-1], list(result.params.values()))
    # Arrays instead of a Trace: the same fit.
    again = mckibben.fit(stair.input, stair.output, stair.dt, seed=1)
    assert again.params == result.params


def model_file_without_provenance(path):
    doc = json.loads(pathlib.Path(path).read_text())
    del doc["provenance"]
    return doc


def test_a_list_of_experiments_is_the_commands_fit_of_several_files(stair, cli, tmp_path):
    sine = mckibben.read_csv(pathlib.Path(stair.source).parent / "sine_2rads_4.5kg.csv")
    expected = cli("fit", stair.source, sine.source, "--backend", "cpu", "--pop", "200", "--gens", "40",
                   "--out", tmp_path)
    result = mckibben.fit([stair, sine], pop=200, gens=40)
    assert [bits(v) for v in result.params.values()] == [bits(v) for v in expected["params"].values()]
    assert result.records == expected["records"]
    assert [r["data"] for r in result.records] == [stair.source, sine.source]
    saved = tmp_path / "model.json"
    result.model.save(saved)
    sources = [f["file"] for f in json.loads(saved.read_text())["provenance"]["data"]]
    assert sources == [stair.source, sine.source]
    # A tuple of Traces is such a list; records of other columns are refused.
    assert mckibben.fit((stair, sine), pop=200, gens=40).params == result.params
    kpa = mckibben.Trace(sine.input * 1e3, sine.output, sine.dt, input_name="p_kPa")
    with pytest.raises(ValueError, match="give the records the same columns"):
        mckibben.fit([stair, kpa], pop=20, gens=2)
    # A tuple is an experiment too, named by its place where it is refused.
    with pytest.raises(ValueError, match=r"u\[1\]"):
        mckibben.fit([stair, (stair.input[:10], stair.output[:10], 0.01)], pop=20, gens=2)
    # So is a tuple of them (it was read as one input array).
    with pytest.raises(ValueError, match=r"u\[1\]"):
        mckibben.fit((stair, (stair.input[:10], stair.output[:10], 0.01)), pop=20, gens=2)


def test_fit_with_effects_gives_the_commands_parameters_and_file(stair, cli, tmp_path):
    small = ["--pop", "40", "--gens", "10", "--seed", "2", "--backend", "cpu"]
    out = tmp_path / "cli"
    expected = cli("fit", stair.source, *small, "--effects", "creep", "--out", out)
    result = mckibben.fit(stair, pop=40, gens=10, seed=2, effects=["creep"])
    assert result.effects == expected["effects"] == ["creep"]
    assert list(result.params) == list(expected["params"])
    assert list(result.params)[9:] == ["creep.rho", "creep.kappa", "creep.z0"]
    assert [bits(v) for v in result.params.values()] == [bits(v) for v in expected["params"].values()]
    assert bits(result.sse) == bits(expected["sse"])
    # Its second start, the chain built one effect at a time, as the command's.
    assert result.built == expected["built"] and set(result.built) == {"scratch_sse", "chain_sse", "kept_chain"}
    assert result.model.effects == ["creep"] and result.model.params == result.params
    # The model file: the command's, byte for byte but for where it came from.
    result.model.save(tmp_path / "model.json")
    assert model_file_without_provenance(tmp_path / "model.json") == model_file_without_provenance(
        out / "model.json"
    )
    provenance = json.loads((tmp_path / "model.json").read_text())["provenance"]
    assert provenance["command"] == "mckibben.fit (Python)" and provenance["seed"] == 2
    assert provenance["data"][0]["file"] == stair.source and provenance["data"][0]["sha256"]


def test_the_softening_and_the_set_fit_as_the_command(stair, cli, tmp_path):
    small = ["--pop", "40", "--gens", "10", "--seed", "3", "--backend", "cpu"]
    chain = ["softening:cyclic", "set:ratchet"]
    expected = cli("fit", stair.source, *small, "--effects", ",".join(chain), "--out", tmp_path / "cli")
    result = mckibben.fit(stair, pop=40, gens=10, seed=3, effects=chain)
    assert result.effects == expected["effects"] == chain
    assert list(result.params)[9:] == [
        "softening:cyclic.s", "softening:cyclic.r", "set:ratchet.a", "set:ratchet.q",
    ]
    assert [bits(v) for v in result.params.values()] == [bits(v) for v in expected["params"].values()]
    result.model.save(tmp_path / "model.json")
    assert mckibben.Model.load(tmp_path / "model.json").effects == chain


def test_a_generalized_fit_switches_as_the_command(stair, cli, tmp_path):
    small = ["--pop", "40", "--gens", "10", "--seed", "2", "--backend", "cpu", "--model", "generalized"]
    for switch in ("starts", "zero"):
        expected = cli("fit", stair.source, *small, "--switch", switch, "--out", tmp_path / switch)
        result = mckibben.fit(stair, model="generalized", pop=40, gens=10, seed=2, switch=switch)
        assert [bits(v) for v in result.params.values()] == [bits(v) for v in expected["params"].values()]
        assert result.switching == expected.get("switching")
    # Two starts say which they kept; the default searches the level, one start.
    starts = mckibben.fit(stair, model="generalized", pop=40, gens=10, seed=2, switch="starts")
    assert set(starts.switching) == {"mean_sse", "zero_sse", "kept_zero"}
    s = starts.switching
    assert s["kept_zero"] == (s["zero_sse"] < s["mean_sse"])
    default = mckibben.fit(stair, model="generalized", pop=40, gens=10, seed=2)
    expected = cli("fit", stair.source, *small, "--out", tmp_path / "default")
    assert default.switching is None and expected["switching"] is None
    assert [bits(v) for v in default.params.values()] == [bits(v) for v in expected["params"].values()]
    with pytest.raises(ValueError, match="unknown switch `middle`: expected one of search, starts, mean, zero"):
        mckibben.fit(stair, model="generalized", pop=40, gens=10, switch="middle")
    # The classic model has no switching level: a switch given to it is an
    # error, as `fit --switch` is, not a keyword ignored.
    with pytest.raises(ValueError, match="zero: the switching level belongs to the generalized model"):
        mckibben.fit(stair, pop=40, gens=10, switch="zero")
    # A level asked for and boxed too: one of them would be dropped.
    with pytest.raises(ValueError, match="switch=zero: the switching level is searched or held by it, and also boxed by `x_s=1`"):
        mckibben.fit(stair, model="generalized", pop=40, gens=10, switch="zero", bounds={"x_s": 1.0})


def test_a_fit_refuses_overshooting_loops_as_the_command(stair, cli, tmp_path):
    small = ["--pop", "1000", "--gens", "30", "--seed", "2", "--backend", "cpu"]
    expected = cli("fit", stair.source, *small, "--overshoot", "refuse", "--out", tmp_path)
    refused = mckibben.fit(stair, pop=1000, gens=30, seed=2, overshoot="refuse")
    assert [bits(v) for v in refused.params.values()] == [bits(v) for v in expected["params"].values()]
    # Read, not ignored: on this record some candidate the default admits
    # is refused, and the search ends elsewhere.
    allowed = mckibben.fit(stair, pop=1000, gens=30, seed=2)
    assert refused.sse != allowed.sse
    assert (refused.overshoot, allowed.overshoot) == (expected["overshoot"], "allow") == ("refuse", "allow")
    with pytest.raises(ValueError, match="unknown overshoot `never`: expected one of refuse, allow"):
        mckibben.fit(stair, pop=40, gens=10, overshoot="never")


def test_a_larger_population_runs_tries_as_the_command(stair, cli, tmp_path):
    small = ["--pop", "3000", "--gens", "4", "--seed", "3", "--backend", "cpu"]
    expected = cli("fit", stair.source, *small, "--out", tmp_path)
    result = mckibben.fit(stair, pop=3000, gens=4, seed=3)
    assert (result.tries, result.try_population) == (expected["tries"], expected["try_population"]) == (12, 1000)
    assert result.try_sizes == expected["try_sizes"] == [{"population": 1000, "tries": 2}, {"population": 100, "tries": 10}]
    assert result.agreement == expected["agreement"]
    assert set(result.agreement) == {"tries", "agreeing", "other_basins", "diverged", "threshold", "runner_up"}
    assert 1 <= result.agreement["agreeing"] <= 12 == result.agreement["tries"]
    assert [bits(v) for v in result.params.values()] == [bits(v) for v in expected["params"].values()]
    one = mckibben.fit(stair, pop=1000, gens=4, seed=3)
    assert one.tries == 1 and one.agreement is None
    # The first of the tries is the fit of one: more never end higher.
    assert result.sse <= one.sse


def test_a_refinement_cut_short_is_the_commands_and_warns(stair, cli, tmp_path):
    small = ["--pop", "40", "--gens", "20", "--seed", "3", "--backend", "cpu", "--model", "generalized"]
    expected = cli("fit", stair.source, *small, "--refine-rounds", "1", "--out", tmp_path)
    with pytest.warns(UserWarning, match="refining ran out of rounds.*`refine_rounds=4` lets it go on"):
        result = mckibben.fit(stair, model="generalized", pop=40, gens=20, seed=3, refine_rounds=1)
    assert result.refining == expected["refining"]
    assert result.refining["rounds"] == result.refining["cut_tries"] == 1
    # The command's notes, in order, as the Python terms name its flags.
    assert [n["level"] for n in result.notes] == [n["level"] for n in expected["notes"]]
    assert any("`refine_rounds=4`" in n["text"] for n in result.notes)
    assert any("--refine-rounds 4" in n["text"] for n in expected["notes"])
    assert [bits(v) for v in result.params.values()] == [bits(v) for v in expected["params"].values()]
    assert mckibben.fit(stair, pop=40, gens=2).refining is None
    with pytest.raises(ValueError, match="only a generalized fit is refined"):
        mckibben.fit(stair, pop=40, gens=2, refine_rounds=2)
    with pytest.raises(ValueError, match="refine_rounds must be at least 0, got -1"):
        mckibben.fit(stair, model="generalized", pop=40, gens=2, refine_rounds=-1)


def test_a_warm_start_is_the_commands_fit_from(stair, cli, small_fit, tmp_path):
    start = tmp_path / "start.json"
    small_fit.model.save(start)
    small = ["--pop", "40", "--gens", "5", "--seed", "5", "--backend", "cpu"]
    expected = cli("fit", stair.source, *small, "--from", start, "--effects", "delay", "--out", tmp_path / "cli")
    for given in (start, str(start), small_fit.model):
        result = mckibben.fit(stair, pop=40, gens=5, seed=5, effects=["delay"], start=given)
        assert list(result.params) == list(expected["params"])
        assert [bits(v) for v in result.params.values()] == [bits(v) for v in expected["params"].values()]
        # Its start as it was, scored as the command scores it.
        assert result.start_sse == expected["start_sse"] is not None
        assert result.start_val_fit_percent == expected["start_val_fit_percent"] is not None
    assert small_fit.start_sse is None and small_fit.start_val_fit_percent is None
    # The start's family and effects when not given.
    again = mckibben.fit(stair, pop=40, gens=2, start=result.model)
    assert again.effects == result.effects and again.family == "classic"
    # On the record in kPa the start is read in kPa, effects and all, and
    # validates as it does in MPa.
    in_kpa = mckibben.Trace(stair.input * 1000, stair.output, stair.dt, input_name="p_kPa")
    with pytest.warns(UserWarning, match=r"the start model's `pressure` \(MPa\) is read in kPa"):
        kpa = mckibben.fit(in_kpa, pop=40, gens=2, start=result.model)
    assert kpa.start_val_fit_percent == pytest.approx(again.start_val_fit_percent, abs=1e-3)


def test_a_carried_chain_is_the_commands_fit_carry(stair, cli, tmp_path):
    small = ["--pop", "40", "--gens", "5", "--seed", "5", "--backend", "cpu"]
    source = mckibben.fit(stair, pop=40, gens=5, seed=5, effects=["creep"])
    path = tmp_path / "source.json"
    source.model.save(path)
    expected = cli("fit", stair.source, *small, "--carry", path, "--out", tmp_path / "cli")
    result = mckibben.fit(stair, pop=40, gens=5, seed=5, carry=source.model)
    assert result.effects == ["creep"]
    assert [bits(v) for v in result.params.values()] == [bits(v) for v in expected["params"].values()]
    # The creep's pole is the carried model's; its gain is fitted again.
    assert result.params["creep.rho"] == source.params["creep.rho"]
    assert result.start_sse is None
    with pytest.raises(ValueError, match="start and carry"):
        mckibben.fit(stair, pop=40, gens=2, start=source.model, carry=source.model)
    # As `fit --carry` refuses --model: the carried family would be dropped.
    with pytest.raises(ValueError, match="carry and model: a carried chain keeps its model's family"):
        mckibben.fit(stair, pop=40, gens=2, carry=source.model, model="generalized")


def test_seeds_are_per_call(stair, small_fit):
    same = mckibben.fit(stair, pop=40, gens=20, seed=3)
    other = mckibben.fit(stair, pop=40, gens=20, seed=4)
    assert same.params == small_fit.params
    assert other.params != small_fit.params


def test_progress_sees_every_generation(stair):
    seen = []
    result = mckibben.fit(stair, pop=40, gens=10, progress=seen.append)
    assert len(seen) == len(result.history["generation"])
    assert seen[0]["generation"] == 1 and seen[0]["stage"] == "global"
    assert seen[0]["planned"] == 10 + 2  # G global generations, then G/4 free-run ones
    assert set(seen[-1]) >= {"best_sse", "best_params", "evaluations", "diverged"}


def test_an_exception_in_progress_stops_the_fit_and_is_raised(stair):
    def fail(record):
        if record["generation"] == 3:
            raise RuntimeError("stop here")

    with pytest.raises(RuntimeError, match="stop here"):
        mckibben.fit(stair, pop=40, gens=50, progress=fail)


def test_ctrl_c_returns_the_best_so_far_marked_interrupted(stair, sigint_raises):
    seen = []

    def interrupt_once(record):
        seen.append(record["generation"])
        if len(seen) == 5:
            os.kill(os.getpid(), signal.SIGINT)

    # Five generations validate below the first-order ARX model: the fit says so.
    with pytest.warns(UserWarning, match="first-order ARX model"):
        result = mckibben.fit(stair, pop=200, gens=100_000, progress=interrupt_once)
    assert result.interrupted and result.stop == "interrupted"
    assert result.model is not None and result.params
    assert result.generations < 100


def test_ctrl_c_in_a_long_polish_stops_it_between_waves(stair, sigint_raises):
    # 541 tries polish 2776 starts, most of the fit's evaluations (about
    # 3.4 million in all); a SIGINT at the polish's first record used to
    # be heard only once the whole polish was done.
    sent = []

    def interrupt_in_the_polish(record):
        if record["stage"] == "polish" and not sent:
            sent.append(record["evaluations"])
            os.kill(os.getpid(), signal.SIGINT)

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        result = mckibben.fit(stair, pop=100_000, gens=5, progress=interrupt_in_the_polish)
    assert sent and result.interrupted and result.stop == "interrupted"
    assert result.evaluations < 1_500_000, (sent, result.evaluations)


def test_a_sigint_from_another_thread_interrupts_too(stair, sigint_raises):
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    timer.start()
    try:
        result = mckibben.fit(stair, pop=200, gens=100_000)
    finally:
        timer.cancel()
    assert result.interrupted and result.model is not None


def test_another_thread_runs_during_a_fit(stair):
    done = threading.Event()
    count = [0]

    def work():
        while not done.is_set():
            count[0] += 1

    worker = threading.Thread(target=work)
    worker.start()
    try:
        before = count[0]
        mckibben.fit(stair, pop=200, gens=60)
        during = count[0] - before
    finally:
        done.set()
        worker.join()
    # Pure-Python increments: with the interpreter held for the whole fit
    # the thread could not count at all while it ran.
    assert during > 10_000, during


@pytest.mark.parametrize(
    "kwargs, error, message",
    [
        ({"start": 3}, TypeError, "start must be a Model or the path"),
        ({"start": "/nonexistent/model.json"}, FileNotFoundError, "No such file or directory: '/nonexistent/model.json'"),
        ({"effects": ["delayy"]}, ValueError, "unknown effect `delayy`"),
        ({"bounds": {"alpah": (0.0, 1.0)}}, ValueError, "no parameter `alpah`"),
        ({"bounds": {"alpha": (0.9, 0.1)}}, ValueError, "the box is empty"),
        ({"bounds": {"alpha": "x"}}, TypeError, "a \\(lo, hi\\) pair"),
        # A bool is not a number to fix a parameter at.
        ({"bounds": {"alpha": True}}, TypeError, "a \\(lo, hi\\) pair"),
        ({"model": "classical"}, ValueError, "unknown model family"),
        ({"algo": "cmaes"}, ValueError, "unknown algorithm"),
        ({"backend": "tpu"}, ValueError, "unknown backend `tpu`"),
        ({"pop": 0}, ValueError, "pop must be at least 1"),
        # The library's messages name the argument, not the command's flag.
        ({"time_budget": -1}, ValueError, "^`time_budget` must be at least 0 seconds"),
        ({"target_sse": float("nan")}, ValueError, "^`target_sse` must be a finite SSE"),
        ({"target_sse": -1.0}, ValueError, "^`target_sse` must be a finite SSE"),
        ({"effects": ["creep", "creep"]}, ValueError, "^effects names `creep` twice"),
        ({"seed": -1}, ValueError, "seed must be an integer"),
        ({"progress": 3}, TypeError, "progress must be callable"),
    ],
)
def test_bad_arguments_raise_the_named_exception(stair, kwargs, error, message):
    with pytest.raises(error, match=message):
        mckibben.fit(stair, **{"pop": 40, "gens": 2, **kwargs})


def test_bad_data_raise_value_errors(stair):
    u, y = stair.input, stair.output
    with pytest.raises(ValueError, match="differ in length"):
        mckibben.fit(u, y[:-1], 0.01)
    with pytest.raises(ValueError, match=r"y\[7\] is NaN"):
        mckibben.fit(u, np.where(np.arange(len(y)) == 7, np.nan, y), 0.01)
    # A masked sample was run on the number under its mask.
    masked = np.ma.masked_array(y, mask=np.arange(len(y)) == 9)
    with pytest.raises(ValueError, match=r"^y\[9\] is masked: a free run needs a number"):
        mckibben.fit(u, masked, 0.01)
    # Nothing masked: the data, as a plain array.
    unmasked = mckibben.fit(u, np.ma.masked_array(y), 0.01, pop=40, gens=2)
    assert unmasked.params == mckibben.fit(u, y, 0.01, pop=40, gens=2).params
    with pytest.raises(ValueError, match="give the output y"):
        mckibben.fit(u)
    with pytest.raises(ValueError, match="not both"):
        mckibben.fit(stair, y, 0.01)
    with pytest.raises(ValueError, match="u is empty"):
        mckibben.fit([], [], 0.01)
    # A sample time past a day (its last sample's time was infinite).
    with pytest.raises(ValueError, match=r"^dt: 1e307 s is outside a nanosecond to a day"):
        mckibben.fit(u, y, 1e307)
    # Text or None where an array goes is a TypeError naming the argument.
    with pytest.raises(TypeError, match="^u must be an array of numbers .*, got str 'u.csv'"):
        mckibben.fit("u.csv", y, 0.01)
    with pytest.raises(TypeError, match="^y must be an array of numbers .*, got str 'y'"):
        mckibben.fit(u, "y", 0.01)


def test_a_fixed_parameter_stays_fixed(stair):
    result = mckibben.fit(stair, pop=40, gens=5, bounds={"alpha": 0.5})
    assert result.params["alpha"] == 0.5
    # A box may be any pair of numbers: a tuple, a list or an array.
    boxed = mckibben.fit(stair, pop=40, gens=5, bounds={"alpha": np.array([0.4, 0.6])})
    assert 0.4 <= boxed.params["alpha"] <= 0.6


def test_ctrl_c_while_the_chain_is_built_raises(stair, sigint_raises):
    # Ten stairs end to end: the fit takes about 8 s on two cores, most of it
    # building the chain, and it has nothing to return before the chain is built.
    long = mckibben.Trace(np.tile(stair.input, 10), np.tile(stair.output, 10), stair.dt)
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    started = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            mckibben.fit(long, effects=["creep"], pop=40, gens=2)
    finally:
        timer.cancel()
    assert time.monotonic() - started < 10


def test_a_fit_where_every_candidate_diverges_warns_and_holds_no_model(stair):
    # A pole of 1.5 diverges on every candidate (as `fit --fix a=1.5`, an
    # error there): the result says so instead of returning quietly.
    with pytest.warns(UserWarning, match="every candidate diverged: the result holds no model"):
        result = mckibben.fit(stair, pop=20, gens=5, bounds={"a": 1.5})
    assert result.model is None and result.params == {}
    # Stopped before any score, nothing diverged: it said so, wrongly.
    with pytest.warns(UserWarning, match=r"stopped \(TimeBudget\) before any candidate was scored") as seen:
        result = mckibben.fit(stair, pop=20, gens=5, time_budget=0)
    assert result.model is None
    assert not any("diverged" in str(w.message) for w in seen)


@pytest.mark.parametrize(
    "kwargs, message",
    [
        # PyO3 names an argument it cannot convert only in a note on the
        # exception: the message itself names it here.
        ({"dt": "0.01"}, r"^dt must be a number \(an int or a float\), got str '0.01'"),
        ({"pop": 1.5}, "^pop must be an integer, got float 1.5"),
        ({"gens": "2"}, "^gens must be an integer, got str '2'"),
        ({"seed": 1.0}, "^seed must be an integer, got float 1.0"),
        ({"model": 3}, "^model must be a str, got int 3"),
        ({"algo": None}, "^algo must be a str, got None"),
        ({"backend": b"cpu"}, "^backend must be a str, got bytes b'cpu'"),
        ({"effects": "creep"}, "^effects must be a list of names \\(str\\), got str 'creep'"),
        ({"effects": ["creep", 2]}, r"^effects\[1\] must be a str, got int 2"),
        ({"effects": 3}, r"^effects must be a list of names \(str\), got int 3"),
        # A set's order, the chain's, changed with PYTHONHASHSEED.
        ({"effects": {"creep", "delay"}}, r"^effects must be a list of names \(str\), got set .*a set's changes"),
        ({"effects": {"creep": 1}}, r"^effects must be a list of names \(str\), got dict"),
        ({"free_n": 1}, "^free_n must be True or False, got int 1"),
        ({"thesis_flow": "yes"}, "^thesis_flow must be True or False, got str 'yes'"),
        ({"loop": 0}, "^loop must be a str, got int 0"),
        ({"switch": 1}, "^switch must be a str, got int 1"),
        ({"bounds": [("alpha", 0.5)]}, r"^bounds must be a dict, \{name: \(lo, hi\)\} or \{name: value\}"),
        ({"bounds": {"alpha": (0.1, "x")}}, r'^bounds\["alpha"\]\[1\] must be a number'),
        ({"target_sse": "1"}, "^target_sse must be a number"),
        ({"time_budget": 1j}, "^time_budget must be a number .*, got complex 1j"),
        ({"stall": 2.0}, "^stall must be an integer, got float 2.0"),
        ({"refine_rounds": "3"}, "^refine_rounds must be an integer, got str '3'"),
    ],
)
def test_a_value_of_the_wrong_type_names_its_argument(stair, kwargs, message):
    u, y = stair.input[:200], stair.output[:200]
    with pytest.raises(TypeError, match=message):
        mckibben.fit(u, y, **{"dt": 0.01, "pop": 40, "gens": 2, **kwargs})


@pytest.mark.parametrize(
    "kwargs, name",
    [
        ({"pop": True}, "pop"),
        ({"gens": np.True_}, "gens"),
        ({"dt": True}, "dt"),
        ({"seed": False}, "seed"),
        ({"stall": True}, "stall"),
        ({"target_sse": True}, "target_sse"),
        ({"time_budget": np.False_}, "time_budget"),
        ({"bounds": {"alpha": (False, 1.0)}}, r'bounds\["alpha"\]\[0\]'),
    ],
)
def test_a_bool_is_not_a_number(stair, kwargs, name):
    # `pop=True` ran a population of 1, `dt=True` a step of 1 s.
    u, y = stair.input[:200], stair.output[:200]
    with pytest.raises(TypeError, match=f"^{name} must be .*, got bool (True|False|np.True_|np.False_)"):
        mckibben.fit(u, y, **{"dt": 0.01, "pop": 40, "gens": 2, **kwargs})


@pytest.mark.parametrize(
    "kwargs, message",
    [
        # Beyond 2**64 these were a bare OverflowError.
        ({"seed": 2**200}, r"^seed must be an integer in \[0, 2\*\*53\), got 1606938044258990275541962092341162602522202993782792835301376"),
        ({"seed": -(2**130)}, r"^seed must be an integer in \[0, 2\*\*53\), got -1361129467683753853853498429727072845824"),
        # A seed the runs would add to past 2**64 (wrapping to seed 0).
        ({"seed": 2**64 - 1}, r"^seed must be an integer in \[0, 2\*\*53\), got 18446744073709551615"),
        ({"pop": 2**70}, r"^pop must be less than 2\*\*63, got 1180591620717411303424"),
        ({"gens": 2**63}, r"^gens must be less than 2\*\*63, got 9223372036854775808"),
        ({"stall": -(2**200)}, r"^stall must be at least 1, got -1606938044258990275541962092341162602522202993782792835301376"),
        ({"refine_rounds": 10**5000}, r"^refine_rounds must be less than 2\*\*63, got an integer of 16610 bits"),
        ({"dt": 10**400}, "^dt must be a finite number, got an integer too large for a float"),
    ],
)
def test_an_integer_out_of_range_names_its_argument_and_range(stair, kwargs, message):
    u, y = stair.input[:200], stair.output[:200]
    with pytest.raises(ValueError, match=message):
        mckibben.fit(u, y, **{"dt": 0.01, "pop": 40, "gens": 2, **kwargs})


def test_provenance_names_a_piece_by_its_file_and_arrays_by_their_source(tmp_path):
    pieces = mckibben.read_csv(REPO / "data" / "logger_example.csv", input="p_kPa", output="stroke_mm",
                               time="time_s", split_gaps=True)
    arrays = mckibben.Trace(pieces[0].input, pieces[0].output, pieces[0].dt, input_name="p_kPa",
                            output_name="stroke_mm", source="rig-run-7")
    for trace, file, hashed in [(pieces[0], str(REPO / "data" / "logger_example.csv"), True),
                                (arrays, "rig-run-7", False)]:
        result = mckibben.fit(trace, pop=40, gens=3)
        result.model.save(tmp_path / "m.json")
        data = json.loads((tmp_path / "m.json").read_text())["provenance"]["data"]
        assert [d["file"] for d in data] == [file]
        assert bool(data[0]["sha256"]) == hashed
    # The box says where each bound came from, as fit --json does.
    origin = result.search_box["origin"]
    assert len(origin) == len(result.search_box["names"])
    assert all(set(pair) <= {"data", "class", "user"} for pair in origin)


def test_a_message_quoting_a_command_keeps_its_flags(stair):
    # Renamed inside its code span, the flag came out as `diagnose `effects``.
    with pytest.raises(ValueError) as raised:
        mckibben.fit(stair, effects=["creep:log", "creep"], pop=20, gens=2)
    assert "`diagnose --effects`" in str(raised.value), raised.value


def test_a_flags_named_value_reads_as_the_keywords_string(stair):
    start = REPO / "tests" / "fixtures" / "generalized_before_x_s.json"
    with pytest.raises(ValueError) as raised:
        mckibben.fit(stair, model="generalized", switch="starts", start=start, pop=20, gens=2)
    assert '`switch="starts"` runs two fresh fits' in str(raised.value), raised.value


def test_a_bound_past_the_largest_float_is_named_as_a_number(stair):
    # It read "must be a (lo, hi) pair ... or a number", of a number.
    with pytest.raises(ValueError, match=r'bounds\["alpha"\] must be a finite number'):
        mckibben.fit(stair, bounds={"alpha": 10**400}, pop=20, gens=2)


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads /proc and RLIMIT_AS")
def test_a_population_past_the_free_memory_is_refused_before_it_runs():
    # Under a limit on the address space the allocation that failed midway
    # aborted the interpreter ("memory allocation failed", exit 134).
    script = (
        "import resource, mckibben\n"
        "resource.setrlimit(resource.RLIMIT_AS, (2_500_000_000, resource.RLIM_INFINITY))\n"
        f"trace = mckibben.read_csv({str(STAIR)!r})\n"
        "try:\n"
        "    mckibben.fit(trace, pop=10**7, gens=1)\n"
        "except ValueError as e:\n"
        "    print('refused:', e)\n"
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    assert run.stdout.startswith("refused: `pop=10000000`: its candidates need at least 3.6 GB"), run.stdout
    assert "are free here" in run.stdout, run.stdout


def test_a_bound_given_as_bounds_is_named_once(stair):
    # The command says `--bound or --fix`; both are `bounds` here, named once.
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        mckibben.fit(stair, pop=30, gens=3, bounds={"alpha": [0, 0.5]})
    texts = [str(w.message) for w in caught]
    assert any("(your `bounds`)" in t for t in texts), texts
    assert not any("`bounds` or `bounds`" in t for t in texts), texts
    # Joined by "and" too: "--bound and --fix need the joint flow".
    with pytest.raises(ValueError, match="flow searches its own tables: `bounds` need the joint flow"):
        mckibben.fit(stair, pop=20, gens=2, thesis_flow=True, bounds={"alpha": (0, 0.5)})
