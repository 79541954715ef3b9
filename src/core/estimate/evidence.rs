//! Each sample's likelihood of a frame's torques with the push magnitude
//! integrated over its range in closed form (erf differences, fast in
//! lanes), and the profile over the magnitude where that is negligible.

use rayon::prelude::*;

use crate::core::estimate::contact::PARALLEL_MIN_POINTS;
use crate::core::numerics::fastmath::{self, ErfTable};
use crate::core::numerics::lanes;
use crate::core::numerics::simd::{Kernel, widest};
use crate::core::numerics::special::ln_erf_difference;

/// Points whose profile log-likelihood is this far below the best get the
/// profile value instead of the erf form: their posterior mass is below
/// e^-50 of the best either way.
pub(crate) const FAR_BELOW: f64 = 60.0;

/// The per-measurement quantities of a point: `a = Σ w u²`, `b = Σ w u τ`,
/// `c = Σ w τ²` with `w = 1/σ²` (per point once the resolution noise is
/// added), and `norm`, the point's share of the Gaussian normaliser
/// relative to the bare noise model.
/// Per-point `c` and normaliser arrays.
type PerPoint<'a> = (&'a [f64], &'a [f64]);

pub(crate) struct Quadratic<'a> {
    pub(crate) a: &'a [f64],
    pub(crate) b: &'a [f64],
    /// `c` shared by every point (the bare noise model)…
    pub(crate) c: f64,
    /// …or one per point, with its normaliser (patches).
    pub(crate) per_point: Option<PerPoint<'a>>,
    /// Per-point patch volumes (`det(I + f₀²ρ² G) ≥ 1`, see
    /// [`patch_terms`]), when patches are used: the normaliser's `-½ ln`
    /// of it is left out of profiles (which stay upper bounds) and added
    /// where the evidence is computed.
    pub(crate) volume: Option<&'a [f64]>,
    pub(crate) f_min: f64,
    pub(crate) f_max: f64,
}

