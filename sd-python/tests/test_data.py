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


def test_multiaxis_testbed(tmp_path, sdctl):
    cfg = ("seed = 3\n[stage]\n[[experiment]]\nname = \"fast\"\nrate_hz = 2000.0\n"
           "period = 1000\nperiods = 3\nf_max = 900.0\n")
    d = sd.testbed(cfg, out=tmp_path / "axes")
    assert [e.name for e in d.experiments] == ["fast_1", "fast_2"]
    e = d.experiments[0]
    assert len(e.u) == 2 and len(e.y) == 3 and e.y[2].shape == (3 * 1000,)
    assert d.truth.nstates == 10
    # the files sdctl reads: the 3x2 FRF of the pair
    g = sd.Frd.from_json(sdctl("frf", d.manifest, "--experiment", "fast_1", "--experiment", "fast_2"))
    assert g.response.shape[:2] == (3, 2)


def test_multiaxis_diagnosis(tmp_path):
    exp = ("[[experiment]]\nname = \"{}\"\nrate_hz = {}\nrole = \"{}\"\nperiod = {}\n"
           "periods = 4\nf_max = {}\n")
    cfg = ("seed = 9\n[stage]\n[nonideal]\nhold_delay = [0.0, 0.3]\n"
           + exp.format("fast", 5000.0, "model", 2500, 2400.0)
           + exp.format("slow", 1000.0, "validation", 500, 499.0))
    d = sd.testbed(cfg, out=tmp_path / "axes")
    r = sd.diagnose(d.manifest, out=tmp_path / "diag").to_dict()
    assert r["kind"] == "mimo" and r["verdict"] == "discrepancy"
    named = [c for c in r["channels"] if c["named"]]
    assert [(c["kind"], c["channel"]) for c in named] == [("actuator", 1)]
    assert abs(named[0]["fraction"] - 0.3125) < 0.01
    # one slower set: the gain is measured on the data the delay was fitted on, and says so
    assert r["gain"]["held_out"] is False
    assert (tmp_path / "diag" / "report.md").exists()


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


def test_fit_of_a_mimo_frd_matches_sdctl(sdctl, tmp_path):
    # two lightly damped pairs with rank-one residues, 2x2, noise-free, at 1 kHz
    ts = 1e-3
    f = np.linspace(1.0, 450.0, 200)
    z = np.exp(2j * np.pi * f * ts)
    poles = [0.98 * np.exp(0.3j), 0.95 * np.exp(1.1j)]
    shapes = [(np.array([1.0, -0.4]), np.array([0.5, 0.2])), (np.array([0.3, 1.0]), np.array([-0.6, 0.8]))]
    g = np.zeros((2, 2, f.size), dtype=complex)
    for p, (c, b) in zip(poles, shapes):
        r = np.outer(c, b) * (0.05 + 0.02j)
        g += r[:, :, None] / (z - p) + np.conj(r)[:, :, None] / (z - np.conj(p))
    frd = sd.Frd(f, g, None, ts)
    r = sd.fit(frd, 4, strictly_proper=True)
    assert r.states == 4 and list(r.ranks) == [1, 1]
    assert r.median_rel_error < 1e-8
    p = tmp_path / "g.json"
    p.write_text(frd.to_json())
    cli = json.loads(sdctl("fit", p, "--order", 4, "--strictly-proper", "--json"))
    assert r.cost == pytest.approx(cli["cost"], rel=1e-6, abs=1e-20)
    assert cli["states"] == 4
    with pytest.raises(ValueError, match="rank"):
        sd.fit(frd, 4, rank="two")
    # input 1 recorded 3 samples late: the outputs lead it (G·diag(z^3, 1)); a fixed delay
    # list takes it back exactly, and the CLI gives the same fit
    lead = g.copy()
    lead[:, 0, :] *= z ** 3
    frd3 = sd.Frd(f, lead, None, ts)
    r3 = sd.fit(frd3, 4, strictly_proper=True, input_delay=[-3, 0])
    assert list(r3.input_delay) == [-3, 0] and r3.median_rel_error < 1e-8
    p3 = tmp_path / "g3.json"
    p3.write_text(frd3.to_json())
    cli3 = json.loads(sdctl("fit", p3, "--order", 4, "--strictly-proper", "--input-delay", "-3,0", "--json"))
    assert cli3["input_delay"] == [-3, 0]
    assert r3.cost == pytest.approx(cli3["cost"], rel=1e-6, abs=1e-20)
    with pytest.raises(ValueError, match="input_delay"):
        sd.fit(frd, 4, input_delay="soon")


