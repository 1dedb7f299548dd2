"""sd.plot: Bode and loop-gain figures (matplotlib, the optional `plot` extra; CI installs it)."""

import numpy as np
import pytest

import sdtoolkit as sd

mpl = pytest.importorskip("matplotlib")
mpl.use("Agg")


def test_bode_draws_the_measurement_last_with_units_and_unwrapped_phase(stage):
    P = sd.c2d(stage, 1e-3)
    f = np.arange(1, 1000) * 0.5
    g = sd.freqresp(P, f, squeeze=False)
    frd = sd.Frd(f, g * 1.05, np.full(g.shape, 1e-14), 1e-3)
    fig, (am, ap) = sd.plot.bode(P, frd, labels=["model", "measured"], unit="m/N")
    assert am.get_ylabel() == "magnitude [dB re 1 m/N]"
    assert ap.get_xlabel() == "frequency [Hz]" and ap.get_ylabel() == "phase [°]"
    # the measurement is the last line drawn (on top), with its ±2σ band
    assert am.lines[-1].get_label() == "measured"
    assert any("±2σ" in c.get_label() for c in am.collections)
    for line in ap.lines:
        y = line.get_ydata()
        assert np.all(np.abs(np.diff(y)) < 180.0), "phase not unwrapped"
        assert -300.0 < y[0] <= 60.0
    # the legend is outside the axes (off the data)
    leg = am.get_legend()
    assert leg is not None and leg.get_bbox_to_anchor().x0 >= am.get_window_extent().x1 - 1


def test_loop_marks_the_margins_of_analyze(stage):
    P = sd.c2d(stage, 1e-3)
    K = sd.weight_pid(30.0, 2.0, dt=1e-3)
    fig, (am, ap), r = sd.plot.loop(P, K)
    texts = [t.get_text() for t in am.texts]
    assert any(t.startswith("PM") and f"{r.phase_margin_deg:.1f}" in t for t in texts)
    assert any(t.startswith("GM") for t in texts)
    f = np.arange(1, 1000) * 0.5
    frd = sd.Frd(f, sd.freqresp(P, f, squeeze=False), None, 1e-3)
    _, _, rm = sd.plot.loop(frd, K)
    assert rm.phase_margin_deg == pytest.approx(r.phase_margin_deg, abs=0.05)


def test_unwrap_starts_on_the_stated_branch():
    assert sd.plot.unwrap_deg(np.array([170.0, -170.0]))[0] == pytest.approx(-190.0)
    # −90°, then +170° is −190° and −170° stays −170°: steps below 180° in magnitude
    assert np.allclose(sd.plot.unwrap_deg(np.array([-90.0, 170.0, -170.0])), [-90.0, -190.0, -170.0])