impl Quadratic<'_> {
    /// Best magnitude in range at point k (the tests' reference for
    /// [`profile_chunk`]).
    #[cfg(test)]
    pub(crate) fn best_force(&self, k: usize) -> f64 {
        let (a, b) = (self.a[k], self.b[k]);
        if a > 0.0 {
            (b / a).clamp(self.f_min, self.f_max)
        } else {
            self.f_min
        }
    }

    /// Point k's `c` and normaliser.
    #[inline]
    fn c_norm(&self, k: usize) -> (f64, f64) {
        match self.per_point {
            None => (self.c, 0.0),
            Some((c, norm)) => (c[k], norm[k]),
        }
    }

    /// Log-likelihood of magnitude f at point k: `-½ (c - 2 b f + a f²)`.
    pub(crate) fn log_likelihood(&self, k: usize, f: f64) -> f64 {
        let (_, norm) = self.c_norm(k);
        norm - 0.5 * self.residual(k, f)
    }

    /// `Σ w (τ - f u)²` at point k.
    #[inline]
    pub(crate) fn residual(&self, k: usize, f: f64) -> f64 {
        let (c, _) = self.c_norm(k);
        residual(self.a[k], self.b[k], c, f)
    }

    /// Each listed point's best magnitude and its log-likelihood there
    /// (the profile), and the largest profile. Whole-surface lists read
    /// the arrays in place; the loops vectorise, and large surfaces share
    /// them among threads.
    fn profiles(&self, points: &[usize], surface_points: usize) -> Profiles {
        const CHUNK: usize = 4096;
        let gather = |values: &[f64]| -> Vec<f64> { points.iter().map(|&k| values[k]).collect() };
        let full = points.len() == surface_points;
        let gathered;
        let (a, b, per_point): (&[f64], &[f64], Option<PerPoint>) = if full {
            (self.a, self.b, self.per_point)
        } else {
            gathered = (
                gather(self.a),
                gather(self.b),
                self.per_point.map(|(c, norm)| (gather(c), gather(norm))),
            );
            (
                &gathered.0,
                &gathered.1,
                gathered.2.as_ref().map(|(c, norm)| (c.as_slice(), norm.as_slice())),
            )
        };
        let len = a.len();
        let (mut force, mut mass, mut residual) = (vec![0.0; len], vec![0.0; len], vec![0.0; len]);
        let chunk = |start: usize, force: &mut [f64], mass: &mut [f64], residual: &mut [f64]| -> f64 {
            let range = start..start + force.len();
            let c = match per_point {
                None => Shared::Value(self.c),
                Some((c, norm)) => Shared::PerPoint(&c[range.clone()], &norm[range.clone()]),
            };
            widest(ProfileKernel(
                &a[range.clone()],
                &b[range],
                c,
                (self.f_min, self.f_max),
                force,
                mass,
                residual,
            ))
        };
        let best = if len >= PARALLEL_MIN_POINTS {
            force
                .par_chunks_mut(CHUNK)
                .zip(mass.par_chunks_mut(CHUNK))
                .zip(residual.par_chunks_mut(CHUNK))
                .enumerate()
                .map(|(i, ((force, mass), residual))| chunk(i * CHUNK, force, mass, residual))
                .reduce(|| f64::NEG_INFINITY, f64::max)
        } else {
            chunk(0, &mut force, &mut mass, &mut residual)
        };
        Profiles {
            force,
            mass,
            residual,
            best,
        }
    }

    /// The exact evaluation of the listed points: the evidence near the
    /// best, the profile (a tight upper bound) elsewhere.
    pub(crate) fn exact_scores(&self, points: &[usize], surface_points: usize) -> Scores {
        let Profiles {
            force,
            mut mass,
            residual,
            best: profile_best,
        } = self.profiles(points, surface_points);
        let slots_from = |low: f64, high: f64| -> Vec<usize> {
            let slots_in = |start: usize, mass: &[f64]| -> Vec<usize> {
                let mut slots = lanes::positions_where(mass, |m| m >= low && m < high);
                for slot in &mut slots {
                    *slot += start;
                }
                slots
            };
            if mass.len() >= PARALLEL_MIN_POINTS {
                const CHUNK: usize = 8192;
                mass.par_chunks(CHUNK)
                    .enumerate()
                    .map(|(c, chunk)| slots_in(c * CHUNK, chunk))
                    .collect::<Vec<_>>()
                    .concat()
            } else {
                slots_in(0, &mass)
            }
        };
        let evidence = |slots: &[usize]| -> Vec<f64> {
            // Many points (a broad posterior): the branch-free evidence,
            // which vectorises; a few: the careful one.
            if slots.len() >= FAST_EVIDENCE_MIN && slots.len() < PARALLEL_MIN_EVIDENCE_FAST {
                return self.log_evidence_many(points, slots, &mass);
            }
            let one = |&i: &usize| self.log_evidence(points[i], mass[i]);
            if slots.len() >= PARALLEL_MIN_EVIDENCE {
                slots.par_iter().map(one).collect()
            } else {
                slots.iter().map(one).collect()
            }
        };
        let threshold = profile_best - FAR_BELOW;
        let mut candidates = slots_from(threshold, f64::INFINITY);
        let mut values = evidence(&candidates);
        // A point's evidence may lie well below its profile (a narrow
        // peak in f); then points with profiles below the first threshold
        // may still be within reach of the best evidence: score them too,
        // so that every point left out is negligible.
        let best_evidence = lanes::max_or(&values, f64::NEG_INFINITY);
        if best_evidence - FAR_BELOW < threshold {
            let extra = slots_from(best_evidence - FAR_BELOW, threshold);
            values.extend(evidence(&extra));
            candidates.extend(extra);
            for (&i, &l) in candidates.iter().zip(&values) {
                mass[i] = l;
            }
            // Two sorted runs: the stable sort merges them in linear time.
            #[allow(clippy::stable_sort_primitive)]
            candidates.sort();
        } else {
            for (&i, &l) in candidates.iter().zip(&values) {
                mass[i] = l;
            }
        }
        Scores {
            mass,
            best: Vec::new(),
            force,
            residual,
            candidates: Some(candidates),
        }
    }

    /// [`Self::log_evidence`] of the points `points[slots[..]]` (their
    /// profiles in `profile[slots[..]]`) at once, with the branch-free erf
    /// difference, `ln` and `exp` of [`crate::core::numerics::fastmath`] (absolute
    /// error below 1e-9) in one loop over gathered arrays, which
    /// vectorises; the rare points that would cancel there (a range narrow
    /// against the likelihood's width in f) take the careful path after.
    pub(crate) fn log_evidence_many(&self, points: &[usize], slots: &[usize], profile: &[f64]) -> Vec<f64> {
        widest(EvidenceKernel(self, points, slots, profile))
    }

    /// [`Self::log_evidence_many`]'s work, inlined into [`widest`].
    #[inline(always)]
    fn log_evidence_many_inner(&self, points: &[usize], slots: &[usize], profile: &[f64]) -> Vec<f64> {
        // No closures here: they are not inlined into the wide copy (a
        // call per point each), hence the plain loops and `gather`.
        let table = ErfTable::get();
        let m = slots.len();
        let index = gather_indices(points, slots);
        let (a, b) = (gather(self.a, &index, 0.0), gather(self.b, &index, 0.0));
        let (c, norm) = match self.per_point {
            None => (vec![self.c; m], vec![0.0; m]),
            Some((c, norm)) => (gather(c, &index, 0.0), gather(norm, &index, 0.0)),
        };
        let volume = match self.volume {
            None => vec![1.0; m],
            Some(v) => gather(v, &index, 1.0),
        };
        let (f_min, f_max) = (self.f_min, self.f_max);
        let ln_range = (f_max - f_min).ln();
        // Everything but the erf difference, the ends x₁ < x₂ of its
        // interval, and whether the interval is too narrow for the
        // branch-free difference: one vectorised pass.
        let mut out = vec![0.0; m];
        let (mut x1, mut x2) = (vec![0.0; m], vec![0.0; m]);
        let mut narrow = vec![false; m];
        {
            let (a, b, c, norm, volume) = (&a[..m], &b[..m], &c[..m], &norm[..m], &volume[..m]);
            let (x1, x2, narrow) = (&mut x1[..m], &mut x2[..m], &mut narrow[..m]);
            for j in 0..m {
                let aj = if a[j] > f64::MIN_POSITIVE {
                    a[j]
                } else {
                    f64::MIN_POSITIVE
                };
                let s = (0.5 * aj).sqrt();
                let mu = b[j] / aj;
                let residual = c[j] - b[j] * mu;
                let residual = if residual > 0.0 { residual } else { 0.0 };
                out[j] = norm[j] - 0.5 * residual + 0.5 * fastmath::ln(std::f64::consts::PI / (2.0 * aj * volume[j]))
                    - ln_range;
                x1[j] = s * (f_min - mu);
                x2[j] = s * (f_max - mu);
                narrow[j] = (0.5 * a[j]).sqrt() * (f_max - f_min) < 0.05;
            }
        }
        // The erf difference by kind of interval, each kind in a loop of
        // its own (`y` the end nearer 0 in absolute value, `Y` the other;
        // erfc(4.6) < 2e-10 and e⁻²¹ < 1e-9 bound what each drops):
        // (0) ends on both sides of 0 beyond ±4.6: ln 2; (1) both on one
        // side, erfc(Y) below e⁻²¹ of erfc(y): y alone; (2) the rest,
        // branch-free in full; (3) both sides, Y beyond 4.6:
        // ln(2 - erfc(y)).
        let (kinds, near_end) = interval_kinds(&x1, &x2);
        for &j in &kinds[0] {
            if let Some(o) = out.get_mut(j) {
                *o += std::f64::consts::LN_2;
            }
        }
        let near = gather(&near_end, &kinds[1], 0.0);
        let mut term = vec![0.0; near.len()];
        one_sided_terms(&table, &near, &mut term);
        add_at(&mut out, &kinds[1], &term);
        let near = gather(&near_end, &kinds[3], 0.0);
        let mut term = vec![0.0; near.len()];
        for (t, &y) in term.iter_mut().zip(&near) {
            let (tn, pn) = table.parts(y);
            *t = fastmath::ln(2.0 - tn * fastmath::exp(-y * y + pn));
        }
        add_at(&mut out, &kinds[3], &term);
        let (lo, hi) = (gather(&x1, &kinds[2], 0.0), gather(&x2, &kinds[2], 0.0));
        let mut term = vec![0.0; lo.len()];
        two_sided_terms(&table, &lo, &hi, &mut term);
        add_at(&mut out, &kinds[2], &term);
        for (j, (&i, &narrow)) in slots.iter().zip(&narrow).enumerate() {
            if narrow && let (Some(&k), Some(&p), Some(o)) = (points.get(i), profile.get(i), out.get_mut(j)) {
                *o = self.log_evidence(k, p);
            }
        }
        out
    }

    /// ln of the likelihood averaged over a uniform f in `[F_min, F_max]`,
    /// given the likelihood at the point's best magnitude (`profile`) and
    /// the best such value over the points (`profile_best`).
    pub(crate) fn log_evidence(&self, k: usize, profile: f64) -> f64 {
        let (a, b) = (self.a[k], self.b[k]);
        let range = self.f_max - self.f_min;
        let volume = self.volume.and_then(|v| v.get(k)).map_or(0.0, |v| -0.5 * v.ln());
        if range <= 1e-12 * self.f_max.max(1.0) {
            return profile + volume;
        }
        let s = (0.5 * a).sqrt();
        if s * range < 1e-6 {
            // Flat over the range (a → 0: the point makes almost no torque).
            let mid = 0.5 * (self.f_min + self.f_max);
            return self.log_likelihood(k, mid) + volume;
        }
        let mu = b / a;
        let (c, norm) = self.c_norm(k);
        norm + volume - 0.5 * (c - b * mu).max(0.0)
            + 0.5 * (std::f64::consts::PI / (2.0 * a)).ln()
            + ln_erf_difference(s * (self.f_min - mu), s * (self.f_max - mu))
            - range.ln()
    }
}

