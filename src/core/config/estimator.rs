//! The one estimator configuration: everything a user chooses about how
//! frames are estimated (σ, the push magnitudes, exact or particle mode,
//! phases, friction, the surface's resolution and seed, the temporal
//! model's rates), with the program's only defaults and its only
//! validation. Scenes, the command line and the app's panels each map
//! straight into it; the estimator, the temporal model and the batch
//! jobs are built from it.

use crate::core::config::limits::{self, CountOutOfRange, OutOfRange};
use crate::core::estimate::estimator::Estimator;
use crate::core::estimate::pair::PairSettings;
use crate::core::estimate::settings::{EstimatorSettings, Mode, ParticleSettings, Sampling};
use crate::core::over_time::calibration::{CalibrationSettings, ObserverGain};
use crate::core::over_time::pairs::SecondContactChain;
use crate::core::over_time::sequence::Temporal;
use crate::core::over_time::temporal::{TemporalError, TemporalModel, TemporalSettings};
use crate::core::robot::model::{LinkId, Robot};
use crate::core::surface::sampling::{Surface, SurfaceError, SurfaceRequest};

/// The likelihood σ when nobody says: 0.05 N·m, the noise of the LWR 4+'s
/// joint torque sensors and of every example session in `../shared`. A
/// σ below the sensors' noise makes every frame a confident misfit; one
/// far above blurs what the torques say.
pub const DEFAULT_SIGMA_NEWTON_METRES: f64 = 0.05;

/// The push magnitudes considered when nobody says, N: from a light touch
/// to a firm push on a collaborative arm (the estimator's own
/// [`EstimatorSettings::exact`] takes the same).
pub use crate::core::estimate::settings::DEFAULT_FORCE_RANGE_NEWTONS;

/// Surface samples when nobody says: 5000 places the contact within
/// millimetres on the wrist and centimetres on the upper arm of the LWR
/// at a few hundred microseconds a frame.
pub const DEFAULT_SURFACE_POINTS: usize = 5000;

/// Surface samples when nobody says and frames arrive live (`estimate
/// --live`, the app listening): the filter's work grows with the samples,
/// and a live frame has to be done before the next. On the shared
/// dynamic examples (`bench`, one thread of the 2-core development VM,
/// surface seeds 0–4) a filtered frame takes 346–365 µs at p99 with 2500
/// samples against 625–708 µs with 5000, and the filtered place is as
/// good within the seeds' spread (link 4: 12.5–33.0 mm at the median
/// against 13.1–27.6 mm; link 6: 4.0–4.3 mm against 4.1–4.4 mm;
/// `docs/validation.md`, *Long recordings at robot rates*).
pub const LIVE_SURFACE_POINTS: usize = 2500;

/// Surface samples when nobody says and frames arrive live, with
/// `contacts_at_once` contacts looked for: [`LIVE_SURFACE_POINTS`] for
/// one; for two, a file's [`DEFAULT_SURFACE_POINTS`]: on the `../shared`
/// two-contact example streamed live the live surface called two in 33
/// of the 83 frames where both probes press, 5000 samples in 61, and a
/// frame searched for a pair takes milliseconds either way
/// (`docs/validation.md`, *Two contacts*).
#[must_use]
pub const fn live_surface_points(contacts_at_once: usize) -> usize {
    if contacts_at_once >= 2 {
        DEFAULT_SURFACE_POINTS
    } else {
        LIVE_SURFACE_POINTS
    }
}

/// The likelihood σ: one value for every sensed joint, or one per joint.
#[derive(Debug, Clone, PartialEq)]
pub enum Sigma {
    /// The same σ for every sensed joint, N·m.
    All(f64),
    /// One σ per sensed joint, in sensed order, N·m.
    PerJoint(Vec<f64>),
}

/// How the push magnitude is handled.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ModeKind {
    /// Per sample, the likelihood integrated over the magnitude in closed
    /// form.
    #[default]
    Exact,
    /// The thesis' particles: `magnitudes_per_point` magnitudes per sample.
    ParticlesDeterministic,
    /// The thesis' particles: `particles` uniform random (sample,
    /// magnitude) pairs.
    ParticlesRandom,
}

