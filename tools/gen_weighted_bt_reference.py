"""Frequency-weighted (Enns) balanced truncation references, committed as
test_data/weighted_bt_reference.json for `tests/tests/controller_reduction.rs`.
Usage: python3 tools/gen_weighted_bt_reference.py   (numpy, scipy; run once, not at test time)

Eight seeded stable discrete systems G (n 4-10, 1-2 inputs and outputs, spectral radius 0.6-0.98)
with a stable input weight V (2-4 states): P = leading n x n block of the controllability
Gramian of the cascade G V (scipy.linalg.solve_discrete_lyapunov), Q = observability Gramian of
G, and the weighted Hankel singular values sqrt(eig(P Q)), descending.
"""
import json
import numpy as np
import scipy.linalg as sl

rng = np.random.default_rng(4105)


def stable(n, rho):
    a = rng.standard_normal((n, n))
    return a * rho / np.max(np.abs(np.linalg.eigvals(a)))


cases = []
for i in range(8):
    n, m, p = int(rng.integers(4, 11)), int(rng.integers(1, 3)), int(rng.integers(1, 3))
    a = stable(n, rng.uniform(0.6, 0.98))
    b, c, d = rng.standard_normal((n, m)), rng.standard_normal((p, n)), rng.standard_normal((p, m))
    nv = int(rng.integers(2, 5))
    av = stable(nv, rng.uniform(0.3, 0.9))
    bv, cv, dv = rng.standard_normal((nv, m)), rng.standard_normal((m, nv)), rng.standard_normal((m, m))
    # cascade G V: states [x_G; x_V], x_G' = A x_G + B Cv x_V + B Dv u, x_V' = Av x_V + Bv u
    ac = np.block([[a, b @ cv], [np.zeros((nv, n)), av]])
    bc = np.vstack([b @ dv, bv])
    pc = sl.solve_discrete_lyapunov(ac, bc @ bc.T)
    pw = pc[:n, :n]
    q = sl.solve_discrete_lyapunov(a.T, c.T @ c)
    hsv = np.sqrt(np.maximum(np.sort(np.linalg.eigvals(pw @ q).real)[::-1], 0.0))
    cases.append({"g": {"type": "ss", "ts": 1e-3, "a": a.tolist(), "b": b.tolist(),
                        "c": c.tolist(), "d": d.tolist()},
                  "v": {"type": "ss", "ts": 1e-3, "a": av.tolist(), "b": bv.tolist(),
                        "c": cv.tolist(), "d": dv.tolist()},
                  "weighted_hsv": hsv.tolist()})
with open("test_data/weighted_bt_reference.json", "w") as f:
    json.dump({"generator": "tools/gen_weighted_bt_reference.py", "cases": cases}, f, indent=1)
print(len(cases), "cases")
