//! The smoother's product of the forward and backward beliefs, per sample
//! (see [`crate::core::over_time::temporal::TemporalModel::combine`]),
//! written four samples at a time for the widest vector unit. The
//! formulas are those of `offsets::overlap` (kept as the tests'
//! reference) and [`Offset::confined`], in the same order, each branch
//! turned into both sides and a choice: the results are theirs bit for
//! bit (tested). Measured against the scalar code, the whole smoothed run
//! moved within the development VM's noise (`docs/decisions.md`, session
//! 48): the lanes compute what the scalar code's early returns skipped.

use crate::core::numerics::fastmath;
use crate::core::numerics::simd::{Kernel, lanes};
use crate::core::over_time::offsets::{Offset, PATCH_REACH};

/// Samples taken at once (one AVX2 register).
const LANES: usize = 4;

/// Each sample's log weight given both halves, before the normalisation,
/// and (when offsets are tracked) the offset given both halves.
pub(crate) struct CombineKernel<'a> {
    pub(crate) forward_points: &'a [f64],
    pub(crate) backward_points: &'a [f64],
    pub(crate) ln_prior: &'a [f64],
    /// `ln` of the stationary contact probability.
    pub(crate) ln_contact: f64,
    /// The log weight of "no contact" (the floor of the top).
    pub(crate) none: f64,
    /// Weights below the best less this margin skip the offsets' share.
    pub(crate) margin: f64,
    /// Empty when offsets are not tracked; else one per sample, as the
    /// windows.
    pub(crate) forward_offsets: &'a [Offset],
    pub(crate) backward_offsets: &'a [Offset],
    pub(crate) window_m: &'a [f64],
}

impl Kernel for CombineKernel<'_> {
    type Output = (Vec<f64>, Vec<Offset>);
    #[inline(always)]
    fn run(self) -> (Vec<f64>, Vec<Offset>) {
        let n = self
            .forward_points
            .len()
            .min(self.backward_points.len())
            .min(self.ln_prior.len());
        let mut logs = vec![f64::NEG_INFINITY; self.forward_points.len()];
        let (Some(f), Some(b), Some(p), Some(out)) = (
            self.forward_points.get(..n),
            self.backward_points.get(..n),
            self.ln_prior.get(..n),
            logs.get_mut(..n),
        ) else {
            return (logs, Vec::new());
        };
        for (((l, &f), &b), &p) in out.iter_mut().zip(f).zip(b).zip(p) {
            *l = fast_ln(f) + fast_ln(b) - p - self.ln_contact;
        }
        // The rare sample whose `ln` the fast formula does not cover.
        for (((l, &f), &b), &p) in out.iter_mut().zip(f).zip(b).zip(p) {
            if !(normal(f) && normal(b)) {
                *l = fastmath::ln_or_minus_infinity(f) + fastmath::ln_or_minus_infinity(b) - p - self.ln_contact;
            }
        }
        let tracked = self.forward_offsets.len() == logs.len()
            && self.backward_offsets.len() == logs.len()
            && self.window_m.len() == logs.len();
        if !tracked {
            return (logs, Vec::new());
        }
        let floor = logs.iter().copied().filter(|l| !l.is_nan()).fold(self.none, f64::max) - self.margin;
        let mut both = vec![Offset::window(1.0); logs.len()];
        let mut k = 0;
        while k + LANES <= logs.len() {
            combine_at::<LANES>(&self, k, floor, &mut logs, &mut both);
            k += LANES;
        }
        while k < logs.len() {
            combine_at::<1>(&self, k, floor, &mut logs, &mut both);
            k += 1;
        }
        (logs, both)
    }
}

/// True where [`fastmath::ln`] gives `ln x` (a positive normal number).
#[inline(always)]
fn normal(x: f64) -> bool {
    (f64::MIN_POSITIVE..f64::INFINITY).contains(&x)
}