/// The friction μ: by how frames are combined, or one value.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub enum Friction {
    /// [`Temporal::default_friction`]: none for a frame alone, a little
    /// over time, where a press takes it only if it explains the press.
    #[default]
    Auto,
    /// This μ everywhere (0: frictionless).
    Mu(f64),
}

/// Everything a user chooses about the estimator (see the module docs).
#[derive(Debug, Clone, PartialEq)]
pub struct EstimatorConfig {
    /// Likelihood σ.
    pub sigma: Sigma,
    /// Push magnitudes considered, N: smallest and largest.
    pub force_range_newtons: (f64, f64),
    /// Exact or particles.
    pub mode: ModeKind,
    /// Random particles over the whole surface.
    pub particles: usize,
    /// Magnitudes per sample of deterministic particles.
    pub magnitudes_per_point: usize,
    /// Seed of random particles.
    pub particle_seed: u64,
    /// Search coarse-to-fine in phases A/B/C.
    pub phases: bool,
    /// Samples of phases A and B.
    pub phase_sizes: [usize; 2],
    /// Keep clusters with P ≥ α `P_max` between phases.
    pub alpha: f64,
    /// Friction μ.
    pub friction: Friction,
    /// Each sample stands for its patch of surface (exact mode); false is
    /// the thesis' model, a sample is a point.
    pub patches: bool,
    /// Samples over the candidate links.
    pub surface_points: usize,
    /// Seed of the surface sampling (and the phase clustering).
    pub surface_seed: u64,
    /// The temporal model's rates and slide length.
    pub temporal: TemporalSettings,
    /// What a recording's torques are taken to carry besides contacts.
    pub torques: TorqueModel,
    /// Memory a smoothed recording may take, MiB: [`STORE_SHARE`] of it
    /// for what the smoother holds (whatever the recording's length), the
    /// rest for the session and what is not counted (the frames under
    /// way, the allocator's overhead).
    pub memory_mib: usize,
    /// Most contacts looked for at once in a frame: 1, or 2 (a second
    /// push where the evidence asks for it,
    /// [`crate::core::estimate::pair`]).
    pub contacts_at_once: usize,
    /// How a second contact is looked for.
    pub pair: PairSettings,
}

/// What a recording's torques carry besides contacts, and what the
/// program learns of it from the recording itself
/// ([`crate::core::over_time::calibration`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TorqueModel {
    /// σ per joint learned from the recording's free stretches (widened
    /// for their correlation over time); `sigma` is then the fallback
    /// where nothing can be learned (frames alone, too few free frames).
    pub sigma_auto: bool,
    /// Learn and take off the model error (inertials, friction, offset).
    pub calibrate: bool,
    /// What is fitted, and the observer's gain.
    pub calibration: CalibrationSettings,
}

impl Default for TorqueModel {
    /// σ learned, the model error learned and taken off, the observer's
    /// gain estimated: a user who has never heard of σ opens a recording.
    fn default() -> Self {
        Self {
            sigma_auto: true,
            calibrate: true,
            calibration: CalibrationSettings::default(),
        }
    }
}

impl Default for EstimatorConfig {
    /// σ [`DEFAULT_SIGMA_NEWTON_METRES`], 1–30 N, exact with patches, 5000
    /// samples (seed 0), no phases (A 200, B 1000, α 0.5 when on), friction
    /// by how frames are combined, the temporal model's defaults;
    /// particles 20,000 random or 5 magnitudes a sample.
    fn default() -> Self {
        Self {
            sigma: Sigma::All(DEFAULT_SIGMA_NEWTON_METRES),
            force_range_newtons: DEFAULT_FORCE_RANGE_NEWTONS,
            mode: ModeKind::Exact,
            particles: 20_000,
            magnitudes_per_point: 5,
            particle_seed: 0,
            phases: false,
            phase_sizes: [200, 1000],
            alpha: 0.5,
            friction: Friction::Auto,
            patches: true,
            surface_points: DEFAULT_SURFACE_POINTS,
            surface_seed: 0,
            temporal: TemporalSettings::default(),
            torques: TorqueModel::default(),
            memory_mib: DEFAULT_MEMORY_MIB,
            contacts_at_once: 1,
            pair: PairSettings::default(),
        }
    }
}

