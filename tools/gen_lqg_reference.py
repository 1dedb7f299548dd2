"""Discrete LQR / Kalman references from python-control, and SLICOT's documented discrete H2
example, committed as test_data/lqg_reference.json for `tests/tests/h2syn.rs`.
Usage: python3 tools/gen_lqg_reference.py   (python-control 0.10.2, scipy, numpy; run once)

- dlqr: twelve seeded systems (n 2-8 states, m 1-3 inputs, A scaled to spectral radius
  0.5-1.3 so that some are open-loop unstable), weights [Q N; N' R] = F'F with F random, so
  N != 0; control.dlqr(A, B, Q, R, N) -> K, S (the DARE solution), E (closed-loop poles).
- dlqe: the same systems with G = I, C random (p x n), QN, RN random SPD;
  control.dlqe(A, G, C, QN, RN) -> L, P, E (python-control 0.10 refuses a cross covariance).
- SLICOT's documented SB10ED example (SLICOT-Reference examples/SB10ED.dat / .res,
  BSD-3-Clause; sample time taken as 1 ms): the plant, the controller the documentation prints
  (four decimals), and the H2 norm of the printed controller's closed loop (numpy LFT,
  scipy.linalg.solve_discrete_lyapunov), with the plant's D11 and with D11 set to zero.
"""
import json
import numpy as np
import scipy.linalg as sl
import control

rng = np.random.default_rng(4102)
TS = 1e-3


def spd(k):
    f = rng.standard_normal((k, k))
    w = f.T @ f + 0.1 * np.eye(k)
    return 0.5 * (w + w.T)


lqr, lqe = [], []
for i in range(12):
    n, m = int(rng.integers(2, 9)), int(rng.integers(1, 4))
    a = rng.standard_normal((n, n))
    a *= rng.uniform(0.5, 1.3) / np.max(np.abs(np.linalg.eigvals(a)))
    b = rng.standard_normal((n, m))
    w = spd(n + m)
    q, r, nn = w[:n, :n], w[n:, n:], w[:n, n:]
    k, s, e = control.dlqr(a, b, q, r, nn)
    lqr.append({"a": a.tolist(), "b": b.tolist(), "q": q.tolist(), "r": r.tolist(),
                "n": nn.tolist(), "k": np.asarray(k).tolist(), "x": np.asarray(s).tolist(),
                "poles_abs": sorted(np.abs(e).tolist())})
    qd, p = int(rng.integers(1, 4)), int(rng.integers(1, 4))
    # python-control checks G QN G' for exact symmetry, which a general G breaks by rounding:
    # G = I (the general G is exercised by the cross-covariance test, against a Lyapunov
    # equation)
    g = np.eye(n)
    qn = spd(n)
    c = rng.standard_normal((p, n))
    rn = spd(p)
    l, pp, e = control.dlqe(a, g, c, qn, rn)
    lqe.append({"a": a.tolist(), "g": g.tolist(), "c": c.tolist(), "qn": qn.tolist(),
                "rn": rn.tolist(), "l": np.asarray(l).tolist(), "p": np.asarray(pp).tolist(),
                "poles_abs": sorted(np.abs(e).tolist())})

A = np.array([[-0.7, 0.0, 0.3, 0.0, -0.5, -0.1], [-0.6, 0.2, -0.4, -0.3, 0.0, 0.0],
              [-0.5, 0.7, -0.1, 0.0, 0.0, -0.8], [-0.7, 0.0, 0.0, -0.5, -1.0, 0.0],
              [0.0, 0.3, 0.6, -0.9, 0.1, -0.4], [0.5, -0.8, 0.0, 0.0, 0.2, -0.9]])
B = np.array([[-1.0, -2.0, -2.0, 1.0, 0.0], [1.0, 0.0, 1.0, -2.0, 1.0],
              [-3.0, -4.0, 0.0, 2.0, -2.0], [1.0, -2.0, 1.0, 0.0, -1.0],
              [0.0, 1.0, -2.0, 0.0, 3.0], [1.0, 0.0, 3.0, -1.0, -2.0]])
