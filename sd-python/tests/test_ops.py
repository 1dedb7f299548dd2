"""tf, norm, balred (#43 item 4) — against python-control where it has the operation, and
against the mathematics (the balanced-truncation error bound) where it needs slycot."""

import control as ct
import numpy as np
import pytest

import sdtoolkit as sd

from test_models import close


def stable_random(n, seed, dt=None, proper=False):
    rng = np.random.default_rng(seed)
    A = rng.standard_normal((n, n))
    if dt is None:
        A -= (max(np.linalg.eigvals(A).real) + 0.5) * np.eye(n)
    else:
        A *= 0.9 / max(abs(np.linalg.eigvals(A)))
    B = rng.standard_normal((n, 1))
    C = rng.standard_normal((1, n))
    D = rng.standard_normal((1, 1)) if proper else np.zeros((1, 1))
    return A, B, C, D


def test_tf_is_python_controls():
    for dt in (None, 1e-3):
        num, den = [2.0, 1.0, 101.0], [1.0, 3.0, 10.0, 5.0]
        if dt:
            num, den = [0.0, 0.1, -0.05], [1.0, -1.8, 0.9]
        s = sd.tf(num, den, dt)
        ref = ct.tf(num, den, dt) if dt else ct.tf(num, den)
        f = np.linspace(0.1, 400.0, 50)
        pts = np.exp(2j * np.pi * f * dt) if dt else 2j * np.pi * f
        close(sd.freqresp(s, f), ref(pts), 1e-10)
    with pytest.raises(ValueError):
        sd.tf([1.0, 0.0, 0.0], [1.0, 1.0])  # improper
    with pytest.raises(TypeError, match="num is complex"):
        sd.tf([1j], [1.0, 1.0])


def test_norms_are_python_controls():
    for seed in range(4):
        for dt in (None, 1e-2):
            A, B, C, D = stable_random(5, seed, dt)
            ref = ct.ss(A, B, C, D, dt) if dt else ct.ss(A, B, C, D)
            s = sd.StateSpace(A, B, C, D, dt)
            assert abs(sd.norm(s, 2) / ct.norm(ref, 2) - 1) < 1e-9
            # python-control without slycot bisects the H∞ norm on a frequency grid
            h, peak = sd.norm(s, "inf", return_peak=True)
            assert abs(h / ct.norm(ref, "inf") - 1) < 1e-4
            g = abs(sd.freqresp(s, [peak])[0])
            assert abs(g / h - 1) < 1e-9
            assert s.norm(np.inf) == h
    with pytest.raises(ValueError, match="2 or"):
        sd.norm(s, 1)
    with pytest.warns(UserWarning, match="not stable"):
        sd.norm(sd.StateSpace([[0.5]], [[1.0]], [[1.0]], [[0.0]]), "inf")


def test_balred_within_its_bound():
    A, B, C, D = stable_random(10, 3, proper=True)
    s = sd.StateSpace(A, B, C, D)
    r = sd.balred(s, 4)
    assert r.model.A.shape == (4, 4)
    hsv = r.hankel_sv
    assert np.all(np.diff(hsv) <= 0) and abs(r.error_bound - 2 * hsv[4:].sum()) < 1e-12 * hsv[0]
    # ‖G − G_r‖∞ between σ₅ and 2Σ_{k>4} σ_k (Glover 1984)
    f = np.logspace(-3, 3, 4000)
    err = np.max(np.abs(sd.freqresp(s, f) - sd.freqresp(r.model, f)))
    assert hsv[4] * (1 - 1e-6) <= err * (1 + 1e-3) and err <= r.error_bound * (1 + 1e-9)
    with pytest.raises(TypeError):
        sd.balred(s, 4.0)
