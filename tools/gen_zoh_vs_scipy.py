"""Generate test_data/zoh_vs_scipy.json: ZOH discretizations of stiff and lightly damped
systems against a 60-digit reference (mpmath's expm of [[A, B], [0, 0]]·h, rounded to double at
the end), with scipy.signal.cont2discrete's relative error on the same case recorded beside it:
the test (tests/tests/zoh_reference.rs) requires sd_model's c2d to be at or below scipy's error.
Run once (python3 tools/gen_zoh_vs_scipy.py, with numpy, scipy and mpmath); the output is
committed, never needed at test time."""
import json
import math

import mpmath as mp
import numpy as np
import scipy.signal

from mp_zoh import zoh_mp

mp.mp.dps = 60
rng = np.random.default_rng(20261127)


def condition(A, B, h, trials=3):
    """A lower estimate of the relative condition number of exp at M = [[A, B], [0, 0]]·h:
    max over random unit directions E of ‖L(M, E)‖_F·‖M‖_F/‖e^M‖_F, the Fréchet derivative
    L(M, E) the upper-right block of exp([[M, E], [0, M]]) (Van Loan 1978), in 60 digits."""
    n, m = B.shape
    k = n + m
    M = np.zeros((k, k))
    M[:n, :n] = A * h
    M[:n, n:] = B * h
    eM = mp.expm(mp.matrix(M.tolist()))
    norm = lambda X: mp.sqrt(sum(X[i, j] ** 2 for i in range(X.rows) for j in range(X.cols)))
    best = 0.0
    for _ in range(trials):
        E = rng.standard_normal((k, k))
        E[n:, :] = 0.0
        E /= np.linalg.norm(E)
        big = np.zeros((2 * k, 2 * k))
        big[:k, :k] = M
        big[k:, k:] = M
        big[:k, k:] = E
        L = mp.expm(mp.matrix(big.tolist()))
        Lb = mp.matrix(k, k)
        for i in range(k):
            for j in range(k):
                Lb[i, j] = L[i, k + j]
        best = max(best, float(norm(Lb) * np.linalg.norm(M) / norm(eM)))
    return best


def rel(x, ref):
    return float(np.linalg.norm(x - ref) / np.linalg.norm(ref))


def similarity(Ablk, cond):
    n = Ablk.shape[0]
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    s = np.exp(rng.uniform(0, math.log(cond), n))
    T = Q @ np.diag(s)
    return T @ Ablk @ np.linalg.inv(T)


def modal(freqs_hz, zetas):
    n = 2 * len(freqs_hz)
    A = np.zeros((n, n))
    for k, (f, z) in enumerate(zip(freqs_hz, zetas)):
        w = 2 * math.pi * f
        A[2 * k:2 * k + 2, 2 * k:2 * k + 2] = [[0.0, 1.0], [-w * w, -2 * z * w]]
    return A


cases = []


def add(name, A, B, h):
    Ad, Bd = zoh_mp(A, B, h)
    n = A.shape[0]
    C = np.zeros((1, n))
    D = np.zeros((1, B.shape[1]))
    sa, sb, _, _, _ = scipy.signal.cont2discrete((A, B, C, D), h, method="zoh")
    cases.append({
        "name": name, "h": h, "A": A.tolist(), "B": B.tolist(),
        "Ad": Ad.tolist(), "Bd": Bd.tolist(),
        "scipy_err_A": rel(sa, Ad), "scipy_err_B": rel(sb, Bd),
        "condition": condition(A, B, h),
    })
    print(f"{name}: n={n} scipy A {rel(sa, Ad):.2e} B {rel(sb, Bd):.2e} "
          f"κ {cases[-1]['condition']:.2e}", flush=True)


# lightly damped: 8 modes (16 states), three inputs, ζ 1e-4..1e-2, 50 Hz..2 kHz, at 5 kHz and 1 kHz
for h in (2e-4, 1e-3):
    f = np.exp(rng.uniform(math.log(50), math.log(2000), 8))
    z = np.exp(rng.uniform(math.log(1e-4), math.log(1e-2), 8))
    add(f"light16_h{h:g}", modal(f, z), rng.standard_normal((16, 3)), h)
    add(f"light16_sim_h{h:g}", similarity(modal(f, z), 10.0), rng.standard_normal((16, 3)), h)
# stiff: real poles from -1 to -1e6 (a fast current loop beside a slow thermal mode) and mixed
for n, span in ((6, 1e6), (12, 1e5)):
    p = -np.exp(rng.uniform(0, math.log(span), n))
    add(f"stiff_real_n{n}", similarity(np.diag(p), 10.0), rng.standard_normal((n, 2)), 1e-3)
Ab = modal([5.0, 300.0, 3000.0], [0.01, 0.002, 0.05])
Ab = np.block([[Ab, np.zeros((6, 2))], [np.zeros((2, 6)), np.diag([-2e5, -5e4])]])
add("stiff_mixed_n8", similarity(Ab, 4.0), rng.standard_normal((8, 2)), 2e-4)
# a rigid body (double integrator) with lightly damped modes
Ab = modal([0.0, 650.0, 1650.0, 2400.0], [0.0, 0.01, 0.005, 0.002])
Ab[0:2, 0:2] = [[0.0, 1.0], [0.0, 0.0]]
add("rigid_modes_n8", Ab, rng.standard_normal((8, 1)), 1e-3)

with open("test_data/zoh_vs_scipy.json", "w") as fh:
    json.dump({"generator": "tools/gen_zoh_vs_scipy.py (mpmath expm, 60 digits; scipy "
               + scipy.__version__ + ")", "cases": cases}, fh)
