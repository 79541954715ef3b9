//! Per configuration, the torque per newton of a push at every surface
//! point, in structure-of-arrays form for fast likelihoods.

use rayon::prelude::*;

use crate::core::estimate::phases::link_ranges;
use crate::core::numerics::simd::{Kernel, widest};
use crate::core::robot::torque::TorqueModel;
use crate::core::surface::sampling::Surface;

/// From this many points on, the per-point work is shared among threads
/// (below, thread hand-off costs more than it saves).
pub const PARALLEL_MIN_POINTS: usize = 16_384;

/// Where the estimator gets each surface point's torque per newton.
pub trait UnitTorqueSource: Sync {
    /// Number of sensed joints.
    fn joints(&self) -> usize;
    /// Number of surface points.
    fn points(&self) -> usize;
    /// Point k's unit torques, written into `out` (one per joint).
    fn unit_torques_into(&self, point: usize, out: &mut [f64]);
    /// For the measured `tau` and per-joint weights `1/σ²`, each point's
    /// `a_k = Σ w u²` and `b_k = Σ w u τ` (its log-likelihood in the
    /// magnitude f is `-½ (c - 2 b_k f + a_k f²)`).
    fn quadratic_forms(&self, weights: &[f64], tau: &[f64], a: &mut Vec<f64>, b: &mut Vec<f64>);
    /// Each point's [`PatchForms`]: the likelihood terms of its push line
    /// and of how that line changes across the patch the point stands
    /// for. `false` when the source knows no patches (then the estimator
    /// treats each point as a point).
    fn patch_forms(&self, weights: &[f64], tau: &[f64], out: &mut PatchForms) -> bool {
        let _ = (weights, tau, out);
        false
    }
}

/// Per point (structure of arrays), with `u` the torque per newton of the
/// point's push, `d_1`, `d_2` its derivatives per metre along the two
/// tangents, `⟨x, y⟩ = Σ_j x_j y_j / σ_j²` and `τ` the measurement:
/// `a = ⟨u, u⟩`, `b = ⟨u, τ⟩`, `h_i = ⟨u, d_i⟩`, `e_i = ⟨d_i, τ⟩`,
/// `g_ij = ⟨d_i, d_j⟩`; and the patch's width and area.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PatchForms {
    /// `⟨u, u⟩`.
    pub a: Vec<f64>,
    /// `⟨u, τ⟩`.
    pub b: Vec<f64>,
    /// `⟨u, d_1⟩`.
    pub h1: Vec<f64>,
    /// `⟨u, d_2⟩`.
    pub h2: Vec<f64>,
    /// `⟨d_1, τ⟩`.
    pub e1: Vec<f64>,
    /// `⟨d_2, τ⟩`.
    pub e2: Vec<f64>,
    /// `⟨d_1, d_1⟩`.
    pub g11: Vec<f64>,
    /// `⟨d_1, d_2⟩`.
    pub g12: Vec<f64>,
    /// `⟨d_2, d_2⟩`.
    pub g22: Vec<f64>,
    /// Width (standard deviation) of each point's Gaussian patch, m.
    pub window_m: Vec<f64>,
    /// ln of each point's area, m² (its prior weight).
    pub ln_area: Vec<f64>,
}

impl PatchForms {
    /// Seeded random forms of `n` samples, for tests of the loops over
    /// them: `a` in `[a_min, 1e4)`, `b` in `[-1e3, b_max)`, the rest in
    /// ranges like a frame's.
    #[cfg(test)]
    pub(crate) fn random(seed: u64, n: usize, a_min: f64, b_max: f64) -> Self {
        let mut rng = crate::core::numerics::rng::Rng::new(seed);
        let mut column = |lo: f64, hi: f64| -> Vec<f64> { (0..n).map(|_| rng.uniform_in(lo, hi)).collect() };
        Self {
            a: column(a_min, 1e4),
            b: column(-1e3, b_max),
            h1: column(-1e3, 1e3),
            h2: column(-1e3, 1e3),
            e1: column(-1e4, 1e4),
            e2: column(-1e4, 1e4),
            g11: column(0.0, 1e6),
            g12: column(-1e5, 1e5),
            g22: column(0.0, 1e6),
            window_m: column(1e-3, 1e-2),
            ln_area: column(-12.0, -8.0),
        }
    }