/// [`fastmath::ln`] of `x` where it is [`normal`], of the smallest normal
/// number elsewhere (those lanes are recomputed).
#[inline(always)]
fn fast_ln(x: f64) -> f64 {
    fastmath::ln(if normal(x) { x } else { f64::MIN_POSITIVE })
}

/// `nᵀ Λ⁻¹ n` of a precision `l` and shift `n` (0 when Λ is singular).
#[inline(always)]
fn explained(l11: f64, l12: f64, l22: f64, n1: f64, n2: f64) -> f64 {
    let det = l11 * l22 - l12 * l12;
    let value = (l22 * n1 * n1 - 2.0 * l12 * n1 * n2 + l11 * n2 * n2) / det;
    if det > 0.0 { value } else { 0.0 }
}

/// [`Offset::confined`]'s charge, branch free.
#[inline(always)]
fn charge(l11: f64, l12: f64, l22: f64, n1: f64, n2: f64, reach: f64) -> f64 {
    let det = l11 * l22 - l12 * l12;
    let (a1, a2) = ((l22 * n1 - l12 * n2) / det, (l11 * n2 - l12 * n1) / det);
    let usable = det > 0.0 && a1.is_finite() && a2.is_finite();
    let (m1, m2) = if usable { (a1, a2) } else { (0.0, 0.0) };
    let r2 = m1 * m1 + m2 * m2;
    let k = reach / r2.sqrt();
    let (s1, s2) = (m1 * k, m2 * k);
    let (d1, d2) = (m1 - s1, m2 - s2);
    let penalty = 0.5 * (l11 * d1 * d1 + 2.0 * l12 * d1 * d2 + l22 * d2 * d2);
    if r2.is_nan() || r2 <= reach * reach {
        0.0
    } else {
        penalty
    }
}