/// The share of [`EstimatorConfig::memory_mib`] that the smoother counts
/// as it holds a recording's steps, the frames waiting for them and the
/// pieces being smoothed: two fifths. Resident memory runs about 1.4×
/// what is counted (what is not counted: each block's likelihoods under
/// way, the smoothed stretches, the allocator's freed pieces), on top of
/// the session itself; at two fifths the 10-minute 1 kHz recording peaks
/// under 2 GiB at the default (`docs/decisions.md`, *the memory
/// limit*).
pub const STORE_SHARE: (usize, usize) = (2, 5);

/// [`EstimatorConfig::memory_mib`] when the user has not said: 2 GiB.
pub const DEFAULT_MEMORY_MIB: usize = 2048;

/// A field of the configuration, for the message of a value it refuses:
/// scenes, the command line and the app each name it their own way
/// ([`ConfigField::scene_field`], [`ConfigField::option`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ConfigField {
    /// [`EstimatorConfig::sigma`].
    Sigma,
    /// The smallest push considered.
    ForceMin,
    /// The largest push considered.
    ForceMax,
    /// [`EstimatorConfig::particles`].
    Particles,
    /// [`EstimatorConfig::magnitudes_per_point`].
    MagnitudesPerPoint,
    /// [`EstimatorConfig::phase_sizes`].
    PhaseSizes,
    /// [`EstimatorConfig::alpha`].
    Alpha,
    /// [`EstimatorConfig::friction`].
    Friction,
    /// [`EstimatorConfig::surface_points`].
    SurfacePoints,
    /// [`TemporalSettings::onset_per_s`].
    OnsetRate,
    /// [`TemporalSettings::release_per_s`].
    ReleaseRate,
    /// [`TemporalSettings::slide_m_per_sqrt_s`].
    Slide,
    /// [`TemporalSettings::jump_per_s`].
    JumpRate,
    /// [`TemporalSettings::step_secs`].
    TimeStep,
    /// The observer gain of [`TorqueModel::calibration`].
    ObserverGain,
    /// [`EstimatorConfig::memory_mib`].
    Memory,
    /// [`EstimatorConfig::contacts_at_once`].
    ContactsAtOnce,
    /// [`PairSettings::prior_two`] of [`EstimatorConfig::pair`].
    PriorTwo,
}

impl ConfigField {
    /// The field as a scene file names it.
    #[must_use]
    pub const fn scene_field(self) -> &'static str {
        match self {
            Self::Sigma => "estimator.sigma_newton_metres",
            Self::ForceMin => "estimator.force_min_newtons",
            Self::ForceMax => "estimator.force_max_newtons",
            Self::Particles => "estimator.particles",
            Self::MagnitudesPerPoint => "estimator.magnitudes_per_point",
            Self::PhaseSizes => "estimator.phases.sizes",
            Self::Alpha => "estimator.phases.alpha",
            Self::Friction => "estimator.friction",
            Self::SurfacePoints => "surface_points",
            Self::OnsetRate => "temporal.onset_per_s",
            Self::ReleaseRate => "temporal.release_per_s",
            Self::Slide => "temporal.slide_m_per_sqrt_s",
            Self::JumpRate => "temporal.jump_per_s",
            Self::TimeStep => "temporal.step_secs",
            Self::ObserverGain => "torques.observer_gain_per_s",
            Self::Memory => "memory_mib",
            Self::ContactsAtOnce => "estimator.contacts",
            Self::PriorTwo => "estimator.prior_two",
        }
    }

    /// The command line's option for the field.
    #[must_use]
    pub const fn option(self) -> &'static str {
        match self {
            Self::Sigma => "--sigma",
            Self::ForceMin => "--fmin",
            Self::ForceMax => "--fmax",
            Self::Particles => "--particles",
            Self::MagnitudesPerPoint => "--m",
            Self::PhaseSizes => "--phase-sizes",
            Self::Alpha => "--alpha",
            Self::Friction => "--friction",
            Self::SurfacePoints => "--points",
            Self::OnsetRate => "--onset-rate",
            Self::ReleaseRate => "--release-rate",
            Self::Slide => "--slide",
            Self::JumpRate => "--jump-rate",
            Self::TimeStep => "--time-step",
            Self::ObserverGain => "--observer-gain",
            Self::Memory => "--memory",
            Self::ContactsAtOnce => "--contacts",
            Self::PriorTwo => "--prior-two",
        }
    }
}

