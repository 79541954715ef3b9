//! The contact estimator: a posterior over surface points from measured
//! joint torques (thesis eq. 2.3–2.6), in exact mode (ours) or with the
//! thesis' particles, optionally coarse-to-fine in phases A/B/C.

use crate::core::estimate::contact::{PatchForms, UnitTorqueSource};
use crate::core::estimate::evidence::{NEGLIGIBLE_LOG_MASS, Quadratic, Scores, exp_or_zero};
use crate::core::estimate::phases::PhaseHierarchy;
use crate::core::estimate::settings::{EstimateError, EstimatorSettings, Mode, ParticleSettings, Sampling, validate};
use crate::core::numerics::fastmath::{self};
use crate::core::numerics::lanes;
use crate::core::numerics::rng::Rng;
use crate::core::numerics::simd::{Kernel, widest};

/// What one phase evaluated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct PhaseReport {
    /// Surface points evaluated.
    pub points: usize,
    /// Particles evaluated (points in exact mode).
    pub particles: usize,
}

/// Phase membership flags in [`Posterior::phase_flags`].
pub mod phase_flag {

    /// The point is a phase-A representative.
    pub const A: u8 = 1;
    /// The point was evaluated in phase B.
    pub const B: u8 = 2;
    /// The point was evaluated in the last phase (C, or the full search).
    pub const C: u8 = 4;
}

/// A posterior over the surface points.
#[derive(Debug, Clone, PartialEq)]
pub struct Posterior {
    /// Posterior mass of each point (sums to 1; 0 where not evaluated or
    /// below 1e-26 of the total).
    pub probability: Vec<f64>,
    /// What a heatmap shows: in particle mode the probability of the
    /// point's best particle (§3.1.3), in exact mode the point's mass.
    pub display: Vec<f64>,
    /// ln of each point's likelihood (integrated over the magnitude in
    /// exact mode), up to a constant shared by all points; `-inf` where
    /// not evaluated.
    pub log_likelihood: Vec<f64>,
    /// Most likely push magnitude at each point, N (0 where not evaluated).
    pub force_newtons: Vec<f64>,
    /// Per phase (one entry without phases).
    pub phases: Vec<PhaseReport>,
    /// Per point, [`phase_flag`] bits.
    pub phase_flags: Vec<u8>,
    /// The points with non-zero probability, in index order (usually a
    /// few dozen: summaries read these instead of the whole surface).
    pub support: Vec<usize>,
    /// Index of the most probable point.
    pub map_point: usize,
    /// Smallest `Σ (τ - f u)² / σ²` over evaluated points and magnitudes.
    pub best_residual_chi2: f64,
    /// `Σ τ² / σ²`: the residual of "no contact".
    pub no_contact_chi2: f64,
}

impl Posterior {
    /// Bytes its per-point vectors hold (what a frame waiting for its
    /// smoothed belief keeps).
    #[must_use]
    pub fn bytes(&self) -> usize {
        (self.probability.len() + self.display.len() + self.log_likelihood.len() + self.force_newtons.len())
            * size_of::<f64>()
            + self.phase_flags.len()
            + self.support.len() * size_of::<usize>()
    }
}

/// A posterior held while its frame waits (for its smoothed belief): the
/// probability kept on its support alone, the display dropped where it is
/// the probability. [`CompactPosterior::expand`] gives the same posterior
/// back, bit for bit; a frame waits with 80 kB instead of 165 kB at 5,000
/// points.
#[derive(Debug, Clone)]
pub struct CompactPosterior {
    /// The posterior, its dense vectors emptied where they are kept below.
    posterior: Posterior,
    /// With the probability emptied: the surface's points, and the
    /// probability at each support point.
    sparse: Option<(usize, Vec<f64>)>,
    /// The display was the probability.
    display_is_probability: bool,
}

