"""Peer timings for `cargo xtask bench`: the same operations on the same inputs in
python-control / scipy. Usage: python3 tools/bench_python.py CASES.json  (prints JSON), or
python3 tools/bench_python.py --scaling SCALING.json (the scaling table's peers).

CASES.json: {"c2d": {"model": path, "ts": h, "repeats": k},
             "freqresp": {"model": path, "fmin": .., "fmax": .., "n": .., "log": bool, "repeats": k},
             "downsample": {"model": path (DT), "factor": F, "repeats": k},   (optional)
             "dare": {"model": path (DT), "repeats": k},                     (optional)
             "loopshape": {"plant": path, "w1": path, "repeats": k},         (optional)
             "loopshape60": {"plant": path, "w1": path, "repeats": k},       (optional; the 60-state one)
             "frf": {"u": f64 file, "y": f64 file, "period": P, "skip": S, "repeats": k}}
The c2d and freqresp cases are also timed through our own Python package (`sdtoolkit`, from
`pip install ./sd-python`) when it is importable: the cost of calling the library from Python.
"""
import json, sys, time
import numpy as np
import control
import scipy.signal


def load(path):
    m = json.load(open(path))
    return [np.array(m[k], dtype=float).reshape(len(m[k]), -1) if len(m[k]) else np.zeros((0, 0)) for k in "abcd"], m["ts"]


WARM_UP_S = 0.1


def median_time(fn, repeats):
    """Median of `repeats` timed calls after an untimed warm-up, as xtask's `time_it`: calls
    until WARM_UP_S has passed (at least one); a first call of over 1 s is the first timed one."""
    ts = []
    t0 = time.perf_counter(); out = fn(); first = time.perf_counter() - t0
    if first > 1.0:
        ts.append(first)
    while time.perf_counter() - t0 < WARM_UP_S:
        out = fn()
    while len(ts) < max(repeats, 1):
        t1 = time.perf_counter(); out = fn(); ts.append(time.perf_counter() - t1)
    return float(np.median(ts)), out