/// Why a configuration cannot be used.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ConfigError {
    /// A number outside its valid range.
    #[error("{}", .why)]
    OutOfRange {
        /// The field.
        field: ConfigField,
        /// The value and the range.
        why: OutOfRange,
    },
    /// A count outside its valid range.
    #[error("{}", .why)]
    CountOutOfRange {
        /// The field.
        field: ConfigField,
        /// The count and the range.
        why: CountOutOfRange,
    },
    /// The smallest push considered is above the largest.
    #[error("the smallest push considered, {min} N, is above the largest, {max} N")]
    ForceRangeReversed {
        /// Smallest, N.
        min: f64,
        /// Largest, N.
        max: f64,
    },
    /// σ per joint for another number of sensed joints.
    #[error("{given} values of σ for {joints} sensed joints: give one, or one per sensed joint")]
    SigmaCount {
        /// Values given.
        given: usize,
        /// Sensed joints.
        joints: usize,
    },
}

impl ConfigError {
    /// The field the error is about.
    #[must_use]
    pub const fn field(&self) -> ConfigField {
        match self {
            Self::OutOfRange { field, .. } | Self::CountOutOfRange { field, .. } => *field,
            Self::ForceRangeReversed { .. } => ConfigField::ForceMin,
            Self::SigmaCount { .. } => ConfigField::Sigma,
        }
    }
}

