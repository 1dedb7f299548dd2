"""Generate test_data/descriptor_riccati.json: generalized (descriptor, E != I) CARE and DARE
cases (random, E well conditioned), with what scipy.linalg.solve_continuous_are /
solve_discrete_are (their `e=` and `s=` arguments) return on each: X and the relative
residual of the generalized equation, or scipy's error message. The stabilizing solution is
characterised by the mathematics alone (the generalized equation holds and the closed loop
λ(A − BK, E) is stable), which is what the test (tests/tests/riccati_reference.rs) checks of
sd_hinf::gcare / gdare; where scipy solves a case, X must also agree with scipy's and the
residual be at or below max(scipy's, 100·n·eps). Run once (python3 tools/gen_descriptor_riccati.py,
with numpy and scipy); the output is committed, never needed at test time."""
import json

import numpy as np
import scipy
import scipy.linalg as sl

rng = np.random.default_rng(20261127)


def residual(kind, A, E, B, Q, R, S, X):
    if kind == "care":
        axe = A.T @ X @ E
        t = E.T @ X @ B + S
        tk = t @ np.linalg.solve(R, t.T)
        lhs = axe + axe.T - tk + Q
        terms = np.linalg.norm(Q) + 2 * np.linalg.norm(axe) + np.linalg.norm(tk)
    else:
        axa = A.T @ X @ A
        exe = E.T @ X @ E
        t = A.T @ X @ B + S
        tk = t @ np.linalg.solve(R + B.T @ X @ B, t.T)
        lhs = axa - exe - tk + Q
        terms = np.linalg.norm(Q) + np.linalg.norm(axa) + np.linalg.norm(exe) + np.linalg.norm(tk)
    lhs = 0.5 * (lhs + lhs.T)
    return float(np.linalg.norm(lhs) / terms)


cases = []
for kind in ["care", "dare"]:
    for k in range(8):
        n = int(rng.integers(2, 9))
        m = int(rng.integers(1, 4))
        A = rng.standard_normal((n, n))
        if kind == "dare":
            A *= 0.9 / max(abs(np.linalg.eigvals(A)))  # not needed for solvability, keeps X modest
            A += 0.3 * rng.standard_normal((n, n))
        E = np.eye(n) + 0.5 * rng.standard_normal((n, n)) / np.sqrt(n)
        if k % 3 == 2:
            # a badly scaled but well-conditioned E (row scaling 1e-3 .. 1e3 undone in A, B)
            D = np.diag(10.0 ** rng.uniform(-1, 1, n))
            E = D @ E
            A = D @ A
        B = rng.standard_normal((n, m))
        C = rng.standard_normal((n, n))
        Q = C.T @ C + 0.1 * np.eye(n)
        Rm = rng.standard_normal((m, m))
        R = Rm @ Rm.T + np.eye(m)
        S = 0.1 * rng.standard_normal((n, m)) if k % 2 else np.zeros((n, m))
        solve = sl.solve_continuous_are if kind == "care" else sl.solve_discrete_are
        try:
            X = solve(A, B, Q, R, e=E, s=S)
            scipy_out = {"X_scipy": X.tolist(),
                         "scipy_residual": residual(kind, A, E, B, Q, R, S, X)}
        except Exception as ex:  # noqa: BLE001 - recorded: scipy refuses the case
            print(kind, k, "scipy:", ex)
            scipy_out = {"scipy_error": str(ex)}
        cases.append({
            "name": f"{kind}_{k}_n{n}_m{m}",
            "kind": kind,
            "A": A.tolist(), "E": E.tolist(), "B": B.tolist(), "Q": Q.tolist(),
            "R": R.tolist(), "S": S.tolist(),
            "cond_E": float(np.linalg.cond(E, 1)),
            **scipy_out,
        })

out = {
    "generator": "tools/gen_descriptor_riccati.py",
    "scipy": scipy.__version__,
    "cases": cases,
}
with open("test_data/descriptor_riccati.json", "w") as f:
    json.dump(out, f, indent=1)
print(len(cases), "cases")