    fn resize(&mut self, n: usize) {
        for v in [
            &mut self.a,
            &mut self.b,
            &mut self.h1,
            &mut self.h2,
            &mut self.e1,
            &mut self.e2,
            &mut self.g11,
            &mut self.g12,
            &mut self.g22,
            &mut self.window_m,
            &mut self.ln_area,
        ] {
            v.clear();
            v.resize(n, 0.0);
        }
    }
}

/// A surface at one configuration, read without storing unit torques:
/// each point's torques are computed where they are used and summed into
/// its likelihood terms at once (the fast path of an update).
#[derive(Debug, Clone, Copy)]
pub struct PosedSurface<'a> {
    /// The configuration's twists.
    pub torque_model: &'a TorqueModel,
    /// The candidate points.
    pub surface: &'a Surface,
}

impl UnitTorqueSource for PosedSurface<'_> {
    fn joints(&self) -> usize {
        self.torque_model.sensed_count()
    }

    fn points(&self) -> usize {
        self.surface.len()
    }

    fn unit_torques_into(&self, point: usize, out: &mut [f64]) {
        out.fill(0.0);
        let (Some(&link), Some(m), Some(n)) = (
            self.surface.link.get(point),
            self.surface.moment_in_link.get(point),
            self.surface.inward_normal_in_link.get(point),
        ) else {
            return;
        };
        for t in self.torque_model.twists(link) {
            if let Some(slot) = out.get_mut(t.sensed_index) {
                *slot = t.w.dot(*m) + t.v.dot(*n);
            }
        }
    }

    fn patch_forms(&self, weights: &[f64], tau: &[f64], out: &mut PatchForms) -> bool {
        let surface = self.surface;
        let n = surface.len();
        if surface.tangent_lines.iter().any(|c| c.len() != n) || surface.window_m.len() != n {
            return false;
        }
        out.resize(n);
        out.window_m.copy_from_slice(&surface.window_m);
        for (ln_area, &value) in out.ln_area.iter_mut().zip(&surface.ln_area) {
            *ln_area = value;
        }
        let lines = surface.push_lines.each_ref().map(Vec::as_slice);
        let tangents = surface.tangent_lines.each_ref().map(Vec::as_slice);
        for (range, r, beta) in self.link_factors(weights, tau) {
            let block = PatchBlock {
                l0: std::array::from_fn(|i| lines[i].get(range.clone()).unwrap_or(&[])),
                l1: std::array::from_fn(|i| tangents[i].get(range.clone()).unwrap_or(&[])),
                l2: std::array::from_fn(|i| tangents[6 + i].get(range.clone()).unwrap_or(&[])),
            };
            let mut outs = PatchOut::of(out, range.clone());
            match r.len() {
                0 => {}
                1 => widest(PatchFormsKernel::<1>(&r, beta, &block, &mut outs)),
                2 => widest(PatchFormsKernel::<2>(&r, beta, &block, &mut outs)),
                3 => widest(PatchFormsKernel::<3>(&r, beta, &block, &mut outs)),
                4 => widest(PatchFormsKernel::<4>(&r, beta, &block, &mut outs)),
                5 => widest(PatchFormsKernel::<5>(&r, beta, &block, &mut outs)),
                _ => widest(PatchFormsKernel::<6>(&r, beta, &block, &mut outs)),
            }
        }
        true
    }

    fn quadratic_forms(&self, weights: &[f64], tau: &[f64], a: &mut Vec<f64>, b: &mut Vec<f64>) {
        let surface = self.surface;
        let n = surface.len();
        a.clear();
        a.resize(n, 0.0);
        b.clear();
        b.resize(n, 0.0);
        let jobs = self.link_factors(weights, tau);
        let lines = surface.push_lines.each_ref().map(Vec::as_slice);
        let run = |range: std::ops::Range<usize>, r: &[[f64; 6]], beta: [f64; 6], a: &mut [f64], b: &mut [f64]| {
            let lines = lines.map(|l| l.get(range.clone()).unwrap_or(&[]));
            match r.len() {
                0 => {
                    a.fill(0.0);
                    b.fill(0.0);
                }
                1 => widest(FormsKernel::<1>(r, beta, lines, a, b)),
                2 => widest(FormsKernel::<2>(r, beta, lines, a, b)),
                3 => widest(FormsKernel::<3>(r, beta, lines, a, b)),
                4 => widest(FormsKernel::<4>(r, beta, lines, a, b)),
                5 => widest(FormsKernel::<5>(r, beta, lines, a, b)),
                _ => widest(FormsKernel::<6>(r, beta, lines, a, b)),
            }
        };
        if n >= PARALLEL_MIN_POINTS {
            // Split each link's range into blocks and share the blocks.
            let mut blocks = Vec::new();
            let mut a_rest: &mut [f64] = a;
            let mut b_rest: &mut [f64] = b;
            for (range, r, beta) in &jobs {
                let mut at = range.start;
                while at < range.end {
                    let len = (range.end - at).min(4096);
                    let (a_block, a_tail) = std::mem::take(&mut a_rest).split_at_mut(len);
                    let (b_block, b_tail) = std::mem::take(&mut b_rest).split_at_mut(len);
                    a_rest = a_tail;
                    b_rest = b_tail;
                    blocks.push((at..at + len, r.as_slice(), *beta, a_block, b_block));
                    at += len;
                }
            }
            blocks
                .into_par_iter()
                .for_each(|(range, r, beta, a_block, b_block)| run(range, r, beta, a_block, b_block));
        } else {
            for (range, r, beta) in &jobs {
                if let (Some(a_block), Some(b_block)) = (a.get_mut(range.clone()), b.get_mut(range.clone())) {
                    run(range.clone(), r, *beta, a_block, b_block);
                }
            }
        }
    }
}