impl CompactPosterior {
    /// `posterior` compacted where it can be given back exactly: its
    /// probability is zero off its support.
    #[must_use]
    pub fn of(mut posterior: Posterior) -> Self {
        // Bits compared: a -0.0 or a NaN comes back as it was.
        let display_is_probability = posterior.display.len() == posterior.probability.len()
            && posterior
                .display
                .iter()
                .zip(&posterior.probability)
                .all(|(d, p)| d.to_bits() == p.to_bits());
        let mut on_support = 0;
        let mut mass_on_support = Vec::with_capacity(posterior.support.len());
        for &k in &posterior.support {
            if let Some(&p) = posterior.probability.get(k) {
                mass_on_support.push(p);
                on_support += usize::from(p.to_bits() != 0);
            }
        }
        let nonzero = posterior.probability.iter().filter(|p| p.to_bits() != 0).count();
        let off_support = nonzero.saturating_sub(on_support);
        let sparse = (off_support == 0 && mass_on_support.len() == posterior.support.len()).then(|| {
            let points = posterior.probability.len();
            posterior.probability = Vec::new();
            (points, mass_on_support)
        });
        if display_is_probability {
            posterior.display = Vec::new();
        }
        Self {
            posterior,
            sparse,
            display_is_probability,
        }
    }

    /// Bytes it holds.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.posterior.bytes() + self.sparse.as_ref().map_or(0, |(_, p)| p.len() * size_of::<f64>())
    }

    /// The posterior it was made of.
    #[must_use]
    pub fn expand(self) -> Posterior {
        let Self {
            mut posterior,
            sparse,
            display_is_probability,
        } = self;
        if let Some((points, mass_on_support)) = sparse {
            let mut probability = vec![0.0; points];
            for (&k, p) in posterior.support.iter().zip(mass_on_support) {
                if let Some(slot) = probability.get_mut(k) {
                    *slot = p;
                }
            }
            posterior.probability = probability;
        }
        if display_is_probability {
            posterior.display.clone_from(&posterior.probability);
        }
        posterior
    }
}

/// Estimates the contact from measured torques `tau` (N·m, sensed order).
/// `hierarchy` is needed when `settings.phase_alpha` is set.
pub fn estimate(
    model: &impl UnitTorqueSource,
    tau: &[f64],
    settings: &EstimatorSettings,
    hierarchy: Option<&PhaseHierarchy>,
) -> Result<Posterior, EstimateError> {
    estimate_keeping_forms(model, tau, settings, hierarchy, None)
}