def frf_average(u, y, p, skip):
    """The plain periodic FRF: mean spectra over whole periods after `skip`, G = Ȳ/Ū."""
    m = len(u) // p - skip
    U = np.fft.fft(u[skip * p:(skip + m) * p].reshape(m, p), axis=1)
    Y = np.fft.fft(y[skip * p:(skip + m) * p].reshape(m, p), axis=1)
    Um, Ym = U.mean(0), Y.mean(0)
    lines = np.arange(1, p // 2)
    G = Ym[lines] / Um[lines]
    var = (np.var(Y[:, lines], axis=0, ddof=1) / np.abs(Um[lines]) ** 2) / m
    return G, var


def scaling(path):
    """The peers of `cargo xtask bench`'s scaling table (xtask/src/scaling.rs): per model size
    c2d (scipy), Lemma 6 by matrix power (numpy), freqresp per point (python-control), DARE
    (scipy); per record length the numpy period average."""
    import scipy.linalg
    sc = json.load(open(path))
    out = {"c2d": [], "downsample": [], "freqresp_per_point": [], "freqresp_setup": [], "dare": [], "frf": []}
    hz = np.geomspace(0.1, 2500.0, sc["points"])
    hz10 = np.geomspace(0.1, 2500.0, 10 * sc["points"])
    for m in sc["models"]:
        reps = 3 if m["n"] <= 120 else 1
        (a, b, cc, d), _ = load(m["ct"])
        out["c2d"].append(median_time(lambda: scipy.signal.cont2discrete((a, b, cc, d), 2e-4, method="zoh"), reps)[0])
        (a, b, cc, d), ts = load(m["dt"])
        n, nu = a.shape[0], b.shape[1]
        blk = np.zeros((n + nu, n + nu)); blk[:n, :n] = a; blk[:n, n:] = b; blk[n:, n:] = np.eye(nu)
        out["downsample"].append(median_time(lambda: np.linalg.matrix_power(blk, 5), reps)[0])
        sys_d = control.ss(a, b, cc, d, ts)
        t1, _ = median_time(lambda: control.frequency_response(sys_d, 2 * np.pi * hz), 1)
        t2, _ = median_time(lambda: control.frequency_response(sys_d, 2 * np.pi * hz10), 1)
        per = max((t2 - t1) / (9 * len(hz)), 0.0)
        out["freqresp_per_point"].append(per)
        out["freqresp_setup"].append(max(t1 - per * len(hz), 0.0))
        q, r = cc.T @ cc, np.eye(nu)
        out["dare"].append(median_time(lambda: scipy.linalg.solve_discrete_are(a, b, q, r), reps)[0])
    for rec in sc["records"]:
        u = np.fromfile(rec["u"], dtype="<f8"); y = np.fromfile(rec["y"], dtype="<f8")
        out["frf"].append(median_time(lambda: frf_average(u, y, rec["period"], 1), 3)[0])
    print(json.dumps(out))


if sys.argv[1] == "--scaling":
    scaling(sys.argv[2])
    sys.exit(0)

cases = json.load(open(sys.argv[1]))
res = {"versions": {"control": control.__version__, "scipy": scipy.__version__, "numpy": np.__version__}}
try:
    import slycot
    res["versions"]["slycot"] = slycot.__version__
except Exception:
    pass

c = cases["c2d"]
(a, b, cc, d), _ = load(c["model"])
sys_c = control.ss(a, b, cc, d)
t, sd = median_time(lambda: control.sample_system(sys_c, c["ts"], method="zoh"), c["repeats"])
res["c2d_python_control"] = {"median_s": t, "ad": np.asarray(sd.A).tolist(), "bd": np.asarray(sd.B).tolist()}
t, _ = median_time(lambda: scipy.signal.cont2discrete((a, b, cc, d), c["ts"], method="zoh"), c["repeats"])
res["c2d_scipy"] = {"median_s": t}

f = cases["freqresp"]
(a, b, cc, d), ts = load(f["model"])
sys_d = control.ss(a, b, cc, d, ts)
hz = np.geomspace(f["fmin"], f["fmax"], f["n"]) if f["log"] else np.linspace(f["fmin"], f["fmax"], f["n"])
w = 2 * np.pi * hz
t, r = median_time(lambda: control.frequency_response(sys_d, w), f["repeats"])
resp = np.asarray(r.response).reshape(-1)
res["freqresp_python_control"] = {"median_s": t, "re_sample": resp[:: max(1, len(resp) // 1000)].real.tolist(), "im_sample": resp[:: max(1, len(resp) // 1000)].imag.tolist(), "stride": max(1, len(resp) // 1000)}
try:
    import sdtoolkit

    (a, b, cc, d), _ = load(c["model"])
    sys_t = sdtoolkit.StateSpace(a, b, cc, d)
    t_c2d, _ = median_time(lambda: sdtoolkit.c2d(sys_t, c["ts"]), c["repeats"])
    (a, b, cc, d), ts = load(f["model"])
    sys_td = sdtoolkit.StateSpace(a, b, cc, d, ts)
    t_fr, g = median_time(lambda: sdtoolkit.freqresp(sys_td, hz), f["repeats"])
    res["sdtoolkit"] = {"c2d_s": t_c2d, "freqresp_s": t_fr, "max_rel_difference_vs_python_control": float(np.max(np.abs(g - resp) / np.abs(resp)))}
except ImportError:
    res["sdtoolkit"] = {"error": "not importable (pip install ./sd-python)"}
ds = cases.get("downsample")
if ds:
    (a, b, cc, d), _ = load(ds["model"])
    n, nu = a.shape[0], b.shape[1]
    blk = np.zeros((n + nu, n + nu)); blk[:n, :n] = a; blk[:n, n:] = b; blk[n:, n:] = np.eye(nu)
    t, pw = median_time(lambda: np.linalg.matrix_power(blk, ds["factor"]), ds["repeats"])
    res["downsample_numpy_matrix_power"] = {"median_s": t, "ad": pw[:n, :n].tolist(), "bd": pw[:n, n:].tolist()}
dr = cases.get("dare")
if dr:
    import scipy.linalg
    (a, b, cc, d), _ = load(dr["model"])
    q = cc.T @ cc
    r = np.eye(b.shape[1])
    def rel_res(x):
        k = np.linalg.solve(r + b.T @ x @ b, b.T @ x @ a)
        res = a.T @ x @ a - x - a.T @ x @ b @ k + q
        scale = np.linalg.norm(q) + np.linalg.norm(a.T @ x @ a) + np.linalg.norm(x) + np.linalg.norm(a.T @ x @ b @ k)
        return float(np.linalg.norm(res) / scale), float(max(abs(np.linalg.eigvals(a - b @ k))))
    t, x = median_time(lambda: scipy.linalg.solve_discrete_are(a, b, q, r), dr["repeats"])
    rr, rho = rel_res(x)
    res["dare_scipy"] = {"median_s": t, "rel_residual": rr, "closed_loop_radius": rho}
    try:
        t, out = median_time(lambda: control.dare(a, b, q, r), dr["repeats"])
        xx = np.asarray(out[0])
        rr, rho = rel_res(xx)
        res["dare_python_control"] = {"median_s": t, "rel_residual": rr, "closed_loop_radius": rho}
    except Exception as e:
        res["dare_python_control"] = {"error": str(e).strip().splitlines()[0][:200]}
def shaped_gamma_min(case):
    """gamma_min of W1*P from scipy's two DAREs (control and filter), the peer of our design."""
    import scipy.linalg
    (pa, pb, pc, pd_), pts = load(case["plant"])
    (wa, wb, wc, wd), _ = load(case["w1"])
    def gamma_min():
        gs = control.series(control.ss(wa, wb, wc, wd, pts), control.ss(pa, pb, pc, pd_, pts))
        a, b, c = np.asarray(gs.A), np.asarray(gs.B), np.asarray(gs.C)
        x = scipy.linalg.solve_discrete_are(a, b, c.T @ c, np.eye(b.shape[1]))
        z = scipy.linalg.solve_discrete_are(a.T, c.T, b @ b.T, np.eye(c.shape[0]))
        return float(np.sqrt(1 + max(abs(np.linalg.eigvals(x @ z)))))
    t, g = median_time(gamma_min, case["repeats"])
    return {"median_s": t, "gamma_min": g}


if cases.get("loopshape"):
    res["loopshape_scipy_gamma_min"] = shaped_gamma_min(cases["loopshape"])
if cases.get("loopshape60"):
    try:
        res["loopshape60_scipy_two_dares"] = shaped_gamma_min(cases["loopshape60"])
    except Exception as e:
        res["loopshape60_scipy_two_dares"] = {"error": str(e).strip().splitlines()[0][:200]}
fr = cases.get("frf")
if fr:
    u = np.fromfile(fr["u"], dtype="<f8"); y = np.fromfile(fr["y"], dtype="<f8")
    t, (G, var) = median_time(lambda: frf_average(u, y, fr["period"], fr["skip"]), fr["repeats"])
    res["frf_numpy_periodic_average"] = {"median_s": t, "lines": int(len(G))}
ft = cases.get("fit")
if ft:
    # scipy's AAA (Nakatsukasa, Sète & Trefethen 2018) on z = e^{jωT}, the same lines and
    # number of poles as our order-60 fit; its cost with our weights 1/var
    try:
        from scipy.interpolate import AAA
        with open(ft["frd"]) as fh:
            fj = json.load(fh)
        hz = np.asarray(fj["freq_hz"])
        g = np.asarray(fj["re"])[:, 0, 0] + 1j * np.asarray(fj["im"])[:, 0, 0]
        var = np.asarray(fj["var"])[:, 0, 0]
        z = np.exp(2j * np.pi * hz * fj["ts"])
        t, r = median_time(lambda: AAA(z, g, rtol=0.0, max_terms=ft["poles"] + 1), ft["repeats"])
        cost = float(np.sum(np.abs(g - r(z)) ** 2 / var))
        p = r.poles()
        res["fit_scipy_aaa"] = {"median_s": t, "cost": cost, "poles": int(len(p)),
                                "largest_pole_modulus": float(np.max(np.abs(p))),
                                "stable": bool(np.all(np.abs(p) < 1.0)),
                                "median_rel_error": float(np.median(np.abs(g - r(z)) / np.abs(g)))}
    except Exception as e:
        res["fit_scipy_aaa"] = {"error": str(e).strip().splitlines()[0][:200]}
print(json.dumps(res))
