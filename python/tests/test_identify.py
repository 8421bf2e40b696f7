"""identify: the thesis' ARX identification, as `mckibben identify --json`."""

import json
import pickle
import subprocess

import numpy as np
import pytest

import mckibben
from conftest import REPO, STAIR


def command(binary, *args):
    out = subprocess.run([binary, "identify", *map(str, args), "--json"], check=True, capture_output=True)
    return json.loads(out.stdout)


def without_provenance(document):
    if document.get("model"):
        document = {**document, "model": {k: v for k, v in document["model"].items() if k != "provenance"}}
    return document


def test_the_stair_identifies_as_the_command_does(binary, stair):
    result = mckibben.identify(stair)
    expected = command(binary, STAIR)
    assert without_provenance(result.document) == without_provenance(expected)
    # Eq. 12's two coefficients, as the linear family every command reads.
    assert result.model.family == "linear"
    assert result.model.params["a"] == result.document["arx"]["a"][0]
    assert result.model.params["b"] == result.document["arx"]["b"][0]
    assert result.document["model"]["provenance"]["command"] == "mckibben.identify (Python)"
    # Its free run on the record is the second half's figure the command
    # gives `fit`'s yardstick (the model runs in f32, the identification in
    # f64).
    y = result.model.simulate(stair.input, x0=stair.output[0])
    half = len(stair) // 2
    measured = stair.output[half:]
    fit = 100 * (1 - np.linalg.norm(measured - y[half:]) / np.linalg.norm(measured - measured.mean()))
    assert fit == pytest.approx(result.document["continued_validation_fit_percent"], abs=1e-3)
    back = pickle.loads(pickle.dumps(result))
    assert back.document == result.document and back.model == result.model
    validation = result.document["validation_fit_percent"]
    assert repr(back) == f"Identification(validation fit {validation:.2f} %)"


def test_other_orders_and_several_records(binary, stair):
    second = REPO / "data" / "stair_7kg.csv"
    result = mckibben.identify(stair, na=2, nb=2, nk=1)
    assert result.model is None
    assert result.document == command(binary, STAIR, "--na", 2, "--nb", 2)
    joint = mckibben.identify([stair, mckibben.read_csv(second)])
    expected = command(binary, STAIR, second)
    assert without_provenance(joint.document) == without_provenance(expected)
    assert [r["data"] for r in joint.document["records"]] == [str(STAIR), str(second)]
    # Arrays with their sample time, as `fit` takes them.
    arrays = mckibben.identify(stair.input, stair.output, stair.dt)
    assert arrays.document["arx"] == mckibben.identify(stair).document["arx"]


def test_identify_is_refused_in_the_arguments_words(stair):
    with pytest.raises(ValueError, match="^nb must be at least 1, got 0"):
        mckibben.identify(stair, nb=0)
    with pytest.raises(ValueError, match="give the sample time dt with the arrays u and y"):
        mckibben.identify(stair.input, stair.output)
    with pytest.raises(TypeError, match="^na must be an integer, got float 1.5"):
        mckibben.identify(stair, na=1.5)