/// [`estimate`], also handing over the per-point [`PatchForms`] it
/// computed (left empty when it used none): what a temporal model needs
/// besides the posterior, without computing them twice.
///
/// # Errors
/// As [`estimate`].
pub fn estimate_keeping_forms(
    model: &impl UnitTorqueSource,
    tau: &[f64],
    settings: &EstimatorSettings,
    hierarchy: Option<&PhaseHierarchy>,
    forms_out: Option<&mut PatchForms>,
) -> Result<Posterior, EstimateError> {
    validate(model, tau, settings)?;
    let n = model.points();
    let weights = settings.weights();
    let no_contact_chi2: f64 = weights.iter().zip(tau).map(|(w, t)| w * t * t).sum();
    let (patches, a, b, terms) = likelihood_terms(model, tau, settings, &weights, no_contact_chi2, forms_out);
    let q = Quadratic {
        a: &a,
        b: &b,
        c: no_contact_chi2,
        per_point: patches.then_some((terms.c.as_slice(), terms.norm.as_slice())),
        volume: patches.then_some(terms.volume.as_slice()),
        f_min: settings.force_min_newtons,
        f_max: settings.force_max_newtons,
    };
    let mut rng = match settings.mode {
        Mode::Particles(ParticleSettings {
            sampling: Sampling::Random { seed, .. },
        }) => Rng::new(seed),
        _ => Rng::new(0),
    };
    let mut flags = vec![0u8; n];
    let mut phases = Vec::new();
    let last = search_phases(&q, settings, hierarchy, n, &mut rng, &mut flags, &mut phases)?;
    let (mut scored, report) = evaluate(&q, &last, settings, n, &mut rng);
    phases.push(report);
    if last.len() == n {
        for f in &mut flags {
            *f |= phase_flag::C;
        }
    } else {
        for &p in &last {
            flags[p] |= phase_flag::C;
        }
    }
    let candidates = scored
        .candidates
        .take()
        .unwrap_or_else(|| (0..scored.mass.len()).collect());
    let candidate_mass: Vec<f64> = candidates
        .iter()
        .map(|&i| scored.mass.get(i).copied().unwrap_or(f64::NEG_INFINITY))
        .collect();
    let best_mass = lanes::max_or(&candidate_mass, f64::NEG_INFINITY);
    let map_slot = candidates
        .iter()
        .zip(&candidate_mass)
        .find(|&(_, m)| m.total_cmp(&best_mass).is_eq())
        .map_or(0, |(&i, _)| i);
    // Only points near the best carry mass; listing them first keeps
    // `exp` off the rest (a branch around `exp` in a loop over every point
    // is compiled into an unconditional call, slow for large negative
    // arguments). Each is written, and kept where near (no branch on the
    // data), with its log-mass relative to the best.
    let (mut near, mut relative) = (vec![0; candidates.len()], vec![0.0; candidates.len()]);
    let mut count = 0;
    for (&i, &m) in candidates.iter().zip(&candidate_mass) {
        if let (Some(slot), Some(r)) = (near.get_mut(count), relative.get_mut(count)) {
            *slot = i;
            *r = m - best_mass;
        }
        count += usize::from(m >= best_mass + NEGLIGIBLE_LOG_MASS);
    }
    near.truncate(count);
    relative.truncate(count);
    // Relative masses with the branch-free `exp` (one vectorised loop).
    let weights: Vec<f64> = widest(ExpKernel(&relative));
    // Summed in order (eight running sums round differently, and some
    // frames' rival regions are decided within rounding: the static
    // example's medians over surface seeds moved by up to 4 mm).
    let weight_sum: f64 = weights.iter().sum();
    let total = best_mass + weight_sum.ln();
    // The smallest residual is among the likeliest points (exact mode:
    // the profile's, at the same magnitude).
    let residual_of = |i: usize| match (last.get(i), scored.mass.get(i), scored.force.get(i)) {
        (Some(&k), Some(m), Some(&f)) if m.is_finite() => {
            scored.residual.get(i).copied().unwrap_or_else(|| q.residual(k, f))
        }
        _ => f64::INFINITY,
    };
    let residuals: Vec<f64> = near.iter().map(|&i| residual_of(i)).collect();
    let best_residual_chi2 = lanes::min_or(&residuals, f64::INFINITY);
    let (probability, display, support) = spread_mass(&scored, &last, &near, &weights, (weight_sum, total), n);
    let (log_likelihood, force_newtons) = if last.len() == n {
        // A full search scores every point in order: no scatter needed.
        (scored.mass, scored.force)
    } else {
        let (mut l, mut f) = (vec![f64::NEG_INFINITY; n], vec![0.0; n]);
        for ((&k, &mass), &force) in last.iter().zip(&scored.mass).zip(&scored.force) {
            l[k] = mass;
            f[k] = force;
        }
        (l, f)
    };
    Ok(Posterior {
        probability,
        display,
        log_likelihood,
        force_newtons,
        phases,
        phase_flags: flags,
        support,
        map_point: last.get(map_slot).copied().unwrap_or(0),
        best_residual_chi2,
        no_contact_chi2,
    })
}

/// Per surface point: probability (a near point's weight over the sum of
/// the weights, 0 below e^-60 of the total), the value shown (the same in
/// exact mode, the best particle's otherwise) and the points with either.
/// `near[i]` is the slot of `weights[i]`; `last[slot]` its point.
fn spread_mass(
    scored: &Scores,
    last: &[usize],
    near: &[usize],
    weights: &[f64],
    (weight_sum, total): (f64, f64),
    n: usize,
) -> (Vec<f64>, Vec<f64>, Vec<usize>) {
    // In exact mode the value shown is the probability: copied once at
    // the end instead of written beside it point by point.
    let exact = scored.best.is_empty();
    let mut probability = vec![0.0; n];
    let mut display = if exact { Vec::new() } else { vec![0.0; n] };
    let mut support = vec![0; near.len()];
    let mut count = 0;
    for (&i, &weight) in near.iter().zip(weights) {
        let (Some(&k), Some(&mass)) = (last.get(i), scored.mass.get(i)) else {
            continue;
        };
        let p = if mass - total < NEGLIGIBLE_LOG_MASS {
            0.0
        } else {
            weight / weight_sum
        };
        let shown = if exact { p } else { exp_or_zero(scored.best(i) - total) };
        if let Some(pk) = probability.get_mut(k) {
            *pk = p;
        }
        if let Some(dk) = display.get_mut(k) {
            *dk = shown;
        }
        // Written always, kept where it carries mass: no branch to miss.
        if let Some(slot) = support.get_mut(count) {
            *slot = k;
        }
        count += usize::from(p > 0.0 || shown > 0.0);
    }
    if exact {
        display.clone_from(&probability);
    }
    support.truncate(count);
    // `last` is in index order already; this keeps the promise if that changes.
    if !support.is_sorted() {
        support.sort_unstable();
    }
    (probability, display, support)
}

