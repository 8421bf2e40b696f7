"""diagnose: the document `mckibben diagnose --json` prints, and its models."""

import json
import os
import signal
import threading
import time
import subprocess
import warnings

import numpy as np
import pytest

import mckibben
from conftest import REPO, missing


def without_provenance(path):
    doc = json.loads(path.read_text())
    del doc["provenance"]
    return doc


def test_diagnose_returns_the_commands_document_and_models(stair, cli, tmp_path):
    args = dict(effects=["delay"], seeds=1, generations=10, scratch_seeds=0)
    out = tmp_path / "cli"
    expected = cli(
        "diagnose", stair.source, "--effects", "delay", "--seeds", "1",
        "--generations", "10", "--scratch-seeds", "0", "--out", out,
    )
    got = mckibben.diagnose(stair, **args)
    doc = got.document
    assert doc == expected
    assert doc["schema_version"] == 5 and "verdict" in doc and "final" in doc
    assert isinstance(got.model, mckibben.Model) and got.baseline.effects == []
    assert got.baseline.params == doc["baseline"]["params"]
    for model, name in ((got.model, "model.json"), (got.baseline, "baseline.json")):
        model.save(tmp_path / name)
        assert without_provenance(tmp_path / name) == without_provenance(out / name)
        assert mckibben.Model.load(out / name) == model
    again = mckibben.diagnose([(stair.input, stair.output, stair.dt)], **args)
    assert again.document["baseline"]["params"] == doc["baseline"]["params"]


def test_diagnose_cuts_blocks_and_transfers_as_the_command(stair, cli):
    args = dict(effects=["saturation:output"], seeds=1, generations=10, scratch_seeds=0)
    # Another record of the same muscle: the stair at 7 kg.
    seven = stair.source.replace("4.5kg", "7kg")
    got = mckibben.diagnose(stair, blocks=4, transfer=[mckibben.read_csv(seven)], **args)
    doc = got.document
    parts = doc["parts"][0]
    assert len(parts["selection"]) == 2 and len(parts["test"]) == 2
    assert [t["dataset"] for t in doc["transfers"]] == [seven]
    expected = cli(
        "diagnose", stair.source, "--effects", "saturation:output", "--seeds", "1",
        "--generations", "10", "--scratch-seeds", "0", "--blocks", "4", "--transfer", seven,
    )
    assert doc == expected
    with pytest.raises(ValueError, match="blocks must be at least 2"):
        mckibben.diagnose(stair, blocks=1, **args)
    # A count no record holds answers at once, naming the length it needs.
    with pytest.raises(ValueError, match="it needs at least"):
        mckibben.diagnose(stair, blocks=2**32, **args)
    # One model, one sample time: a second record at another step is refused.
    coarse = (stair.input[::2], stair.output[::2], 2 * stair.dt)
    with pytest.raises(ValueError, match="one model's poles are per sample"):
        mckibben.diagnose([stair, coarse], **args)


def test_diagnose_repeats_from_seeds_as_the_command(stair, cli):
    args = dict(effects=["saturation:output"], seeds=1, generations=10, scratch_seeds=0)
    got = mckibben.diagnose(stair, repeat=2, **args).document
    runs = got["repeats"]["runs"]
    assert [r["seed"] for r in runs] == [1, 2]
    assert runs[0]["verdict"] == got["verdict"]
    expected = cli(
        "diagnose", stair.source, "--effects", "saturation:output", "--seeds", "1",
        "--generations", "10", "--scratch-seeds", "0", "--repeat", "2",
    )
    assert got == expected
    assert mckibben.diagnose(stair, **args).document["repeats"] is None
    with pytest.raises(ValueError, match="repeat must be at least 1"):
        mckibben.diagnose(stair, repeat=0, **args)


