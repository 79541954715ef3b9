//! The estimator's settings for one frame (σ, the force range, exact or
//! particle mode, phases' α, patches, friction), their limits, and why
//! an estimate cannot be made.

use crate::core::estimate::contact::UnitTorqueSource;

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
    /// that patch (see `patch_terms`) rather than taken at the point.
    /// `false` is the thesis' model (a point is a point); particle modes
    /// ignore it.
    pub patches: bool,
    /// μ of the friction model ([`crate::core::estimate::friction`]): the spread of
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

pub(crate) fn validate(
    model: &impl UnitTorqueSource,
    tau: &[f64],
    settings: &EstimatorSettings,
) -> Result<(), EstimateError> {
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
    if !force_range_is_valid(min, max) {
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

/// Whether `[min, max]` is a range of pushes a fit can clamp to: both
/// finite, `0 ≤ min ≤ max` (NaN fails).
#[must_use]
pub fn force_range_is_valid(min: f64, max: f64) -> bool {
    min.is_finite() && max.is_finite() && min >= 0.0 && min <= max
}
