//! The contact estimator: a posterior over surface points from measured
//! joint torques (thesis eq. 2.3–2.6), in exact mode (ours) or with the
//! thesis' particles, optionally coarse-to-fine in phases A/B/C.

use rayon::prelude::*;

use crate::core::contact::{PARALLEL_MIN_POINTS, UnitTorqueSource};
use crate::core::phases::PhaseHierarchy;
use crate::core::rng::Rng;
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
    /// RMS distance, m, between a candidate point and a true contact in
    /// the patch it stands for (ours; 0 is the thesis' model). A push of f
    /// newtons then adds torque noise of about `f · resolution_m` per
    /// joint, so that a σ below the surface's resolution does not make the
    /// posterior collapse onto single wrong points (thesis Fig. 3.17).
    pub resolution_m: f64,
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
    /// Phases asked for without a hierarchy, or a hierarchy of another surface.
    #[error("phases A/B/C need a phase hierarchy built on this surface")]
    NoHierarchy,
    /// A surface without points.
    #[error("there are no candidate points")]
    NoCandidates,
    /// A resolution that is negative or not finite.
    #[error("the surface resolution is {value} m; it must be a finite number ≥ 0")]
    BadResolution {
        /// The value.
        value: f64,
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
struct Quadratic<'a> {
    a: &'a [f64],
    b: &'a [f64],
    /// `c` shared by every point (the bare noise model)…
    c: f64,
    /// …or one per point, with its normaliser (resolution noise).
    per_point: Option<(&'a [f64], &'a [f64])>,
    f_min: f64,
    f_max: f64,
}

impl Quadratic<'_> {
    /// Best magnitude in range at point k.
    fn best_force(&self, k: usize) -> f64 {
        let (a, b) = (self.a[k], self.b[k]);
        if a > 0.0 {
            (b / a).clamp(self.f_min, self.f_max)
        } else {
            self.f_min
        }
    }

    /// Point k's `c` and normaliser.
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
    fn residual(&self, k: usize, f: f64) -> f64 {
        let (c, _) = self.c_norm(k);
        (c - 2.0 * self.b[k] * f + self.a[k] * f * f).max(0.0)
    }

    /// ln of the likelihood averaged over a uniform f in `[F_min, F_max]`,
    /// given the likelihood at the point's best magnitude (`profile`) and
    /// the best such value over the points (`profile_best`).
    fn log_evidence(&self, k: usize, profile: f64, profile_best: f64) -> f64 {
        let (a, b) = (self.a[k], self.b[k]);
        let range = self.f_max - self.f_min;
        if range <= 1e-12 * self.f_max.max(1.0) {
            return profile;
        }
        let s = (0.5 * a).sqrt();
        if s * range < 1e-6 {
            // Flat over the range (a → 0: the point makes almost no torque).
            let mid = 0.5 * (self.f_min + self.f_max);
            return self.log_likelihood(k, mid);
        }
        if profile < profile_best - FAR_BELOW {
            // Far below the best: the profile likelihood, a tight upper
            // bound (the average over f never exceeds the peak), saves a
            // logarithm per point where the mass is below e^-50 anyway.
            return profile;
        }
        let mu = b / a;
        let (c, norm) = self.c_norm(k);
        norm - 0.5 * (c - b * mu).max(0.0)
            + 0.5 * (std::f64::consts::PI / (2.0 * a)).ln()
            + ln_erf_difference(s * (self.f_min - mu), s * (self.f_max - mu))
            - range.ln()
    }
}

/// Per evaluated point: the score that sums (ln mass), the score a
/// heatmap shows (ln of the best particle), and the best magnitude.
struct Scored {
    mass: f64,
    best: f64,
    force: f64,
}