def test_an_output_in_metres_taken_as_mm_starts_from_fits_fit(stair):
    args = dict(effects=["delay"], seeds=1, generations=10, scratch_seeds=0)
    u, y = stair.input * 1000, stair.output / 1000
    # In metres, as a tuple: taken in mm, the loop is too sharp for the
    # searched box; `fit`'s fit, in the data's scale, beats it, and the
    # diagnosis starts again from it, off the box's edge.
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = mckibben.diagnose([(u, y, stair.dt)], **args)
    assert got.document["from"] == "`mckibben fit`'s fit of the baseline"
    assert got.document["baseline"]["plain_fit"]["started_from"] is True
    assert got.document["baseline"]["on_edge"] == []
    named = mckibben.Trace(u, y, stair.dt, output_name="x_m")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        got = mckibben.diagnose(named, **args)
    assert got.document["baseline"]["on_edge"] == []


def test_a_baseline_on_the_boxs_edge_warns():
    # The Cavatappi muscle at 200 g (mm, a stroke of about 5 mm): the
    # searched baseline ends on the edge, and `fit`'s fit does not beat it.
    path = REPO.parent / "shared" / "data" / "external" / "cavatappi_muscle" / "sample1_200g.csv"
    if not path.exists():
        missing(f"no external data at {path}")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the reader's notes on the resampling
        record = mckibben.read_csv(
            path, input="pressure_psi", output="disp_mm", time="t_s", resample=0.01
        )
    with pytest.warns(UserWarning, match="ended on the edge of the diagnosis' box"):
        got = mckibben.diagnose(record)
    assert got.document["baseline"]["on_edge"]
    assert got.document["from"] is None


def test_a_baseline_that_misses_fits_basin_starts_from_fits(binary, tmp_path):
    # The twin's stair with three times the braid's friction: `fit`'s own
    # fit of the baseline beats the searched one on both halves, and the
    # diagnosis starts again from it.
    record = tmp_path / "friction3.csv"
    subprocess.run(
        [str(binary), "twin", "--effect", "friction=3", "--out", str(record)],
        check=True,
        capture_output=True,
    )
    got = mckibben.diagnose(mckibben.read_csv(record))
    plain = got.document["baseline"]["plain_fit"]
    assert plain["beats_baseline"] is True and plain["started_from"] is True
    assert got.document["from"] == "`mckibben fit`'s fit of the baseline"
    assert got.document["baseline"]["selection_rmse"] < 0.5 * plain["searched_selection_rmse"]


def test_diagnose_rejects_bad_arguments(stair):
    with pytest.raises(ValueError, match="unknown effect `wobble`"):
        mckibben.diagnose(stair, effects=["wobble"])
    # As `diagnose --effects delay,delay`: each effect is tried once (it
    # was tried twice, a whole round's fits).
    with pytest.raises(ValueError, match="^effects names `delay` twice"):
        mckibben.diagnose(stair, effects=["delay", "delay"])
    with pytest.raises(ValueError, match="datasets is empty"):
        mckibben.diagnose([])
    with pytest.raises(TypeError, match="datasets must be"):
        mckibben.diagnose(3)
    # A tuple's arrays are named by their place.
    with pytest.raises(TypeError, match=r"^datasets\[1\]\[0\] must be an array of numbers .*, got str 'u'"):
        mckibben.diagnose([stair, ("u", stair.output, stair.dt)])
    with pytest.raises(ValueError, match=r"^datasets\[0\]\[2\]: 1e308 s is outside a nanosecond to a day"):
        mckibben.diagnose([(stair.input, stair.output, 1e308)])
    with pytest.raises(ValueError, match=r"^datasets\[0\]\[1\]\[2\] is NaN"):
        mckibben.diagnose([(stair.input[:3], [1.0, 2.0, np.nan], stair.dt)])
    with pytest.raises(ValueError, match="seeds must be at least 1"):
        mckibben.diagnose(stair, seeds=0)
    # A negative count is a ValueError naming it, not an OverflowError.
    for name in ["seeds", "generations", "scratch_seeds", "max_effects", "repeat"]:
        with pytest.raises(ValueError, match=f"^{name} must be at least"):
            mckibben.diagnose(stair, **{name: -1})
        # Past 2**63 (2**53 for a seed) it was a bare OverflowError.
        with pytest.raises(ValueError, match=rf"^{name} must be less than 2\*\*63, got 1180591620717411303424"):
            mckibben.diagnose(stair, **{name: 2**70})
    with pytest.raises(ValueError, match=r"^seed must be an integer in \[0, 2\*\*53\), got -1361129467683753853853498429727072845824"):
        mckibben.diagnose(stair, seed=-(2**130))