_OTHER_RATE = """seed = 2
[nonideal]
averaging = 0.6

[[experiment]]
name = "mid"
rate_hz = 2500.0
role = "model"
pid_bandwidth_hz = 25.0
period = 2500
periods = 5
transient_periods = 1
f_min = 1.0
f_max = 1249.0
injection = "input"
"""


def test_predict_matches_sdctl_on_another_rate(stage_data, sdctl, tmp_path):
    sd.diagnose(stage_data.manifest, out=tmp_path / "diag")
    new = sd.testbed(_OTHER_RATE, out=tmp_path / "new")
    ours = sd.predict(tmp_path / "diag", new.manifest, out=tmp_path / "py")
    sdctl("predict", tmp_path / "diag", new.manifest, "--out", tmp_path / "cli")
    cli = json.loads((tmp_path / "cli" / "prediction.json").read_text())
    assert ours.to_dict().keys() == cli.keys()
    x, c = ours.experiments[0], cli["experiments"][0]
    assert ours.extension == "rate_tied" and x.why is None
    # the averaging window fitted at 5 kHz and 1 kHz predicts the 2.5 kHz experiment
    assert x.ratio == pytest.approx(c["ratio"], rel=1e-12) and x.ratio > 2.0
    assert (tmp_path / "py" / "report.md").is_file()
    assert (tmp_path / "py" / "frf_mid.svg").is_file()


def test_predict_refuses_when_nothing_can_be_predicted(stage_data, tmp_path):
    sd.diagnose(stage_data.manifest, out=tmp_path / "diag")
    new = sd.testbed(_OTHER_RATE.replace("2500.0", "1500.0").replace("2500", "1500")
                     .replace("1249.0", "749.0"), out=tmp_path / "new")
    with pytest.raises(ValueError, match="no whole fraction"):
        sd.predict(tmp_path / "diag", new.manifest)
    with pytest.raises(ValueError, match="predictor.json"):
        sd.predict(tmp_path / "new", new.manifest)


def test_fit_physical_matches_sdctl(stage_data, sdctl, tmp_path):
    frd = sd.frf(stage_data.manifest, "slow")
    keep = frd.freq_hz >= 2.0
    frd = sd.Frd(frd.freq_hz[keep], frd.response[..., keep], frd.variance[..., keep], frd.dt)
    r = sd.fit_physical(frd, max_order=10, max_delay=2)
    p = tmp_path / "slow.json"
    p.write_text(frd.to_json())
    sdctl("fit", p, "--stabilization", "--max-order", 10, "--max-delay", 2, "--out", tmp_path / "phys")
    cli = json.loads((tmp_path / "phys" / "modes.json").read_text())
    assert r.order == cli["order"] and r.rigid_body == cli["rigid_body"]
    assert r.delay_samples == pytest.approx(cli["delay_samples"], abs=1e-12)
    assert r.cost_per_line == pytest.approx(cli["cost_per_line"], rel=1e-9)
    assert [m["freq_hz"] for m in r.modes] == pytest.approx([m["freq_hz"] for m in cli["modes"]], rel=1e-9)
    lo, hi = r.delay_interval
    assert lo <= r.delay_samples <= hi
    model = sd.StateSpace.from_json((tmp_path / "phys" / "model.json").read_text())
    assert r.model.nstates == model.nstates and r.model.dt == frd.dt
    with pytest.raises(ValueError):
        sd.fit_physical(sd.Frd(frd.freq_hz, frd.response, frd.variance, None))


def test_fit_order_auto_matches_sdctl(stage_data, sdctl, tmp_path):
    frd = sd.frf(stage_data.manifest, "slow")
    keep = frd.freq_hz >= 2.0
    frd = sd.Frd(frd.freq_hz[keep], frd.response[..., keep], frd.variance[..., keep], frd.dt)
    r = sd.fit(frd, "auto", max_order=10)
    p = tmp_path / "slow.json"
    p.write_text(frd.to_json())
    cli = json.loads(sdctl("fit", p, "--order", "auto", "--max-order", 10, "--json"))
    assert r.order == cli["order"] and r.rigid_body == cli["rigid_body"]
    assert r.cost_per_line == pytest.approx(cli["cost_per_line"], rel=1e-9)
    assert r.model.nstates == len(cli["model"]["a"])
    with pytest.raises(ValueError, match="no model order"):
        sd.fit(frd, "sixty")
    with pytest.raises(ValueError, match="give a number of poles"):
        sd.fit(frd, "auto", weighting="uniform")
    with pytest.raises(TypeError):
        sd.fit(frd, 6.5)
