"""Design and analysis: dare, care, loopshape, weight_pid, analyze — against `sdctl` and scipy."""

import json

import numpy as np
import pytest
import scipy.linalg as sl

import sdtoolkit as sd

from test_models import SAME, close


def riccati_case(n=6, seed=3):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    A /= 1.2 * max(abs(np.linalg.eigvals(A)))
    B = rng.standard_normal((n, 2))
    Q = np.eye(n)
    R = np.eye(2)
    return A, B, Q, R


def test_dare_and_care_against_scipy():
    A, B, Q, R = riccati_case()
    r = sd.dare(A, B, Q, R)
    ref = sl.solve_discrete_are(A, B, Q, R)
    close(r.X, ref, 1e-9)
    assert r.residual < 1e-12 and r.closed_loop < 1.0 and r.condition >= 1.0
    close(r.K, np.linalg.solve(R + B.T @ ref @ B, B.T @ ref @ A), 1e-9)
    c = sd.care(A - 0.5 * np.eye(6), B, Q, R)
    close(c.X, sl.solve_continuous_are(A - 0.5 * np.eye(6), B, Q, R), 1e-9)
    assert c.closed_loop < 0.0


def test_generalized_riccati_with_e():
    """#40 item 5: E ≠ I (scipy's ``e=``): the generalized equation holds to rounding and the
    closed loop λ(A − BK, E) is stable; on a case scipy solves, X equals scipy's."""
    rng = np.random.default_rng(7)
    n, m = 4, 2
    A = rng.standard_normal((n, n))
    E = np.eye(n) + 0.3 * rng.standard_normal((n, n))
    B = rng.standard_normal((n, m))
    Q, R = np.eye(n), np.eye(m)
    c = sd.care(A, B, Q, R, E=E)
    X = c.X
    res = A.T @ X @ E + E.T @ X @ A - E.T @ X @ B @ np.linalg.solve(R, B.T @ X @ E) + Q
    assert np.linalg.norm(res) <= 1e-12 * (1 + np.linalg.norm(X) * np.linalg.norm(A) * np.linalg.norm(E))
    assert c.residual < 1e-13
    assert max(np.linalg.eigvals(np.linalg.solve(E, A - B @ c.K)).real) < 0
    d = sd.dare(0.5 * A, B, Q, R, E=E)
    Xd = d.X
    Ad = 0.5 * A
    K = np.linalg.solve(R + B.T @ Xd @ B, B.T @ Xd @ Ad)
    res = Ad.T @ Xd @ Ad - E.T @ Xd @ E - Ad.T @ Xd @ B @ K + Q
    assert np.linalg.norm(res) <= 1e-11 * (1 + np.linalg.norm(Xd))
    assert max(abs(np.linalg.eigvals(np.linalg.solve(E, Ad - B @ d.K)))) < 1
    try:
        ref = sl.solve_continuous_are(A, B, Q, R, e=E)
    except ValueError:
        ref = None  # scipy refuses many well-conditioned E (test_data/descriptor_riccati.json)
    if ref is not None:
        close(X, ref, 1e-9)
    with pytest.raises(ValueError, match="E is singular"):
        sd.care(A, B, Q, R, E=np.diag([1.0, 1.0, 1.0, 0.0]))


