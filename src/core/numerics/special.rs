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
    } else if x < TABLE_START {
        1.0 - erf_series(x)
    } else {
        (-x * x).exp() * erfcx(x)
    }
}

/// From here on, `erfcx` sums its asymptotic series (whose smallest term,
/// about e^{-x²}, is below double precision there).
const ASYMPTOTIC_LIMIT: f64 = 8.0;

/// From here on, `erfc` and `erfcx` come from a table, not `1 - erf`
/// (which loses digits as `erf` nears 1: 5e-12 of `erfc(3)`).
const TABLE_START: f64 = 0.5;

/// Spacing of the `erfcx` table between [`TABLE_START`] and
/// [`ASYMPTOTIC_LIMIT`].
const TABLE_STEP: f64 = 1.0 / 64.0;

/// `erfcx` at `TABLE_START + i·TABLE_STEP`, computed once (about 2 ms).
/// From 3 on: the continued fraction summed backwards from a term far past
/// convergence (it rounds less than the forward, Lentz, evaluation).
/// Below 3: Taylor steps down from the value at 3; `y' = 2xy - 2/√π`
/// damps errors in that direction.
fn erfcx_table() -> &'static [f64] {
    static TABLE: std::sync::OnceLock<Vec<f64>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let at = |i: usize| TABLE_START + i as f64 * TABLE_STEP;
        let n = ((ASYMPTOTIC_LIMIT - TABLE_START) / TABLE_STEP).round() as usize + 1;
        let first_fraction = ((SERIES_LIMIT - TABLE_START) / TABLE_STEP).round() as usize;
        let mut table = vec![0.0; n];
        for (i, value) in table.iter_mut().enumerate().skip(first_fraction) {
            let x = at(i);
            let tail = (1..=1000).rev().fold(x, |f, k| x + 0.5 * f64::from(k) / f);
            *value = 1.0 / (PI.sqrt() * tail);
        }
        for i in (0..first_fraction).rev() {
            let above = table.get(i + 1).copied().unwrap_or(0.0);
            if let Some(value) = table.get_mut(i) {
                *value = erfcx_taylor(at(i + 1), above, at(i));
            }
        }
        table
    })
}

/// `erfcx` near a table point `x0` with value `y0`, by its Taylor series:
/// `y = erfcx` solves `y' = 2xy - 2/√π`, so the coefficients follow
/// `c₁ = 2x₀c₀ - 2/√π`, `c_{n+1} = 2(x₀cₙ + c_{n-1})/(n+1)`. With
/// `|x - x₀| ≤ 1/64` the terms shrink at least fourfold each.
fn erfcx_taylor(x0: f64, y0: f64, x: f64) -> f64 {
    let h = x - x0;
    let (mut previous, mut current) = (y0, 2.0 * x0 * y0 - FRAC_2_SQRT_PI);
    let mut sum = y0 + current * h;
    let mut power = h;
    for n in 1..30 {
        let next = 2.0 * (x0 * current + previous) / f64::from(n + 1);
        power *= h;
        let term = next * power;
        sum += term;
        if term.abs() <= 1e-17 * sum.abs() {
            break;
        }
        previous = current;
        current = next;
    }
    sum
}

/// `erfcx(x)` for `x ≥ ASYMPTOTIC_LIMIT`: `1/(x√π) Σ (-1)ⁿ (2n-1)!! / (2x²)ⁿ`,
/// summed while its terms shrink below double precision.
fn erfcx_asymptotic(x: f64) -> f64 {
    let inverse = 1.0 / (2.0 * x * x);
    let mut term = 1.0;
    let mut sum = 1.0;
    for n in 1..60 {
        term *= -f64::from(2 * n - 1) * inverse;
        sum += term;
        if term.abs() < 1e-17 * sum {
            break;
        }
    }
    sum / (x * PI.sqrt())
}

