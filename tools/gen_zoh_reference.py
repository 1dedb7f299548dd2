"""Generate test_data/zoh_random.json: ZOH references computed in 50-digit arithmetic (mpmath).

Independent of the Rust code: the block exponential expm([[A, B], [0, 0]] h) is evaluated by
mpmath's own scaling-and-squaring Taylor method at mp.dps = 50 and rounded to double at the end.
Run once (python3 tools/gen_zoh_reference.py); the output is committed, never needed at test time.
The 60-state stage uses the same formula as sd_model::stage::stage60 (a test checks they agree).
"""
import json, math
import numpy as np
import mpmath as mp

from mp_zoh import zoh_mp

mp.mp.dps = 50
rng = np.random.default_rng(20261121)


def similarity(Ablk, cond=10.0):
    n = Ablk.shape[0]
    Q, _ = np.linalg.qr(rng.standard_normal((n, n)))
    s = np.exp(rng.uniform(0, math.log(cond), n))
    T = Q @ np.diag(s)
    return T @ Ablk @ np.linalg.inv(T)


def oscillatory(n, fmax, zmin, zmax):
    A = np.zeros((n, n))
    k = 0
    while k + 1 < n:
        w = 2 * math.pi * rng.uniform(1, fmax)
        z = rng.uniform(zmin, zmax)
        A[k:k + 2, k:k + 2] = [[-z * w, w * math.sqrt(1 - z * z)], [-w * math.sqrt(1 - z * z), -z * w]]
        k += 2
    if k < n:
        A[k, k] = -rng.uniform(1, 100)
    return A


def stage60():
    modes = []
    for i in range(29):
        t = i / 28.0
        f = 300.0 * 20.0 ** t
        u = ((i * 7) % 29) / 28.0
        zeta = 0.002 * 15.0 ** u
        r = (1.0 if i % 2 == 0 else -0.6) * (1.0 - 0.8 * t) * 2.0
        modes.append((f, zeta, r))
    n = 60
    A = np.zeros((n, n)); B = np.zeros((n, 1)); m = 20.0
    A[0, 1] = 1.0; B[1, 0] = 1.0 / m
    k = 2
    for f, z, r in modes:
        w = 2 * math.pi * f
        A[k, k + 1] = 1.0; A[k + 1, k] = -w * w; A[k + 1, k + 1] = -2 * z * w; B[k + 1, 0] = r / m
        k += 2
    return A, B


cases = []
def add(name, A, B, h):
    Ad, Bd = zoh_mp(A, B, h)
    cases.append({"name": name, "h": h, "A": A.tolist(), "B": B.tolist(), "Ad": Ad.tolist(), "Bd": Bd.tolist()})
    print(name, A.shape, flush=True)

for n in [3, 8, 20, 40, 60]:
    m = 1 + n % 3
    # stable: random matrix shifted left
    A = rng.standard_normal((n, n)) * 10
    A -= (np.max(np.linalg.eigvals(A).real) + rng.uniform(0.5, 5)) * np.eye(n)
    add(f"stable_n{n}", A, rng.standard_normal((n, m)), float(rng.uniform(1e-3, 0.1)))
    # oscillatory, lightly damped, well-conditioned similarity
    add(f"oscillatory_n{n}", similarity(oscillatory(n, 50, 0.001, 0.05)), rng.standard_normal((n, m)), float(rng.uniform(1e-3, 0.02)))
    # integrating: a chain of two integrators (Jordan block at 0) plus oscillatory modes
    Ab = oscillatory(n, 50, 0.005, 0.05)
    Ab[0:2, 0:2] = [[0, 1], [0, 0]]
    add(f"integrating_n{n}", similarity(Ab, 4.0), rng.standard_normal((n, m)), float(rng.uniform(1e-3, 0.02)))

A, B = stage60()
add("stage60_h0.2ms", A, B, 2e-4)
add("stage60_h1ms", A, B, 1e-3)

with open("test_data/zoh_random.json", "w") as f:
    json.dump({"generator": "tools/gen_zoh_reference.py (mpmath expm, 50 digits)", "cases": cases}, f)