/// Why an estimator could not be built from a configuration.
#[derive(Debug, thiserror::Error)]
pub enum BuildError {
    /// The configuration is invalid.
    #[error(transparent)]
    Config(#[from] ConfigError),
    /// The surface could not be sampled.
    #[error(transparent)]
    Surface(#[from] SurfaceError),
    /// The temporal model refused its settings.
    #[error(transparent)]
    Temporal(#[from] TemporalError),
}

/// `value` of `field` within `range`.
fn in_range(field: ConfigField, range: &limits::Range, value: f64) -> Result<f64, ConfigError> {
    range.check(value).map_err(|why| ConfigError::OutOfRange { field, why })
}

/// `value` of `field` within `range`.
fn counted(field: ConfigField, range: &limits::CountRange, value: usize) -> Result<usize, ConfigError> {
    range
        .check(value)
        .map_err(|why| ConfigError::CountOutOfRange { field, why })
}

impl EstimatorConfig {
    /// Every field within its range ([`limits`]), the force range in
    /// order; with `joints`, σ's count checked against them too. The one
    /// place a configuration is validated.
    ///
    /// # Errors
    /// The first field that is not, by [`ConfigField`].
    pub fn validate(&self, joints: Option<usize>) -> Result<(), ConfigError> {
        use ConfigField as F;
        let sigmas: &[f64] = match &self.sigma {
            Sigma::All(s) => std::slice::from_ref(s),
            Sigma::PerJoint(v) => v,
        };
        for &s in sigmas {
            in_range(F::Sigma, &limits::SIGMA, s)?;
        }
        if let (Sigma::PerJoint(v), Some(joints)) = (&self.sigma, joints)
            && v.len() != joints
        {
            return Err(ConfigError::SigmaCount { given: v.len(), joints });
        }
        let (min, max) = self.force_range_newtons;
        in_range(F::ForceMin, &limits::FORCE_MIN, min)?;
        in_range(F::ForceMax, &limits::FORCE_MAX, max)?;
        if min > max {
            return Err(ConfigError::ForceRangeReversed { min, max });
        }
        counted(F::Particles, &limits::PARTICLES, self.particles)?;
        counted(F::MagnitudesPerPoint, &limits::MAGNITUDES, self.magnitudes_per_point)?;
        for &size in &self.phase_sizes {
            counted(F::PhaseSizes, &limits::PHASE_POINTS, size)?;
        }
        in_range(F::Alpha, &limits::ALPHA, self.alpha)?;
        if let Friction::Mu(mu) = self.friction {
            in_range(F::Friction, &limits::FRICTION, mu)?;
        }
        counted(F::SurfacePoints, &limits::SURFACE_POINTS, self.surface_points)?;
        if let ObserverGain::PerSecond(k) = self.torques.calibration.observer_gain {
            in_range(F::ObserverGain, &limits::OBSERVER_GAIN, k)?;
        }
        let t = &self.temporal;
        in_range(F::OnsetRate, &limits::EVENT_RATE, t.onset_per_s)?;
        in_range(F::ReleaseRate, &limits::EVENT_RATE, t.release_per_s)?;
        in_range(F::Slide, &limits::SLIDE, t.slide_m_per_sqrt_s)?;
        in_range(F::JumpRate, &limits::EVENT_RATE, t.jump_per_s)?;
        in_range(F::TimeStep, &limits::TIME_STEP, t.step_secs)?;
        counted(F::Memory, &limits::MEMORY_MIB, self.memory_mib)?;
        counted(F::ContactsAtOnce, &limits::CONTACTS_AT_ONCE, self.contacts_at_once)?;
        in_range(F::PriorTwo, &limits::PRIOR_TWO, self.pair.prior_two)?;
        Ok(())
    }

    /// σ for each of `joints` sensed joints.
    ///
    /// # Errors
    /// [`ConfigError::SigmaCount`] where σ is per joint for another count.
    pub fn sigma_per_joint(&self, joints: usize) -> Result<Vec<f64>, ConfigError> {
        match &self.sigma {
            Sigma::All(s) => Ok(vec![*s; joints]),
            Sigma::PerJoint(v) if v.len() == joints => Ok(v.clone()),
            Sigma::PerJoint(v) => Err(ConfigError::SigmaCount { given: v.len(), joints }),
        }
    }

    /// The friction μ for frames combined by `temporal`.
    #[must_use]
    pub fn friction_for(&self, temporal: Temporal) -> f64 {
        match self.friction {
            Friction::Auto => temporal.default_friction(),
            Friction::Mu(mu) => mu,
        }
    }

    /// The estimator's settings for a robot of `joints` sensed joints and
    /// frames combined by `temporal` (which sets the friction when it is
    /// automatic; particle modes take none).
    ///
    /// # Errors
    /// As [`EstimatorConfig::validate`].
    pub fn settings(&self, joints: usize, temporal: Temporal) -> Result<EstimatorSettings, ConfigError> {
        self.validate(Some(joints))?;
        let mode = match self.mode {
            ModeKind::Exact => Mode::Exact,
            ModeKind::ParticlesDeterministic => Mode::Particles(ParticleSettings {
                sampling: Sampling::Deterministic {
                    magnitudes_per_point: self.magnitudes_per_point,
                },
            }),
            ModeKind::ParticlesRandom => Mode::Particles(ParticleSettings {
                sampling: Sampling::Random {
                    count: self.particles,
                    seed: self.particle_seed,
                },
            }),
        };
        let friction = if self.mode == ModeKind::Exact {
            self.friction_for(temporal)
        } else {
            0.0
        };
        Ok(EstimatorSettings {
            sigma: self.sigma_per_joint(joints)?,
            force_min_newtons: self.force_range_newtons.0,
            force_max_newtons: self.force_range_newtons.1,
            mode,
            phase_alpha: self.phases.then_some(self.alpha),
            patches: self.patches,
            friction,
        })
    }

    /// Phase A and B sizes, with phases.
    #[must_use]
    pub fn phase_sizes(&self) -> Option<[usize; 2]> {
        self.phases.then_some(self.phase_sizes)
    }

    /// The surface to sample over `links`.
    #[must_use]
    pub fn surface_request(&self, links: Vec<LinkId>) -> SurfaceRequest {
        SurfaceRequest {
            links,
            total_points: self.surface_points,
            seed: self.surface_seed,
        }
    }

    /// The estimator for `robot` over the candidate `links`, for frames
    /// combined by `temporal`.
    ///
    /// # Errors
    /// An invalid configuration, or a surface that cannot be sampled.
    pub fn estimator(&self, robot: &Robot, links: Vec<LinkId>, temporal: Temporal) -> Result<Estimator, BuildError> {
        let settings = self.settings(robot.sensed().len(), temporal)?;
        Ok(Estimator::new(
            robot,
            &self.surface_request(links),
            settings,
            self.phase_sizes(),
        )?)
    }

    /// The temporal model over `surface` (the samples are patches when
    /// `patches`).
    ///
    /// # Errors
    /// Settings the model refuses.
    pub fn temporal_model(&self, surface: &Surface, patches: bool) -> Result<TemporalModel, BuildError> {
        Ok(TemporalModel::new(surface, self.temporal, patches)?.with_store_limit(self.store_bytes()))
    }

    /// Whether a second contact presses, over the frames: the temporal
    /// model's onset and release rates.
    #[must_use]
    pub fn second_contact_chain(&self) -> SecondContactChain {
        SecondContactChain {
            onset_per_s: self.temporal.onset_per_s,
            release_per_s: self.temporal.release_per_s,
        }
    }

    /// What the smoother may hold: [`STORE_SHARE`] of
    /// [`EstimatorConfig::memory_mib`].
    #[must_use]
    pub fn store_bytes(&self) -> usize {
        let (num, den) = STORE_SHARE;
        self.memory_mib.saturating_mul(1 << 20) / den * num
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_smoother_counts_two_fifths_of_the_memory() {
        let mib = |memory_mib| {
            EstimatorConfig {
                memory_mib,
                ..EstimatorConfig::default()
            }
            .store_bytes()
        };
        assert_eq!(mib(DEFAULT_MEMORY_MIB), 858_993_458);
        for m in [limits::MEMORY_MIB.min, 1000, limits::MEMORY_MIB.max] {
            let share = mib(m) as f64 / (m as f64 * 1_048_576.0);
            assert!((share - 0.4).abs() < 1e-6, "{m} MiB: {share}");
        }
    }

    #[test]
    fn the_defaults_are_valid_and_every_field_is_checked() {
        let config = EstimatorConfig::default();
        assert_eq!(config.validate(Some(7)), Ok(()));
        let settings = config.settings(7, Temporal::None).unwrap();
        assert_eq!(settings.sigma, vec![DEFAULT_SIGMA_NEWTON_METRES; 7]);
        assert_eq!(settings, EstimatorSettings::exact(vec![DEFAULT_SIGMA_NEWTON_METRES; 7]));
        let broken = [
            (
                EstimatorConfig {
                    sigma: Sigma::All(1e-9),
                    ..config.clone()
                },
                ConfigField::Sigma,
            ),
            (
                EstimatorConfig {
                    sigma: Sigma::PerJoint(vec![0.1; 3]),
                    ..config.clone()
                },
                ConfigField::Sigma,
            ),
            (
                EstimatorConfig {
                    force_range_newtons: (20.0, 10.0),
                    ..config.clone()
                },
                ConfigField::ForceMin,
            ),
            (
                EstimatorConfig {
                    force_range_newtons: (1.0, 1e308),
                    ..config.clone()
                },
                ConfigField::ForceMax,
            ),
            (
                EstimatorConfig {
                    friction: Friction::Mu(3.0),
                    ..config.clone()
                },
                ConfigField::Friction,
            ),
            (
                EstimatorConfig {
                    surface_points: 0,
                    ..config.clone()
                },
                ConfigField::SurfacePoints,
            ),
            (
                EstimatorConfig {
                    phase_sizes: [0, 10],
                    ..config.clone()
                },
                ConfigField::PhaseSizes,
            ),
            (
                EstimatorConfig {
                    temporal: TemporalSettings {
                        slide_m_per_sqrt_s: f64::NAN,
                        ..TemporalSettings::default()
                    },
                    ..config.clone()
                },
                ConfigField::Slide,
            ),
        ];
        for (config, field) in broken {
            let e = config.validate(Some(7)).unwrap_err();
            assert_eq!(e.field(), field, "{e}");
        }
    }

    #[test]
    fn friction_follows_how_frames_are_combined_unless_set() {
        let auto = EstimatorConfig::default();
        assert!(auto.settings(7, Temporal::None).unwrap().friction.abs() < f64::EPSILON);
        let smooth = auto.settings(7, Temporal::Smooth).unwrap().friction;
        assert!((smooth - Temporal::Smooth.default_friction()).abs() < f64::EPSILON);
        let set = EstimatorConfig {
            friction: Friction::Mu(0.3),
            ..EstimatorConfig::default()
        };
        assert!((set.settings(7, Temporal::None).unwrap().friction - 0.3).abs() < f64::EPSILON);
        let particles = EstimatorConfig {
            mode: ModeKind::ParticlesRandom,
            ..set
        };
        assert!(particles.settings(7, Temporal::Smooth).unwrap().friction.abs() < f64::EPSILON);
    }
}