C = np.array([[1.0, -1.0, 2.0, -2.0, 0.0, -3.0], [-3.0, 0.0, 1.0, -1.0, 1.0, 0.0],
              [0.0, 2.0, 0.0, -4.0, 0.0, -2.0], [1.0, -3.0, 0.0, 0.0, 3.0, 1.0],
              [0.0, 1.0, -2.0, 1.0, 0.0, -2.0]])
D = np.array([[1.0, -1.0, -2.0, 0.0, 0.0], [0.0, 1.0, 0.0, 1.0, 0.0],
              [2.0, -1.0, -3.0, 0.0, 1.0], [0.0, 1.0, 0.0, 1.0, -1.0],
              [0.0, 0.0, 1.0, 2.0, 1.0]])
AK = [[-0.0551, -2.1891, -0.6607, -0.2532, 0.6674, -1.0044],
      [-1.0379, 2.3804, 0.5031, 0.3960, -0.6605, 1.2673],
      [-0.0876, -2.1320, -0.4701, -1.1461, 1.2927, -1.5116],
      [-0.1358, -2.1237, -0.9560, -0.7144, 0.6673, -0.7957],
      [0.4900, 0.0895, 0.2634, -0.2354, 0.1623, -0.2663],
      [0.1672, -0.4163, 0.2871, -0.1983, 0.4944, -0.6967]]
BK = [[-0.5985, -0.5464], [0.5285, 0.6087], [-0.7600, -0.4472], [-0.7288, -0.6090],
      [0.0532, 0.0658], [-0.0663, 0.0059]]
CK = [[0.2500, -1.0200, -0.3371, -0.2733, 0.2747, -0.4444],
      [0.0654, 0.2095, 0.0632, 0.2089, -0.1895, 0.1834]]
DK = [[-0.2181, -0.2070], [0.1094, 0.1159]]


def h2_of_loop(d):
    ncon = nmeas = 2
    m1, p1 = 3, 3
    b1, b2 = B[:, :m1], B[:, m1:]
    c1, c2 = C[:p1], C[p1:]
    d11, d12, d21, d22 = d[:p1, :m1], d[:p1, m1:], d[p1:, :m1], d[p1:, m1:]
    ak, bk, ck, dk = (np.array(x) for x in (AK, BK, CK, DK))
    mm = np.linalg.inv(np.eye(ncon) - dk @ d22)
    ux, uk, uw = mm @ dk @ c2, mm @ ck, mm @ dk @ d21
    yx, yk, yw = c2 + d22 @ ux, d22 @ uk, d21 + d22 @ uw
    acl = np.block([[A + b2 @ ux, b2 @ uk], [bk @ yx, ak + bk @ yk]])
    bcl = np.vstack([b1 + b2 @ uw, bk @ yw])
    ccl = np.hstack([c1 + d12 @ ux, d12 @ uk])
    dcl = d11 + d12 @ uw
    assert np.max(np.abs(np.linalg.eigvals(acl))) < 1
    p = sl.solve_discrete_lyapunov(acl, bcl @ bcl.T)
    return float(np.sqrt(np.trace(ccl @ p @ ccl.T + dcl @ dcl.T)))


d0 = D.copy()
d0[:3, :3] = 0.0
sb10ed = {
    "plant": {"type": "ss", "ts": TS, "a": A.tolist(), "b": B.tolist(), "c": C.tolist(),
              "d": D.tolist()},
    "ncon": 2, "nmeas": 2,
    "controller": {"type": "ss", "ts": TS, "a": AK, "b": BK, "c": CK, "d": DK},
    "printed_loop_h2": h2_of_loop(D),
    "printed_loop_h2_without_d11": h2_of_loop(d0),
}
print("SB10ED printed controller: H2", sb10ed["printed_loop_h2"], "without D11",
      sb10ed["printed_loop_h2_without_d11"])
with open("test_data/lqg_reference.json", "w") as f:
    json.dump({"generator": "tools/gen_lqg_reference.py", "control": control.__version__,
               "dlqr": lqr, "dlqe": lqe, "sb10ed": sb10ed}, f, indent=1)