/// Each point's likelihood terms: patch-integrated in exact mode when the
/// source knows patches (`true` and the per-point `c`, normaliser and
/// volumes in [`PatchTerms`]), else the plain `a`, `b` of a point.
fn likelihood_terms(
    model: &impl UnitTorqueSource,
    tau: &[f64],
    settings: &EstimatorSettings,
    weights: &[f64],
    c: f64,
    forms_out: Option<&mut PatchForms>,
) -> (bool, Vec<f64>, Vec<f64>, PatchTerms) {
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let mut forms = PatchForms::default();
    let mut terms = PatchTerms::default();
    let patches = settings.patches
        && settings.mode == Mode::Exact
        && model.patch_forms(weights, tau, &mut forms)
        && forms.a.len() == model.points();
    if patches {
        let range = (settings.force_min_newtons, settings.force_max_newtons);
        patch_terms(&forms, c, range, &mut terms);
        a = std::mem::take(&mut terms.a);
        b = std::mem::take(&mut terms.b);
        if let Some(out) = forms_out {
            *out = forms;
        }
    } else {
        model.quadratic_forms(weights, tau, &mut a, &mut b);
        if let Some(out) = forms_out {
            *out = PatchForms::default();
        }
    }
    (patches, a, b, terms)
}

/// Runs phases A and B (when asked for) and returns the points of the
/// last phase, marking phase membership in `flags`.
fn search_phases(
    q: &Quadratic,
    settings: &EstimatorSettings,
    hierarchy: Option<&PhaseHierarchy>,
    n: usize,
    rng: &mut Rng,
    flags: &mut [u8],
    phases: &mut Vec<PhaseReport>,
) -> Result<Vec<usize>, EstimateError> {
    Ok(match (settings.phase_alpha, hierarchy) {
        (None, _) => (0..n).collect(),
        (Some(_), None) => return Err(EstimateError::NoHierarchy),
        (Some(alpha), Some(h)) => {
            if h.b_of_point.len() != n {
                return Err(EstimateError::NoHierarchy);
            }
            let keep = |points: &[usize], scored: &Scores| {
                let best = (0..points.len())
                    .map(|i| scored.best(i))
                    .fold(f64::NEG_INFINITY, f64::max);
                points
                    .iter()
                    .enumerate()
                    .filter(|(i, _)| scored.best(*i) >= best + alpha.ln())
                    .map(|(_, p)| *p)
                    .collect::<Vec<usize>>()
            };
            let (scored_a, report) = evaluate(q, &h.a_points, settings, n, rng);
            phases.push(report);
            for &p in &h.a_points {
                flags[p] |= phase_flag::A;
            }
            let kept_a: std::collections::HashSet<usize> = keep(&h.a_points, &scored_a)
                .iter()
                .filter_map(|p| h.a_points.iter().position(|x| x == p))
                .collect();
            let b_set: Vec<usize> = (0..h.b_points.len())
                .filter(|&bi| kept_a.contains(&h.a_of_b[bi]))
                .map(|bi| h.b_points[bi])
                .collect();
            let (scored_b, report) = evaluate(q, &b_set, settings, n, rng);
            phases.push(report);
            for &p in &b_set {
                flags[p] |= phase_flag::B;
            }
            let kept_b: std::collections::HashSet<usize> =
                keep(&b_set, &scored_b).iter().map(|p| h.b_of_point[*p]).collect();
            (0..n).filter(|p| kept_b.contains(&h.b_of_point[*p])).collect()
        }
    })
}