/// A link's points, the triangular factor of its weighted twists, and `β`.
type LinkFactor = (std::ops::Range<usize>, Vec<[f64; 6]>, [f64; 6]);

impl PosedSurface<'_> {
    /// Per link (its points are contiguous): the range of its points, the
    /// triangular factor of its weighted twists and `β = Σ_j w_j τ_j (ω_j, v_j)`.
    fn link_factors(&self, weights: &[f64], tau: &[f64]) -> Vec<LinkFactor> {
        link_ranges(&self.surface.link)
            .into_iter()
            .map(|(link, range)| {
                let mut rows = Vec::new();
                let mut beta = [0.0; 6];
                for t in self.torque_model.twists(link) {
                    let (Some(&w), Some(&torque)) = (weights.get(t.sensed_index), tau.get(t.sensed_index)) else {
                        continue;
                    };
                    let line = [t.w.x, t.w.y, t.w.z, t.v.x, t.v.y, t.v.z];
                    rows.push(line.map(|x| x * w.sqrt()));
                    for (bc, x) in beta.iter_mut().zip(line) {
                        *bc += w * torque * x;
                    }
                }
                (range, r_factor(&rows), beta)
            })
            .collect()
    }
}

/// A link's points: their push lines and tangent derivatives, six arrays each.
struct PatchBlock<'a> {
    l0: [&'a [f64]; 6],
    l1: [&'a [f64]; 6],
    l2: [&'a [f64]; 6],
}

/// Where a link's [`PatchForms`] go.
struct PatchOut<'a> {
    a: &'a mut [f64],
    b: &'a mut [f64],
    h1: &'a mut [f64],
    h2: &'a mut [f64],
    e1: &'a mut [f64],
    e2: &'a mut [f64],
    g11: &'a mut [f64],
    g12: &'a mut [f64],
    g22: &'a mut [f64],
}

impl PatchOut<'_> {
    /// Writes the forms of `L` points from `k` (in [`patch_forms_of`]'s
    /// order).
    #[inline(always)]
    fn store<const L: usize>(&mut self, k: usize, forms: &[[f64; L]; 9]) {
        let [a, b, h1, h2, e1, e2, g11, g12, g22] = forms;
        for (column, values) in [
            (&mut *self.a, a),
            (&mut *self.b, b),
            (&mut *self.h1, h1),
            (&mut *self.h2, h2),
            (&mut *self.e1, e1),
            (&mut *self.e2, e2),
            (&mut *self.g11, g11),
            (&mut *self.g12, g12),
            (&mut *self.g22, g22),
        ] {
            if let Some(slots) = column.get_mut(k..k + L) {
                slots.copy_from_slice(values);
            }
        }
    }
}

