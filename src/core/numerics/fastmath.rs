//! Branch-free `exp`, `ln` and `ln erf` differences for loops over many
//! surface points: plain arithmetic and bit operations that the compiler
//! turns into vector instructions (calls into the maths library would stop
//! that), each with a tested error bound.

use std::f64::consts::{LN_2, LOG2_E, PI, SQRT_2};
use std::sync::OnceLock;

use crate::core::numerics::special::erfcx;

/// 1.5 · 2⁵²: adding it rounds a double to an integer, which then sits in
/// the low bits of the sum's representation.
const ROUNDER: f64 = 6_755_399_441_055_744.0;

/// ln 2 split so that `k · LN2_HI` is exact for |k| < 2²⁰.
const LN2_HI: f64 = f64::from_bits(LN_2.to_bits() & 0xFFFF_FFFF_0000_0000);
const LN2_LO: f64 = LN_2 - LN2_HI;

/// `e^x` for `x ≤ 709`; below -708 it returns `e^-708` (negligible beside
/// anything it is added to here). Relative error below 5e-14 (tested).
#[inline(always)]
#[must_use]
pub fn exp(x: f64) -> f64 {
    let x = if x > -708.0 { x } else { -708.0 };
    let x = if x < 709.0 { x } else { 709.0 };
    let shifted = x * LOG2_E + ROUNDER;
    let k = shifted - ROUNDER;
    let r = x - k * LN2_HI - k * LN2_LO;
    // e^r, |r| ≤ ln2/2: Taylor to r¹³ (the next term is below 1e-17).
    let mut p = 1.0 / 6_227_020_800.0;
    for d in [
        479_001_600.0,
        39_916_800.0,
        3_628_800.0,
        362_880.0,
        40_320.0,
        5_040.0,
        720.0,
        120.0,
        24.0,
        6.0,
        2.0,
        1.0,
        1.0,
    ] {
        p = p * r + 1.0 / d;
    }
    // 2^k from k's bits (the low bits of `shifted`).
    let scale = f64::from_bits(shifted.to_bits().wrapping_add(1023) << 52);
    p * scale
}

/// `ln y` for a positive normal `y`. Absolute error below 1e-15 · max(1,
/// |ln y|) (tested).
#[inline(always)]
#[must_use]
pub fn ln(y: f64) -> f64 {
    let bits = y.to_bits();
    let exponent = f64::from_bits(0x4330_0000_0000_0000 | (bits >> 52)) - (4_503_599_627_370_496.0 + 1023.0);
    let mantissa = f64::from_bits((bits & 0x000F_FFFF_FFFF_FFFF) | 0x3FF0_0000_0000_0000);
    let big = mantissa > SQRT_2;
    let m = if big { 0.5 * mantissa } else { mantissa };
    let e = if big { exponent + 1.0 } else { exponent };
    // ln m = 2 atanh z, |z| ≤ 0.172: the series to z¹⁹.
    let z = (m - 1.0) / (m + 1.0);
    let z2 = z * z;
    let mut s = 1.0 / 21.0;
    for d in [19.0, 17.0, 15.0, 13.0, 11.0, 9.0, 7.0, 5.0, 3.0, 1.0] {
        s = s * z2 + 1.0 / d;
    }
    e * LN_2 + 2.0 * z * s
}

/// `ln x` (by [`ln`] where `x` is a normal number), -∞ for
/// `x ≤ 0` or NaN.
#[inline]
#[must_use]
pub fn ln_or_minus_infinity(x: f64) -> f64 {
    if (f64::MIN_POSITIVE..f64::INFINITY).contains(&x) {
        ln(x)
    } else if x > 0.0 {
        x.ln()
    } else {
        f64::NEG_INFINITY
    }
}

/// Scale of the variable `t = K/(K + x)` of [`ln_erfcx`]'s fit.
const ERFCX_K: f64 = 3.0;

/// Degree of the Chebyshev fit of `ln(erfcx(x)/t)` in `t`.
const ERFCX_DEGREE: usize = 22;

/// Chebyshev coefficients of `P(t) = ln(erfcx(x) / t)` on `t ∈ [0, 1]`
/// (`x = K(1/t - 1)`), interpolated once at Chebyshev nodes from the
/// accurate [`erfcx`]. `P` is smooth on the whole interval: at `t = 0`
/// (`x = ∞`) it tends to `-ln(K √π)`.
fn erfcx_coefficients() -> &'static [f64; ERFCX_DEGREE] {
    static COEFFICIENTS: OnceLock<[f64; ERFCX_DEGREE]> = OnceLock::new();
    COEFFICIENTS.get_or_init(|| {
        let n = ERFCX_DEGREE;
        let values: Vec<f64> = (0..n)
            .map(|j| {
                let u = (PI * (j as f64 + 0.5) / n as f64).cos();
                let t = 0.5 * (u + 1.0);
                let x = ERFCX_K * (1.0 / t - 1.0);
                (erfcx(x) / t).ln()
            })
            .collect();
        std::array::from_fn(|k| {
            let sum: f64 = values
                .iter()
                .enumerate()
                .map(|(j, v)| v * (PI * k as f64 * (j as f64 + 0.5) / n as f64).cos())
                .sum();
            let c = 2.0 * sum / n as f64;
            if k == 0 { 0.5 * c } else { c }
        })
    })
}