/// The `L` samples from `k`: the offsets of both halves added (less the
/// window counted twice), and the weight's share of the offsets where
/// the weight is above `floor`.
#[inline(always)]
#[allow(clippy::too_many_lines)] // one formula, written out lane by lane
fn combine_at<const L: usize>(kernel: &CombineKernel, k: usize, floor: f64, logs: &mut [f64], both: &mut [Offset]) {
    let range = k..k + L;
    let (Some(fo), Some(bo), Some(rho), Some(logs), Some(both)) = (
        kernel.forward_offsets.get(range.clone()),
        kernel.backward_offsets.get(range.clone()),
        kernel.window_m.get(range.clone()),
        logs.get_mut(range.clone()),
        both.get_mut(range),
    ) else {
        return;
    };
    let (Ok(fo), Ok(bo), Ok(rho), Ok(logs), Ok(both)) = (
        <&[Offset; L]>::try_from(fo),
        <&[Offset; L]>::try_from(bo),
        <&[f64; L]>::try_from(rho),
        <&mut [f64; L]>::try_from(logs),
        <&mut [Offset; L]>::try_from(both),
    ) else {
        return;
    };
    let q = lanes!(i, L, 1.0 / (rho[i] * rho[i]));
    let f11 = lanes!(i, L, fo[i].precision[0]);
    let f12 = lanes!(i, L, fo[i].precision[1]);
    let f22 = lanes!(i, L, fo[i].precision[2]);
    let fn1 = lanes!(i, L, fo[i].shift[0]);
    let fn2 = lanes!(i, L, fo[i].shift[1]);
    let b11 = lanes!(i, L, bo[i].precision[0]);
    let b12 = lanes!(i, L, bo[i].precision[1]);
    let b22 = lanes!(i, L, bo[i].precision[2]);
    let bn1 = lanes!(i, L, bo[i].shift[0]);
    let bn2 = lanes!(i, L, bo[i].shift[1]);
    let c11 = lanes!(i, L, f11[i] + b11[i] - q[i]);
    let c12 = lanes!(i, L, f12[i] + b12[i]);
    let c22 = lanes!(i, L, f22[i] + b22[i] - q[i]);
    let cn1 = lanes!(i, L, fn1[i] + bn1[i]);
    let cn2 = lanes!(i, L, fn2[i] + bn2[i]);
    for i in 0..L {
        both[i] = Offset {
            precision: [c11[i], c12[i], c22[i]],
            shift: [cn1[i], cn2[i]],
        };
    }
    // Most blocks lie far below the best: their weights need no share.
    let mut any_above = false;
    for l in logs.iter() {
        any_above |= *l > floor;
    }
    if !any_above {
        return;
    }
    // The overlap of the two Gaussians over the window's.
    let df = lanes!(i, L, f11[i] * f22[i] - f12[i] * f12[i]);
    let db = lanes!(i, L, b11[i] * b22[i] - b12[i] * b12[i]);
    let d = lanes!(i, L, c11[i] * c22[i] - c12[i] * c12[i]);
    let d0 = lanes!(i, L, q[i] * q[i] - 0.0 * 0.0);
    let defined = lanes!(
        i,
        L,
        if df[i] > 0.0 && db[i] > 0.0 && d[i] > 0.0 && c11[i] > 0.0 && d[i].is_finite() {
            1.0
        } else {
            0.0
        }
    );
    let ratio = lanes!(i, L, df[i] * db[i] / (d[i] * d0[i]));
    let mut ln_ratio = lanes!(i, L, fast_ln(ratio[i]));
    for i in 0..L {
        if !normal(ratio[i]) {
            ln_ratio[i] = fastmath::ln_or_minus_infinity(ratio[i]);
        }
    }
    let explained_all = lanes!(
        i,
        L,
        explained(c11[i], c12[i], c22[i], cn1[i], cn2[i])
            - explained(f11[i], f12[i], f22[i], fn1[i], fn2[i])
            - explained(b11[i], b12[i], b22[i], bn1[i], bn2[i])
    );
    let overlap = lanes!(
        i,
        L,
        if defined[i] > 0.0 {
            0.5 * explained_all[i] + 0.5 * ln_ratio[i]
        } else {
            0.0
        }
    );
    // Each half was charged for its own reach; the whole is charged for
    // the whole's.
    let reach = lanes!(i, L, PATCH_REACH * rho[i]);
    let share = lanes!(
        i,
        L,
        overlap[i]
            + charge(f11[i], f12[i], f22[i], fn1[i], fn2[i], reach[i])
            + charge(b11[i], b12[i], b22[i], bn1[i], bn2[i], reach[i])
            - charge(c11[i], c12[i], c22[i], cn1[i], cn2[i], reach[i])
    );
    for i in 0..L {
        if logs[i] > floor {
            logs[i] += share[i];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::numerics::rng::Rng;
    use crate::core::numerics::simd::widest;
    use crate::core::over_time::offsets::overlap;

    /// The scalar formulas, sample by sample.
    fn reference(kernel: &CombineKernel) -> (Vec<f64>, Vec<Offset>) {
        let n = kernel.forward_points.len();
        let mut logs: Vec<f64> = (0..n)
            .map(|k| {
                fastmath::ln_or_minus_infinity(kernel.forward_points[k])
                    + fastmath::ln_or_minus_infinity(kernel.backward_points[k])
                    - kernel.ln_prior[k]
                    - kernel.ln_contact
            })
            .collect();
        let floor = logs.iter().copied().filter(|l| !l.is_nan()).fold(kernel.none, f64::max) - kernel.margin;
        let mut both = Vec::new();
        for (k, l) in logs.iter_mut().enumerate() {
            let (fo, bo, rho) = (
                &kernel.forward_offsets[k],
                &kernel.backward_offsets[k],
                kernel.window_m[k],
            );
            let window = Offset::window(rho);
            let whole = Offset {
                precision: [
                    fo.precision[0] + bo.precision[0] - window.precision[0],
                    fo.precision[1] + bo.precision[1],
                    fo.precision[2] + bo.precision[2] - window.precision[2],
                ],
                shift: [fo.shift[0] + bo.shift[0], fo.shift[1] + bo.shift[1]],
            };
            if *l > floor {
                *l += overlap(fo, bo, rho) + fo.confined(rho).0 + bo.confined(rho).0 - whole.confined(rho).0;
            }
            both.push(whole);
        }
        (logs, both)
    }

    /// Ordinary offsets, singular ones, means far beyond the patch, zero,
    /// subnormal and NaN weights: the lanes give the scalar formulas'
    /// numbers bit for bit (NaN where they give NaN), on 4 lanes and the
    /// rest.
    #[test]
    fn the_lanes_give_the_scalar_formulas_bit_for_bit() {
        let mut rng = Rng::new(11);
        let n = 203;
        let special = [0.0, 5e-324, 1e-310, f64::NAN, 1.0, 0.5];
        let draw_offset = |rng: &mut Rng, k: usize| {
            let scale = [1e2, 1e6, 1e-3, 1e9][k % 4];
            let l11 = scale * (0.1 + rng.uniform());
            let l22 = scale * (0.1 + rng.uniform());
            // Every seventh: singular or indefinite.
            let l12 = if k.is_multiple_of(7) {
                2.0 * (l11 * l22).sqrt()
            } else {
                0.5 * (l11 * l22).sqrt() * (2.0 * rng.uniform() - 1.0)
            };
            // Shifts whose means fall inside and far beyond the patch.
            let reach = if k.is_multiple_of(3) { 1e3 } else { 1e-2 };
            Offset {
                precision: [l11, l12, l22],
                shift: [
                    scale * reach * (2.0 * rng.uniform() - 1.0),
                    scale * reach * (2.0 * rng.uniform() - 1.0),
                ],
            }
        };
        let forward_points: Vec<f64> = (0..n)
            .map(|k| {
                if k % 11 == 0 {
                    special[k / 11 % special.len()]
                } else {
                    rng.uniform() * 1e-2
                }
            })
            .collect();
        let backward_points: Vec<f64> = (0..n).map(|k| if k % 13 == 0 { 0.0 } else { rng.uniform() }).collect();
        let ln_prior: Vec<f64> = (0..n).map(|_| -(n as f64).ln()).collect();
        let forward_offsets: Vec<Offset> = (0..n).map(|k| draw_offset(&mut rng, k)).collect();
        let backward_offsets: Vec<Offset> = (0..n).map(|k| draw_offset(&mut rng, k + 1)).collect();
        let window_m: Vec<f64> = (0..n).map(|k| 0.01 + 0.001 * (k % 5) as f64).collect();
        for margin in [100.0, 3.0] {
            let kernel = || CombineKernel {
                forward_points: &forward_points,
                backward_points: &backward_points,
                ln_prior: &ln_prior,
                ln_contact: 0.3_f64.ln(),
                none: -2.0,
                margin,
                forward_offsets: &forward_offsets,
                backward_offsets: &backward_offsets,
                window_m: &window_m,
            };
            let (logs, both) = widest(kernel());
            let (want_logs, want_both) = reference(&kernel());
            assert_eq!(logs.len(), n);
            for k in 0..n {
                assert!(
                    logs[k].to_bits() == want_logs[k].to_bits() || (logs[k].is_nan() && want_logs[k].is_nan()),
                    "sample {k}: {} against {}",
                    logs[k],
                    want_logs[k]
                );
                assert_eq!(format!("{:?}", both[k]), format!("{:?}", want_both[k]), "sample {k}");
            }
            // Not trivially so: some samples took the offsets' share.
            let plain = CombineKernel {
                forward_offsets: &[],
                ..kernel()
            };
            let (untracked, none) = widest(plain);
            assert!(none.is_empty());
            assert!(
                untracked
                    .iter()
                    .zip(&logs)
                    .any(|(a, b)| a.is_finite() && (a - b).abs() > 1e-9)
            );
        }
    }
}