/// Each interval's kind (see `log_evidence_many_inner`) as lists of
/// positions, and each interval's end nearer 0 in absolute value.
#[inline(always)]
fn interval_kinds(x1: &[f64], x2: &[f64]) -> ([Vec<usize>; 4], Vec<f64>) {
    let m = x1.len().min(x2.len());
    let mut kind = vec![0_u8; m];
    let mut near_end = vec![0.0; m];
    {
        let (x1, x2, kind, near_end) = (&x1[..m], &x2[..m], &mut kind[..m], &mut near_end[..m]);
        for j in 0..m {
            let (lo, hi) = (x1[j], x2[j]);
            let (yl, yh) = (lo.abs(), hi.abs());
            let (yn, yf) = if yl < yh { (yl, yh) } else { (yh, yl) };
            near_end[j] = yn;
            let opposite = lo < 0.0 && hi > 0.0;
            let both_far = opposite && yn > ERFC_NEGLIGIBLE_BEYOND;
            let far_end_far = opposite && yf > ERFC_NEGLIGIBLE_BEYOND;
            let one_sided_far = !opposite && (yf - yn) * (yf + yn) > FAR_END_NEGLIGIBLE_BELOW;
            kind[j] = if both_far {
                0
            } else if far_end_far {
                3
            } else if one_sided_far {
                1
            } else {
                2
            };
        }
    }
    let mut kinds: [Vec<usize>; 4] = [
        Vec::with_capacity(m),
        Vec::with_capacity(m),
        Vec::with_capacity(m),
        Vec::with_capacity(m),
    ];
    for (j, &k) in kind.iter().enumerate() {
        if let Some(list) = kinds.get_mut(usize::from(k)) {
            list.push(j);
        }
    }
    (kinds, near_end)
}