/// `(t, P)` with `erfcx(x) = t e^P` for `x ≥ 0`: `t = K/(K + x)`, `P` from
/// the Chebyshev fit. `ln erfc(x) = -x² + ln t + P`. Absolute error of `P`
/// below 1e-12 (tested).
#[inline(always)]
#[must_use]
pub fn ln_erfcx_parts(x: f64, coefficients: &[f64; ERFCX_DEGREE]) -> (f64, f64) {
    let ([t], [p]) = ln_erfcx_parts_lanes(&[x], coefficients);
    (t, p)
}

/// [`ln_erfcx_parts`] of `L` values at once, lane by lane: the same
/// operations in the same order for each lane (so the same bits as `L`
/// of 1, which is what [`ln_erfcx_parts`] is), but `L` independent
/// Clenshaw chains in flight, which a loop of one value per step leaves
/// waiting on each step's latency.
#[inline(always)]
#[must_use]
pub fn ln_erfcx_parts_lanes<const L: usize>(x: &[f64; L], coefficients: &[f64; ERFCX_DEGREE]) -> ([f64; L], [f64; L]) {
    let mut t = [0.0; L];
    let mut u = [0.0; L];
    for l in 0..L {
        t[l] = ERFCX_K / (ERFCX_K + x[l]);
        u[l] = 2.0 * t[l] - 1.0;
    }
    // Clenshaw.
    let (mut b1, mut b2) = ([0.0; L], [0.0; L]);
    for &c in coefficients.iter().skip(1).rev() {
        for l in 0..L {
            let b0 = 2.0 * u[l] * b1[l] - b2[l] + c;
            b2[l] = b1[l];
            b1[l] = b0;
        }
    }
    let mut p = [0.0; L];
    for l in 0..L {
        p[l] = u[l] * b1[l] - b2[l] + coefficients[0];
    }
    (t, p)
}

/// What `ln_erf_difference_many` needs, fetched once.
#[derive(Debug, Clone, Copy)]
pub struct ErfTable {
    coefficients: &'static [f64; ERFCX_DEGREE],
}

impl ErfTable {
    /// The fit (computed on first use).
    #[must_use]
    pub fn get() -> Self {
        Self {
            coefficients: erfcx_coefficients(),
        }
    }

    /// `ln(erfcx(x) · t⁻¹) = P` and `t` for `x ≥ 0` (see [`ln_erfcx_parts`]).
    #[inline(always)]
    #[must_use]
    pub fn parts(&self, x: f64) -> (f64, f64) {
        ln_erfcx_parts(x, self.coefficients)
    }

    /// [`Self::parts`] of `L` values at once (see [`ln_erfcx_parts_lanes`]).
    #[inline(always)]
    #[must_use]
    pub fn parts_lanes<const L: usize>(&self, x: &[f64; L]) -> ([f64; L], [f64; L]) {
        ln_erfcx_parts_lanes(x, self.coefficients)
    }

    /// `ln(erf(hi) - erf(lo))` for `lo < hi` with `hi - lo ≥ 0.05`, branch
    /// free: absolute error below 1e-10 (tested against
    /// [`crate::core::numerics::special::ln_erf_difference`]). Narrower intervals
    /// cancel; callers take the careful path for them.
    #[inline(always)]
    #[must_use]
    pub fn ln_erf_difference(&self, lo: f64, hi: f64) -> f64 {
        let [out] = self.ln_erf_difference_lanes(&[lo], &[hi]);
        out
    }

    /// [`Self::ln_erf_difference`] of `L` intervals at once, lane by lane
    /// (the same bits as one at a time; see [`ln_erfcx_parts_lanes`]).
    #[inline(always)]
    #[must_use]
    pub fn ln_erf_difference_lanes<const L: usize>(&self, lo: &[f64; L], hi: &[f64; L]) -> [f64; L] {
        // Same side of 0: the end nearer 0 ("near") and the other ("far").
        let (mut yn, mut yf) = ([0.0; L], [0.0; L]);
        for l in 0..L {
            let (y_lo, y_hi) = (lo[l].abs(), hi[l].abs());
            let near_is_lo = y_lo < y_hi;
            (yn[l], yf[l]) = if near_is_lo { (y_lo, y_hi) } else { (y_hi, y_lo) };
        }
        let (tn, pn) = self.parts_lanes(&yn);
        let (tf, pf) = self.parts_lanes(&yf);
        let mut out = [0.0; L];
        for l in 0..L {
            // erfc(yn) - erfc(yf) = e^{-yn² + Pn} (tn - tf e^{yn² - yf² + Pf - Pn}).
            let ratio = exp((yn[l] - yf[l]) * (yn[l] + yf[l]) + pf[l] - pn[l]);
            let same = -yn[l] * yn[l] + pn[l] + ln(tn[l] - tf[l] * ratio);
            // Opposite sides: erf(hi) - erf(lo) = 2 - erfc(|lo|) - erfc(|hi|).
            let both = 2.0 - tn[l] * exp(-yn[l] * yn[l] + pn[l]) - tf[l] * exp(-yf[l] * yf[l] + pf[l]);
            let opposite = ln(both);
            out[l] = if lo[l] < 0.0 && hi[l] > 0.0 { opposite } else { same };
        }
        out
    }
}