impl<'a> PatchOut<'a> {
    fn of(forms: &'a mut PatchForms, range: std::ops::Range<usize>) -> Self {
        let take = |v: &'a mut Vec<f64>| -> &'a mut [f64] { v.get_mut(range.clone()).unwrap_or(&mut []) };
        Self {
            a: take(&mut forms.a),
            b: take(&mut forms.b),
            h1: take(&mut forms.h1),
            h2: take(&mut forms.h2),
            e1: take(&mut forms.e1),
            e2: take(&mut forms.e2),
            g11: take(&mut forms.g11),
            g12: take(&mut forms.g12),
            g22: take(&mut forms.g22),
        }
    }
}

/// Samples computed together in [`patch_forms_with`]: four `f64` lanes
/// fill an AVX2 register.
const LANES: usize = 4;

/// [`patch_forms_with`] as a [`Kernel`].
struct PatchFormsKernel<'a, 'b, const N: usize>(&'a [[f64; 6]], [f64; 6], &'a PatchBlock<'b>, &'a mut PatchOut<'b>);

impl<const N: usize> Kernel for PatchFormsKernel<'_, '_, N> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        patch_forms_with::<N>(self.0, self.1, self.2, self.3);
    }
}

/// [`PatchForms`] of a link's points with `R` of `N` rows: three products
/// `R l` per point, then their inner products. The points go [`LANES`] at
/// a time through [`patch_forms_of`], written lane by lane so that each
/// operation becomes one vector instruction (as one loop over points the
/// compiler left it scalar: a point's 18 inputs and 9 outputs do not fit
/// the registers); the last few go one at a time through the same code.
#[inline(always)]
fn patch_forms_with<const N: usize>(r: &[[f64; 6]], beta: [f64; 6], block: &PatchBlock, out: &mut PatchOut) {
    let mut rows = [[0.0; 6]; N];
    for (dst, src) in rows.iter_mut().zip(r) {
        *dst = *src;
    }
    let len = [
        out.a.len(),
        out.b.len(),
        out.h1.len(),
        out.h2.len(),
        out.e1.len(),
        out.e2.len(),
        out.g11.len(),
        out.g12.len(),
        out.g22.len(),
    ]
    .into_iter()
    .chain(block.l0.iter().chain(&block.l1).chain(&block.l2).map(|c| c.len()))
    .min()
    .unwrap_or(0);
    let mut k = 0;
    while k + LANES <= len {
        patch_forms_at::<N, LANES>(&rows, &beta, block, out, k);
        k += LANES;
    }
    while k < len {
        patch_forms_at::<N, 1>(&rows, &beta, block, out, k);
        k += 1;
    }
}

/// The forms of the `L` points from `k`: gathered, computed, stored.
#[inline(always)]
fn patch_forms_at<const N: usize, const L: usize>(
    rows: &[[f64; 6]; N],
    beta: &[f64; 6],
    block: &PatchBlock,
    out: &mut PatchOut,
    k: usize,
) {
    let x = [
        gather_line(&block.l0, k),
        gather_line(&block.l1, k),
        gather_line(&block.l2, k),
    ];
    out.store::<L>(k, &patch_forms_of::<N, L>(rows, beta, &x));
}