/// Estimates the contact from measured torques `tau` (N·m, sensed order).
/// `hierarchy` is needed when `settings.phase_alpha` is set.
pub fn estimate(
    model: &impl UnitTorqueSource,
    tau: &[f64],
    settings: &EstimatorSettings,
    hierarchy: Option<&PhaseHierarchy>,
) -> Result<Posterior, EstimateError> {
    validate(model, tau, settings)?;
    let n = model.points();
    let weights: Vec<f64> = settings.sigma.iter().map(|s| 1.0 / (s * s)).collect();
    let no_contact_chi2: f64 = weights.iter().zip(tau).map(|(w, t)| w * t * t).sum();
    let (mut a, mut b) = (Vec::new(), Vec::new());
    model.quadratic_forms(&weights, tau, &mut a, &mut b);
    let (mut c, mut norm) = (Vec::new(), Vec::new());
    if settings.resolution_m > 0.0 {
        add_resolution_noise(model, tau, settings, &mut a, &mut b, &mut c, &mut norm);
    }
    let q = Quadratic {
        a: &a,
        b: &b,
        c: no_contact_chi2,
        per_point: (settings.resolution_m > 0.0).then_some((c.as_slice(), norm.as_slice())),
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
    let (scored, report) = evaluate(&q, &last, settings, n, &mut rng);
    phases.push(report);

    for &p in &last {
        flags[p] |= phase_flag::C;
    }
    let total = log_sum_exp(scored.iter().map(|s| s.mass));
    let (map_slot, best_mass) =
        scored.iter().enumerate().fold(
            (0, f64::NEG_INFINITY),
            |(bi, bm), (i, s)| if s.mass > bm { (i, s.mass) } else { (bi, bm) },
        );
    // The smallest residual is among the likeliest points.
    let best_residual_chi2 = last
        .iter()
        .zip(&scored)
        .filter(|(_, s)| s.mass.is_finite() && s.mass >= best_mass - FAR_BELOW)
        .map(|(&p, s)| q.residual(p, s.force))
        .fold(f64::INFINITY, f64::min);
    let (probability, display, log_likelihood, force_newtons) = if last.len() == n {
        // A full search scores every point in order: no scatter needed.
        (
            scored.iter().map(|s| exp_or_zero(s.mass - total)).collect(),
            scored.iter().map(|s| exp_or_zero(s.best - total)).collect(),
            scored.iter().map(|s| s.mass).collect(),
            scored.iter().map(|s| s.force).collect(),
        )
    } else {
        let (mut p, mut d, mut l, mut f) = (vec![0.0; n], vec![0.0; n], vec![f64::NEG_INFINITY; n], vec![0.0; n]);
        for (&k, s) in last.iter().zip(&scored) {
            p[k] = exp_or_zero(s.mass - total);
            d[k] = exp_or_zero(s.best - total);
            l[k] = s.mass;
            f[k] = s.force;
        }
        (p, d, l, f)
    };
    Ok(Posterior {
        probability,
        display,
        log_likelihood,
        force_newtons,
        phases,
        phase_flags: flags,
        map_point: last.get(map_slot).copied().unwrap_or(0),
        best_residual_chi2,
        no_contact_chi2,
    })
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
            let keep = |points: &[usize], scored: &[Scored]| {
                let best = scored.iter().map(|s| s.best).fold(f64::NEG_INFINITY, f64::max);
                points
                    .iter()
                    .zip(scored)
                    .filter(|(_, s)| s.best >= best + alpha.ln())
                    .map(|(p, _)| *p)
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

/// Replaces each point's weights `1/σ²` by `1/(σ² + (f* ρ)²)`, with f*
/// the point's best magnitude under the bare noise, and adds the matching
/// normaliser `-½ Σ ln(1 + (f* ρ)²/σ²)`.
fn add_resolution_noise(
    model: &impl UnitTorqueSource,
    tau: &[f64],
    settings: &EstimatorSettings,
    a: &mut [f64],
    b: &mut [f64],
    c: &mut Vec<f64>,
    norm: &mut Vec<f64>,
) {
    c.resize(model.points(), 0.0);
    norm.resize(model.points(), 0.0);
    let mut u = vec![0.0; model.joints()];
    let (f_min, f_max) = (settings.force_min_newtons, settings.force_max_newtons);
    let variance: Vec<f64> = settings.sigma.iter().map(|s| s * s).collect();
    for k in 0..model.points() {
        let f_star = if a[k] > 0.0 {
            (b[k] / a[k]).clamp(f_min, f_max)
        } else {
            f_min
        };
        let extra = (f_star * settings.resolution_m).powi(2);
        let (mut ak, mut bk, mut ck, mut nk) = (0.0, 0.0, 0.0, 0.0);
        model.unit_torques_into(k, &mut u);
        for ((v, t), u) in variance.iter().zip(tau).zip(&u) {
            let w = 1.0 / (v + extra);
            ak += w * u * u;
            bk += w * u * t;
            ck += w * t * t;
            nk -= 0.5 * (extra / v).ln_1p();
        }
        a[k] = ak;
        b[k] = bk;
        c[k] = ck;
        norm[k] = nk;
    }
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
    let (min, max) = (settings.force_min_newtons, settings.force_max_newtons);
    if !(min.is_finite() && max.is_finite() && min >= 0.0 && min <= max) {
        return Err(EstimateError::BadForceRange { min, max });
    }
    if let Some(alpha) = settings.phase_alpha
        && !(0.0..1.0).contains(&alpha)
    {
        return Err(EstimateError::BadAlpha { alpha });
    }
    if model.points() == 0 {
        return Err(EstimateError::NoCandidates);
    }
    if !(settings.resolution_m.is_finite() && settings.resolution_m >= 0.0) {
        return Err(EstimateError::BadResolution {
            value: settings.resolution_m,
        });
    }
    match settings.mode {
        Mode::Particles(ParticleSettings {
            sampling:
                Sampling::Deterministic {
                    magnitudes_per_point: 0,
                }
                | Sampling::Random { count: 0, .. },
        }) => Err(EstimateError::NoParticles),
        _ => Ok(()),
    }
}

/// Scores the points of one phase.
fn evaluate(
    q: &Quadratic,
    points: &[usize],
    settings: &EstimatorSettings,
    surface_points: usize,
    rng: &mut Rng,
) -> (Vec<Scored>, PhaseReport) {
    let range = q.f_max - q.f_min;
    match settings.mode {
        Mode::Exact => {
            // One pass for the best magnitudes and their likelihoods, one
            // for the evidence (exact near the best, the profile far below).
            let score = |&k: &usize| {
                let force = q.best_force(k);
                let profile = q.log_likelihood(k, force);
                Scored {
                    mass: profile,
                    best: profile,
                    force,
                }
            };
            let mut scored: Vec<Scored> = if points.len() >= PARALLEL_MIN_POINTS {
                points.par_iter().map(score).collect()
            } else {
                points.iter().map(score).collect()
            };
            let profile_best = scored.iter().map(|s| s.mass).fold(f64::NEG_INFINITY, f64::max);
            for (&k, s) in points.iter().zip(&mut scored) {
                if s.mass >= profile_best - FAR_BELOW {
                    let l = q.log_evidence(k, s.mass, profile_best);
                    s.mass = l;
                    s.best = l;
                }
            }
            let report = PhaseReport {
                points: points.len(),
                particles: points.len(),
            };
            (scored, report)
        }
        Mode::Particles(ParticleSettings {
            sampling: Sampling::Deterministic {
                magnitudes_per_point: m,
            },
        }) => {
            let scored = points
                .iter()
                .map(|&k| {
                    let mut s = Scored {
                        mass: f64::NEG_INFINITY,
                        best: f64::NEG_INFINITY,
                        force: q.f_min,
                    };
                    for i in 1..=m {
                        let f = q.f_min + i as f64 * range / m as f64;
                        add_particle(&mut s, q.log_likelihood(k, f), f);
                    }
                    s
                })
                .collect();
            let report = PhaseReport {
                points: points.len(),
                particles: m * points.len(),
            };
            (scored, report)
        }
        Mode::Particles(ParticleSettings {
            sampling: Sampling::Random { count, .. },
        }) => {
            // The phase's share of the N particles, at least one per point.
            let draws = (count * points.len())
                .div_ceil(surface_points)
                .max(points.len().min(count));
            let mut scored: Vec<Scored> = points
                .iter()
                .map(|_| Scored {
                    mass: f64::NEG_INFINITY,
                    best: f64::NEG_INFINITY,
                    force: 0.0,
                })
                .collect();
            for _ in 0..draws {
                let slot = rng.below(points.len());
                let f = rng.uniform_in(q.f_min, q.f_max);
                add_particle(&mut scored[slot], q.log_likelihood(points[slot], f), f);
            }
            let report = PhaseReport {
                points: points.len(),
                particles: draws,
            };
            (scored, report)
        }
    }
}

fn add_particle(s: &mut Scored, l: f64, f: f64) {
    s.mass = log_add(s.mass, l);
    if l > s.best {
        s.best = l;
        s.force = f;
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
    if x < NEGLIGIBLE_LOG_MASS { 0.0 } else { x.exp() }
}

/// `ln Σ e^xᵢ` without overflow; `-inf` for no terms.
fn log_sum_exp(values: impl Iterator<Item = f64> + Clone) -> f64 {
    let hi = values.clone().fold(f64::NEG_INFINITY, f64::max);
    if hi == f64::NEG_INFINITY {
        return hi;
    }
    // Terms 40 below the largest change the sum by less than 1e-17.
    hi + values
        .filter(|v| *v > hi - 40.0)
        .map(|v| (v - hi).exp())
        .sum::<f64>()
        .ln()
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
                f_min,
                f_max,
            };
            let f = q.best_force(0);
            let exact = q.log_evidence(0, q.log_likelihood(0, f), q.log_likelihood(0, f));
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
            f_min: 2.0,
            f_max: 2.0,
        };
        let f = q.best_force(0);
        assert!((q.log_evidence(0, q.log_likelihood(0, f), 0.0) - (-0.5 * (10.0 - 12.0 + 8.0))).abs() < 1e-15);
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
        EstimatorSettings {
            sigma: vec![sigma; 7],
            force_min_newtons: 1.0,
            force_max_newtons: 30.0,
            mode: Mode::Exact,
            phase_alpha: None,
            resolution_m: 0.0,
        }
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
