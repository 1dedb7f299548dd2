"""Mixed-sensitivity references, committed as test_data/mixsyn_reference.json for
`tests/tests/mixsyn.rs`.
Usage: cd tools && python3 gen_mixsyn_reference.py   (python-control 0.10.2, slycot 0.7.1)

Skogestad & Postlethwaite, *Multivariable Feedback Control* (2nd ed.), Example 2.11 (the
python-control example `robust_siso.py`): G = 200/((10s + 1)(0.05s + 1)^2),
W1 = (s/M + wb)/(s + wb A) with M = 1.5, wb = 10, A = 1e-4, W2 = 1.
- continuous: python-control's `mixsyn` (SLICOT SB10AD) gamma, and the checked optimum by
  bisection on SB10FD + closed-loop stability + frequency-grid norm (gen_hinfsyn_reference);
- discrete at ts = 0.01 s (G by ZOH, W1 by Tustin, W2 = 1): python-control's `augw` of the
  discrete models, the checked optimum by bisection on SB10DD, and the grid norm of the loops
  SB10DD's controllers give at gamma = 1.398, 1.400, 1.402 (below that optimum SB10DD returns
  controllers whose loops are stable but far above gamma).
"""
import json
import numpy as np
import control
from gen_hinfsyn_reference import bisect, checked, hinf_grid, lft, solve


def ssdict(sys):
    sys = control.ss(sys)
    ts = None if sys.dt in (0, None) else float(sys.dt)
    return {"type": "ss", "ts": ts, "a": np.atleast_2d(sys.A).tolist(),
            "b": np.atleast_2d(sys.B).tolist(), "c": np.atleast_2d(sys.C).tolist(),
            "d": np.atleast_2d(sys.D).tolist()}


def optimum(p, discrete):
    p = control.ss(p)
    data = (p.A, p.B, p.C, p.D, 1, 1)
    return bisect(lambda g: checked(data, g, discrete))


s = control.tf('s')
g = 200 / (10 * s + 1) / (0.05 * s + 1) ** 2
M, wb, A = 1.5, 10.0, 1e-4
w1 = (s / M + wb) / (s + wb * A)
w2 = control.tf(1, 1)
k, cl, info = control.mixsyn(g, w1, w2)
ct = {"g": ssdict(g), "w1": ssdict(w1), "w2": ssdict(w2),
      "python_control_gamma": float(info[0]),
      "gamma_opt": optimum(control.augw(g, w1, w2), False)}
TS = 0.01
gd = control.c2d(control.ss(g), TS, 'zoh')
w1d = control.c2d(control.ss(w1), TS, 'tustin')
w2d = control.ss([], [], [], [[1.0]], TS)
pd = control.ss(control.augw(gd, w1d, w2d))
dt = {"g": ssdict(gd), "w1": ssdict(w1d), "w2": ssdict(w2d),
      "gamma_opt": optimum(pd, True), "slicot_loop_norm_at": {}}
# what SB10DD's controllers achieve just below its checked optimum (grid norm of the loop)
data = (pd.A, pd.B, pd.C, pd.D, 1, 1)
for gam in (1.398, 1.400, 1.402):
    k = solve(data, gam, True)
    dt["slicot_loop_norm_at"][f"{gam:.3f}"] = (
        None if k is None else float(hinf_grid(*lft(*data[:4], 1, 1, *k), True)))
print("continuous:", ct["python_control_gamma"], ct["gamma_opt"], "discrete:", dt["gamma_opt"])
with open("../test_data/mixsyn_reference.json", "w") as f:
    json.dump({"generator": "tools/gen_mixsyn_reference.py", "control": control.__version__,
               "example": "Skogestad & Postlethwaite Example 2.11, design 1",
               "continuous": ct, "discrete": dt}, f, indent=1)
