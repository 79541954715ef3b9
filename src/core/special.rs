//! Special functions for Gaussian likelihoods in log space: the error
//! function family and the chi-square survival function.

use std::f64::consts::PI;

const FRAC_2_SQRT_PI: f64 = std::f64::consts::FRAC_2_SQRT_PI;

/// Below this, `erf` uses its everywhere-positive series; above, `erfc`
/// uses its continued fraction (both converge to full precision there).
const SERIES_LIMIT: f64 = 3.0;

/// `erf(x) = 2/√π e^{-x²} Σ 2ⁿ x^{2n+1} / (1·3·…·(2n+1))`: every term is
/// positive, so nothing cancels.
fn erf_series(x: f64) -> f64 {
    let x2 = x * x;
    let mut term = x;
    let mut sum = x;
    let mut n = 0.0;
    while term.abs() > 1e-17 * sum.abs() {
        n += 1.0;
        term *= 2.0 * x2 / (2.0 * n + 1.0);
        sum += term;
    }
    FRAC_2_SQRT_PI * (-x2).exp() * sum
}

/// `erfc(x) e^{x²}` for `x ≥ SERIES_LIMIT`, by its continued fraction
/// `1/√π · 1/(x + (1/2)/(x + 1/(x + (3/2)/(x + …))))` (modified Lentz).
fn erfcx_continued_fraction(x: f64) -> f64 {
    let tiny = 1e-300;
    let mut f = x;
    let mut c = x;
    let mut d = 0.0;
    for k in 1..200 {
        let a = f64::from(k) / 2.0;
        d = x + a * d;
        d = if d.abs() < tiny { tiny } else { d };
        c = x + a / c;
        c = if c.abs() < tiny { tiny } else { c };
        d = 1.0 / d;
        let delta = c * d;
        f *= delta;
        if (delta - 1.0).abs() < 1e-16 {
            break;
        }
    }
    1.0 / (PI.sqrt() * f)
}

/// The error function.
#[must_use]
pub fn erf(x: f64) -> f64 {
    if x.abs() < SERIES_LIMIT {
        erf_series(x)
    } else {
        x.signum() * (1.0 - erfc(x.abs()))
    }
}

/// The complementary error function `1 - erf(x)`, accurate in the tail.
#[must_use]
pub fn erfc(x: f64) -> f64 {
    if x < 0.0 {
        2.0 - erfc(-x)
    } else if x < SERIES_LIMIT {
        1.0 - erf_series(x)
    } else {
        (-x * x).exp() * erfcx_continued_fraction(x)
    }
}

/// The scaled complementary error function `erfc(x) e^{x²}` for `x ≥ 0`
/// (finite where `erfc` underflows).
#[must_use]
pub fn erfcx(x: f64) -> f64 {
    if x < SERIES_LIMIT {
        (x * x).exp() * (1.0 - erf_series(x.max(0.0)))
    } else {
        erfcx_continued_fraction(x)
    }
}

/// `ln(erf(hi) - erf(lo))` for `lo ≤ hi`, without cancellation or
/// underflow far in either tail; `-inf` when `lo == hi`.
#[must_use]
pub fn ln_erf_difference(lo: f64, hi: f64) -> f64 {
    if lo >= hi {
        return f64::NEG_INFINITY;
    }
    if lo < -6.0 && hi > 6.0 {
        // erf(6) = 1 - 2e-17: the difference is 2 to double precision.
        return std::f64::consts::LN_2;
    }
    if hi <= 0.0 {
        return ln_erf_difference(-hi, -lo);
    }
    if lo < 0.0 {
        // Both erf(hi) and erf(-lo) are positive: no cancellation.
        return (erf(hi) + erf(-lo)).ln();
    }
    // 0 ≤ lo < hi: erfc(lo) - erfc(hi) = e^{-lo²} [erfcx(lo) - e^{lo²-hi²} erfcx(hi)].
    let ratio = ((lo - hi) * (lo + hi)).exp() * erfcx(hi) / erfcx(lo);
    -lo * lo + erfcx(lo).ln() + (-ratio).ln_1p()
}

