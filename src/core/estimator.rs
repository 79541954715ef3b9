//! The contact estimator: a posterior over surface points from measured
//! joint torques (thesis eq. 2.3–2.6), in exact mode (ours) or with the
//! thesis' particles, optionally coarse-to-fine in phases A/B/C.

use rayon::prelude::*;

use crate::core::contact::{PARALLEL_MIN_POINTS, PatchForms, UnitTorqueSource};
use crate::core::fastmath::{self, ErfTable};
use crate::core::lanes;
use crate::core::phases::PhaseHierarchy;
use crate::core::rng::Rng;
use crate::core::simd::{Kernel, widest};
use crate::core::special::ln_erf_difference;

/// How the magnitude of the push is handled.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Mode {
    /// Per point, the likelihood integrated over a uniform magnitude in
    /// `[F_min, F_max]` in closed form; N is the number of surface points.
    Exact,
    /// The thesis' particles: (point, magnitude) pairs.
    Particles(ParticleSettings),
}

/// How particles are drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Sampling {
    /// `m` magnitudes per point, `F_k = F_min + k (F_max - F_min) / m`,
    /// `k = 1..m` (eq. 2.10).
    Deterministic {
        /// Magnitudes per point.
        magnitudes_per_point: usize,
    },
    /// `count` particles, each a uniformly chosen point and a uniform
    /// magnitude (§3.1.1–3.1.2).
    Random {
        /// Number of particles N over the whole surface.
        count: usize,
        /// Seed.
        seed: u64,
    },
}

/// Particle-mode settings.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ParticleSettings {
    /// How particles are drawn.
    pub sampling: Sampling,
}

/// Everything but the measurement and the surface.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorSettings {
    /// Standard deviation of each joint's torque noise, N·m (one per sensed joint).
    pub sigma: Vec<f64>,
    /// Smallest push magnitude considered, N.
    pub force_min_newtons: f64,
    /// Largest push magnitude considered, N.
    pub force_max_newtons: f64,
    /// Exact or particles.
    pub mode: Mode,
    /// Phases A/B/C with this α (keep clusters with P ≥ α `P_max`; 0 keeps
    /// every cluster, the limit α → 0); `None` searches every point.
    pub phase_alpha: Option<f64>,
    /// Exact mode (ours): each surface point stands for the patch of
    /// surface around it, and its mass is the likelihood integrated over
    /// that patch (see [`patch_terms`]) rather than taken at the point.
    /// `false` is the thesis' model (a point is a point); particle modes
    /// ignore it.
    pub patches: bool,
    /// μ of the friction model ([`crate::core::friction`]): the spread of
    /// the tangential force per newton of push, per tangent direction.
    /// 0: frictionless. The refined contact uses it: a frame's own
    /// refinement searches the surface for the place that the friction
    /// model explains best and reports its force and fit; under a temporal
    /// model (whose place is the whole recording's) the force and fit at
    /// that place. The posterior over the samples is the frictionless one.
    pub friction: f64,
}

/// The push magnitudes considered unless asked otherwise, N: the command
/// line's `--fmin`/`--fmax` defaults.
pub const DEFAULT_FORCE_RANGE_NEWTONS: (f64, f64) = (1.0, 30.0);

impl EstimatorSettings {
    /// `1/σ²` per sensed joint: the weights of the likelihood's metric.
    #[must_use]
    pub fn weights(&self) -> Vec<f64> {
        self.sigma.iter().map(|s| 1.0 / (s * s)).collect()
    }

    /// Exact mode with patches over every sample, the default force range,
    /// frictionless, with torque noise `sigma` per sensed joint: what the
    /// command line estimates with unless told otherwise. Vary a field
    /// with `EstimatorSettings { friction, ..EstimatorSettings::exact(σ) }`.
    #[must_use]
    pub fn exact(sigma: Vec<f64>) -> Self {
        let (force_min_newtons, force_max_newtons) = DEFAULT_FORCE_RANGE_NEWTONS;
        Self {
            sigma,
            force_min_newtons,
            force_max_newtons,
            mode: Mode::Exact,
            phase_alpha: None,
            patches: true,
            friction: 0.0,
        }
    }
}

