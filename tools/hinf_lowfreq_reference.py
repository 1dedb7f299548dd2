"""Reference singular values for `tests/tests/hinf_norm_reference.rs`: sigma_max of a discrete
model's frequency response computed in 30-digit arithmetic (mpmath) on the model's own
double-precision matrices, at the frequencies listed below.

The model (test_data/hinf/loop128_1khz.json) is the 128-state closed loop of the central H-infinity
controller of `cargo xtask bench --only hinfsyn` (the 60-state stage's mixed-sensitivity plant
at 1 kHz) with its plant: nearly flat near its peak, with poles within 1.6e-4 of z = 1.

Usage: python3 tools/hinf_lowfreq_reference.py MODEL.json OUT.json   (pip install mpmath numpy)
"""
import json
import math
import sys

import mpmath as mp
import numpy as np

mp.mp.dps = 30
with open(sys.argv[1]) as f:
    m = json.load(f)
ts = float(m["ts"])
a, b, c, d = (mp.matrix(np.array(m[k], dtype=float).tolist()) for k in "abcd")
n = a.rows
nyq = 0.5 / ts
freqs = [nyq * 10 ** (-8 + 8 * i / 31) for i in range(32)]
freqs += [100.0 + 0.25 * i for i in range(17)]


def sigma_max(f):
    z = mp.expjpi(2 * f * ts)
    m_ = z * mp.eye(n) - a
    x = mp.matrix(n, b.cols)
    for j in range(b.cols):
        col = mp.lu_solve(m_, b.column(j))
        for i in range(n):
            x[i, j] = col[i]
    g = c * x + d
    gh = g.H * g if g.rows >= g.cols else g * g.H
    ev = mp.eighe(gh)[0]
    return float(mp.sqrt(max(mp.re(e) for e in ev)))


out = {"source": "tools/hinf_lowfreq_reference.py (mpmath, 30 digits)", "ts": ts,
       "freq_hz": freqs, "sigma_max": []}
for k, f in enumerate(freqs):
    out["sigma_max"].append(sigma_max(f))
    print(f"{k + 1}/{len(freqs)} {f:.6e} Hz {out['sigma_max'][-1]:.15f}", file=sys.stderr)
with open(sys.argv[2], "w") as f:
    json.dump(out, f, indent=1)