/// Points evaluated together in the evidence's erfc fits: sixteen
/// independent chains in flight (four AVX2 registers), where one point
/// per step leaves each step waiting on the one before (the fits of
/// 5000 points: 42 → 29 µs in a scratch timing on the development VM).
const EVIDENCE_LANES: usize = 16;

/// `ln erfc(y)` (`-y² + P + ln t`) of each near end `y` of a one-sided
/// interval, [`EVIDENCE_LANES`] at a time; the same bits as one at a time.
#[inline(always)]
fn one_sided_terms(table: &ErfTable, near: &[f64], term: &mut [f64]) {
    const L: usize = EVIDENCE_LANES;
    let mut near_chunks = near.chunks_exact(L);
    let mut term_chunks = term.chunks_exact_mut(L);
    for (y, t) in (&mut near_chunks).zip(&mut term_chunks) {
        let (Ok(y), Ok(t)) = (<&[f64; L]>::try_from(y), <&mut [f64; L]>::try_from(t)) else {
            continue;
        };
        let (tn, pn) = table.parts_lanes(y);
        for l in 0..L {
            t[l] = -y[l] * y[l] + pn[l] + fastmath::ln(tn[l]);
        }
    }
    for (t, &y) in term_chunks.into_remainder().iter_mut().zip(near_chunks.remainder()) {
        let (tn, pn) = table.parts(y);
        *t = -y * y + pn + fastmath::ln(tn);
    }
}

