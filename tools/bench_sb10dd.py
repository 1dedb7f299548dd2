"""The peer of `cargo xtask bench`'s H-infinity entry: SLICOT SB10DD (slycot) at a given gamma
on a generalized plant (model JSON, 1 measurement, 1 control), median of REPEATS timed calls
after one untimed call, and whether the returned controller's loop is stable.
Usage: python3 tools/bench_sb10dd.py PLANT.json GAMMA REPEATS   (prints JSON)
"""
import json
import sys
import time

import numpy as np
import slycot

with open(sys.argv[1]) as f:
    m = json.load(f)
gamma, reps = float(sys.argv[2]), int(sys.argv[3])
a, b, c, d = (np.array(m[k], dtype=float) for k in "abcd")
n, mm, p = a.shape[0], b.shape[1], c.shape[0]


def call():
    return slycot.sb10dd(n, mm, p, 1, 1, gamma, a, b, c, d)


out = {"gamma": gamma}
try:
    call()
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        r = call()
        times.append(time.perf_counter() - t0)
    ak, bk, ck, dk = r[1:5]
    m1, p1 = mm - 1, p - 1
    b1, b2, c1, c2 = b[:, :m1], b[:, m1:], c[:p1], c[p1:]
    d21, d22 = d[p1:, :m1], d[p1:, m1:]
    mi = np.linalg.inv(np.eye(1) - dk @ d22)
    acl = np.block([[a + b2 @ mi @ dk @ c2, b2 @ mi @ ck],
                    [bk @ (c2 + d22 @ mi @ dk @ c2), ak + bk @ d22 @ mi @ ck]])
    out.update({"median_s": float(np.median(times)),
                "closed_loop_max_pole": float(np.max(np.abs(np.linalg.eigvals(acl))))})
except Exception as e:  # slycot raises on INFO != 0
    out["error"] = str(e).strip().splitlines()[0][:200]
print(json.dumps(out))
