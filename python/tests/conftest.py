"""Shared fixtures: the shipped stair, the command-line binary, a small fit.

With CI=true (as `.ci/run` sets), what a test needs and lacks (the
`mckibben` binary that `cargo test --release` builds, a Vulkan adapter for
the GPU checks) fails the test instead of skipping it, as the Rust tests do
(tests/common/mod.rs).
"""

import json
import os
import pathlib
import signal
import subprocess

import pytest

import mckibben

REPO = pathlib.Path(__file__).resolve().parents[2]
STAIR = REPO / "data" / "stair_4.5kg.csv"
IN_CI = os.environ.get("CI") == "true"


def missing(what):
    """Skip, or fail under CI=true, for something the machine lacks."""
    if IN_CI:
        pytest.fail(f"CI=true but {what}")
    pytest.skip(f"SKIP: {what}")


@pytest.fixture
def sigint_raises():
    """SIGINT raises KeyboardInterrupt for the test, as at an interactive
    prompt. Python leaves SIGINT ignored when its parent ignored it (a
    shell's background job does), and a Ctrl-C test would then see no
    Ctrl-C at all."""
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    yield
    signal.signal(signal.SIGINT, previous)


@pytest.fixture(scope="session")
def stair():
    return mckibben.read_csv(STAIR)


@pytest.fixture(scope="session")
def binary():
    """The `mckibben` binary: MCKIBBEN_BIN, else target/release/mckibben."""
    path = pathlib.Path(os.environ.get("MCKIBBEN_BIN", REPO / "target" / "release" / "mckibben"))
    if not path.exists():
        missing(f"no mckibben binary at {path} (run `cargo build --release` first)")
    return path


@pytest.fixture(scope="session")
def cli(binary):
    """Runs the `mckibben` binary with `--json` and returns its document."""

    def run(*args):
        out = subprocess.run(
            [str(binary), *map(str, args), "--json"],
            check=True,
            capture_output=True,
            text=True,
            cwd=REPO,
        )
        return json.loads(out.stdout)

    return run


@pytest.fixture(scope="session")
def small_fit(stair):
    """A quick fit of the stair (N = 40, G = 20)."""
    return mckibben.fit(stair, pop=40, gens=20, seed=3)