def test_complex_riccati_keeps_the_imaginary_parts():
    """#40 item 1: complex A, B, Q, R (and only a complex B) solve the equation with conjugate
    transposes — its residual to rounding, the closed loop stable, X Hermitian and complex —
    and X equals scipy's complex solution."""
    rng = np.random.default_rng(11)
    n, m = 4, 2
    cr = lambda *s: rng.standard_normal(s) + 1j * rng.standard_normal(s)  # noqa: E731
    A, B, C = cr(n, n) / 2, cr(n, m), cr(n, n)
    Q = C.conj().T @ C + 0.1 * np.eye(n)
    R = np.eye(m) + 0.2 * (lambda r: r @ r.conj().T)(cr(m, m))
    H = lambda x: x.conj().T  # noqa: E731
    c = sd.care(A, B, Q, R)
    X = c.X
    assert np.iscomplexobj(X) and np.linalg.norm(X.imag) > 0.1 * np.linalg.norm(X)
    assert np.array_equal(X, H(X))
    res = H(A) @ X + X @ A - X @ B @ np.linalg.solve(R, H(B) @ X) + Q
    assert np.linalg.norm(res) <= 1e-13 * (np.linalg.norm(Q) + np.linalg.norm(X) * np.linalg.norm(A)
                                           + np.linalg.norm(X @ B) ** 2)
    assert max(np.linalg.eigvals(A - B @ c.K).real) < 0
    close(X, sl.solve_continuous_are(A, B, Q, R), 1e-9)
    Ad = 1.1 * A / max(abs(np.linalg.eigvals(A)))
    d = sd.dare(Ad, B, Q, R)
    K = np.linalg.solve(R + H(B) @ d.X @ B, H(B) @ d.X @ Ad)
    close(d.K, K, 1e-10)
    res = H(Ad) @ d.X @ Ad - d.X - H(Ad) @ d.X @ B @ K + Q
    assert np.linalg.norm(res) <= 1e-12 * np.linalg.norm(d.X)
    assert max(abs(np.linalg.eigvals(Ad - B @ d.K))) < 1
    close(d.X, sl.solve_discrete_are(Ad, B, Q, R), 1e-9)
    # only B complex: the real parts alone would be a different equation
    Br = B.real + 1j * B.imag
    e = sd.dare(Ad.real, Br, Q.real, R.real)
    close(e.X, sl.solve_discrete_are(Ad.real, Br, Q.real, R.real), 1e-9)
    assert np.linalg.norm(e.X - sd.dare(Ad.real, Br.real, Q.real, R.real).X) > 1e-3
    with pytest.raises(ValueError, match="Q must be Hermitian"):
        sd.care(A, B, Q + 1j * np.eye(n), R)


def test_care_near_the_axis_carex_2_8():
    # CAREX 2.8 (ε = 1e-6): Hamiltonian eigenvalues ±5e-13 off the axis at ±1j; scipy solves it
    e = 1e-6
    A = np.array([[-e, 1, 0, 0], [-1, -e, 0, 0], [0, 0, e, 1], [0, 0, -1, e]])
    B, Q, R = np.ones((4, 1)), np.ones((4, 4)), np.eye(1)
    c = sd.care(A, B, Q, R)
    X = c.X
    res = A.T @ X + X @ A - X @ B @ B.T @ X + Q
    assert np.linalg.norm(res) <= 1e-12 * (1 + np.linalg.norm(X) ** 2)
    assert -1e-6 < c.closed_loop < 0.0
    ref = sl.solve_continuous_are(A, B, Q, R)
    res_ref = A.T @ ref + ref @ A - ref @ B @ B.T @ ref + Q
    assert np.linalg.norm(res) <= 10 * np.linalg.norm(res_ref) + 1e-15


def test_dare_without_a_solution_says_why():
    with pytest.raises(ValueError) as e:
        sd.dare([[2.0]], [[0.0]], [[1.0]], [[1.0]])
    assert str(e.value)  # one line naming the reason
    assert "\n" not in str(e.value)


def test_loopshape_weight_and_analyze_match_sdctl(stage, sdctl, tmp_path):
    P = sd.c2d(stage, 1e-3)
    W = sd.weight_pid(30.0, 2.0, dt=1e-3)
    cliW = sd.StateSpace.from_json(sdctl("weight", "pid", "--bandwidth-hz", 30, "--mass", 2.0, "--ts", 1e-3))
    for m in "ABCD":
        close(getattr(W, m), getattr(cliW, m), SAME)
    d = sd.loopshape(P, W)
    pp, wp = tmp_path / "p.json", tmp_path / "w.json"
    pp.write_text(P.to_json())
    wp.write_text(W.to_json())
    cli = json.loads(sdctl("loopshape", pp, "--w1", wp, "--json"))
    assert d.gamma_min == pytest.approx(cli["gamma_min"], rel=1e-12)
    assert d.achieved == pytest.approx(cli["achieved"], rel=1e-9)
    assert d.closed_loop_stable and cli["closed_loop_stable"]
    assert 1.0 < d.gamma / d.gamma_min < 1.1 + 1e-12
    K = d.controller
    assert K.dt == 1e-3
    a = sd.analyze(P, K)
    kp = tmp_path / "k.json"
    kp.write_text(K.to_json())
    cli_a = json.loads(sdctl("analyze", "--plant", pp, "--controller", kp, "--json"))
    assert a.stable and cli_a["stable"]
    for k in ("sensitivity_peak_db", "crossover_hz", "phase_margin_deg", "gain_margin_db"):
        assert getattr(a, k) == pytest.approx(cli_a[k], rel=1e-6), k
    assert a.to_dict().keys() == cli_a.keys()
    ny = a.to_dict()["nyquist"]
    # the same count (the accumulated argument's roundoff may differ through the JSON file)
    same = {k: v for k, v in ny.items() if k != "turn_residual"}
    assert same == {k: v for k, v in cli_a["nyquist"].items() if k != "turn_residual"}
    assert ny["agrees"] and ny["stable"] and ny["turn_residual"] < 1e-6