/// [`ErfTable::ln_erf_difference`] of each interval `[lo, hi]`,
/// [`EVIDENCE_LANES`] at a time; the same bits as one at a time.
#[inline(always)]
fn two_sided_terms(table: &ErfTable, lo: &[f64], hi: &[f64], term: &mut [f64]) {
    const L: usize = EVIDENCE_LANES;
    let mut lo_chunks = lo.chunks_exact(L);
    let mut hi_chunks = hi.chunks_exact(L);
    let mut term_chunks = term.chunks_exact_mut(L);
    for ((l, h), t) in (&mut lo_chunks).zip(&mut hi_chunks).zip(&mut term_chunks) {
        let (Ok(l), Ok(h)) = (<&[f64; L]>::try_from(l), <&[f64; L]>::try_from(h)) else {
            continue;
        };
        t.copy_from_slice(&table.ln_erf_difference_lanes(l, h));
    }
    for ((t, &l), &h) in term_chunks
        .into_remainder()
        .iter_mut()
        .zip(lo_chunks.remainder())
        .zip(hi_chunks.remainder())
    {
        *t = table.ln_erf_difference(l, h);
    }
}

/// `points[slots[j]]` for each j (0 where out of range, which callers
/// never give).
#[inline(always)]
fn gather_indices(points: &[usize], slots: &[usize]) -> Vec<usize> {
    let mut out = vec![0; slots.len()];
    for (o, &i) in out.iter_mut().zip(slots) {
        if let Some(&k) = points.get(i) {
            *o = k;
        }
    }
    out
}

/// `values[index[j]]` for each j (`fallback` where out of range).
#[inline(always)]
fn gather(values: &[f64], index: &[usize], fallback: f64) -> Vec<f64> {
    let mut out = vec![fallback; index.len()];
    for (o, &k) in out.iter_mut().zip(index) {
        if let Some(&v) = values.get(k) {
            *o = v;
        }
    }
    out
}