/// `P(X > x)` for `X` chi-square distributed with `dof` degrees of freedom
/// (closed forms for integer degrees of freedom); 1 for `dof = 0`.
#[must_use]
pub fn chi_square_survival(x: f64, dof: usize) -> f64 {
    if dof == 0 || x <= 0.0 {
        return 1.0;
    }
    let half = 0.5 * x;
    if dof.is_multiple_of(2) {
        // e^{-x/2} Σ_{j < k/2} (x/2)^j / j!
        let mut term = 1.0;
        let mut sum = 1.0;
        for j in 1..dof / 2 {
            term *= half / j as f64;
            sum += term;
        }
        ((-half).exp() * sum).min(1.0)
    } else {
        // erfc(√(x/2)) + e^{-x/2} Σ_{j=1}^{(k-1)/2} x^{j-1/2} / (√(2π)/2 · 1·3·…·(2j-1))
        let root = x.sqrt();
        let mut term = root * (2.0 / PI).sqrt();
        let mut sum = 0.0;
        for j in 1..=(dof - 1) / 2 {
            if j > 1 {
                term *= x / (2 * j - 1) as f64;
            }
            sum += term;
        }
        (erfc((half).sqrt()) + (-half).exp() * sum).min(1.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reference values (Abramowitz and Stegun, Table 7.1, and mpmath).
    #[test]
    fn erf_and_erfc_match_tables() {
        let cases = [
            (0.0, 0.0),
            (0.1, 0.112_462_916_018_284_9),
            (0.5, 0.520_499_877_813_046_5),
            (1.0, 0.842_700_792_949_714_9),
            (2.0, 0.995_322_265_018_952_7),
            (2.9, 0.999_958_902_121_900_8),
            (3.5, 0.999_999_256_901_627_7),
        ];
        for (x, e) in cases {
            assert!((erf(x) - e).abs() < 1e-15, "erf({x}) = {} vs {e}", erf(x));
            assert!((erf(-x) + e).abs() < 1e-15);
        }
        let tails = [
            (3.0, 2.209_049_699_858_544e-5),
            (5.0, 1.537_459_794_428_035e-12),
            (10.0, 2.088_487_583_762_545e-45),
        ];
        for (x, e) in tails {
            assert!((erfc(x) / e - 1.0).abs() < 1e-13, "erfc({x}) = {} vs {e}", erfc(x));
        }
        assert!((erfc(-1.0) - (1.0 + 0.842_700_792_949_714_9)).abs() < 1e-15);
        // erfcx(x) ~ 1/(x√π) for large x.
        assert!((erfcx(1e6) * 1e6 * PI.sqrt() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn ln_erf_difference_agrees_with_direct_values_and_stays_finite_in_tails() {
        for (lo, hi) in [(-1.0, 2.0), (0.3, 0.4), (-2.0, -0.5), (1.0, 1.5)] {
            let direct = (erf(hi) - erf(lo)).ln();
            assert!((ln_erf_difference(lo, hi) - direct).abs() < 1e-12, "{lo} {hi}");
        }
        // Deep tail: erf(31) - erf(30) ≈ erfc(30) = e^{-900} erfcx(30).
        let v = ln_erf_difference(30.0, 31.0);
        let expected = -900.0 + erfcx(30.0).ln();
        assert!(v.is_finite() && (v - expected).abs() < 1e-9, "{v} vs {expected}");
        assert!((ln_erf_difference(-31.0, -30.0) - v).abs() < 1e-12);
        assert!(ln_erf_difference(1.0, 1.0).is_infinite());
    }

    /// Against the integral of the density, and known quantiles.
    #[test]
    fn chi_square_survival_matches_known_values() {
        // Medians and 95 % quantiles (dof: x).
        let quantiles_95 = [
            (1, 3.841_458_820_694_124),
            (2, 5.991_464_547_107_979),
            (3, 7.814_727_903_251_178),
            (7, 14.067_140_449_340_169),
        ];
        for (k, x) in quantiles_95 {
            assert!(
                (chi_square_survival(x, k) - 0.05).abs() < 1e-12,
                "dof {k}: {}",
                chi_square_survival(x, k)
            );
        }
        assert!((chi_square_survival(2.0 * 2f64.ln(), 2) - 0.5).abs() < 1e-15);
        assert!((chi_square_survival(0.0, 5) - 1.0).abs() < f64::EPSILON);
        assert!(chi_square_survival(1e12, 6) < f64::MIN_POSITIVE);
    }
}