/// The scaled complementary error function `erfc(x) e^{x²}` for `x ≥ 0`
/// (finite where `erfc` underflows): `e^{x²}(1 - erf(x))` below 0.5, a
/// table with a Taylor step up to 8, its asymptotic series beyond.
#[must_use]
pub fn erfcx(x: f64) -> f64 {
    if x < TABLE_START {
        (x * x).exp() * (1.0 - erf_series(x.max(0.0)))
    } else if x < ASYMPTOTIC_LIMIT {
        let table = erfcx_table();
        let i = ((x - TABLE_START) / TABLE_STEP).round() as usize;
        match table.get(i) {
            Some(&y0) => erfcx_taylor(TABLE_START + i as f64 * TABLE_STEP, y0, x),
            None => erfcx_continued_fraction(x),
        }
    } else if x.is_finite() {
        erfcx_asymptotic(x)
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
    let scaled_lo = erfcx(lo);
    let ratio = ((lo - hi) * (lo + hi)).exp() * erfcx(hi) / scaled_lo;
    -lo * lo + scaled_lo.ln() + (-ratio).ln_1p()
}

/// `P(X > x)` for `X` chi-square distributed with `dof` degrees of freedom
/// (closed forms for integer degrees of freedom, each term taken in log
/// space so that huge `x` gives 0, not an overflow); 1 for `dof = 0`, 0
/// for a NaN `x`.
#[must_use]
pub fn chi_square_survival(x: f64, dof: usize) -> f64 {
    if x.is_nan() || (x.is_infinite() && x > 0.0) {
        return 0.0;
    }
    if dof == 0 || x <= 0.0 {
        return 1.0;
    }
    let half = 0.5 * x;
    if dof.is_multiple_of(2) {
        // e^{-x/2} Σ_{j < k/2} (x/2)^j / j!
        let mut ln_term = -half;
        let mut sum = ln_term.exp();
        for j in 1..dof / 2 {
            ln_term += half.ln() - (j as f64).ln();
            sum += ln_term.exp();
        }
        sum.min(1.0)
    } else {
        // erfc(√(x/2)) + e^{-x/2} Σ_{j=1}^{(k-1)/2} x^{j-1/2} / (√(2π)/2 · 1·3·…·(2j-1))
        let mut ln_term = 0.5 * x.ln() + 0.5 * (2.0 / PI).ln() - half;
        let mut sum = 0.0;
        for j in 1..=(dof - 1) / 2 {
            if j > 1 {
                ln_term += x.ln() - ((2 * j - 1) as f64).ln();
            }
            sum += ln_term.exp();
        }
        (erfc(half.sqrt()) + sum).min(1.0)
    }
}

/// `1 / (1 + e^-x)`: a probability from its log odds, without overflow
/// at either end.
#[must_use]
pub fn logistic(x: f64) -> f64 {
    if x >= 0.0 {
        1.0 / (1.0 + (-x).exp())
    } else {
        let e = x.exp();
        e / (1.0 + e)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn logistic_is_the_sigmoid_and_saturates_without_overflow() {
        assert!((logistic(0.0) - 0.5).abs() < 1e-15);
        // σ(x) = e^x / (1 + e^x), and σ(x) + σ(-x) = 1.
        for x in [-30.0, -2.5, -1e-3, 0.7, 4.0, 30.0] {
            let e: f64 = f64::exp(x);
            assert!((logistic(x) - e / (1.0 + e)).abs() < 1e-15, "{x}");
            assert!((logistic(x) + logistic(-x) - 1.0).abs() < 1e-15, "{x}");
        }
        assert!(logistic(-1e308) >= 0.0 && logistic(-1e308) < 1e-300);
        assert!((logistic(1e308) - 1.0).abs() < 1e-15);
        assert_eq!(
            [logistic(f64::INFINITY), logistic(f64::NEG_INFINITY)].map(f64::to_bits),
            [1.0, 0.0].map(f64::to_bits)
        );
    }

    /// Torques of 1e70 N·m gave 0·∞ = NaN and a survival of 1 ("no
    /// contact").
    #[test]
    fn huge_chi_squares_have_no_chance() {
        for dof in 1..=8 {
            for x in [1e4, 1e100, 1e300, f64::INFINITY] {
                assert!(chi_square_survival(x, dof) < f64::MIN_POSITIVE, "{x} with {dof}");
            }
            assert!(chi_square_survival(f64::NAN, dof) < f64::MIN_POSITIVE);
        }
    }

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
    fn tabled_and_asymptotic_erfcx_agree_with_the_continued_fraction() {
        // Values computed in 60- to 80-digit decimal arithmetic: below 3
        // from the series of erf, from 3 on the continued fraction summed
        // backwards from its 5000th term.
        let reference = [
            (0.25, 0.770_346_547_730_996_8),
            (0.5, 0.615_690_344_192_925_9),
            (1.0, 0.427_583_576_155_807),
            (1.7, 0.291_663_297_075_343_44),
            (2.5, 0.210_806_364_061_143_6),
            (2.9, 0.184_601_825_955_590_83),
            (3.0, 0.179_001_151_181_389_96),
            (3.1, 0.173_718_408_605_408_24),
            (3.359_375, 0.161_323_309_488_379_42),
            (4.25, 0.129_345_274_785_987_92),
            (5.5, 0.100_962_218_399_499_09),
            (7.99, 0.070_071_436_717_952_68),
            (8.0, 0.069_985_166_200_880_92),
            (12.5, 0.044_992_099_001_027_92),
            (30.0, 0.018_795_888_861_416_75),
        ];
        for (x, e) in reference {
            assert!((erfcx(x) / e - 1.0).abs() < 1e-15, "erfcx({x}) = {} vs {e}", erfcx(x));
        }
        // Every table interval from 3, both sides of each node, and far
        // out, against the continued fraction (itself good to a few 1e-16).
        let mut x = SERIES_LIMIT;
        while x < 40.0 {
            let (fast, slow) = (erfcx(x), erfcx_continued_fraction(x));
            assert!((fast / slow - 1.0).abs() < 5e-15, "erfcx({x}) = {fast} vs {slow}");
            x += if x < ASYMPTOTIC_LIMIT { TABLE_STEP / 7.0 } else { 0.37 };
        }
        // Continuous across the series/table and table/asymptotic joins.
        for join in [TABLE_START, SERIES_LIMIT, ASYMPTOTIC_LIMIT] {
            let (below, above) = (erfcx(join - 1e-12), erfcx(join));
            assert!((below / above - 1.0).abs() < 1e-12, "{join}: {below} vs {above}");
        }
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
