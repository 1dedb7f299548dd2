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

The first case is SLICOT's documented SB10DD example (SLICOT-Reference, examples/SB10DD.dat
and SB10DD.res, BSD-3-Clause) with the controller the documentation prints for gamma = 111.294
(four decimals), so that the test can evaluate that published controller's loop itself (recorded beside it:
that loop's largest pole modulus and grid norm, and the grid norm of the full-precision
controller slycot returns at the same gamma).

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


DOC_A = [[-0.7, 0.0, 0.3, 0.0, -0.5, -0.1], [-0.6, 0.2, -0.4, -0.3, 0.0, 0.0],
         [-0.5, 0.7, -0.1, 0.0, 0.0, -0.8], [-0.7, 0.0, 0.0, -0.5, -1.0, 0.0],
         [0.0, 0.3, 0.6, -0.9, 0.1, -0.4], [0.5, -0.8, 0.0, 0.0, 0.2, -0.9]]
DOC_B = [[-1.0, -2.0, -2.0, 1.0, 0.0], [1.0, 0.0, 1.0, -2.0, 1.0], [-3.0, -4.0, 0.0, 2.0, -2.0],
         [1.0, -2.0, 1.0, 0.0, -1.0], [0.0, 1.0, -2.0, 0.0, 3.0], [1.0, 0.0, 3.0, -1.0, -2.0]]
DOC_C = [[1.0, -1.0, 2.0, -2.0, 0.0, -3.0], [-3.0, 0.0, 1.0, -1.0, 1.0, 0.0],
         [0.0, 2.0, 0.0, -4.0, 0.0, -2.0], [1.0, -3.0, 0.0, 0.0, 3.0, 1.0],
         [0.0, 1.0, -2.0, 1.0, 0.0, -2.0]]
DOC_D = [[1.0, -1.0, -2.0, 0.0, 0.0], [0.0, 1.0, 0.0, 1.0, 0.0], [2.0, -1.0, -3.0, 0.0, 1.0],
         [0.0, 1.0, 0.0, 1.0, -1.0], [0.0, 0.0, 1.0, 2.0, 1.0]]
DOC_K = {
    "type": "ss", "ts": TS,
    "a": [[-18.0030, 52.0376, 26.0831, -0.4271, -40.9022, 18.0857],
          [18.8203, -57.6244, -29.0938, 0.5870, 45.3309, -19.8644],
          [-26.5994, 77.9693, 39.0368, -1.4020, -60.1129, 26.6910],
          [-21.4163, 62.1719, 30.7507, -0.9201, -48.6221, 21.8351],
          [-0.8911, 4.2787, 2.3286, -0.2424, -3.0376, 1.2169],
          [-5.3286, 16.1955, 8.4824, -0.2489, -12.2348, 5.1590]],
    "b": [[16.9788, 14.1648], [-18.9215, -15.6726], [25.2046, 21.2848], [20.1122, 16.8322],
          [1.4104, 1.2040], [5.3181, 4.5149]],
    "c": [[-9.1941, 27.5165, 13.7364, -0.3639, -21.5983, 9.6025],
          [3.6490, -10.6194, -5.2772, 0.2432, 8.1108, -3.6293]],
    "d": [[9.0317, 7.5348], [-3.4006, -2.8219]],
}

def main():
    cases = []
    doc = tuple(np.array(m) for m in (DOC_A, DOC_B, DOC_C, DOC_D)) + (2, 2)
    cases.append({
        "name": "SLICOT SB10DD documented example (6 states, ncon 2, nmeas 2)",
        "plant": {"type": "ss", "ts": TS, "a": DOC_A, "b": DOC_B, "c": DOC_C, "d": DOC_D},
        "ncon": 2, "nmeas": 2, "routine": "SB10DD",
        "gamma_opt": bisect(lambda g: checked(doc, g, True)),
        "slicot_accepts_down_to": bisect(lambda g: solve(doc, g, True) is not None),
        "published": {"gamma": 111.294, "controller": DOC_K},
    })
    # the printed (four-decimal) controller's loop, and the full-precision one slycot returns
    printed = [np.array(DOC_K[x]) for x in "abcd"]
    cl = lft(*doc[:4], 2, 2, *printed)
    cases[-1]["published"]["printed_loop_max_pole"] = float(np.max(np.abs(np.linalg.eigvals(cl[0]))))
    cases[-1]["published"]["printed_loop_norm"] = float(hinf_grid(*cl, True))
    full = solve(doc, 111.294, True)
    cases[-1]["published"]["slycot_loop_norm"] = float(hinf_grid(*lft(*doc[:4], 2, 2, *full), True))
    print(cases[-1]["name"], cases[-1]["gamma_opt"], cases[-1]["slicot_accepts_down_to"], flush=True)
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


if __name__ == "__main__":
    main()