/// Each point's likelihood integrated over its patch, as an equivalent
/// quadratic in the push magnitude f: `ln L(f) = norm - ½ (c - 2 b f + a f²)`.
///
/// Within its patch a point's torque per newton is `u + D s` (`s` the
/// offset along the two tangents, m; [`PatchForms`]), and the patch is a
/// Gaussian window of width ρ around the point. With `g = f s` the
/// likelihood is Gaussian in `(f, g)`, and so is the window once its
/// width in `g`, `f ρ`, is taken at the point's best magnitude `f₀`:
/// integrating `g` out leaves, with `Q = G + I/(f₀ρ)²`,
/// `a' = a - hᵀQ⁻¹h`, `b' = b - hᵀQ⁻¹e`, `c' = c - eᵀQ⁻¹e` and the
/// normaliser `ln A - ½ ln det(I + f₀²ρ² G)`. A peak far narrower than
/// the patch then counts with its whole mass (times the window at its
/// place), a broad one as the value at the point times the area, and the
/// windows of evenly spread points add up to one, so the masses are those
/// of the continuous surface whatever the sampling (as N grows they tend
/// to the plain values at the points).
pub fn patch_terms(forms: &PatchForms, c: f64, range: (f64, f64), out: &mut PatchTerms) {
    widest(PatchTermsKernel(forms, c, range, out));
}

/// [`patch_terms`]' work, inlined into [`widest`].
#[inline(always)]
fn patch_terms_inner(forms: &PatchForms, c: f64, (f_min, f_max): (f64, f64), out: &mut PatchTerms) {
    let n = forms.a.len();
    for v in [&mut out.a, &mut out.b, &mut out.c, &mut out.volume] {
        v.clear();
        v.resize(n, 0.0);
    }
    out.norm.clear();
    out.norm.extend_from_slice(&forms.ln_area);
    out.norm.resize(n, 0.0);
    let f = forms;
    // Equal lengths up front, so that the loop runs without bounds checks
    // and vectorises (no branches, divisions only).
    let (a_in, b_in, h1, h2) = (
        &f.a[..n],
        &f.b[..n.min(f.b.len())],
        &f.h1[..n.min(f.h1.len())],
        &f.h2[..n.min(f.h2.len())],
    );
    let (e1, e2, g11) = (
        &f.e1[..n.min(f.e1.len())],
        &f.e2[..n.min(f.e2.len())],
        &f.g11[..n.min(f.g11.len())],
    );
    let (g12, g22, rho) = (
        &f.g12[..n.min(f.g12.len())],
        &f.g22[..n.min(f.g22.len())],
        &f.window_m[..n.min(f.window_m.len())],
    );
    let m = [
        b_in.len(),
        h1.len(),
        h2.len(),
        e1.len(),
        e2.len(),
        g11.len(),
        g12.len(),
        g22.len(),
        rho.len(),
    ]
    .into_iter()
    .min()
    .unwrap_or(0);
    let (a_out, b_out, c_out, v_out) = (&mut out.a[..m], &mut out.b[..m], &mut out.c[..m], &mut out.volume[..m]);
    for k in 0..m {
        let (ak, bk) = (a_in[k], b_in[k]);
        // f₀: the point's own best magnitude.
        let q0 = bk / ak.max(f64::MIN_POSITIVE);
        let q0 = if q0 > f_min { q0 } else { f_min };
        let f0 = if q0 < f_max { q0 } else { f_max };
        let width = (f0 * rho[k]).max(1e-150);
        let q = 1.0 / (width * width);
        let (q11, q22) = (g11[k] + q, g22[k] + q);
        let det = q11 * q22 - g12[k] * g12[k];
        let det = if det > q * q { det } else { q * q };
        let inv = 1.0 / det;
        let (i11, i12, i22) = (q22 * inv, -g12[k] * inv, q11 * inv);
        let (x1, x2) = (h1[k], h2[k]);
        let (y1, y2) = (e1[k], e2[k]);
        let hh = x1 * (i11 * x1 + i12 * x2) + x2 * (i12 * x1 + i22 * x2);
        let he = x1 * (i11 * y1 + i12 * y2) + x2 * (i12 * y1 + i22 * y2);
        let ee = y1 * (i11 * y1 + i12 * y2) + y2 * (i12 * y1 + i22 * y2);
        let a1 = ak - hh;
        a_out[k] = if a1 > 0.0 { a1 } else { 0.0 };
        b_out[k] = bk - he;
        c_out[k] = c - ee;
        v_out[k] = det * width * width * width * width;
    }
}

