"""Seeded random generalized plants with SLICOT's H-infinity optimum, committed as
test_data/hinfsyn_slicot.json for sd-hinf's synthesis test (`sd-hinf/tests/hinfsyn.rs`).
Usage: python3 tools/gen_hinfsyn_reference.py   (slycot 0.7.1, numpy; run once, not at test time)

For each plant (discrete at ts = 1 ms: SLICOT SB10DD; continuous: SB10FD) the reference optimum
gamma_opt is found by bisection (relative 1e-7) on "SLICOT returns a controller at gamma AND
the closed loop F_l(P, K), formed here in numpy, has all poles stable AND its H-infinity norm,
evaluated on a 20000-point frequency grid refined around the peak by golden section, is at most
gamma (1 + 1e-6)". The grid check is independent of the Riccati formulas. Also recorded:
`slicot_accepts_down_to` — the least gamma at which SLICOT still *returns* a controller when
nothing is checked (bisection on INFO = 0 alone): where it is below gamma_opt, the routine hands
out controllers whose loops are unstable or miss the bound.

Plants: n states (2-8), m1 exogenous inputs, p1 performance outputs, ncon, nmeas (1-2), entries
standard normal, A scaled to spectral radius 0.5-1.3 (discrete) or shifted to abscissa -1..+0.5
(continuous) so that some plants are open-loop unstable; D11, D22 random (D22 = 0 for every
third plant), D12 / D21 random (full rank almost surely).
"""
import json
import numpy as np
import slycot

rng = np.random.default_rng(4101)
TS = 1e-3


def lft(a, b, c, d, ncon, nmeas, ak, bk, ck, dk):
    n = a.shape[0]
    m1 = b.shape[1] - ncon
    p1 = c.shape[0] - nmeas
    b1, b2 = b[:, :m1], b[:, m1:]
    c1, c2 = c[:p1], c[p1:]
    d11, d12, d21, d22 = d[:p1, :m1], d[:p1, m1:], d[p1:, :m1], d[p1:, m1:]
    m = np.linalg.inv(np.eye(ncon) - dk @ d22)
    ux, uk, uw = m @ dk @ c2, m @ ck, m @ dk @ d21
    yx, yk, yw = c2 + d22 @ ux, d22 @ uk, d21 + d22 @ uw
    acl = np.block([[a + b2 @ ux, b2 @ uk], [bk @ yx, ak + bk @ yk]])
    bcl = np.vstack([b1 + b2 @ uw, bk @ yw])
    ccl = np.hstack([c1 + d12 @ ux, d12 @ uk])
    dcl = d11 + d12 @ uw
    return acl, bcl, ccl, dcl


def sigma(acl, bcl, ccl, dcl, s):
    n = acl.shape[0]
    g = ccl @ np.linalg.solve(s * np.eye(n) - acl, bcl) + dcl
    return np.linalg.svd(g, compute_uv=False)[0]


def hinf_grid(acl, bcl, ccl, dcl, discrete):
    if discrete:
        w = np.linspace(0, np.pi, 20000)
        pts = np.exp(1j * w)
    else:
        w = np.concatenate([[0], np.logspace(-4, 5, 20000)])
        pts = 1j * w
    vals = np.array([sigma(acl, bcl, ccl, dcl, p) for p in pts])
    k = int(np.argmax(vals))
    lo, hi = w[max(k - 1, 0)], w[min(k + 1, len(w) - 1)]
    f = (lambda x: sigma(acl, bcl, ccl, dcl, np.exp(1j * x))) if discrete else \
        (lambda x: sigma(acl, bcl, ccl, dcl, 1j * x))
    gr = (np.sqrt(5) - 1) / 2
    for _ in range(80):
        x1, x2 = hi - gr * (hi - lo), lo + gr * (hi - lo)
        if f(x1) > f(x2):
            hi = x2
        else:
            lo = x1
    return max(vals[k], f(0.5 * (lo + hi)))


def solve(p, g, discrete):
    a, b, c, d, ncon, nmeas = p
    n, m, np_ = a.shape[0], b.shape[1], c.shape[0]
    try:
        if discrete:
            out = slycot.sb10dd(n, m, np_, ncon, nmeas, g, a, b, c, d)
            return out[1:5]
        out = slycot.sb10fd(n, m, np_, ncon, nmeas, g, a, b, c, d)
        return out[0:4]
    except Exception:  # slycot raises on INFO != 0
        return None


def checked(p, g, discrete):
    k = solve(p, g, discrete)
    if k is None:
        return False
    a, b, c, d, ncon, nmeas = p
    cl = lft(a, b, c, d, ncon, nmeas, *k)
    ev = np.linalg.eigvals(cl[0])
    if discrete and np.max(np.abs(ev)) >= 1:
        return False
    if not discrete and np.max(ev.real) >= 0:
        return False
    return hinf_grid(*cl, discrete) <= g * (1 + 1e-6)


def bisect(ok):
    hi = 1.0
    while not ok(hi):
        hi *= 2
        if hi > 1e9:
            return None
    lo = hi / 2
    while ok(lo):
        hi, lo = lo, lo / 2
        if lo < 1e-9:
            return hi
    while hi - lo > 1e-7 * hi:
        mid = 0.5 * (lo + hi)
        if ok(mid):
            hi = mid
        else:
            lo = mid
    return hi


def plant(i, discrete):
    n = int(rng.integers(2, 9))
    ncon, nmeas = int(rng.integers(1, 3)), int(rng.integers(1, 3))
    m1 = nmeas + int(rng.integers(0, 3))
    p1 = ncon + int(rng.integers(0, 3))
    a = rng.standard_normal((n, n))
    ev = np.linalg.eigvals(a)
    if discrete:
        a *= rng.uniform(0.5, 1.3) / np.max(np.abs(ev))
    else:
        a += (rng.uniform(-1.0, 0.5) - np.max(ev.real)) * np.eye(n)
    b = rng.standard_normal((n, m1 + ncon))
    c = rng.standard_normal((p1 + nmeas, n))
    d = rng.standard_normal((p1 + nmeas, m1 + ncon)) * 0.5
    if i % 3 == 0:
        d[p1:, m1:] = 0.0
    return a, b, c, d, ncon, nmeas


cases = []
for i in range(16):
    discrete = i % 2 == 0
    p = plant(i, discrete)
    a, b, c, d, ncon, nmeas = p
    g_opt = bisect(lambda g: checked(p, g, discrete))
    g_acc = bisect(lambda g: solve(p, g, discrete) is not None)
    cases.append({
        "name": f"random {'discrete' if discrete else 'continuous'} plant {i}: "
                f"{a.shape[0]} states, ncon {ncon}, nmeas {nmeas}",
        "plant": {"type": "ss", "ts": TS if discrete else None, "a": a.tolist(),
                  "b": b.tolist(), "c": c.tolist(), "d": d.tolist()},
        "ncon": ncon, "nmeas": nmeas,
        "routine": "SB10DD" if discrete else "SB10FD",
        "gamma_opt": g_opt,
        "slicot_accepts_down_to": g_acc,
    })
    print(cases[-1]["name"], g_opt, g_acc, flush=True)

with open("test_data/hinfsyn_slicot.json", "w") as f:
    json.dump({"generator": "tools/gen_hinfsyn_reference.py", "slycot": slycot.__version__,
               "cases": cases}, f, indent=1)
