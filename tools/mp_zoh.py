"""The exact ZOH in mpmath, shared by the generators of test_data/zoh_random.json and
test_data/zoh_vs_scipy.json: exp([[A, B], [0, 0]]·h) by mpmath's own scaling-and-squaring
Taylor method at the caller's mp.mp.dps, rounded to double at the end."""
import mpmath as mp
import numpy as np


def zoh_mp(A, B, h):
    """(A_d, B_d) as float arrays."""
    n, m = B.shape
    M = mp.zeros(n + m, n + m)
    for i in range(n):
        for j in range(n):
            M[i, j] = mp.mpf(float(A[i, j])) * mp.mpf(h)
        for j in range(m):
            M[i, n + j] = mp.mpf(float(B[i, j])) * mp.mpf(h)
    E = mp.expm(M)
    Ad = np.array([[float(E[i, j]) for j in range(n)] for i in range(n)])
    Bd = np.array([[float(E[i, n + j]) for j in range(m)] for i in range(n)])
    return Ad, Bd
