"""Fifty seeded random loops with python-control's stability margins, committed as
test_data/margins_random.json for the margins test of sd-analysis (`tests/tests/analysis_reference.rs`).
Usage: python3 tools/gen_margins_random.py   (python-control 0.10.2, numpy; run once, not at test time)

Loops L = P K of five kinds, continuous and discrete (ts = 1 ms): random stable plants
(control.rss / drss, 1-5 states) with a random gain or PI controller; integrating plants
k/(s(s + a)) with a lead; unstable first-order plants with a proportional controller (stabilizing
or not); static gains (P and K constants); and lightly damped resonances with a PI controller.
For each: gm, pm, sm and the crossover frequencies (Hz) of control.stability_margins(L)
(JSON null for inf/nan), whether the closed loop is stable, and for stable continuous loops
control.bandwidth(T) (Hz), the closed-loop -3 dB bandwidth.
"""
import json
import numpy as np
import control

rng = np.random.default_rng(2026)
np.random.seed(2026)  # control.rss / drss draw from numpy's global generator
s = control.tf('s')


def ssdict(sys):
    sys = control.ss(sys)
    ts = None if sys.dt in (0, None) else float(sys.dt)
    return {"type": "ss", "ts": ts, "a": np.atleast_2d(sys.A).tolist() if sys.nstates else [],
            "b": np.atleast_2d(sys.B).tolist() if sys.nstates else [],
            "c": np.atleast_2d(sys.C).tolist() if sys.nstates else [[]],
            "d": np.atleast_2d(sys.D).tolist()}


def maybe_dt(p, k, dt):
    if dt:
        return control.c2d(p, dt, 'zoh'), control.c2d(k, dt, 'tustin')
    return p, k


loops = []
for i in range(50):
    kind = i % 5
    dt = 1e-3 if (i // 5) % 2 else None
    if kind == 0:
        n = int(rng.integers(1, 6))
        p = control.drss(n, 1, 1, dt=dt) if dt else control.rss(n, 1, 1)
        kp = float(10 ** rng.uniform(-1, 1))
        k = control.tf([kp], [1], dt) if dt else control.tf([kp], [1])
        name = f"random stable plant ({n} states), K = {kp:.3g}"
        if dt:
            loops.append((name, p, k))
            continue
    elif kind == 1:
        a, g = float(rng.uniform(1, 20)), float(10 ** rng.uniform(0, 3))
        p = control.tf([g], [1, a, 0])
        wz = float(rng.uniform(0.5, 5)) * np.sqrt(g)
        k = control.tf([1 / wz, 1], [1 / (10 * wz), 1])
        name = f"integrating plant {g:.3g}/(s(s+{a:.3g})), lead"
    elif kind == 2:
        a, kp = float(rng.uniform(0.1, 5)), float(rng.uniform(0.2, 4)) * 1.0
        p = control.tf([1], [1, -a])
        k = control.tf([kp * a], [1])
        name = f"unstable plant 1/(s-{a:.3g}), K = {kp * a:.3g}"
    elif kind == 3:
        g = float(rng.uniform(-3, 3))
        p = control.ss([], [], [], [[g]], dt) if dt else control.ss([], [], [], [[g]])
        kp = float(rng.uniform(0.1, 2))
        k = control.ss([], [], [], [[kp]], dt) if dt else control.ss([], [], [], [[kp]])
        loops.append((f"static gains P = {g:.3g}, K = {kp:.3g}", p, k))
        continue
    else:
        f0, z = float(rng.uniform(1, 50)), float(10 ** rng.uniform(-3, -1))
        w = 2 * np.pi * f0
        p = control.tf([w * w], [1, 2 * z * w, w * w])
        k = control.tf([0.3, 0.3 * w / 10], [1, 0])
        name = f"resonance {f0:.3g} Hz (zeta {z:.2g}), PI"
    p, k = maybe_dt(p, k, dt)
    loops.append((name, p, k))

out = []
for name, p, k in loops:
    L = control.series(control.ss(k), control.ss(p))
    gm, pm, sm, wpc, wgc, wms = control.stability_margins(L)
    dt = L.dt if L.dt not in (0, None) else None
    cl = control.feedback(L, 1)
    poles = control.poles(cl)
    stable = bool(np.all(np.abs(poles) < 1)) if dt else bool(np.all(np.real(poles) < 0))
    fin = lambda x: float(x) if np.isfinite(x) else None
    hz = lambda x: float(x) / (2 * np.pi) if np.isfinite(x) else None
    # closed-loop -3 dB bandwidth of T = L/(1 + L); python-control evaluates it at s = jw
    # even for discrete systems, so it is recorded for the continuous loops only
    bw = hz(control.bandwidth(cl)) if not dt and stable else None
    out.append({"name": name + (" (discrete, 1 ms)" if dt else ""), "plant": ssdict(p),
                "controller": ssdict(k), "stable": stable, "gm": fin(gm), "pm": fin(pm),
                "sm": fin(sm), "wpc_hz": hz(wpc), "wgc_hz": hz(wgc), "wms_hz": hz(wms),
                "bandwidth_hz": bw})

json.dump({"source": f"python-control {control.__version__} stability_margins, tools/gen_margins_random.py",
           "null_means": "inf or nan in python-control", "loops": out},
          open("test_data/margins_random.json", "w"), indent=1)
for o in out:
    print(o["name"], o["gm"], o["pm"], o["sm"], o["stable"])
