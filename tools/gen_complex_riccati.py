"""Generate test_data/complex_riccati.json: CARE and DARE cases with complex data (A, B, Q, R,
S and, in some cases, E complex), with what scipy.linalg.solve_continuous_are /
solve_discrete_are return on each (X and the relative residual of the complex equation, or
scipy's error message). The stabilizing solution is characterised by the mathematics alone —
the complex equation holds (with the conjugate transpose) and the closed loop A − BK (with E)
is stable — which is what tests/tests/riccati_complex.rs checks of sd_hinf::care_complex /
dare_complex; where scipy solves a case, X must also agree with scipy's and the residual be at
or below max(scipy's, 100·n·eps). Complex matrices are stored as {"re": [[...]], "im": [[...]]}.
Run once (python3 tools/gen_complex_riccati.py, with numpy and scipy); the output is committed,
never needed at test time."""
import json

import numpy as np
import scipy
import scipy.linalg as sl

rng = np.random.default_rng(20261128)


def H(m):
    return m.conj().T


def residual(kind, A, E, B, Q, R, S, X):
    if kind == "care":
        axe = H(A) @ X @ E
        t = H(E) @ X @ B + S
        tk = t @ np.linalg.solve(R, H(t))
        lhs = axe + H(axe) - tk + Q
        terms = np.linalg.norm(Q) + 2 * np.linalg.norm(axe) + np.linalg.norm(tk)
    else:
        axa = H(A) @ X @ A
        exe = H(E) @ X @ E
        t = H(A) @ X @ B + S
        tk = t @ np.linalg.solve(R + H(B) @ X @ B, H(t))
        lhs = axa - exe - tk + Q
        terms = np.linalg.norm(Q) + np.linalg.norm(axa) + np.linalg.norm(exe) + np.linalg.norm(tk)
    lhs = 0.5 * (lhs + H(lhs))
    return float(np.linalg.norm(lhs) / terms)


def crandn(*shape):
    return rng.standard_normal(shape) + 1j * rng.standard_normal(shape)


def store(m):
    m = np.asarray(m, dtype=complex)
    return {"re": m.real.tolist(), "im": m.imag.tolist()}


cases = []
for kind in ["care", "dare"]:
    for k in range(10):
        n = int(rng.integers(1, 8))
        m = int(rng.integers(1, 4))
        A = crandn(n, n) / np.sqrt(2)
        if kind == "dare":
            A *= 1.1 / max(abs(np.linalg.eigvals(A)))  # some unstable poles, X modest
        B = crandn(n, m)
        C = crandn(n, n)
        Q = H(C) @ C + 0.1 * np.eye(n)
        Rm = crandn(m, m)
        R = Rm @ H(Rm) + np.eye(m)
        S = 0.1 * crandn(n, m) if k % 2 else np.zeros((n, m), dtype=complex)
        # only B complex (the "complex B" case) in one case per kind
        if k == 0:
            A, Q, R = A.real.astype(complex), Q.real.astype(complex), R.real.astype(complex)
        E = np.eye(n, dtype=complex)
        if k % 4 == 3:
            E = np.eye(n) + 0.4 * crandn(n, n) / np.sqrt(2 * n)
        solve = sl.solve_continuous_are if kind == "care" else sl.solve_discrete_are
        try:
            X = solve(A, B, Q, R, e=None if k % 4 != 3 else E, s=S)
            scipy_out = {"X_scipy": store(X),
                         "scipy_residual": residual(kind, A, E, B, Q, R, S, X)}
        except Exception as ex:  # noqa: BLE001 - recorded: scipy refuses the case
            print(kind, k, "scipy:", ex)
            scipy_out = {"scipy_error": str(ex)}
        cases.append({
            "name": f"{kind}_{k}_n{n}_m{m}",
            "kind": kind,
            "descriptor": k % 4 == 3,
            "A": store(A), "E": store(E), "B": store(B), "Q": store(Q),
            "R": store(R), "S": store(S),
            **scipy_out,
        })

out = {
    "generator": "tools/gen_complex_riccati.py",
    "scipy": scipy.__version__,
    "cases": cases,
}
with open("test_data/complex_riccati.json", "w") as f:
    json.dump(out, f, indent=1)
print(len(cases), "cases")
