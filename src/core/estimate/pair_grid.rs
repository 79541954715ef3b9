//! The coarse grid the pair search starts from where nothing is known:
//! the best pair of an evenly strided subset of the surface samples.

use crate::core::estimate::contact::{PosedSurface, UnitTorqueSource};

/// Samples of the coarse grid the pair search starts from.
pub const COARSE_SAMPLES: usize = 256;

/// The best pair `(i, f_i, j, f_j)` of an evenly strided subset of the
/// samples (at most [`COARSE_SAMPLES`]), every pair tried with both
/// magnitudes fitted within `force_range` (least squares in the noise's
/// metric, the box's edges where the free optimum lies outside). Starts
/// from the best three pairs were tried: on ten firm pushes on links 5
/// and 7 they found no more pairs, and no nearer.
pub(crate) fn coarse_pair(
    posed: &PosedSurface<'_>,
    tau: &[f64],
    weights: &[f64],
    force_range: (f64, f64),
) -> Vec<(usize, f64, usize, f64)> {
    let n = posed.points();
    let joints = posed.joints();
    let m = n.min(COARSE_SAMPLES);
    if m < 2 {
        return Vec::new();
    }
    let points: Vec<usize> = (0..m).map(|i| i * n / m).collect();
    // The samples' torques per newton scaled by √w (plain dot products
    // below), a column per joint: one sample's dot products with all
    // later ones run down the columns.
    let roots: Vec<f64> = weights.iter().map(|w| w.sqrt()).collect();
    let mut columns = vec![vec![0.0; m]; joints];
    let mut u = vec![0.0; joints];
    for (slot, &k) in points.iter().enumerate() {
        posed.unit_torques_into(k, &mut u);
        for ((column, x), root) in columns.iter_mut().zip(&u).zip(&roots) {
            if let Some(cell) = column.get_mut(slot) {
                *cell = x * root;
            }
        }
    }
    let t: Vec<f64> = tau.iter().zip(&roots).map(|(x, root)| x * root).collect();
    // Each sample's `⟨u, u⟩` and `⟨u, τ⟩`, summed over the joints in order.
    let (mut a, mut b) = (vec![0.0; m], vec![0.0; m]);
    for (column, tj) in columns.iter().zip(&t) {
        for ((aa, bb), x) in a.iter_mut().zip(b.iter_mut()).zip(column) {
            *aa += x * x;
            *bb += x * tj;
        }
    }
    let mut c = vec![0.0; m];
    let mut best: Option<(f64, usize, f64, usize, f64)> = None;
    for i in 0..m {
        let later = i + 1..m;
        let (Some(c_later), Some(&ai), Some(&bi)) = (c.get_mut(later.clone()), a.get(i), b.get(i)) else {
            continue;
        };
        c_later.fill(0.0);
        for column in &columns {
            let (Some(&x), Some(ys)) = (column.get(i), column.get(later.clone())) else {
                continue;
            };
            c_later.iter_mut().zip(ys).for_each(|(cj, y)| *cj += x * y);
        }
        let later_samples = a.iter().zip(&b).skip(i + 1).zip(c_later.iter());
        for (j, ((&aj, &bj), &cij)) in (i + 1..).zip(later_samples) {
            // The free optimum's gain `bᵀH⁻¹b` bounds the box's: a pair
            // that cannot beat the best so far is not fitted.
            let det = ai * aj - cij * cij;
            if let Some((top, ..)) = best
                && det > 1e-12 * (ai * aj).max(f64::MIN_POSITIVE)
                && (bi * bi * aj - 2.0 * bi * bj * cij + bj * bj * ai) / det < top - 1e-9 * top.abs().max(1.0)
            {
                continue;
            }
            let (fi, fj, gain) = best_magnitudes([ai, cij, aj], [bi, bj], force_range);
            if best.is_none_or(|(top, ..)| gain > top)
                && let (Some(&pi), Some(&pj)) = (points.get(i), points.get(j))
            {
                best = Some((gain, pi, fi, pj, fj));
            }
        }
    }
    best.into_iter().map(|(_, i, fi, j, fj)| (i, fi, j, fj)).collect()
}

/// The magnitudes in the box `range²` that maximise `2 fᵀb − fᵀHf` for
/// `H = [[h11, h12], [h12, h22]]`, and that maximum (the fall in the
/// squared residual).
pub(crate) fn best_magnitudes([h11, h12, h22]: [f64; 3], [b1, b2]: [f64; 2], (lo, hi): (f64, f64)) -> (f64, f64, f64) {
    let gain = |f1: f64, f2: f64| 2.0 * (f1 * b1 + f2 * b2) - (h11 * f1 * f1 + 2.0 * h12 * f1 * f2 + h22 * f2 * f2);
    let det = h11 * h22 - h12 * h12;
    if det > 1e-12 * (h11 * h22).max(f64::MIN_POSITIVE) {
        let f1 = (b1 * h22 - b2 * h12) / det;
        let f2 = (b2 * h11 - b1 * h12) / det;
        if (lo..=hi).contains(&f1) && (lo..=hi).contains(&f2) {
            return (f1, f2, gain(f1, f2));
        }
    }
    // On an edge: one magnitude at a bound, the other its best given it.
    let other = |b: f64, h: f64, f: f64, hh: f64| if hh > 0.0 { ((b - h * f) / hh).clamp(lo, hi) } else { lo };
    let mut best = (lo, lo, gain(lo, lo));
    for bound in [lo, hi] {
        let f2 = other(b2, h12, bound, h22);
        let f1 = other(b1, h12, bound, h11);
        for (x, y) in [(bound, f2), (f1, bound)] {
            let g = gain(x, y);
            if g > best.2 {
                best = (x, y, g);
            }
        }
    }
    best
}