def test_c2d_matched_and_impulse_match_scipy_and_the_definition():
    # impulse-invariant: scipy's cont2discrete(method="impulse") is the same mapping
    import scipy.signal as ss
    A = np.array([[0.0, 1.0], [-100.0, -2.0]])
    B, C, D = np.array([[0.0], [100.0]]), np.array([[1.0, 0.0]]), np.zeros((1, 1))
    G = sd.StateSpace(A, B, C, D)
    i = sd.c2d(G, 0.01, method="impulse")
    ad, bd, cd, dd, _ = ss.cont2discrete((A, B, C, D), 0.01, method="impulse")
    w = np.exp(1j * np.linspace(0.01, 3.0, 7))
    for z in w:
        mine = (i.C @ np.linalg.solve(z * np.eye(2) - i.A, i.B) + i.D)[0, 0]
        ref = (cd @ np.linalg.solve(z * np.eye(2) - ad, bd) + dd)[0, 0]
        assert abs(mine - ref) <= 1e-12 * abs(ref)
    m = sd.c2d(G, 0.01, method="matched")
    assert np.allclose(sorted(np.abs(np.linalg.eigvals(m.A))), sorted(np.abs(np.exp(np.linalg.eigvals(A) * 0.01))))
    dc = (m.C @ np.linalg.solve(np.eye(2) - m.A, m.B) + m.D)[0, 0]
    assert abs(dc - 1.0) < 1e-10
    with pytest.raises(ValueError):
        sd.c2d(sd.StateSpace([[-1.0]], [[1.0]], [[1.0]], [[2.0]]), 0.01, method="impulse")


def test_analyze_a_measured_plant_against_its_model(stage, sdctl, tmp_path):
    """#40 item 5: ``analyze(frd, K)`` — the loop on the lines — gives the margins of the model
    it was measured from (the model-based analysis, bisection on the model, as the reference;
    python-control's ``stability_margins`` for the gain margin — its phase margin on this
    60-state loop, 12.7° at 36.8 Hz, is not a crossover of |L|), equals ``sdctl analyze
    --plant-frd``, and folds a fast FRF by Lemma 6 (``downsample``)."""
    import control
    P = sd.c2d(stage, 1e-3)
    K = sd.weight_pid(30.0, 2.0, dt=1e-3)
    f = np.arange(1, 1000) * 0.5
    frd = sd.Frd(f, sd.freqresp(P, f, squeeze=False), None, 1e-3)
    a = sd.analyze(frd, K)
    assert a.nyquist["verdict"] == "counted" and a.nyquist["stable"]
    gm = control.stability_margins(P.to_control() * K.to_control())[0]
    m = sd.analyze(P, K)
    pm = m.phase_margin_deg
    assert a.phase_margin_deg == pytest.approx(pm, abs=0.05)
    assert a.phase_margin_hz == pytest.approx(m.phase_margin_hz, rel=1e-3)
    assert a.gain_margin_db == pytest.approx(20 * np.log10(gm), abs=0.05)
    assert a.gain_margin_hz == pytest.approx(m.gain_margin_hz, rel=1e-2)
    S = a.S.response[0, 0]
    L = frd.response[0, 0] * sd.freqresp(K, f)
    assert np.max(np.abs(S - 1 / (1 + L))) < 1e-12 * np.max(np.abs(S))
    fp, kp = tmp_path / "f.json", tmp_path / "k.json"
    fp.write_text(frd.to_json())
    kp.write_text(K.to_json())
    cli = json.loads(sdctl("analyze", "--plant-frd", fp, "--controller", kp, "--json"))
    for k in ("phase_margin_deg", "gain_margin_db", "sensitivity_peak_db"):
        assert getattr(a, k) == pytest.approx(cli[k], rel=1e-9), k
    fast = sd.c2d(stage, 2e-4)
    ff = np.arange(1, 5001) * 0.5
    b = sd.analyze(sd.Frd(ff, sd.freqresp(fast, ff, squeeze=False), None, 2e-4), K, downsample=5)
    assert b.phase_margin_deg == pytest.approx(pm, abs=0.05)
    with pytest.raises(ValueError, match="sample time"):
        sd.analyze(sd.Frd(ff, sd.freqresp(fast, ff, squeeze=False), None, 2e-4), K)
    with pytest.raises(ValueError, match="measured plant"):
        sd.analyze(P, K, integrators=2)