/// `out[index[j]] += terms[j]`.
#[inline(always)]
fn add_at(out: &mut [f64], index: &[usize], terms: &[f64]) {
    for (&j, &t) in index.iter().zip(terms) {
        if let Some(o) = out.get_mut(j) {
            *o += t;
        }
    }
}

/// Beyond this, `erfc` is below 2e-10: dropped beside 1 or 2.
const ERFC_NEGLIGIBLE_BEYOND: f64 = 4.6;

/// Where `Y² - y²` exceeds this, `erfc(Y) < e⁻²¹ erfc(y)` (< 1e-9 relative)
/// for `Y > y ≥ 0`: the far end of a one-sided interval is dropped.
const FAR_END_NEGLIGIBLE_BELOW: f64 = 21.0;

/// [`Quadratic::profiles`]' output, one value per listed point: the best
/// magnitude, the log-likelihood there and its residual
/// `Σ w (τ - f u)²`; and the largest log-likelihood.
struct Profiles {
    pub(crate) force: Vec<f64>,
    pub(crate) mass: Vec<f64>,
    pub(crate) residual: Vec<f64>,
    pub(crate) best: f64,
}

/// Per evaluated point (one array each, so that the exact mode's loops
/// vectorise): the score that sums (ln mass), the score a heatmap shows
/// (ln of the best particle), and the best magnitude.
pub(crate) struct Scores {
    pub(crate) mass: Vec<f64>,
    /// Empty where each point's best is its mass (exact mode).
    pub(crate) best: Vec<f64>,
    pub(crate) force: Vec<f64>,
    /// `Σ w (τ - f u)²` at each slot's `force` (exact mode, where the
    /// profile computed it anyway); empty otherwise.
    pub(crate) residual: Vec<f64>,
    /// The slots that may hold mass, in order (every other slot is below
    /// e^-60 of the best); `None`: any slot may.
    pub(crate) candidates: Option<Vec<usize>>,
}

impl Scores {
    /// `len` points, none scored yet.
    pub(crate) fn unscored(len: usize, force: f64) -> Self {
        Self {
            mass: vec![f64::NEG_INFINITY; len],
            best: vec![f64::NEG_INFINITY; len],
            force: vec![force; len],
            residual: Vec::new(),
            candidates: None,
        }
    }

    /// Slot i's heatmap score.
    pub(crate) fn best(&self, i: usize) -> f64 {
        self.best
            .get(i)
            .or(self.mass.get(i))
            .copied()
            .unwrap_or(f64::NEG_INFINITY)
    }

    /// Adds a particle of log-likelihood `l` and magnitude `f` to slot `i`.
    pub(crate) fn add_particle(&mut self, i: usize, l: f64, f: f64) {
        if let (Some(mass), Some(best), Some(force)) =
            (self.mass.get_mut(i), self.best.get_mut(i), self.force.get_mut(i))
        {
            *mass = log_add(*mass, l);
            if l > *best {
                *best = l;
                *force = f;
            }
        }
    }
}

/// From this many near-best points on, their evidence takes the
/// branch-free path…
const FAST_EVIDENCE_MIN: usize = 64;

/// …up to this many, beyond which threads share the careful one.
const PARALLEL_MIN_EVIDENCE_FAST: usize = 1 << 20;

/// From this many near-best points on, their evidence is shared among
/// threads.
const PARALLEL_MIN_EVIDENCE: usize = 512;

/// [`Quadratic::log_evidence_many_inner`] as a [`Kernel`].
pub(crate) struct EvidenceKernel<'a>(
    pub(crate) &'a Quadratic<'a>,
    pub(crate) &'a [usize],
    pub(crate) &'a [usize],
    pub(crate) &'a [f64],
);

impl Kernel for EvidenceKernel<'_> {
    type Output = Vec<f64>;
    #[inline(always)]
    fn run(self) -> Vec<f64> {
        self.0.log_evidence_many_inner(self.1, self.2, self.3)
    }
}

