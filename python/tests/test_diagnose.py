"""diagnose: the document `mckibben diagnose --json` prints."""

import pytest

import mckibben


def test_diagnose_returns_the_commands_document(stair, cli):
    args = dict(effects=["delay"], seeds=1, generations=10, scratch_seeds=0)
    expected = cli(
        "diagnose", stair.source, "--effects", "delay", "--seeds", "1",
        "--generations", "10", "--scratch-seeds", "0",
    )
    got = mckibben.diagnose(stair, **args)
    assert got == expected
    assert got["schema_version"] == 1 and "verdict" in got and "final" in got
    again = mckibben.diagnose([(stair.input, stair.output, stair.dt)], **args)
    assert again["baseline"]["params"] == got["baseline"]["params"]


def test_diagnose_rejects_bad_arguments(stair):
    with pytest.raises(ValueError, match="unknown effect `wobble`"):
        mckibben.diagnose(stair, effects=["wobble"])
    with pytest.raises(ValueError, match="datasets is empty"):
        mckibben.diagnose([])
    with pytest.raises(TypeError, match="datasets must be"):
        mckibben.diagnose(3)
    with pytest.raises(ValueError, match="seeds must be at least 1"):
        mckibben.diagnose(stair, seeds=0)
