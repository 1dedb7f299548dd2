//! Golden-section search for the minimum of a unimodal function on a bracket.

/// Minimizes `f` on `[a, b]` by `iters` golden-section steps (one new evaluation each; the
/// bracket shrinks by 0.618 per step, Kiefer 1953). Returns the better of the two final interior
/// points and its value. `f` may return NaN or ∞ for points to avoid (they never win). A smooth
/// minimum is located to about `√ε·(b − a)`, where f is flat to rounding. A smooth
/// minimum is located to about `√ε·(b − a)`, where f is flat to rounding.
pub fn golden_min(mut f: impl FnMut(f64) -> f64, a: f64, b: f64, iters: usize) -> (f64, f64) {
    let g = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (a, b);
    let val = |v: f64| if v.is_nan() { f64::INFINITY } else { v };
    let mut x1 = b - g * (b - a);
    let mut x2 = a + g * (b - a);
    let (mut f1, mut f2) = (val(f(x1)), val(f(x2)));
    for _ in 0..iters {
        if f1 < f2 {
            b = x2;
            x2 = x1;
            f2 = f1;
            x1 = b - g * (b - a);
            f1 = val(f(x1));
        } else {
            a = x1;
            x1 = x2;
            f1 = f2;
            x2 = a + g * (b - a);
            f2 = val(f(x2));
        }
    }
    if f1 <= f2 {
        (x1, f1)
    } else {
        (x2, f2)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn finds_the_minimum_of_a_parabola() {
        let (x, fx) = golden_min(|x| (x - 0.3).powi(2) + 2.0, 0.0, 1.0, 60);
        // a smooth minimum is located to about √ε of the bracket (f is flat to rounding there)
        assert!(
            (x - 0.3).abs() < 1e-7 && (fx - 2.0).abs() < 1e-15,
            "{x} {fx}"
        );
        // after k steps the bracket is 0.618^k wide: 20 steps leave it below 1e-4
        let (x, _) = golden_min(|x| (x - 0.7).abs(), 0.0, 1.0, 20);
        assert!((x - 0.7).abs() < 1e-4, "{x}");
    }
}