/// [`profile_chunk`] as a [`Kernel`].
pub(crate) struct ProfileKernel<'a>(
    pub(crate) &'a [f64],
    pub(crate) &'a [f64],
    pub(crate) Shared<'a>,
    pub(crate) (f64, f64),
    pub(crate) &'a mut [f64],
    pub(crate) &'a mut [f64],
    pub(crate) &'a mut [f64],
);

impl Kernel for ProfileKernel<'_> {
    type Output = f64;
    #[inline(always)]
    fn run(self) -> f64 {
        let Self(a, b, c, (f_min, f_max), force, mass, residual) = self;
        profile_chunk(a, b, c, (f_min, f_max), force, mass, residual)
    }
}

/// The `c` and normaliser of a chunk of points.
#[derive(Clone, Copy)]
pub(crate) enum Shared<'a> {
    /// One `c` for all, no normaliser.
    Value(f64),
    /// Per point.
    PerPoint(&'a [f64], &'a [f64]),
}

/// Writes each point's best magnitude in `[f_min, f_max]`, its
/// log-likelihood and its residual there, and returns the largest
/// log-likelihood.
#[inline(always)]
fn profile_chunk(
    a: &[f64],
    b: &[f64],
    c: Shared,
    (f_min, f_max): (f64, f64),
    force: &mut [f64],
    mass: &mut [f64],
    residuals: &mut [f64],
) -> f64 {
    // `a = 0` implies `b = 0`, so the guarded quotient is then 0 and
    // clamps to `F_min`, without a branch that would stop the loop from
    // vectorising (as would `f64::clamp`'s NaN rules).
    for ((f, &a), &b) in force.iter_mut().zip(a).zip(b) {
        let q = b / a.max(f64::MIN_POSITIVE);
        let q = if q > f_min { q } else { f_min };
        *f = if q < f_max { q } else { f_max };
    }
    match c {
        Shared::Value(c) => {
            for ((((m, r), &a), &b), &f) in mass.iter_mut().zip(&mut *residuals).zip(a).zip(b).zip(&*force) {
                *r = residual(a, b, c, f);
                *m = -0.5 * *r;
            }
        }
        Shared::PerPoint(c, norm) => {
            for ((((m, r), &a), &b), (&f, (&c, &norm))) in mass
                .iter_mut()
                .zip(&mut *residuals)
                .zip(a)
                .zip(b)
                .zip(force.iter().zip(c.iter().zip(norm)))
            {
                *r = residual(a, b, c, f);
                *m = norm - 0.5 * *r;
            }
        }
    }
    let mut best = f64::NEG_INFINITY;
    for &m in &*mass {
        best = if m > best { m } else { best };
    }
    best
}

/// `c - 2 b f + a f²`, not below 0 (a function, not a closure, so that it
/// is inlined into the wide copy).
#[inline(always)]
fn residual(a: f64, b: f64, c: f64, f: f64) -> f64 {
    let r = c - 2.0 * b * f + a * f * f;
    if r > 0.0 { r } else { 0.0 }
}

/// `ln(e^x + e^y)` without overflow.
fn log_add(x: f64, y: f64) -> f64 {
    let (hi, lo) = if x > y { (x, y) } else { (y, x) };
    if hi == f64::NEG_INFINITY {
        hi
    } else {
        hi + (lo - hi).exp().ln_1p()
    }
}

/// Posterior masses below e^-60 (1e-26) of the total are stored as 0:
/// they change no sum, and the log-likelihood keeps their exact value for
/// log-scale displays. Skipping their `exp` is most of an update's time.
pub(crate) const NEGLIGIBLE_LOG_MASS: f64 = -60.0;

/// `e^x`, or 0 where that is negligible.
pub(crate) fn exp_or_zero(x: f64) -> f64 {
    if x < NEGLIGIBLE_LOG_MASS { 0.0 } else { fastmath::exp(x) }
}