@pytest.mark.parametrize(
    "kwargs, message",
    [
        # PyO3 names an argument it cannot convert only in a note on the
        # exception: the message itself names it here.
        ({"seeds": 1.5}, "^seeds must be an integer, got float 1.5"),
        ({"blocks": "4"}, "^blocks must be an integer, got str '4'"),
        ({"baseline": 1}, "^baseline must be a str, got int 1"),
        ({"effects": "delay"}, r"^effects must be a list of names \(str\), got str 'delay'"),
        ({"backend": None}, "^backend must be a str, got None"),
        # A bool is not a count.
        ({"repeat": True}, "^repeat must be an integer, got bool True"),
        ({"generations": False}, "^generations must be an integer, got bool False"),
    ],
)
def test_a_value_of_the_wrong_type_names_its_argument(stair, kwargs, message):
    with pytest.raises(TypeError, match=message):
        mckibben.diagnose(stair, **kwargs)
    # In a (u, y, dt) tuple, the sample time by its place.
    with pytest.raises(TypeError, match=r"^datasets\[0\]\[2\] must be a number .*, got str '0.01'"):
        mckibben.diagnose([(stair.input, stair.output, "0.01")])


def test_a_record_at_fault_is_named_by_its_place_in_the_list(stair):
    args = dict(effects=["delay"], seeds=1, generations=2, scratch_seeds=0)
    u, y = stair.input, stair.output
    # The library names a record by its source, which Traces share.
    short = mckibben.Trace(u[:30], y[:30], stair.dt)
    with pytest.raises(ValueError, match=r"^datasets\[1\] \(python\): 30 samples are too few"):
        mckibben.diagnose([stair, short], **args)
    with pytest.raises(ValueError, match=r"^datasets\[2\] \(python\): the input `pressure` is constant"):
        mckibben.diagnose([stair, mckibben.Trace(u[:2000], y[:2000], stair.dt), mckibben.Trace(np.ones(100), y[:100], stair.dt)], **args)
    # The stair given twice would weigh double; two records that share a
    # source are named by their places (it was "python and python").
    same = mckibben.Trace(u, y, stair.dt)
    with pytest.raises(ValueError, match=r"datasets\[1\] \(python\) hold the same samples"):
        mckibben.diagnose([stair, same, same], **args)
    slower = mckibben.Trace(u[::2], y[::2], 2 * stair.dt)
    with pytest.raises(ValueError, match=r"^u\[2\] \(python\) is sampled every 0.02 s, u\[0\] \(.*\) every 0.01 s"):
        mckibben.fit([stair, mckibben.Trace(u[:3000], y[:3000], stair.dt), slower])
    # A tuple's source is its place: named once, and a transfer's as such
    # (it was "cannot fit datasets[1]: datasets[1]: ...").
    with pytest.raises(ValueError, match=r"^datasets\[1\]: 30 samples are too few to split"):
        mckibben.diagnose([stair, (u[:30], y[:30], stair.dt)], **args)
    with pytest.raises(ValueError) as e:
        mckibben.diagnose([stair, (u * 1e30, y, stair.dt)], **args)
    assert str(e.value).startswith("column `pressure` of datasets[1] spans")
    assert str(e.value).count("datasets[1]") == 1
    # An output that names no length unit is taken in mm, and Python is
    # told so, as the command tells its user.
    unnamed = mckibben.Trace(u, y, stair.dt, output_name="y")
    with pytest.warns(UserWarning, match="the output column `y` names no length unit"):
        with pytest.raises(ValueError):
            mckibben.diagnose([unnamed, (u[:30], y[:30], stair.dt)], **args)
    # Records in other units are not pooled, as `fit` does not pool them.
    in_kpa = mckibben.Trace(u * 1000, y, stair.dt, input_name="p_kPa")
    with pytest.raises(ValueError, match="one model takes one input and one output, in one unit"):
        mckibben.diagnose([stair, in_kpa], **args)
    seven = mckibben.read_csv(stair.source.replace("4.5kg", "7kg"))
    with pytest.raises(ValueError, match=r"^transfer\[1\]: 30 samples are too few to split"):
        mckibben.diagnose(stair, transfer=[seven, (u[:30], y[:30], stair.dt)], **args)


