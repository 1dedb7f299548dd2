"""Uncertainty, intersample, multisine and weights — each against `sdctl` on the same input
(the same code behind both: equal to rounding) and against the mathematics where it is short."""

import json

import numpy as np
import pytest

import sdtoolkit as sd

from test_models import close


@pytest.fixture(scope="module")
def fitted(stage_data, tmp_path_factory):
    """The fast FRF of the virtual stage, a 6th-order fit of it, and both as files."""
    d = tmp_path_factory.mktemp("unc")
    frd = sd.frf(stage_data.manifest, "fast")
    keep = frd.freq_hz >= 2.0
    frd = sd.Frd(frd.freq_hz[keep], frd.response[..., keep], frd.variance[..., keep], frd.dt)
    model = sd.fit(frd, 6, rigid_body=2, strictly_proper=True).model
    (d / "frd.json").write_text(frd.to_json())
    (d / "m.json").write_text(model.to_json())
    return frd, model, d


def test_uncertainty_trio_matches_sdctl(fitted, sdctl):
    frd, model, d = fitted
    u = sd.uncertainty(model, frd, form="multiplicative", weight_order=4)
    cli = sdctl("uncertainty", d / "m.json", d / "frd.json", "--form", "multiplicative",
                "--weight-order", 4)
    assert json.loads(u.to_json()) == json.loads(cli)
    assert u.form == "multiplicative" and len(u.freq_hz) == len(frd.freq_hz)
    assert sd.Uncertainty.from_json(cli).to_json() == cli
    (d / "u.json").write_text(u.to_json())
    c = sd.coverage(u, frd)
    assert c.to_dict() == json.loads(sdctl("coverage", d / "u.json", d / "frd.json", "--json"))
    # the bound holds on its own lines at (about) its confidence
    assert c.fraction >= 0.9
    slow = sd.downsample_uncertainty(u, 5)
    sdctl("downsample", d / "m.json", "--factor", 5, "--uncertainty", d / "u.json",
          "--uncertainty-out", d / "u1.json", "-o", d / "m1.json")
    cli_slow = json.loads((d / "u1.json").read_text())
    mine = json.loads(slow.to_json())
    assert mine == cli_slow
    assert slow.ts == pytest.approx(1e-3) and isinstance(slow.missing_hz, list)
    # robust stability of a PID on the slow model against the slow bound
    m1 = sd.StateSpace.from_json(d / "m1.json")
    K = sd.weight_pid(10.0, 20.0, dt=1e-3)
    (d / "k.json").write_text(K.to_json())
    r = sd.robust_stability(m1, K, slow)
    cli_r = json.loads(sdctl("analyze", "--plant", d / "m1.json", "--controller", d / "k.json",
                             "--uncertainty", d / "u1.json", "--json"))["robust"]
    assert r.margin_lines == pytest.approx(cli_r["margin_lines"], rel=1e-12)
    with pytest.raises(ValueError, match="form"):
        sd.uncertainty(model, frd, form="relative")
    with pytest.raises(TypeError, match="weight_order"):
        sd.uncertainty(model, frd, weight_order=2.5)


def test_intersample_matches_sdctl(fitted, sdctl):
    frd, model, d = fitted
    K = sd.weight_pid(10.0, 20.0, dt=1e-3)
    (d / "k.json").write_text(K.to_json())
    r = sd.intersample(model, K, points=400)
    cli = json.loads(sdctl("intersample", "--plant-fast", d / "m.json", "--controller",
                           d / "k.json", "--points", 400, "--json"))
    for k in ("rms_fast", "rms_slow", "dominant_hz_fast", "dominant_hz_slow",
              "control_sensitivity_peak_hz"):
        assert getattr(r, k) == pytest.approx(cli[k], rel=1e-12), k
    close(r.fast_psd, np.asarray(cli["fast_psd"]), 1e-12)
    assert r.factor == 5 and r.rms_fast > 0 and r.rms_slow > 0
    with pytest.raises(ValueError, match="integer multiple"):
        sd.intersample(model, sd.weight_pid(10.0, 20.0, dt=7e-4))


def test_multisine_matches_sdctl_and_its_lines(sdctl, tmp_path):
    m = sd.multisine(1000.0, 1000, 2.0, 300.0, lines="random_odd", seed=3, rms=0.5)
    sdctl("multisine", "--fs", 1000, "--period", 1000, "--f-min", 2, "--f-max", 300,
          "--lines", "random-odd", "--seed", 3, "--rms", 0.5, "--periods", 2, "--skip", 1,
          "--out", tmp_path / "ms")
    col = np.loadtxt(tmp_path / "ms" / "exp_1.csv", delimiter=",", skiprows=1)
    u = col[:1000] if col.ndim == 1 else col[:1000, 0]
    close(m.signal, u, 1e-9)
    spec = np.fft.rfft(m.signal)
    excited = np.abs(spec) > 1e-8 * np.abs(spec).max()
    assert set(np.nonzero(excited)[0]) == set(m.excited_bins)
    assert all(b % 2 == 1 for b in m.excited_bins)
    assert np.sqrt(np.mean(m.signal ** 2)) == pytest.approx(0.5, rel=1e-12)
    two = sd.multisine(1000.0, 1000, 2.0, 300.0, inputs=2)
    assert len(two.signals) == 2 and len(two.signals[0]) == 2
    with pytest.raises(ValueError, match="lines"):
        sd.multisine(1000.0, 1000, 2.0, 300.0, lines="odd")


def test_weights_match_sdctl(sdctl):
    cases = [
        (sd.weight_notch(347.0, 0.01, 0.2, dt=1e-3),
         ("weight", "notch", "--freq-hz", 347, "--zeta-zero", 0.01, "--zeta-pole", 0.2, "--ts", 1e-3)),
        (sd.weight_lowpass(200.0, 0.7), ("weight", "lowpass", "--freq-hz", 200, "--zeta", 0.7)),
        (sd.makeweight(100.0, 10.0, 1.0, 0.1, order=2, dt=1e-3),
         ("weight", "makeweight", "--dc", 100, "--freq-hz", 10, "--mag", 1, "--hf", 0.1,
          "--order", 2, "--ts", 1e-3)),
    ]
    for w, args in cases:
        cli = sd.StateSpace.from_json(sdctl(*args))
        for k in "ABCD":
            close(getattr(w, k), getattr(cli, k), 1e-15)
    # the notch's depth ζz/ζp at its frequency, the low-pass's −3 dB… at ζ = 1/√2
    n = sd.freqresp(sd.weight_notch(347.0, 0.01, 0.2), np.array([347.0]))
    assert abs(n[0]) == pytest.approx(0.05, rel=1e-9)
    lp = sd.freqresp(sd.weight_lowpass(200.0, 2 ** -0.5), np.array([200.0]))
    assert abs(lp[0]) == pytest.approx(2 ** -0.5, rel=1e-9)
