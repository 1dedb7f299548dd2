"""Reference quantiles of Fisher's F law for sd_model::f_quantile's unit test.

Run: python3 tools/f_quantile_reference.py (scipy); the printed rows are the test's table.
"""
from scipy.stats import f

for p in [0.99, 0.95]:
    for d1, d2 in [(12, 18), (12, 36), (12, 72), (12, 144), (12, 1000), (2, 20), (20, 40)]:
        print(f"({p}, {d1}.0, {d2}.0, {float(f.ppf(p, d1, d2))!r}),")