#[cfg(test)]
mod tests {
    /// `ln` where it is defined (the fast one on normal numbers, within
    /// its bound; the library's on subnormal ones), -∞ elsewhere.
    #[test]
    fn ln_or_minus_infinity_covers_every_input() {
        for x in [1e-300, 0.3, 1.0, 2.5, 1e300] {
            let (got, want) = (ln_or_minus_infinity(x), x.ln());
            assert!(
                (got - want).abs() <= 1e-15 * want.abs().max(1.0),
                "{x}: {got} vs {want}"
            );
        }
        assert_eq!(ln_or_minus_infinity(1e-310).to_bits(), 1e-310_f64.ln().to_bits());
        assert_eq!(ln_or_minus_infinity(f64::INFINITY).to_bits(), f64::INFINITY.to_bits());
        for x in [0.0, -0.0, -1.0, f64::NAN, f64::NEG_INFINITY] {
            assert_eq!(ln_or_minus_infinity(x).to_bits(), f64::NEG_INFINITY.to_bits(), "{x}");
        }
    }

    use super::*;
    use crate::core::numerics::special;

    #[test]
    fn exp_matches_the_library_within_5e_14() {
        let mut worst: f64 = 0.0;
        for i in 0..200_000 {
            let x = -708.0 + 1417.0 * f64::from(i) / 200_000.0;
            let (fast, exact) = (exp(x), x.exp());
            worst = worst.max(((fast - exact) / exact).abs());
        }
        assert!(worst < 5e-14, "{worst}");
        assert!((exp(-800.0) - (-708f64).exp()).abs() < 1e-300);
    }

    #[test]
    fn ln_matches_the_library_within_1e_15() {
        let mut worst: f64 = 0.0;
        for i in 0..200_000 {
            let y = (f64::from(i) / 200_000.0 * 1400.0 - 700.0).exp();
            let (fast, exact) = (ln(y), y.ln());
            worst = worst.max((fast - exact).abs() / exact.abs().max(1.0));
        }
        assert!(worst < 1e-15, "{worst}");
    }

    /// The lane versions compute each lane as the scalar functions do,
    /// bit for bit, whatever the lane's neighbours: intervals on one
    /// side, across 0, far in the tails and narrow, shuffled.
    #[test]
    fn lanes_give_the_same_bits_as_one_at_a_time() {
        let table = ErfTable::get();
        let mut rng = crate::core::numerics::rng::Rng::new(5);
        for _ in 0..500 {
            let lo: [f64; 16] = std::array::from_fn(|_| rng.uniform_in(-12.0, 12.0));
            let hi: [f64; 16] = std::array::from_fn(|l| lo[l] + rng.uniform_in(0.05, 20.0));
            let y: [f64; 16] = std::array::from_fn(|l| lo[l].abs());
            let (t, p) = table.parts_lanes(&y);
            let many = table.ln_erf_difference_lanes(&lo, &hi);
            for l in 0..16 {
                let (t1, p1) = table.parts(y[l]);
                assert_eq!(
                    (t[l].to_bits(), p[l].to_bits()),
                    (t1.to_bits(), p1.to_bits()),
                    "{}",
                    y[l]
                );
                let one = table.ln_erf_difference(lo[l], hi[l]);
                assert_eq!(many[l].to_bits(), one.to_bits(), "[{}, {}]", lo[l], hi[l]);
            }
        }
    }

    #[test]
    fn the_erfcx_fit_is_within_1e_12() {
        let c = erfcx_coefficients();
        let mut worst: f64 = 0.0;
        for i in 0..100_000 {
            let x = 60.0 * (f64::from(i) / 100_000.0).powi(2);
            let (t, p) = ln_erfcx_parts(x, c);
            worst = worst.max((t.ln() + p - special::erfcx(x).ln()).abs());
        }
        assert!(worst < 1e-12, "{worst}");
    }

    #[test]
    fn erf_differences_match_the_careful_ones_within_1e_10() {
        let table = ErfTable::get();
        let mut worst: f64 = 0.0;
        let mut at = (0.0, 0.0);
        for i in 0..400 {
            for j in 0..400 {
                let lo = -40.0 + 80.0 * f64::from(i) / 400.0;
                let hi = lo + 0.05 + 60.0 * (f64::from(j) / 400.0).powi(2);
                let (fast, careful) = (table.ln_erf_difference(lo, hi), special::ln_erf_difference(lo, hi));
                let error = (fast - careful).abs();
                if error > worst {
                    worst = error;
                    at = (lo, hi);
                }
            }
        }
        assert!(worst < 1e-10, "{worst} at {at:?}");
    }
}
