"""Monte Carlo of the diagnosis's line score with Satterthwaite's degrees of freedom.

A line compares a measurement with a prediction: x = |e|²/(v̂₁ + v̂₂), e complex Gaussian with
variance v₁ + v₂, v̂ᵢ = vᵢ·χ²_ν/ν (an estimated variance) or vᵢ itself (a computed one). The
score s = (ν'/2)·ln(1 + 2x/ν') is exponential with mean 1 when ν' is right. Printed: the mean
score with ν' from the line's own estimates (what `sd_diagnose`'s `compare` did) and from the
expected sizes (what it does now), for two estimates of a given variance ratio and for an
estimate beside a computed prediction variance. Cited in `sd-diagnose/src/lemma6.rs`.

    python tools/mc_satterthwaite.py      (numpy; 2·10⁶ draws per row, seed 0)
"""
import numpy as np

NU = 6.0  # the LPM's default: 2(2n + 1 − q) = 6
N = 2_000_000


def score(x, nu):
    return nu / 2 * np.log1p(2 * x / nu)


def satterthwaite(parts):
    num = sum(v for v, _ in parts) ** 2
    den = sum(v * v / d for v, d in parts if np.all(np.isfinite(d)))
    return num / den


def main():
    rng = np.random.default_rng(0)
    print("two estimates (ν = 6 each), variance ratio v₁/v₂: mean score own / expected")
    for ratio in [1, 4, 16, 64]:
        v1, v2 = 1.0, 1.0 / ratio
        e = (rng.standard_normal(N) ** 2 + rng.standard_normal(N) ** 2) / 2 * (v1 + v2)
        e1 = v1 * rng.chisquare(NU, N) / NU
        e2 = v2 * rng.chisquare(NU, N) / NU
        x = e / (e1 + e2)
        own = score(x, satterthwaite([(e1, NU), (e2, NU)])).mean()
        exp = score(x, satterthwaite([(v1, NU), (v2, NU)])).mean()
        print(f"  {ratio:3d}: {own:.4f} / {exp:.4f}")
    print("an estimate (ν = 6) beside a computed prediction variance p·v: own / expected")
    for p in [0.1, 0.3, 1.0, 3.0]:
        v, pv = 1.0, p
        e = (rng.standard_normal(N) ** 2 + rng.standard_normal(N) ** 2) / 2 * (v + pv)
        est = v * rng.chisquare(NU, N) / NU
        x = e / (est + pv)
        own = score(x, (est + pv) ** 2 / (est**2 / NU)).mean()
        exp = score(x, (v + pv) ** 2 / (v**2 / NU)).mean()
        print(f"  {p:4.1f}: {own:.4f} / {exp:.4f}")


if __name__ == "__main__":
    main()