/// Why an estimate cannot be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum EstimateError {
    /// The torque vector does not match the sensed joints.
    #[error("expected {expected} torques (one per sensed joint), got {got}")]
    WrongTorqueCount {
        /// Sensed joints.
        expected: usize,
        /// Torques given.
        got: usize,
    },
    /// A measured torque is NaN or infinite.
    #[error("the torque of joint {joint} is {value}, not a finite number")]
    NonFiniteTorque {
        /// Joint index (0-based, sensed order).
        joint: usize,
        /// The value.
        value: f64,
    },
    /// The estimate came out with a number that is not finite: the
    /// inputs are beyond what the arithmetic can carry (e.g. a σ far
    /// below the torques' own precision). Nothing is reported for it.
    #[error(
        "the estimate's {field} is not a finite number: the torques and σ are beyond what can be computed (check their units, and that σ is within its range)"
    )]
    NonFiniteEstimate {
        /// The output field, as the estimate's JSON names it.
        field: &'static str,
    },
    /// The σ vector does not match the sensed joints.
    #[error("expected {expected} values of sigma (one per sensed joint), got {got}")]
    WrongSigmaCount {
        /// Sensed joints.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A σ that is not a positive finite number.
    #[error("sigma of joint {joint} is {value}; it must be a positive number of N·m")]
    BadSigma {
        /// Joint index (0-based).
        joint: usize,
        /// The value.
        value: f64,
    },
    /// An empty or non-finite force range.
    #[error("the force range [{min}, {max}] N is invalid: it needs 0 ≤ F_min ≤ F_max, both finite")]
    BadForceRange {
        /// `F_min`.
        min: f64,
        /// `F_max`.
        max: f64,
    },
    /// α outside [0, 1).
    #[error("alpha is {alpha}; it must lie in [0, 1)")]
    BadAlpha {
        /// The value.
        alpha: f64,
    },
    /// A friction μ that is negative or not a number.
    #[error("friction is {friction}; it must be a finite number ≥ 0 (0: frictionless)")]
    BadFriction {
        /// The value.
        friction: f64,
    },
    /// Phases asked for without a hierarchy, or a hierarchy of another surface.
    #[error("phases A/B/C need a phase hierarchy built on this surface")]
    NoHierarchy,
    /// A surface without points.
    #[error("there are no candidate points")]
    NoCandidates,
    /// Torques so large against σ that their squares overflow.
    #[error(
        "the torques are {chi2:e} times σ² in sum: beyond what can be computed (at most {MAX_CHI2:e}); check their units and σ"
    )]
    TooLarge {
        /// `Σ τ²/σ²`.
        chi2: f64,
    },
    /// More particles than [`MAX_PARTICLES`] (or more than
    /// [`MAX_MAGNITUDES`] per point).
    #[error(
        "{particles} particles asked for: at most {MAX_PARTICLES} in all and {MAX_MAGNITUDES} magnitudes per point are evaluated"
    )]
    TooManyParticles {
        /// Particles asked for.
        particles: usize,
    },
    /// Particle mode with zero particles.
    #[error("particle mode needs at least one particle")]
    NoParticles,
}

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

/// Points whose profile log-likelihood is this far below the best get the
/// profile value instead of the erf form: their posterior mass is below
/// e^-50 of the best either way.
const FAR_BELOW: f64 = 60.0;

/// The per-measurement quantities of a point: `a = Σ w u²`, `b = Σ w u τ`,
/// `c = Σ w τ²` with `w = 1/σ²` (per point once the resolution noise is
/// added), and `norm`, the point's share of the Gaussian normaliser
/// relative to the bare noise model.
/// Per-point `c` and normaliser arrays.
type PerPoint<'a> = (&'a [f64], &'a [f64]);

struct Quadratic<'a> {
    a: &'a [f64],
    b: &'a [f64],
    /// `c` shared by every point (the bare noise model)…
    c: f64,
    /// …or one per point, with its normaliser (patches).
    per_point: Option<PerPoint<'a>>,
    /// Per-point patch volumes (`det(I + f₀²ρ² G) ≥ 1`, see
    /// [`patch_terms`]), when patches are used: the normaliser's `-½ ln`
    /// of it is left out of profiles (which stay upper bounds) and added
    /// where the evidence is computed.
    volume: Option<&'a [f64]>,
    f_min: f64,
    f_max: f64,
}

