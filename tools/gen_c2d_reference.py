"""Generate test_data/c2d_methods.json: FOH and Tustin (plain and prewarped) references from
scipy.signal.cont2discrete and python-control's sample_system. Run once; output committed.
The references are the discrete frequency responses at a few frequencies (realisation-free)
and, for FOH/Tustin without prewarp, scipy's matrices."""
import json
import numpy as np
import scipy.signal
import control

rng = np.random.default_rng(7)
cases = []
systems = [
    ("resonance", np.array([[0, 1], [-(2*np.pi*50)**2, -2*0.02*2*np.pi*50]]), np.array([[0], [1.0]]), np.array([[1.0, 0]]), np.array([[0.0]])),
    ("mimo3", None, None, None, None),
]
A = rng.standard_normal((3, 3)) * 5; A -= (np.max(np.linalg.eigvals(A).real) + 1) * np.eye(3)
systems[1] = ("mimo3", A, rng.standard_normal((3, 2)), rng.standard_normal((2, 3)), rng.standard_normal((2, 2)))
for name, a, b, c, d in systems:
    for h in [1e-3, 1e-2]:
        freqs = [1.0, 10.0, 0.3 / h]
        for method, pw in [("foh", None), ("tustin", None), ("tustin", 40.0)]:
            if pw is None:
                ad, bd, cd, dd, _ = scipy.signal.cont2discrete((a, b, c, d), h, method="foh" if method == "foh" else "bilinear")
            else:
                sd = control.sample_system(control.ss(a, b, c, d), h, method="bilinear", prewarp_frequency=2*np.pi*pw)
                ad, bd, cd, dd = (np.asarray(m) for m in (sd.A, sd.B, sd.C, sd.D))
            resp = []
            for f in freqs:
                z = np.exp(1j * 2 * np.pi * f * h)
                g = cd @ np.linalg.solve(z * np.eye(a.shape[0]) - ad, bd) + dd
                resp.append({"re": g.real.tolist(), "im": g.imag.tolist()})
            cases.append({"name": f"{name}_{method}{'_pw' if pw else ''}_h{h}", "method": method, "prewarp_hz": pw, "h": h,
                          "A": a.tolist(), "B": b.tolist(), "C": c.tolist(), "D": d.tolist(),
                          "Ad": ad.tolist(), "Bd": bd.tolist(), "Cd": cd.tolist(), "Dd": dd.tolist(),
                          "freq_hz": freqs, "response": resp})
json.dump({"generator": "tools/gen_c2d_reference.py (scipy %s, python-control %s)" % (scipy.__version__, control.__version__), "cases": cases},
          open("test_data/c2d_methods.json", "w"))
print(len(cases), "cases")
