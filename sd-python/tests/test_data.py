"""Data: testbed, frf, frf_from_arrays, fit — against `sdctl` on the same files."""

import json

import numpy as np
import pytest

import sdtoolkit as sd

from test_models import SAME, close


def test_testbed_writes_what_sdctl_reads(stage_data):
    names = [e.name for e in stage_data.experiments]
    assert names == ["fast", "slow"]
    fast = stage_data.experiments[0]
    assert fast.rate_hz == 5000.0 and fast.role == "model" and fast.period == 5000
    assert fast.u.shape == fast.y.shape == (5 * 5000,)
    assert stage_data.truth.dt is None and stage_data.truth.nstates >= 6


def test_frf_matches_sdctl_and_the_arrays_route(stage_data, sdctl):
    m = stage_data.manifest
    ours = sd.frf(m, "fast")
    cli = sd.Frd.from_json(sdctl("frf", m, "--experiment", "fast"))
    close(ours.freq_hz, cli.freq_hz, SAME)
    close(ours.response, cli.response, SAME)
    close(ours.variance, cli.variance, SAME)
    assert ours.dt == 2e-4
    e = stage_data.experiments[0]
    arr = sd.frf_from_arrays(e.r, e.u, e.y, e.rate_hz, period=e.period, skip_periods=e.skip_periods)
    close(arr.response, ours.response, 1e-12)
    # non-periodic route (LPM) on the same record, open loop
    lpm = sd.frf_from_arrays(None, e.u, e.y, e.rate_hz)
    assert lpm.response.shape[2] > 100 and lpm.variance is not None


def test_fit_matches_sdctl(stage_data, sdctl, tmp_path):
    frd = sd.frf(stage_data.manifest, "slow")
    keep = frd.freq_hz >= 2.0
    frd = sd.Frd(frd.freq_hz[keep], frd.response[..., keep], frd.variance[..., keep], frd.dt)
    r = sd.fit(frd, 8, rigid_body=2, strictly_proper=True)
    p = tmp_path / "slow.json"
    p.write_text(frd.to_json())
    cli = json.loads(sdctl("fit", p, "--order", 8, "--rigid-body", 2, "--strictly-proper", "--json"))
    assert r.cost == pytest.approx(cli["cost"], rel=1e-9)
    assert r.model.nstates == 8 and r.model.dt == 1e-3
    assert len(r.line_cost) == len(frd.freq_hz) and len(r.poles) == 8
    assert np.all(np.abs(r.poles) <= 1.0 + 1e-12)


def test_diagnose_matches_sdctl(stage_data, sdctl, tmp_path):
    ours = sd.diagnose(stage_data.manifest, out=tmp_path / "py")
    sdctl("diagnose", stage_data.manifest, "--out", tmp_path / "cli")
    cli = json.loads((tmp_path / "cli" / "diagnosis.json").read_text())
    written = json.loads((tmp_path / "py" / "diagnosis.json").read_text())
    assert (tmp_path / "py" / "report.md").is_file()
    assert ours.to_dict().keys() == cli.keys() == written.keys()
    assert ours.verdict == cli["verdict"] and ours.cause == cli["cause"] == "averaging_sampler"
    assert ours.parameters.window_frac == pytest.approx(cli["parameters"]["window_frac"], rel=1e-9)
    assert ours.gain.ratio == pytest.approx(cli["gain"]["ratio"], rel=1e-9)