/// The six coordinates of `L` points from `k`, written out (an array
/// `map` here was left as a call that copies the arrays).
#[inline(always)]
fn gather_line<const L: usize>(columns: &[&[f64]; 6], k: usize) -> [[f64; L]; 6] {
    let [c0, c1, c2, c3, c4, c5] = columns;
    [
        lanes_at(c0, k),
        lanes_at(c1, k),
        lanes_at(c2, k),
        lanes_at(c3, k),
        lanes_at(c4, k),
        lanes_at(c5, k),
    ]
}

/// `L` consecutive values of `column` from `k` (zeros past its end, which
/// the callers never reach).
#[inline(always)]
fn lanes_at<const L: usize>(column: &[f64], k: usize) -> [f64; L] {
    let mut values = [0.0; L];
    if let Some(src) = column.get(k..k + L) {
        values.copy_from_slice(src);
    }
    values
}

/// One point per lane: from its push line `x[0]` and tangent derivatives
/// `x[1]`, `x[2]` (six coordinates each), the forms `a`, `b`, `h1`, `h2`,
/// `e1`, `e2`, `g11`, `g12`, `g22` in that order. Every lane computes the
/// same sums in the same order as a point alone would. (Functions, not
/// closures: closures are not inlined into the wide copy.)
#[inline(always)]
fn patch_forms_of<const N: usize, const L: usize>(
    rows: &[[f64; 6]; N],
    beta: &[f64; 6],
    x: &[[[f64; L]; 6]; 3],
) -> [[f64; L]; 9] {
    let [x0, x1, x2] = x;
    let y0 = apply_rows(rows, x0);
    let y1 = apply_rows(rows, x1);
    let y2 = apply_rows(rows, x2);
    [
        dot_lanes(&y0, &y0),
        project_lanes(beta, x0),
        dot_lanes(&y0, &y1),
        dot_lanes(&y0, &y2),
        project_lanes(beta, x1),
        project_lanes(beta, x2),
        dot_lanes(&y1, &y1),
        dot_lanes(&y1, &y2),
        dot_lanes(&y2, &y2),
    ]
}

/// `R l` per lane (row `i` of `R` is zero before column `i`).
#[inline(always)]
fn apply_rows<const N: usize, const L: usize>(rows: &[[f64; 6]; N], line: &[[f64; L]; 6]) -> [[f64; L]; N] {
    let mut y = [[0.0; L]; N];
    for i in 0..N {
        for c in i..6 {
            let weight = rows[i][c];
            for l in 0..L {
                y[i][l] += weight * line[c][l];
            }
        }
    }
    y
}

/// `Σ_i p_i q_i` per lane.
#[inline(always)]
fn dot_lanes<const N: usize, const L: usize>(p: &[[f64; L]; N], q: &[[f64; L]; N]) -> [f64; L] {
    let mut sum = [0.0; L];
    for i in 0..N {
        for l in 0..L {
            sum[l] += p[i][l] * q[i][l];
        }
    }
    sum
}

/// `β·l` per lane, summed left to right.
#[inline(always)]
fn project_lanes<const L: usize>(beta: &[f64; 6], line: &[[f64; L]; 6]) -> [f64; L] {
    let mut sum = [0.0; L];
    for l in 0..L {
        sum[l] = beta[0] * line[0][l]
            + beta[1] * line[1][l]
            + beta[2] * line[2][l]
            + beta[3] * line[3][l]
            + beta[4] * line[4][l]
            + beta[5] * line[5][l];
    }
    sum
}

