"""Shared fixtures: the `sdctl` binary (the Rust result every function is checked against),
a lightly damped test stage, and a virtual-stage data set written once per session."""

import os
import pathlib
import subprocess

import numpy as np
import pytest

import sdtoolkit as sd

REPO = pathlib.Path(__file__).resolve().parents[2]


@pytest.fixture(scope="session")
def sdctl():
    """Runs `sdctl` (built by the README test command: target/release/sdctl; `SDCTL` overrides)
    and returns its stdout."""
    exe = os.environ.get("SDCTL", str(REPO / "target" / "release" / "sdctl"))
    if not os.path.isfile(exe):
        pytest.fail(f"{exe} is missing: build it with `cargo build --release -p sd-cli` (or set SDCTL)")

    def run(*args, stdin=None):
        p = subprocess.run([exe, *map(str, args)], input=stdin, capture_output=True, text=True)
        if p.returncode != 0:
            raise AssertionError(f"sdctl {' '.join(map(str, args))}: exit {p.returncode}: {p.stderr}")
        return p.stdout

    return run


def modal_stage(modes=((653.0, 0.01, 0.5), (1650.0, 0.02, -0.3), (2300.0, 0.015, 0.2)), mass=2.0):
    """A continuous rigid body plus lightly damped modes (Hz, damping, residue), SISO."""
    n = 2 + 2 * len(modes)
    A = np.zeros((n, n))
    B = np.zeros((n, 1))
    C = np.zeros((1, n))
    A[0, 1] = 1.0
    B[1, 0] = 1.0 / mass
    C[0, 0] = 1.0
    for i, (f, z, r) in enumerate(modes):
        w = 2 * np.pi * f
        k = 2 + 2 * i
        A[k, k + 1] = 1.0
        A[k + 1, k] = -w * w
        A[k + 1, k + 1] = -2 * z * w
        B[k + 1, 0] = r / mass
        C[0, k] = 1.0
    return sd.StateSpace(A, B, C, np.zeros((1, 1)))


@pytest.fixture(scope="session")
def stage():
    return modal_stage()


@pytest.fixture(scope="session")
def stage_data(tmp_path_factory):
    """The virtual stage's default two-rate identification with an averaging sensor (0.6 of each
    period), written as a manifest with CSVs."""
    out = tmp_path_factory.mktemp("stage")
    return sd.testbed(_default_config_with_averaging(0.6), out=out)


def _default_config_with_averaging(frac):
    return f"[nonideal]\naveraging = {frac}\n" + sd.DEFAULT_TESTBED_CONFIG
