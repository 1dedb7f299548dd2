"""Reference loops for the sd-analysis tests (issue #6), generated once with python-control and
committed as test_data/analysis_reference.json. Usage: python3 tools/gen_analysis_reference.py

For each loop: plant P and controller K as state space (a, b, c, d, ts), and python-control's
stability_margins of L = P K (gm, pm, sm and their frequencies, converted to Hz), the peak of
|S| = 1/|1 + L| on a dense grid refined by scipy, and |S|, |T|, |PS|, |KS| at a few frequencies.
"""
import json
import numpy as np
import control
import scipy.optimize as so


def ssdict(sys):
    s = control.ss(sys)
    ts = None if s.dt in (0, None) else float(s.dt)
    return {"type": "ss", "ts": ts, "a": np.atleast_2d(s.A).tolist(), "b": np.atleast_2d(s.B).tolist(),
            "c": np.atleast_2d(s.C).tolist(), "d": np.atleast_2d(s.D).tolist()}


def pid_ct(bw, m):
    wc = 2 * np.pi * bw
    wz, wp, wi = wc / 3, 3 * wc, wc / 5
    k = m * wc ** 2 / 3
    return control.tf([k / wz, k * (1 + wi / wz), k * wi], [1 / wp, 1, 0])


def stage(zeta, m=20.0, f1=653.0, r1=2.0):
    w = 2 * np.pi * f1
    return control.tf([1], [m, 0, 0]) + control.tf([r1], [m, 2 * zeta * w * m, w * w * m])


loops = []
s = control.tf('s')
loops.append(("third order, K = 2", 1 / (s * (s + 1) * (s + 2)), control.tf([2], [1])))
loops.append(("lightly damped resonance, PI", 16 / (s ** 2 + 0.16 * s + 16), control.tf([0.5, 0.4], [1, 0])))
loops.append(("unstable plant 4/(s - 0.001), K = 1", control.tf([4], [1, -0.001]), control.tf([1], [1])))
ts = 1e-3
p1k = control.c2d(stage(0.01), ts, 'zoh')
k2 = control.c2d(pid_ct(65, 20.0), ts, 'tustin')
wn = 2 * np.pi * 347.0
notch = control.c2d(control.tf([1, 2 * 0.02 * wn, wn ** 2], [1, 2 * 0.3 * wn, wn ** 2]), ts, 'tustin', prewarp_frequency=wn)
loops.append(("paper stage 1 kHz, PID 65 Hz (Controller 2)", p1k, k2))
loops.append(("paper stage 1 kHz, PID 65 Hz + 347 Hz notch (Controller 1)", p1k, k2 * notch))
loops.append(("discrete lag, integral control", control.c2d(control.tf([1], [0.05, 1]), 0.01, 'zoh'), control.tf([0.3, 0], [1, -1], 0.01)))

out = []
for name, p, k in loops:
    L = p * k
    gm, pm, sm, wpc, wgc, wms = control.stability_margins(L)
    dt = L.dt
    to_hz = lambda w: float(w) / (2 * np.pi)
    nyq = np.pi / dt if dt else None

    def ev(sys, f):
        w = 2 * np.pi * f
        z = np.exp(1j * w * dt) if dt else 1j * w
        return complex(np.squeeze(sys(z)))
    # |S| peak on a dense grid, refined
    fmax = nyq / (2 * np.pi) if dt else 1e3
    grid = np.geomspace(1e-3, fmax * (0.999999 if dt else 1), 200000)
    smag = np.array([abs(1 / (1 + ev(L, f))) for f in grid[::20]])
    i = int(np.argmax(smag)) * 20
    lo, hi = grid[max(i - 40, 0)], grid[min(i + 40, len(grid) - 1)]
    res = so.minimize_scalar(lambda f: -abs(1 / (1 + ev(L, f))), bounds=(lo, hi), method='bounded',
                             options={'xatol': 1e-12})
    fpk, speak = float(res.x), float(-res.fun)
    freqs = [0.5, 5.0, 50.0] + ([200.0, 347.0] if dt and dt <= 1e-3 else [])
    pts = []
    for f in freqs:
        if dt and f >= 0.5 / dt:
            continue
        l = ev(L, f); pp = ev(p, f); kk = ev(k, f)
        pts.append({"freq_hz": f, "S": abs(1 / (1 + l)), "T": abs(l / (1 + l)), "PS": abs(pp / (1 + l)), "KS": abs(kk / (1 + l))})
    cl = control.feedback(L, 1)
    poles = control.poles(cl)
    stable = bool(np.all(np.abs(poles) < 1)) if dt else bool(np.all(np.real(poles) < 0))
    fin = lambda x: float(x) if np.isfinite(x) else None  # JSON has no inf/nan: null
    out.append({"name": name, "plant": ssdict(p), "controller": ssdict(k), "stable": stable,
                "gm": fin(gm), "pm": fin(pm), "sm": fin(sm),
                "wpc_hz": fin(to_hz(wpc)), "wgc_hz": fin(to_hz(wgc)), "wms_hz": fin(to_hz(wms)),
                "s_peak": speak, "s_peak_hz": fpk, "points": pts})

json.dump({"null_means": "infinite margin or no crossover", "source": "python-control %s (stability_margins), scipy %s" % (control.__version__, __import__('scipy').__version__),
           "loops": out}, open("test_data/analysis_reference.json", "w"), indent=1)
for o in out:
    print(o["name"], "gm", o["gm"], "pm", o["pm"], "sm", o["sm"], "wpc", o["wpc_hz"], "wgc", o["wgc_hz"], "peak", o["s_peak"], o["s_peak_hz"], o["stable"])