def test_a_transfer_the_chain_cannot_run_on_is_refused_before_the_diagnosis(stair):
    args = dict(effects=["delay"], seeds=1, generations=2, scratch_seeds=0)
    seven = mckibben.read_csv(stair.source.replace("4.5kg", "7kg"))
    u, y, dt = seven.input, seven.output, seven.dt
    # Each is said as the command says it before its diagnosis runs; they
    # were found after it (another step, other units) or not at all (the
    # diagnosed record scored as its own transfer).
    cases = [
        ([seven, stair], r"^transfer\[1\] \(.*stair_4.5kg.csv\): it holds the samples of .*stair_4.5kg.csv, which the diagnosis reads"),
        ([(u, y, 2 * dt)], r"^transfer\[0\]: sampled every 0.02 s, the diagnosed record every 0.01 s"),
        ([mckibben.Trace(u, y, dt, input_name="valve_V")],
         r"^transfer\[0\] \(python\): the diagnosed record's input is in MPa \(column `pressure`\), but `valve_V` is in V"),
    ]
    for transfer, message in cases:
        with pytest.raises(ValueError, match=message):
            mckibben.diagnose(stair, transfer=transfer, **args)
    # Other units of the same kinds carry the chain as well: its held
    # dynamics are pure numbers, the rest is fitted in the record's units
    # (whose float rounding moves the searches a little).
    in_mpa = mckibben.diagnose(stair, transfer=[seven], **args).document["transfers"][0]
    kpa = mckibben.Trace(u * 1000, y / 1000, dt, input_name="p_kPa", output_name="x_m")
    in_kpa = mckibben.diagnose(stair, transfer=[kpa], **args).document["transfers"][0]
    for key in ["baseline_val_fit_percent", "chain_val_fit_percent"]:
        assert in_kpa[key] == pytest.approx(in_mpa[key], abs=0.5), key


def test_diagnose_from_a_model_is_the_commands_diagnose_from(stair, cli, tmp_path):
    args = dict(effects=["saturation:output", "delay"], seeds=1, generations=10,
                scratch_seeds=0, max_effects=1)
    first = mckibben.diagnose(stair, **args)
    assert first.document["capped"] is True
    chain = first.model.effects
    assert len(chain) == 1
    first.model.save(tmp_path / "model.json")
    again = mckibben.diagnose(stair, **{**args, "max_effects": 3},
                              start=tmp_path / "model.json")
    doc = again.document
    assert doc["given"] == chain and doc["steps"][1]["effects"] == chain
    assert again.model.effects[: len(chain)] == chain
    expected = cli(
        "diagnose", stair.source, "--effects", "saturation:output,delay", "--seeds", "1",
        "--generations", "10", "--scratch-seeds", "0", "--from", tmp_path / "model.json",
    )
    assert doc["final"] == expected["final"] and doc["given"] == expected["given"]


def test_ctrl_c_stops_a_diagnosis(stair, sigint_raises):
    # Uninterrupted, these candidate fits take minutes (200 s on two cores).
    timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
    started = time.monotonic()
    timer.start()
    try:
        with pytest.raises(KeyboardInterrupt):
            mckibben.diagnose(stair, effects=["delay", "deadzone", "creep"], seeds=3,
                              generations=200_000, scratch_seeds=0)
    finally:
        timer.cancel()
    assert time.monotonic() - started < 10


def test_an_empty_list_of_effects_is_refused(stair):
    # It ran the whole catalogue, where fit's effects=[] means none.
    with pytest.raises(ValueError, match=r"effects=\[\] names no effect to try"):
        mckibben.diagnose(stair, effects=[], seeds=1, generations=1, scratch_seeds=0)
