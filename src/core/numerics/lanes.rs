//! Reductions over many surface points (largest, least, sum) kept in
//! eight independent running values, combined at the end; and the
//! positions of the values that pass a test, without a branch.
//!
//! A fold with one running value waits on the previous step at every
//! element (`f64::max` is a compare and a blend, an addition four cycles):
//! over a broad posterior's thousands of points such folds cost more than
//! the arithmetic around them. Eight running values let the compiler use
//! vector instructions and keep several steps in flight. The largest and
//! the least are exact whatever the order; `sum` adds in another
//! order than a plain fold (eight partial sums), so its last bits may
//! differ from one.

/// Running values per reduction: two AVX2 vectors of four.
const LANES: usize = 8;

/// `step` folded over `values` from `start` in [`LANES`] running values,
/// then the running values and the remainder's fold joined by `join`.
#[inline(always)]
fn fold_lanes(values: &[f64], start: f64, step: impl Fn(f64, f64) -> f64, join: impl Fn(f64, f64) -> f64) -> f64 {
    let mut acc = [start; LANES];
    let mut chunks = values.chunks_exact(LANES);
    for chunk in &mut chunks {
        for (a, &v) in acc.iter_mut().zip(chunk) {
            *a = step(*a, v);
        }
    }
    let rest = chunks.remainder().iter().fold(start, |m, &v| step(m, v));
    acc.iter().fold(rest, |m, &v| join(m, v))
}

/// The largest of `values` and `floor` (NaN ignored, as `f64::max` does).
#[inline(always)]
#[must_use]
pub fn max_or(values: &[f64], floor: f64) -> f64 {
    fold_lanes(values, floor, f64::max, f64::max)
}

/// The least of `values` and `ceiling` (NaN ignored, as `f64::min` does).
#[inline(always)]
#[must_use]
pub fn min_or(values: &[f64], ceiling: f64) -> f64 {
    fold_lanes(values, ceiling, f64::min, f64::min)
}

/// The least positive of `values` (∞ where none is).
#[inline(always)]
#[must_use]
pub fn min_positive(values: &[f64]) -> f64 {
    let least_positive = |m: f64, v: f64| if v > 0.0 { m.min(v) } else { m };
    fold_lanes(values, f64::INFINITY, least_positive, f64::min)
}

/// The sum of `values`, in eight partial sums (see the module's note on
/// the order).
#[inline(always)]
#[must_use]
pub fn sum(values: &[f64]) -> f64 {
    let mut acc = [0.0; LANES];
    let mut chunks = values.chunks_exact(LANES);
    for chunk in &mut chunks {
        for (a, &v) in acc.iter_mut().zip(chunk) {
            *a += v;
        }
    }
    let rest: f64 = chunks.remainder().iter().sum();
    let (low, high) = acc.split_at(LANES / 2);
    let pairs: f64 = low.iter().zip(high).map(|(l, h)| l + h).sum();
    pairs + rest
}

/// The positions of the values that `keep`, in order. Each position is
/// written and kept by count, without a branch on the data (a filter's
/// branch misses half the time over a broad posterior).
#[must_use]
pub fn positions_where(values: &[f64], keep: impl Fn(f64) -> bool) -> Vec<usize> {
    let mut out = vec![0; values.len()];
    let mut count = 0;
    for (i, &v) in values.iter().enumerate() {
        if let Some(slot) = out.get_mut(count) {
            *slot = i;
        }
        count += usize::from(keep(v));
    }
    out.truncate(count);
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::numerics::rng::Rng;

    #[test]
    fn reductions_match_plain_folds() {
        let mut rng = Rng::new(3);
        for n in [0, 1, 7, 8, 9, 100, 4999] {
            let mut values: Vec<f64> = (0..n).map(|_| rng.uniform_in(-1.0, 2.0)).collect();
            if n > 5 {
                values[5] = f64::NAN;
            }
            let plain_max = values.iter().fold(-3.0_f64, |m, &v| m.max(v));
            assert_eq!(max_or(&values, -3.0).to_bits(), plain_max.to_bits(), "n {n}");
            let plain_least = values.iter().fold(1.5_f64, |m, &v| m.min(v));
            assert_eq!(min_or(&values, 1.5).to_bits(), plain_least.to_bits(), "n {n}");
            let plain_min = values
                .iter()
                .fold(f64::INFINITY, |m, &v| if v > 0.0 { m.min(v) } else { m });
            assert_eq!(min_positive(&values).to_bits(), plain_min.to_bits(), "n {n}");
            let finite: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
            let plain_sum: f64 = finite.iter().sum();
            assert!(
                (sum(&finite) - plain_sum).abs() <= 1e-12 * (1.0 + plain_sum.abs()),
                "n {n}"
            );
        }
        assert_eq!(max_or(&[], 0.5).to_bits(), 0.5_f64.to_bits());
        let values = [0.5, f64::NAN, -1.0, 2.0, 0.0];
        assert_eq!(positions_where(&values, |v| v >= 0.0), vec![0, 3, 4]);
        assert!(positions_where(&[], |_| true).is_empty());
        assert!(min_positive(&[-1.0, 0.0]).is_infinite());
    }
}