/// The triangular factor `R` of a link's weighted twists: `rows` are the
/// twists `√w_j (ω_j, v_j)` (one per joint that moves the link), and
/// `Σ_j (rowⱼ·l)² = |R l|²` for every push line `l`. `R` has at most six
/// rows, row i zero before column i, so a point's `a` costs at most 21
/// multiply-adds however many joints move its link.
fn r_factor(rows: &[[f64; 6]]) -> Vec<[f64; 6]> {
    // Householder reflections from the left: the orthogonal factor is not
    // needed, only that it preserves lengths.
    let mut m: Vec<[f64; 6]> = rows.to_vec();
    let rank = m.len().min(6);
    for col in 0..rank {
        let norm = m[col..].iter().map(|r| r[col] * r[col]).sum::<f64>().sqrt();
        if norm == 0.0 {
            continue;
        }
        let alpha = if m[col][col] > 0.0 { -norm } else { norm };
        // v = x - alpha e1 over rows col.., stored apart from m.
        let mut v: Vec<f64> = m[col..].iter().map(|r| r[col]).collect();
        v[0] -= alpha;
        let vv: f64 = v.iter().map(|x| x * x).sum();
        if vv == 0.0 {
            continue;
        }
        for c in col..6 {
            let dot: f64 = v.iter().zip(&m[col..]).map(|(vi, r)| vi * r[c]).sum();
            let scale = 2.0 * dot / vv;
            for (vi, r) in v.iter().zip(&mut m[col..]) {
                r[c] -= scale * vi;
            }
        }
        // Exact zeros below the diagonal (rounding leaves ~1e-17).
        for r in &mut m[col + 1..] {
            r[col] = 0.0;
        }
    }
    m.truncate(rank);
    m
}

/// [`forms_with`] as a [`Kernel`].
struct FormsKernel<'a, const N: usize>(&'a [[f64; 6]], [f64; 6], [&'a [f64]; 6], &'a mut [f64], &'a mut [f64]);

impl<const N: usize> Kernel for FormsKernel<'_, N> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        forms_with::<N>(self.0, self.1, self.2, self.3, self.4);
    }
}

/// Writes each point's `a = |R l|²` and `b = β·l` for the push lines `l`
/// given as six arrays; `R` has `N` rows. Constant `N` unrolls the rows,
/// and the loop over points vectorises.
#[inline(always)]
fn forms_with<const N: usize>(r: &[[f64; 6]], beta: [f64; 6], lines: [&[f64]; 6], a: &mut [f64], b: &mut [f64]) {
    let mut rows = [[0.0; 6]; N];
    for (dst, src) in rows.iter_mut().zip(r) {
        *dst = *src;
    }
    let len = a
        .len()
        .min(b.len())
        .min(lines.iter().map(|l| l.len()).min().unwrap_or(0));
    let [mx, my, mz, nx, ny, nz] = lines.map(|l| &l[..len]);
    let (a, b) = (&mut a[..len], &mut b[..len]);
    for k in 0..len {
        let l = [mx[k], my[k], mz[k], nx[k], ny[k], nz[k]];
        let mut sum = 0.0;
        for (i, row) in rows.iter().enumerate() {
            let mut u = 0.0;
            for c in i..6 {
                u += row[c] * l[c];
            }
            sum += u * u;
        }
        a[k] = sum;
        b[k] = beta[0] * l[0] + beta[1] * l[1] + beta[2] * l[2] + beta[3] * l[3] + beta[4] * l[4] + beta[5] * l[5];
    }
}

/// Unit torques of every surface point for one configuration: pushing
/// with `f` newtons along point k's inward normal produces `f · u_jk` on
/// sensed joint j.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactModel {
    joints: usize,
    points: usize,
    /// Point-major: `unit_torque[k * joints + j]`, so that one point's
    /// torques are contiguous and its likelihood terms accumulate in registers.
    unit_torque: Vec<f64>,
}