impl Quadratic<'_> {
    /// Best magnitude in range at point k (the tests' reference for
    /// [`profile_chunk`]).
    #[cfg(test)]
    fn best_force(&self, k: usize) -> f64 {
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
    fn log_likelihood(&self, k: usize, f: f64) -> f64 {
        let (_, norm) = self.c_norm(k);
        norm - 0.5 * self.residual(k, f)
    }

    /// `Σ w (τ - f u)²` at point k.
    #[inline]
    fn residual(&self, k: usize, f: f64) -> f64 {
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
    fn exact_scores(&self, points: &[usize], surface_points: usize) -> Scores {
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
    /// difference, `ln` and `exp` of [`crate::core::fastmath`] (absolute
    /// error below 1e-9) in one loop over gathered arrays, which
    /// vectorises; the rare points that would cancel there (a range narrow
    /// against the likelihood's width in f) take the careful path after.
    fn log_evidence_many(&self, points: &[usize], slots: &[usize], profile: &[f64]) -> Vec<f64> {
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
    fn log_evidence(&self, k: usize, profile: f64) -> f64 {
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
    force: Vec<f64>,
    mass: Vec<f64>,
    residual: Vec<f64>,
    best: f64,
}

/// Per evaluated point (one array each, so that the exact mode's loops
/// vectorise): the score that sums (ln mass), the score a heatmap shows
/// (ln of the best particle), and the best magnitude.
struct Scores {
    mass: Vec<f64>,
    /// Empty where each point's best is its mass (exact mode).
    best: Vec<f64>,
    force: Vec<f64>,
    /// `Σ w (τ - f u)²` at each slot's `force` (exact mode, where the
    /// profile computed it anyway); empty otherwise.
    residual: Vec<f64>,
    /// The slots that may hold mass, in order (every other slot is below
    /// e^-60 of the best); `None`: any slot may.
    candidates: Option<Vec<usize>>,
}

impl Scores {
    /// `len` points, none scored yet.
    fn unscored(len: usize, force: f64) -> Self {
        Self {
            mass: vec![f64::NEG_INFINITY; len],
            best: vec![f64::NEG_INFINITY; len],
            force: vec![force; len],
            residual: Vec::new(),
            candidates: None,
        }
    }

    /// Slot i's heatmap score.
    fn best(&self, i: usize) -> f64 {
        self.best
            .get(i)
            .or(self.mass.get(i))
            .copied()
            .unwrap_or(f64::NEG_INFINITY)
    }

    /// Adds a particle of log-likelihood `l` and magnitude `f` to slot `i`.
    fn add_particle(&mut self, i: usize, l: f64, f: f64) {
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

fn validate(model: &impl UnitTorqueSource, tau: &[f64], settings: &EstimatorSettings) -> Result<(), EstimateError> {
    let joints = model.joints();
    if tau.len() != joints {
        return Err(EstimateError::WrongTorqueCount {
            expected: joints,
            got: tau.len(),
        });
    }
    if let Some((joint, &value)) = tau.iter().enumerate().find(|(_, t)| !t.is_finite()) {
        return Err(EstimateError::NonFiniteTorque { joint, value });
    }
    if settings.sigma.len() != joints {
        return Err(EstimateError::WrongSigmaCount {
            expected: joints,
            got: settings.sigma.len(),
        });
    }
    if let Some((joint, &value)) = settings
        .sigma
        .iter()
        .enumerate()
        .find(|(_, s)| !(s.is_finite() && **s > 0.0))
    {
        return Err(EstimateError::BadSigma { joint, value });
    }
    let scaled = tau
        .iter()
        .zip(&settings.sigma)
        .map(|(t, s)| (t / s).powi(2))
        .sum::<f64>();
    if scaled.is_nan() || scaled > MAX_CHI2 {
        return Err(EstimateError::TooLarge { chi2: scaled });
    }
    let (min, max) = (settings.force_min_newtons, settings.force_max_newtons);
    if !(min.is_finite() && max.is_finite() && min >= 0.0 && min <= max) {
        return Err(EstimateError::BadForceRange { min, max });
    }
    if let Some(alpha) = settings.phase_alpha
        && !(0.0..1.0).contains(&alpha)
    {
        return Err(EstimateError::BadAlpha { alpha });
    }
    if !(settings.friction.is_finite() && settings.friction >= 0.0) {
        return Err(EstimateError::BadFriction {
            friction: settings.friction,
        });
    }
    if model.points() == 0 {
        return Err(EstimateError::NoCandidates);
    }
    match settings.mode {
        Mode::Particles(ParticleSettings {
            sampling:
                Sampling::Deterministic {
                    magnitudes_per_point: 0,
                }
                | Sampling::Random { count: 0, .. },
        }) => Err(EstimateError::NoParticles),
        Mode::Particles(ParticleSettings {
            sampling: Sampling::Deterministic {
                magnitudes_per_point: m,
            },
        }) if m > MAX_MAGNITUDES || m.saturating_mul(model.points()) > MAX_PARTICLES => {
            Err(EstimateError::TooManyParticles {
                particles: m.saturating_mul(model.points()),
            })
        }
        Mode::Particles(ParticleSettings {
            sampling: Sampling::Random { count, .. },
        }) if count > MAX_PARTICLES => Err(EstimateError::TooManyParticles { particles: count }),
        _ => Ok(()),
    }
}

/// The most particles an update evaluates (about a second's work).
pub const MAX_PARTICLES: usize = 10_000_000;

/// The most magnitudes per point of deterministic particles.
pub const MAX_MAGNITUDES: usize = 1000;

/// The largest `Σ τ²/σ²` the estimator takes: torques of 1e8 σ, beyond
/// what any torque sensor resolves (a 24-bit converter has 1.7e7 steps),
/// so a frame beyond it has torques in the wrong unit or a σ below the
/// sensor's own. Within it every kernel keeps its tolerances (offsets,
/// evidence and smoothing were tested finite at sums of 1e24).
pub const MAX_CHI2: f64 = 1e16;

/// From this many near-best points on, their evidence takes the
/// branch-free path…
const FAST_EVIDENCE_MIN: usize = 64;

/// …up to this many, beyond which threads share the careful one.
const PARALLEL_MIN_EVIDENCE_FAST: usize = 1 << 20;

/// From this many near-best points on, their evidence is shared among
/// threads.
const PARALLEL_MIN_EVIDENCE: usize = 512;

/// [`Quadratic::log_evidence_many_inner`] as a [`Kernel`].
struct EvidenceKernel<'a>(&'a Quadratic<'a>, &'a [usize], &'a [usize], &'a [f64]);

impl Kernel for EvidenceKernel<'_> {
    type Output = Vec<f64>;
    #[inline(always)]
    fn run(self) -> Vec<f64> {
        self.0.log_evidence_many_inner(self.1, self.2, self.3)
    }
}

/// [`profile_chunk`] as a [`Kernel`].
struct ProfileKernel<'a>(
    &'a [f64],
    &'a [f64],
    Shared<'a>,
    (f64, f64),
    &'a mut [f64],
    &'a mut [f64],
    &'a mut [f64],
);

impl Kernel for ProfileKernel<'_> {
    type Output = f64;
    #[inline(always)]
    fn run(self) -> f64 {
        let Self(a, b, c, (f_min, f_max), force, mass, residual) = self;
        profile_chunk(a, b, c, (f_min, f_max), force, mass, residual)
    }
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

/// The `c` and normaliser of a chunk of points.
#[derive(Clone, Copy)]
enum Shared<'a> {
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
const NEGLIGIBLE_LOG_MASS: f64 = -60.0;

/// `e^x`, or 0 where that is negligible.
fn exp_or_zero(x: f64) -> f64 {
    if x < NEGLIGIBLE_LOG_MASS { 0.0 } else { fastmath::exp(x) }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::builtin;
    use crate::core::contact::ContactModel;
    use crate::core::kinematics::RobotPose;
    use crate::core::robot::Robot;
    use crate::core::summary::{Verdict, summarize};
    use crate::core::surface::{Surface, SurfaceRequest};
    use crate::core::torque::{TorqueModel, joint_torques, with_sensor_noise};
    use glam::DVec3;

    /// Simpson's rule on the likelihood over f, normalised by the range.
    fn numeric_log_evidence(a: f64, b: f64, c: f64, f_min: f64, f_max: f64) -> f64 {
        let n = 20_000;
        let h = (f_max - f_min) / f64::from(n);
        let l = |f: f64| -0.5 * (c - 2.0 * b * f + a * f * f);
        let peak = (0..=n)
            .map(|i| l(f_min + f64::from(i) * h))
            .fold(f64::NEG_INFINITY, f64::max);
        let mut sum = 0.0;
        for i in 0..=n {
            let w = if i == 0 || i == n {
                1.0
            } else if i % 2 == 1 {
                4.0
            } else {
                2.0
            };
            sum += w * (l(f_min + f64::from(i) * h) - peak).exp();
        }
        peak + (sum * h / 3.0).ln() - (f_max - f_min).ln()
    }

    #[test]
    fn exact_evidence_matches_numerical_integration() {
        let cases = [
            (4.0, 20.0, 120.0, 1.0, 30.0),       // peak inside the range
            (4.0, -20.0, 120.0, 1.0, 30.0),      // peak below the range
            (0.5, 40.0, 5000.0, 1.0, 30.0),      // peak above the range
            (1e-16, 1e-9, 3.0, 1.0, 30.0),       // the point makes no torque: e^{-c/2}
            (900.0, 9000.0, 90_100.0, 0.5, 3.0), // narrow peak far above the range
        ];
        for (a, b, c, f_min, f_max) in cases {
            let (av, bv) = (vec![a], vec![b]);
            let q = Quadratic {
                a: &av,
                b: &bv,
                c,
                per_point: None,
                volume: None,
                f_min,
                f_max,
            };
            let f = q.best_force(0);
            let exact = q.log_evidence(0, q.log_likelihood(0, f));
            let numeric = numeric_log_evidence(a, b, c, f_min, f_max);
            assert!(
                (exact - numeric).abs() < 1e-6 * numeric.abs().max(1.0),
                "{a} {b} {c}: {exact} vs {numeric}"
            );
        }
        // F_min = F_max: the likelihood at that magnitude.
        let (av, bv) = (vec![2.0], vec![3.0]);
        let q = Quadratic {
            a: &av,
            b: &bv,
            c: 10.0,
            per_point: None,
            volume: None,
            f_min: 2.0,
            f_max: 2.0,
        };
        let f = q.best_force(0);
        assert!((q.log_evidence(0, q.log_likelihood(0, f)) - (-0.5 * (10.0 - 12.0 + 8.0))).abs() < 1e-15);
    }

    /// The batched evidence against the careful one, one point at a time,
    /// over peaks below, inside and above the range, wide and narrow
    /// (every kind of interval the batch sorts them into), with and
    /// without patch volumes.
    #[test]
    fn batched_evidence_matches_the_careful_one_within_1e_9() {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for i in 0..40 {
            let width = 10f64.powf(-3.0 + 0.15 * f64::from(i)); // √(1/a): 1e-3 … 1e3 N
            for j in -20..=80 {
                let mu = 0.5 * f64::from(j); // peak from -10 to 40 N, range [1, 30]
                let a_k = 1.0 / (width * width);
                a.push(a_k);
                b.push(a_k * mu);
            }
        }
        let n = a.len();
        // Each point's own c: a residual of 3 at its peak, so that points
        // peaking in the range have values near 0 (the bound is absolute
        // there; relative for the far-below values of the others).
        let c: Vec<f64> = b.iter().zip(&a).map(|(b, a)| b * b / a + 3.0).collect();
        let norm = vec![0.0; n];
        let volume: Vec<f64> = (0..n).map(|k| 1.0 + (k % 7) as f64).collect();
        for volume in [None, Some(volume.as_slice())] {
            let q = Quadratic {
                a: &a,
                b: &b,
                c: 0.0,
                per_point: Some((&c, &norm)),
                volume,
                f_min: 1.0,
                f_max: 30.0,
            };
            let points: Vec<usize> = (0..n).collect();
            let profile: Vec<f64> = points.iter().map(|&k| q.log_likelihood(k, q.best_force(k))).collect();
            let batched = q.log_evidence_many(&points, &points, &profile);
            // The copy for the CPU's widest vector unit computes what the
            // baseline code does, bit for bit.
            let baseline = EvidenceKernel(&q, &points, &points, &profile).run();
            assert!(batched.iter().zip(&baseline).all(|(x, y)| x.to_bits() == y.to_bits()));
            for k in 0..n {
                let careful = q.log_evidence(k, profile[k]);
                assert!(
                    (batched[k] - careful).abs() < 1e-9 * careful.abs().max(1.0),
                    "a {} b {}: {} vs {careful}",
                    a[k],
                    b[k],
                    batched[k]
                );
            }
        }
    }

    /// The patch terms and profiles run in the copy for the widest vector
    /// unit: bit for bit what the baseline code computes.
    #[test]
    fn the_wide_loops_match_the_baseline_bit_for_bit() {
        let n = 1001;
        let forms = PatchForms::random(5, n, 0.0, 1e3);
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        let (mut wide, mut baseline) = (PatchTerms::default(), PatchTerms::default());
        patch_terms(&forms, 50.0, (1.0, 30.0), &mut wide);
        PatchTermsKernel(&forms, 50.0, (1.0, 30.0), &mut baseline).run();
        for (x, y) in [
            (&wide.a, &baseline.a),
            (&wide.b, &baseline.b),
            (&wide.c, &baseline.c),
            (&wide.volume, &baseline.volume),
        ] {
            assert_eq!(bits(x), bits(y));
        }
        let (mut force, mut mass, mut residual) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let (mut force_base, mut mass_base, mut residual_base) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        let shared = Shared::PerPoint(&wide.c, &wide.norm);
        let best = widest(ProfileKernel(
            &wide.a,
            &wide.b,
            shared,
            (1.0, 30.0),
            &mut force,
            &mut mass,
            &mut residual,
        ));
        let best_base = ProfileKernel(
            &wide.a,
            &wide.b,
            shared,
            (1.0, 30.0),
            &mut force_base,
            &mut mass_base,
            &mut residual_base,
        )
        .run();
        assert_eq!(best.to_bits(), best_base.to_bits());
        assert_eq!(bits(&force), bits(&force_base));
        assert_eq!(bits(&mass), bits(&mass_base));
        assert_eq!(bits(&residual), bits(&residual_base));
        let relative: Vec<f64> = mass.iter().map(|m| m - best).collect();
        assert_eq!(bits(&widest(ExpKernel(&relative))), bits(&ExpKernel(&relative).run()));
    }

    /// The patch formula against brute-force integration: the window
    /// `N(s; 0, ρ²)` over the tangent plane (a 2-D grid) and f over the
    /// range (Simpson), for a point whose torques change along its
    /// tangents. Exact but for the window's width in `g = f s` being taken
    /// at one magnitude: within 2 % (1–1.1 % seen) where f is pinned down, and equal
    /// to the point's own evidence as the window shrinks.
    #[test]
    fn patch_evidence_matches_brute_force_integration_over_the_window() {
        use crate::core::rng::Rng;
        let mut rng = Rng::new(3);
        let w = [400.0; 4];
        for case in 0..6 {
            let u: Vec<f64> = (0..4).map(|_| rng.uniform_in(-0.3, 0.3)).collect();
            let d1: Vec<f64> = (0..4).map(|_| rng.uniform_in(-2.0, 2.0)).collect();
            let d2: Vec<f64> = (0..4).map(|_| rng.uniform_in(-2.0, 2.0)).collect();
            let (f_true, s_true) = (
                rng.uniform_in(5.0, 20.0),
                [rng.uniform_in(-0.004, 0.004), rng.uniform_in(-0.004, 0.004)],
            );
            let tau: Vec<f64> = (0..4)
                .map(|j| f_true * (u[j] + d1[j] * s_true[0] + d2[j] * s_true[1]) + 0.05 * rng.normal())
                .collect();
            let dot = |x: &[f64], y: &[f64]| (0..4).map(|j| w[j] * x[j] * y[j]).sum::<f64>();
            let rho = 0.004;
            let one = |x: f64| vec![x];
            let forms = PatchForms {
                a: one(dot(&u, &u)),
                b: one(dot(&u, &tau)),
                h1: one(dot(&u, &d1)),
                h2: one(dot(&u, &d2)),
                e1: one(dot(&d1, &tau)),
                e2: one(dot(&d2, &tau)),
                g11: one(dot(&d1, &d1)),
                g12: one(dot(&d1, &d2)),
                g22: one(dot(&d2, &d2)),
                window_m: one(rho),
                ln_area: one(0.0),
            };
            let c = dot(&tau, &tau);
            let (f_min, f_max) = (1.0, 30.0);
            let formula = patch_log_evidence(&forms, c, (f_min, f_max));
            // Brute force, relative to the best log-likelihood seen.
            let ll = |f: f64, s1: f64, s2: f64| {
                let r: Vec<f64> = (0..4).map(|j| tau[j] - f * (u[j] + d1[j] * s1 + d2[j] * s2)).collect();
                -0.5 * dot(&r, &r) - 0.5 * (s1 * s1 + s2 * s2) / (rho * rho) - (std::f64::consts::TAU * rho * rho).ln()
            };
            let (nf, ns) = (300, 81);
            let span = 5.0 * rho;
            let hs = 2.0 * span / f64::from(ns - 1);
            let hf = (f_max - f_min) / f64::from(nf);
            let mut peak = f64::NEG_INFINITY;
            let mut values = Vec::new();
            for i in 0..=nf {
                let f = f_min + f64::from(i) * hf;
                let mut row = Vec::new();
                for p in 0..ns {
                    for q in 0..ns {
                        let v = ll(f, -span + f64::from(p) * hs, -span + f64::from(q) * hs);
                        peak = peak.max(v);
                        row.push(v);
                    }
                }
                values.push(row);
            }
            let mut total = 0.0;
            for (i, row) in values.iter().enumerate() {
                let wf = if i == 0 || i == nf as usize {
                    1.0
                } else if i % 2 == 1 {
                    4.0
                } else {
                    2.0
                };
                total += wf * row.iter().map(|v| (v - peak).exp()).sum::<f64>();
            }
            let brute = peak + (total * hf / 3.0 * hs * hs).ln() - (f_max - f_min).ln();
            assert!((formula - brute).abs() < 0.02, "case {case}: {formula} vs {brute}");
            // A vanishing window gives the point's own evidence.
            let mut tiny = forms.clone();
            tiny.window_m = one(1e-9);
            let (a, b) = ([forms.a[0]], [forms.b[0]]);
            let q = Quadratic {
                a: &a,
                b: &b,
                c,
                per_point: None,
                volume: None,
                f_min,
                f_max,
            };
            let point = q.log_evidence(0, q.log_likelihood(0, q.best_force(0)));
            assert!((patch_log_evidence(&tiny, c, (f_min, f_max)) - point).abs() < 1e-6);
        }
    }

    struct Setup {
        robot: Robot,
        pose: RobotPose,
        surface: Surface,
        model: ContactModel,
    }

    fn setup(q: &[f64], points: usize, links: Option<Vec<usize>>) -> Setup {
        let robot = builtin::lwr4plus_generated().unwrap();
        let links = links.unwrap_or_else(|| robot.default_candidate_links());
        let surface = Surface::sample(
            &robot,
            &SurfaceRequest {
                links: links.clone(),
                total_points: points,
                seed: 1,
            },
        )
        .unwrap();
        let pose = RobotPose::new(&robot, &robot.joint_positions(q, &[]).unwrap());
        let model = ContactModel::new(&TorqueModel::new(&robot, &pose, &links), &surface);
        Setup {
            robot,
            pose,
            surface,
            model,
        }
    }

    fn settings(sigma: f64) -> EstimatorSettings {
        EstimatorSettings::exact(vec![sigma; 7])
    }

    /// A push at surface point k with `force` newtons: its torques.
    fn push_at(s: &Setup, k: usize, force: f64) -> (DVec3, Vec<f64>) {
        let link = s.surface.link[k];
        let p = s.pose.point_to_world(link, s.surface.point_in_link[k]);
        let n = s.pose.world_from_link[link].transform_vector3(s.surface.inward_normal_in_link[k]);
        (p, joint_torques(&s.robot, &s.pose, link, p, n * force))
    }

    const Q: [f64; 7] = [0.3, 0.6, -0.4, -1.2, 0.5, 0.9, 0.2];

    #[test]
    fn a_wide_peak_below_a_narrow_one_gets_its_evidence() {
        // Point 0 fits perfectly but only in a narrow band of magnitudes
        // (evidence ≈ -11.7); point 1's profile is 65 below, beyond the
        // first cut, yet its wide peak leaves its evidence within 60 of
        // point 0's: it must be scored exactly, not by its profile.
        let (a, b) = ([1e8, 0.01], [1e8 * 15.0, 0.15]);
        let c = 1e8 * 225.0;
        let (c0, c1) = (c, 0.15 * 15.0 + 130.0);
        let q = Quadratic {
            a: &a,
            b: &b,
            c: 0.0,
            per_point: Some((&[c0, c1], &[0.0, 0.0])),
            volume: None,
            f_min: 1.0,
            f_max: 30.0,
        };
        let scores = q.exact_scores(&[0, 1], 2);
        let profile = [q.log_likelihood(0, 15.0), q.log_likelihood(1, 15.0)];
        assert!(profile[0].abs() < 1e-6 && (profile[1] + 65.0).abs() < 1e-9);
        let evidence = [q.log_evidence(0, profile[0]), q.log_evidence(1, profile[1])];
        assert!(evidence[1] - evidence[0] > -FAR_BELOW, "{evidence:?}");
        assert!((evidence[1] - profile[1]).abs() > 0.1);
        for (k, (mass, evidence)) in scores.mass.iter().zip(evidence).enumerate() {
            assert!((mass - evidence).abs() < 1e-9, "point {k}: {mass} vs {evidence}");
        }
        assert_eq!(scores.candidates, Some(vec![0, 1]));
    }

    #[test]
    fn skipping_far_points_matches_scoring_every_point() {
        // Reference: every point's evidence in closed form, normalised
        // directly, against the estimator that skips the far ones. Several
        // σ, including ones where the evidence lies far below the profile.
        let s = setup(&Q, 3000, None);
        for (sigma, k, force) in [
            (0.05, 2100, 12.0),
            (0.5, 700, 4.0),
            (0.002, 2900, 25.0),
            (1e-5, 1500, 20.0),
            (5.0, 10, 1.0),
        ] {
            let (_, tau) = push_at(&s, k, force);
            let set = settings(sigma);
            let post = estimate(&s.model, &tau, &set, None).unwrap();
            let weights = vec![1.0 / (sigma * sigma); 7];
            let (mut a, mut b) = (Vec::new(), Vec::new());
            s.model.quadratic_forms(&weights, &tau, &mut a, &mut b);
            let q = Quadratic {
                a: &a,
                b: &b,
                c: weights.iter().zip(&tau).map(|(w, t)| w * t * t).sum(),
                per_point: None,
                volume: None,
                f_min: set.force_min_newtons,
                f_max: set.force_max_newtons,
            };
            let evidence: Vec<f64> = (0..a.len())
                .map(|k| q.log_evidence(k, q.log_likelihood(k, q.best_force(k))))
                .collect();
            let top = evidence.iter().copied().fold(f64::NEG_INFINITY, f64::max);
            let sum: f64 = evidence.iter().map(|l| (l - top).exp()).sum();
            for (k, l) in evidence.iter().enumerate() {
                let reference = (l - top).exp() / sum;
                assert!(
                    (post.probability[k] - reference).abs() <= 1e-12 + 1e-9 * reference,
                    "σ {sigma}, point {k}: {} vs {reference}",
                    post.probability[k]
                );
                assert_eq!(
                    post.support.contains(&k),
                    post.probability[k] > 0.0,
                    "σ {sigma}, point {k}"
                );
                // Within e^-60 of the best, the exact evidence itself.
                if *l >= top - FAR_BELOW {
                    assert!((post.log_likelihood[k] - l).abs() < 1e-9, "σ {sigma}, point {k}");
                }
            }
            assert_eq!(
                post.map_point,
                evidence.iter().position(|l| l.total_cmp(&top).is_eq()).unwrap()
            );
        }
    }

    #[test]
    fn noise_free_push_on_the_forearm_is_found() {
        let s = setup(&Q, 2000, None);
        let k = (0..s.surface.len())
            .find(|&k| s.robot.links[s.surface.link[k]].name == "lwr_5_link")
            .unwrap()
            + 40;
        let (truth, tau) = push_at(&s, k, 12.0);
        let post = estimate(&s.model, &tau, &settings(0.05), None).unwrap();
        assert!((post.probability.iter().sum::<f64>() - 1.0).abs() < 1e-12);
        let summary = summarize(&post, &s.surface, &s.pose, 7);
        assert_eq!(summary.verdict, Verdict::Contact);
        assert!(
            summary.map.point_world.distance(truth) < 0.02,
            "{} m",
            summary.map.point_world.distance(truth)
        );
        assert!((summary.map.force_newtons - 12.0).abs() < 1.0);
        assert!(summary.credible90.points.contains(&k));
    }

    #[test]
    fn phases_with_alpha_near_zero_give_the_full_search_map() {
        let s = setup(&Q, 2000, None);
        let hierarchy = PhaseHierarchy::new(&s.surface, [50, 300], 3);
        for (k, sigma, alpha) in [
            (100, 0.05, 0.0),
            (700, 0.05, 0.0),
            (1500, 0.5, 1e-300),
            (400, 1.0, 1e-300),
        ] {
            let (_, tau) = push_at(&s, k, 8.0);
            let tau = with_sensor_noise(&tau, 0.05, k as u64);
            let full = estimate(&s.model, &tau, &settings(sigma), None).unwrap();
            let mut phased_settings = settings(sigma);
            phased_settings.phase_alpha = Some(alpha);
            let phased = estimate(&s.model, &tau, &phased_settings, Some(&hierarchy)).unwrap();
            assert_eq!(phased.phases.len(), 3);
            assert_eq!(phased.phases[0].points, hierarchy.a_points.len());
            assert_eq!(
                phased.phases[2].points,
                s.surface.len(),
                "σ {sigma}, α {alpha}: every cluster kept"
            );
            assert_eq!(full.map_point, phased.map_point);
            // With a real α the last phase evaluates fewer points.
            phased_settings.phase_alpha = Some(0.5);
            let pruned = estimate(&s.model, &tau, &phased_settings, Some(&hierarchy)).unwrap();
            assert!(pruned.phases[2].points < s.surface.len() / 2, "{:?}", pruned.phases);
        }
    }

    #[test]
    fn particle_modes_count_their_particles_and_show_the_best_one() {
        let s = setup(&Q, 500, None);
        let (_, tau) = push_at(&s, 300, 10.0);
        let mut set = settings(0.1);
        set.mode = Mode::Particles(ParticleSettings {
            sampling: Sampling::Deterministic {
                magnitudes_per_point: 5,
            },
        });
        let det = estimate(&s.model, &tau, &set, None).unwrap();
        assert_eq!(det.phases[0].particles, 2500);
        for k in 0..s.surface.len() {
            assert!(det.display[k] <= det.probability[k] + 1e-15);
            assert!(det.display[k] * 5.0 >= det.probability[k] - 1e-15);
        }
        set.mode = Mode::Particles(ParticleSettings {
            sampling: Sampling::Random { count: 18_000, seed: 9 },
        });
        let a = estimate(&s.model, &tau, &set, None).unwrap();
        let b = estimate(&s.model, &tau, &set, None).unwrap();
        assert_eq!(a, b);
        assert_eq!(a.phases[0].particles, 18_000);
    }

    #[test]
    fn tiny_sigma_is_flagged_without_nan() {
        let s = setup(&Q, 1000, None);
        let (_, tau) = push_at(&s, 333, 10.0);
        let tau = with_sensor_noise(&tau, 0.05, 1);
        let post = estimate(&s.model, &tau, &settings(1e-6), None).unwrap();
        assert!(post.probability.iter().all(|p| p.is_finite()));
        assert!((post.probability.iter().sum::<f64>() - 1.0).abs() < 1e-9);
        assert_eq!(summarize(&post, &s.surface, &s.pose, 7).verdict, Verdict::PoorFit);
    }

    #[test]
    fn huge_sigma_gives_back_the_prior() {
        let s = setup(&Q, 1000, None);
        let (_, tau) = push_at(&s, 333, 10.0);
        let post = estimate(&s.model, &tau, &settings(1e6), None).unwrap();
        let n = s.surface.len() as f64;
        assert!(post.probability.iter().all(|p| (p * n - 1.0).abs() < 1e-3));
    }

    #[test]
    fn huge_torques_are_poorly_explained_and_absurd_ones_an_error() {
        let s = setup(&Q, 500, None);
        let post = estimate(&s.model, &[1e5; 7], &settings(0.05), None).unwrap();
        assert!(post.probability.iter().all(|p| p.is_finite()));
        assert_eq!(summarize(&post, &s.surface, &s.pose, 7).verdict, Verdict::PoorFit);
        let e = estimate(&s.model, &[1e70; 7], &settings(0.05), None).unwrap_err();
        assert!(matches!(e, EstimateError::TooLarge { .. }), "{e}");
    }

    #[test]
    fn zero_torque_means_no_contact() {
        let s = setup(&Q, 500, None);
        let post = estimate(&s.model, &[0.0; 7], &settings(0.05), None).unwrap();
        assert!(post.probability.iter().all(|p| p.is_finite()));
        assert_eq!(summarize(&post, &s.surface, &s.pose, 7).verdict, Verdict::NoContact);
    }

    #[test]
    fn bad_inputs_are_named() {
        let s = setup(&Q, 100, None);
        let e = estimate(
            &s.model,
            &[0.0, 0.1, f64::NAN, 0.0, 0.0, 0.0, 0.0],
            &settings(0.05),
            None,
        )
        .unwrap_err();
        assert!(matches!(e, EstimateError::NonFiniteTorque { joint: 2, .. }));
        assert!(e.to_string().contains("joint 2"));
        let e = estimate(&s.model, &[0.0; 6], &settings(0.05), None).unwrap_err();
        assert!(e.to_string().contains("expected 7") && e.to_string().contains("got 6"));
        let mut set = settings(0.05);
        set.force_min_newtons = 5.0;
        set.force_max_newtons = 2.0;
        assert!(matches!(
            estimate(&s.model, &[0.0; 7], &set, None),
            Err(EstimateError::BadForceRange { .. })
        ));
        let mut set = settings(0.05);
        set.phase_alpha = Some(0.5);
        assert_eq!(
            estimate(&s.model, &[0.0; 7], &set, None),
            Err(EstimateError::NoHierarchy)
        );
    }

    #[test]
    fn equal_force_bounds_and_a_single_point_work() {
        let s = setup(&Q, 500, None);
        let (_, tau) = push_at(&s, 250, 10.0);
        let mut set = settings(0.05);
        set.force_min_newtons = 10.0;
        set.force_max_newtons = 10.0;
        let post = estimate(&s.model, &tau, &set, None).unwrap();
        assert_eq!(post.map_point, 250);
        let one = setup(&Q, 1, Some(vec![5]));
        let post = estimate(&one.model, &tau, &settings(0.05), None).unwrap();
        assert_eq!(post.probability, vec![1.0]);
    }

    #[test]
    fn contact_off_the_candidate_links_is_flagged() {
        let s = setup(&Q, 1000, None);
        let k = (0..s.surface.len())
            .rev()
            .find(|&k| s.robot.links[s.surface.link[k]].name == "lwr_6_link")
            .unwrap();
        let (_, tau) = push_at(&s, k, 20.0);
        // Candidates: links 1-3 only.
        let few = setup(&Q, 1000, Some(vec![1, 2, 3]));
        let post = estimate(&few.model, &tau, &settings(0.05), None).unwrap();
        assert_eq!(summarize(&post, &few.surface, &few.pose, 7).verdict, Verdict::PoorFit);
    }
}