/// [`patch_terms`]'s output: per point the equivalent quadratic in f
/// (`a`, `b`, `c`), the normaliser `ln A`, and the patch volume
/// `det(I + f₀²ρ² G)` whose `-½ ln` completes the normaliser.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PatchTerms {
    /// `a'`.
    pub a: Vec<f64>,
    /// `b'`.
    pub b: Vec<f64>,
    /// `c'`.
    pub c: Vec<f64>,
    /// `ln A`.
    pub norm: Vec<f64>,
    /// `det(I + f₀²ρ² G)`.
    pub volume: Vec<f64>,
}

/// ln of the patch-integrated likelihood of one point's [`PatchForms`]
/// (every array of length 1), averaged over the magnitude range: what
/// [`estimate`] gives such a point before normalising. `c` is `Σ τ²/σ²`.
#[must_use]
pub fn patch_log_evidence(forms: &PatchForms, c: f64, (f_min, f_max): (f64, f64)) -> f64 {
    let mut t = PatchTerms::default();
    patch_terms(forms, c, (f_min, f_max), &mut t);
    if t.a.is_empty() {
        return f64::NEG_INFINITY;
    }
    let q = Quadratic {
        a: &t.a,
        b: &t.b,
        c,
        per_point: Some((&t.c, &t.norm)),
        volume: Some(&t.volume),
        f_min,
        f_max,
    };
    let f = if t.a[0] > 0.0 {
        (t.b[0] / t.a[0]).clamp(f_min, f_max)
    } else {
        f_min
    };
    q.log_evidence(0, q.log_likelihood(0, f))
}

/// [`patch_terms_inner`] as a [`Kernel`].
struct PatchTermsKernel<'a>(&'a PatchForms, f64, (f64, f64), &'a mut PatchTerms);

impl Kernel for PatchTermsKernel<'_> {
    type Output = ();
    #[inline(always)]
    fn run(self) {
        patch_terms_inner(self.0, self.1, self.2, self.3);
    }
}

/// `exp` of every value, as a [`Kernel`].
struct ExpKernel<'a>(&'a [f64]);

impl Kernel for ExpKernel<'_> {
    type Output = Vec<f64>;
    #[inline(always)]
    fn run(self) -> Vec<f64> {
        let mut out = vec![0.0; self.0.len()];
        for (o, &x) in out.iter_mut().zip(self.0) {
            *o = fastmath::exp(x);
        }
        out
    }
}

/// Scores the points of one phase.
fn evaluate(
    q: &Quadratic,
    points: &[usize],
    settings: &EstimatorSettings,
    surface_points: usize,
    rng: &mut Rng,
) -> (Scores, PhaseReport) {
    let range = q.f_max - q.f_min;
    match settings.mode {
        Mode::Exact => {
            let scores = q.exact_scores(points, surface_points);
            let report = PhaseReport {
                points: points.len(),
                particles: points.len(),
            };
            (scores, report)
        }
        Mode::Particles(ParticleSettings {
            sampling: Sampling::Deterministic {
                magnitudes_per_point: m,
            },
        }) => {
            let mut scores = Scores::unscored(points.len(), q.f_min);
            for (i, &k) in points.iter().enumerate() {
                for step in 1..=m {
                    let f = q.f_min + step as f64 * range / m as f64;
                    scores.add_particle(i, q.log_likelihood(k, f), f);
                }
            }
            let report = PhaseReport {
                points: points.len(),
                particles: m * points.len(),
            };
            (scores, report)
        }
        Mode::Particles(ParticleSettings {
            sampling: Sampling::Random { count, .. },
        }) => {
            // The phase's share of the N particles, at least one per point.
            let draws = (count * points.len())
                .div_ceil(surface_points)
                .max(points.len().min(count));
            let mut scores = Scores::unscored(points.len(), 0.0);
            for _ in 0..draws {
                let slot = rng.below(points.len());
                let f = rng.uniform_in(q.f_min, q.f_max);
                scores.add_particle(slot, q.log_likelihood(points[slot], f), f);
            }
            let report = PhaseReport {
                points: points.len(),
                particles: draws,
            };
            (scores, report)
        }
    }
}

#[cfg(test)]
#[path = "posterior_tests.rs"]
mod tests;
