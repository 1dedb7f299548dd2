"""Synthesis and controller reduction: hinfsyn, h2syn, mixsyn, reduce_controller — against
`sdctl` on the same inputs, and their refusals."""

import json

import numpy as np
import pytest

import sdtoolkit as sd

# x⁺ = 1.1x + w1 + u, z = [x; u], y = x + w2 at 1 kHz (the sdctl test's plant)
PLANT = sd.StateSpace([[1.1]], [[1.0, 0.0, 1.0]], [[1.0], [0.0], [1.0]],
                      [[0.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]], 1e-3)


def test_hinfsyn_and_h2syn_match_sdctl(sdctl, tmp_path):
    pp = tmp_path / "p.json"
    pp.write_text(PLANT.to_json())
    r = sd.hinfsyn(PLANT, 1, 1)
    cli = json.loads(sdctl("hinfsyn", pp, "--nmeas", 1, "--ncon", 1, "--json"))
    assert r.gamma_min == cli["gamma_min"]
    assert r.achieved_norm == pytest.approx(cli["achieved_norm"], rel=1e-12)
    assert r.achieved_norm <= r.gamma * (1 + 1e-6) and r.closed_loop_stable
    assert r.controller.dt == 1e-3 and len(r.steps) == len(cli["steps"])
    h = sd.h2syn(PLANT, 1, 1)
    cli = json.loads(sdctl("h2syn", pp, "--nmeas", 1, "--ncon", 1, "--json"))
    assert h.achieved_norm == pytest.approx(cli["achieved_norm"], rel=1e-12)
    assert h.closed_loop_stable


def test_hinfsyn_refuses_gamma_below_gamma_min():
    with pytest.raises(ValueError) as e:
        sd.hinfsyn(PLANT, 1, 1, gamma=0.01)
    assert "below γ_min" in str(e.value) and "\n" not in str(e.value)
    with pytest.raises(ValueError):
        sd.hinfsyn(PLANT, 3, 1)


def test_mixsyn_and_reduce_controller():
    # a damped double integrator at 1 kHz, W1 on S, a constant W2 on KS, an input disturbance
    G = sd.c2d(sd.StateSpace([[0.0, 1.0], [0.0, -0.1]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]]), 1e-3)
    one = lambda v: sd.StateSpace(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[v]], 1e-3)
    W = sd.weight_pid(20.0, 1.0, dt=1e-3)
    m = sd.mixsyn(G, W1=one(10.0), W2=one(0.01), Wd=one(1.0))
    assert m.closed_loop_stable and m.achieved_norm <= m.gamma * (1 + 1e-6)
    K = sd.loopshape(G, W).controller
    r = sd.reduce_controller(G, K, 3)
    assert r.order_before == K.A.shape[0] and r.order_after == 3
    assert r.after.stable and r.max_delta_s_db <= 0.1
    with pytest.raises(sd.NumericalError):
        sd.reduce_controller(G, K, 1)
    with pytest.raises(ValueError):
        sd.reduce_controller(G, K, 3, method="optimal")
    c = sd.reduce_controller(G, K, 3, method="coprime")
    assert c.method == "coprime_factor" and c.after.stable and c.order_after == 3
    f = sd.reduce_controller(G, K, 3, method="fit")
    assert f.method == "loop_fit" and f.after.stable and f.order_after == 3
    assert f.max_delta_s_db <= 0.1 and f.max_delta_t_db <= 0.1


def test_multirate_mixsyn_matches_sdctl(sdctl, tmp_path):
    # the same damped double integrator as the fast model at 1 kHz, the controller at 4 ms
    G = sd.c2d(sd.StateSpace([[0.0, 1.0], [0.0, -0.1]], [[0.0], [1.0]], [[1.0, 0.0]], [[0.0]]), 1e-3)
    one = lambda v: sd.StateSpace(np.zeros((0, 0)), np.zeros((0, 1)), np.zeros((1, 0)), [[v]], 1e-3)
    m = sd.mixsyn(G, W1=one(10.0), W2=one(0.01), Wd=one(1.0), factor=4, wn=1e-3)
    assert m.factor == 4 and m.closed_loop_stable
    assert m.achieved_norm <= m.gamma * (1 + 1e-6)
    assert abs(m.controller.dt - 4e-3) < 1e-15
    paths = {}
    for name, sys in (("g", G), ("w1", one(10.0)), ("w2", one(0.01)), ("wd", one(1.0))):
        paths[name] = tmp_path / f"{name}.json"
        paths[name].write_text(sys.to_json())
    cli = json.loads(sdctl("mixsyn", paths["g"], "--w1", paths["w1"], "--w2", paths["w2"],
                           "--wd", paths["wd"], "--factor", 4, "--wn", "1e-3", "--json"))
    assert cli["factor"] == 4
    assert m.gamma == pytest.approx(cli["gamma"], rel=1e-12)
    # the error weighted twice at the sample instants, as sdctl --at-samples 2
    m2 = sd.mixsyn(G, W1=one(10.0), W2=one(0.01), Wd=one(1.0), factor=4, wn=1e-3, at_samples=2.0)
    cli2 = json.loads(sdctl("mixsyn", paths["g"], "--w1", paths["w1"], "--w2", paths["w2"],
                            "--wd", paths["wd"], "--factor", 4, "--wn", "1e-3", "--at-samples", 2,
                            "--json"))
    assert m2.gamma == pytest.approx(cli2["gamma"], rel=1e-12)
    assert m2.gamma_min >= m.gamma_min * (1 - 1e-3)
    with pytest.raises(ValueError):
        sd.mixsyn(G, W1=one(10.0), Wd=one(1.0), factor=4, wn=1e-3, at_samples=0.0)
    with pytest.raises(ValueError):
        sd.mixsyn(G, W1=one(10.0), Wd=one(1.0), wn=1e-3, at_samples=2.0)
    with pytest.raises(ValueError):
        sd.mixsyn(G, W1=one(10.0), Wd=one(1.0), wn=1e-3)
    with pytest.raises(TypeError):
        sd.mixsyn(G, W1=one(10.0), Wd=one(1.0), factor=2.5, wn=1e-3)
