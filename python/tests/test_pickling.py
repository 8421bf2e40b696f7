"""Pickling: traces, models and results cross to worker processes and back
(`concurrent.futures`, `multiprocessing`, joblib) and `copy.deepcopy`
copies them, every value as it was."""

import concurrent.futures
import copy
import multiprocessing
import pickle

import numpy as np

import mckibben


def test_a_trace_pickles_with_its_samples_names_and_read_settings(stair, tmp_path):
    piece = mckibben.read_csv(stair.source, resample=0.02, split_gaps=True)[0]
    for trace in (stair, piece):
        back = pickle.loads(pickle.dumps(trace))
        for column in ("t", "input", "output"):
            assert np.array_equal(getattr(back, column), getattr(trace, column))
        assert list(back.extra) == list(trace.extra)
        for name, values in trace.extra.items():
            assert np.array_equal(back.extra[name], values)
        for name in ("source", "time_name", "input_name", "output_name", "dt"):
            assert getattr(back, name) == getattr(trace, name)
    # The read settings travel too: a model fitted on the copy records that
    # its data were resampled, as one fitted on the original does.
    back = copy.deepcopy(piece)
    for trace, name in ((piece, "a.json"), (back, "b.json")):
        mckibben.fit(trace, pop=10, gens=2).model.save(tmp_path / name)
    assert (tmp_path / "a.json").read_text() == (tmp_path / "b.json").read_text()


def test_a_fit_comes_back_whole_from_a_worker_process(stair, tmp_path):
    here = mckibben.fit(stair, pop=20, gens=5, seed=4)
    # `spawn` pickles everything both ways (`fork` would copy the trace).
    context = multiprocessing.get_context("spawn")
    with concurrent.futures.ProcessPoolExecutor(1, mp_context=context) as pool:
        there = pool.submit(mckibben.fit, stair, pop=20, gens=5, seed=4).result()
    assert isinstance(there, mckibben.FitResult) and there.model == here.model
    assert repr(there).startswith("FitResult(de classic fit, val_fit_percent = ")
    assert there.params == here.params and there.sse == here.sse
    assert there.std_errors == here.std_errors and there.records == here.records
    assert there.search_box["names"] == here.search_box["names"]
    assert np.array_equal(there.search_box["lower"], here.search_box["lower"])
    assert there.history.keys() == here.history.keys()
    for name, values in here.history.items():
        if name != "seconds":  # wall time, the one thing that differs
            # NaN where a generation had no value, equal to NaN here.
            np.testing.assert_array_equal(there.history[name], values, err_msg=name)
    # The model file, provenance and box included, comes back byte for byte.
    copied = copy.deepcopy(here)
    here.model.save(tmp_path / "here.json")
    copied.model.save(tmp_path / "copied.json")
    assert (tmp_path / "here.json").read_bytes() == (tmp_path / "copied.json").read_bytes()


def test_a_model_pickles_as_its_file(small_fit, tmp_path):
    model = small_fit.model
    back = pickle.loads(pickle.dumps(model))
    assert back == model and back.params == model.params
    model.save(tmp_path / "a.json")
    back.save(tmp_path / "b.json")
    assert (tmp_path / "a.json").read_bytes() == (tmp_path / "b.json").read_bytes()


def test_a_diagnosis_pickles_with_its_document_and_models(stair):
    got = mckibben.diagnose(
        stair, effects=["delay"], seeds=1, generations=5, scratch_seeds=0
    )
    back = pickle.loads(pickle.dumps(got))
    assert back.document == got.document
    assert back.model == got.model and back.baseline == got.baseline
    assert repr(back) == repr(got) and repr(got).startswith("Diagnosis(classic + [")
