"""The H2 norm of `test_data/h2_badly_scaled_loop.json` by the impulse-response sum, printed for
`sd-model`'s regression test (`tests/tests/norms_badly_scaled.rs`).
Usage: python3 tools/gen_h2_badly_scaled.py   (numpy, scipy; run once, not at test time)

The loop is the 124-state closed loop of the 60-state stage at 1 kHz with the mixed-sensitivity
controller of `hinfsyn` at γ = 1.2 (written once by this project's pipeline): ‖A‖ = 4.7e4,
spectral radius 0.99984. ‖G‖₂² = Σ_k ‖C A^k B‖²_F + ‖D‖²_F, summed over 400 000 steps (the
terms fall below 1e-30); scipy's `solve_discrete_lyapunov` route is printed beside it.
"""
import json

import numpy as np
import scipy.linalg as sl

m = json.load(open("test_data/h2_badly_scaled_loop.json"))
a, b, c, d = (np.array(m[k]) for k in "abcd")
x, s = b.copy(), float(np.sum(d * d))
for _ in range(400_000):
    y = c @ x
    s += float(np.sum(y * y))
    x = a @ x
p = sl.solve_discrete_lyapunov(a, b @ b.T)
print(json.dumps({"h2_impulse_sum": np.sqrt(s),
                  "h2_scipy_lyapunov": float(np.sqrt(max(np.trace(c @ p @ c.T + d @ d.T), 0.0)))}))