impl ContactModel {
    /// Evaluates the Plücker form for every point (6 multiply-adds per
    /// point and joint that moves its link; 0 elsewhere).
    #[must_use]
    pub fn new(torque_model: &TorqueModel, surface: &Surface) -> Self {
        let joints = torque_model.sensed_count();
        let points = surface.len();
        let mut unit_torque = vec![0.0; joints * points];
        let fill = |(k, row): (usize, &mut [f64])| {
            let link = surface.link[k];
            let p = surface.point_in_link[k];
            let n = surface.inward_normal_in_link[k];
            let moment = p.cross(n);
            for twist in torque_model.twists(link) {
                if let Some(slot) = row.get_mut(twist.sensed_index) {
                    *slot = twist.w.dot(moment) + twist.v.dot(n);
                }
            }
        };
        if joints > 0 {
            if points >= PARALLEL_MIN_POINTS {
                unit_torque.par_chunks_exact_mut(joints).enumerate().for_each(fill);
            } else {
                unit_torque.chunks_exact_mut(joints).enumerate().for_each(fill);
            }
        }
        Self {
            joints,
            points,
            unit_torque,
        }
    }

    /// Point k's unit torque on joint j.
    #[must_use]
    pub fn unit_torque(&self, joint: usize, point: usize) -> f64 {
        self.unit_torques(point).get(joint).copied().unwrap_or(0.0)
    }

    /// Point k's unit torques on every joint (empty past the last point).
    #[must_use]
    pub fn unit_torques(&self, point: usize) -> &[f64] {
        self.unit_torque
            .get(point * self.joints..(point + 1) * self.joints)
            .unwrap_or(&[])
    }

    fn quadratic_forms_stored(&self, weights: &[f64], tau: &[f64], a: &mut Vec<f64>, b: &mut Vec<f64>) {
        let wt: Vec<f64> = weights.iter().zip(tau).map(|(w, t)| w * t).collect();
        a.clear();
        b.clear();
        a.reserve(self.points);
        b.reserve(self.points);
        // Fixed joint counts unroll into straight-line code.
        match self.joints {
            6 => self.quadratic_fixed::<6>(weights, &wt, a, b),
            7 => self.quadratic_fixed::<7>(weights, &wt, a, b),
            _ => {
                for row in self.unit_torque.chunks_exact(self.joints.max(1)) {
                    let (mut ak, mut bk) = (0.0, 0.0);
                    for ((u, w), wt) in row.iter().zip(weights).zip(&wt) {
                        ak += w * u * u;
                        bk += wt * u;
                    }
                    a.push(ak);
                    b.push(bk);
                }
                a.resize(self.points, 0.0);
                b.resize(self.points, 0.0);
            }
        }
    }

    fn quadratic_fixed<const J: usize>(&self, weights: &[f64], wt: &[f64], a: &mut Vec<f64>, b: &mut Vec<f64>) {
        let (Ok(w), Ok(wt)) = (<[f64; J]>::try_from(weights), <[f64; J]>::try_from(wt)) else {
            return;
        };
        let form = |row: &[f64]| {
            let (mut ak, mut bk) = (0.0, 0.0);
            for j in 0..J {
                ak += w[j] * row[j] * row[j];
                bk += wt[j] * row[j];
            }
            (ak, bk)
        };
        if self.points >= PARALLEL_MIN_POINTS {
            let (pa, pb): (Vec<f64>, Vec<f64>) = self.unit_torque.par_chunks_exact(J).map(form).unzip();
            *a = pa;
            *b = pb;
        } else {
            for row in self.unit_torque.chunks_exact(J) {
                let (ak, bk) = form(row);
                a.push(ak);
                b.push(bk);
            }
        }
    }
}

impl UnitTorqueSource for ContactModel {
    fn joints(&self) -> usize {
        self.joints
    }

    fn points(&self) -> usize {
        self.points
    }

    fn unit_torques_into(&self, point: usize, out: &mut [f64]) {
        out.fill(0.0);
        for (slot, u) in out.iter_mut().zip(self.unit_torques(point)) {
            *slot = *u;
        }
    }

    fn quadratic_forms(&self, weights: &[f64], tau: &[f64], a: &mut Vec<f64>, b: &mut Vec<f64>) {
        self.quadratic_forms_stored(weights, tau, a, b);
    }
}

#[cfg(test)]
#[path = "contact_tests.rs"]
mod tests;
