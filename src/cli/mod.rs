//! Headless commands that run the estimator.

pub mod bench;
pub mod bench_pairs;
pub mod bench_recording;
pub mod bench_sessions;
pub mod calibrate;
pub mod estimate;
pub mod estimate_out;
pub mod live;
pub mod output;
pub mod press_gaps;
pub mod synth;
pub mod topics;

use std::path::Path;

use anyhow::{Result, bail};
use glam::DVec3;
use proprioscope::core::config::estimator::{
    BuildError, ConfigError, DEFAULT_FORCE_RANGE_NEWTONS, DEFAULT_SIGMA_NEWTON_METRES, DEFAULT_SURFACE_POINTS,
    EstimatorConfig, Friction, ModeKind, Sigma, TorqueModel, live_surface_points,
};
use proprioscope::core::config::limits::{self, CountRange, Range};
use proprioscope::core::estimate::estimator::Estimator;
use proprioscope::core::estimate::pair::PairSettings;
use proprioscope::core::over_time::calibration::{CalibrationSettings, ObserverGain};
use proprioscope::core::over_time::sequence::Temporal;
use proprioscope::core::over_time::temporal::TemporalSettings;
use proprioscope::core::robot::model::{LinkId, Robot};
use proprioscope::io::recording::{self, TopicChoice, is_recording};

use proprioscope::io::session::{FrameProblem, Session};

/// Topics of a robot recording (MCAP, ROS 1 bag); each left out is
/// inferred when the file leaves one choice (`proprioscope topics FILE`
/// shows the file's).
#[derive(Debug, Clone, Default, clap::Args)]
pub struct TopicArgs {
    /// Recordings: the `JointState` topic of the joint positions
    /// (default: the torque topic when it has them, else the only such
    /// topic, else `/joint_states`).
    #[arg(long)]
    pub q_topic: Option<String>,
    /// Recordings: the topic of the external joint torques (default: the
    /// one with a torque array named *external*, else the only effort or
    /// torque array).
    #[arg(long)]
    pub tau_topic: Option<String>,
    /// Recordings: the float array field of the torque topic, dotted
    /// (`effort`, `external_torque`, `state.tau_ext`).
    #[arg(long)]
    pub tau_field: Option<String>,
}

impl TopicArgs {
    /// As the reader's choice.
    #[must_use]
    pub fn choice(&self) -> TopicChoice {
        TopicChoice {
            q_topic: self.q_topic.clone(),
            tau_topic: self.tau_topic.clone(),
            tau_field: self.tau_field.clone(),
        }
    }
}

/// A session file, or a recording read with `topics` (the mapping and the
/// skipped messages said on stderr), skipping bad frames.
pub fn open_session(path: &Path, topics: &TopicArgs) -> Result<(Session, Vec<FrameProblem>)> {
    open_session_with_origin(path, topics).map(|(s, p, _)| (s, p))
}

/// [`open_session`], with the clock reading of `t = 0` of a recording, ns.
pub fn open_session_with_origin(path: &Path, topics: &TopicArgs) -> Result<(Session, Vec<FrameProblem>, Option<i64>)> {
    if !is_recording(path) {
        let (session, problems) = Session::read_skipping_bad_frames(path)?;
        return Ok((session, problems, None));
    }
    let bytes = recording::read_bytes(path)?;
    let read = recording::read_session(path, &bytes, &topics.choice(), &|_| {})?;
    log::info!(
        "{}: {} frames from {} (time from {})",
        path.display(),
        read.session.frames.len(),
        read.mapping,
        read.stamps
    );
    for note in &read.notes {
        log::warn!("{}: {note}", path.display());
    }
    Ok((read.session, read.problems, Some(read.origin_ns)))
}

/// A finite number (`inf` and `NaN`, which Rust's parser takes, are not).
pub fn finite(text: &str) -> Result<f64, String> {
    text.trim()
        .parse::<f64>()
        .ok()
        .filter(|v| v.is_finite())
        .ok_or_else(|| format!("'{text}' is not a finite number"))
}

/// A value parser for a number within `range` (clap names the argument;
/// the message names the quantity, the value and the range).
pub fn within(range: &'static Range) -> impl Fn(&str) -> Result<f64, String> + Clone + Send + Sync + 'static {
    move |text| {
        let value = finite(text).map_err(|e| format!("{e}; the valid range of {} is {range}", range.quantity))?;
        range.check(value).map_err(|e| e.to_string())
    }
}

/// A value parser for a count within `range`.
pub fn counted(range: &'static CountRange) -> impl Fn(&str) -> Result<usize, String> + Clone + Send + Sync + 'static {
    move |text| {
        let value = text.trim().parse::<usize>().map_err(|_| {
            format!(
                "'{text}' is not a whole number; the valid range of {} is {range}",
                range.quantity
            )
        })?;
        range.check(value).map_err(|e| e.to_string())
    }
}

/// A value parser for `x,y,z`, each within `range`.
pub fn vec3_within(range: &'static Range) -> impl Fn(&str) -> Result<DVec3, String> + Clone + Send + Sync + 'static {
    move |text| {
        let parts: Vec<&str> = text.split(',').map(str::trim).collect();
        let [x, y, z] = parts.as_slice() else {
            return Err(format!("'{text}' is not three comma-separated numbers x,y,z"));
        };
        let component = |s: &str| within(range)(s);
        Ok(DVec3::new(component(x)?, component(y)?, component(z)?))
    }
}

/// Estimator mode on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum ModeArg {
    /// Closed-form likelihood per surface point (N = surface points).
    Exact,
    /// The thesis' particles.
    Particles,
}

/// Particle sampling on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum SamplingArg {
    /// `m` magnitudes per point (eq. 2.10).
    Deterministic,
    /// Uniform random points and magnitudes.
    Random,
}

/// How frames of a session are combined, on the command line.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum TemporalArg {
    /// `smooth` for a recording (frames closer than a contact lasts, see
    /// `core::temporal::is_continuous_recording`), else `none`.
    Auto,
    /// Each frame alone.
    None,
    /// Each frame with the frames before it (causal, as live).
    Filter,
    /// Each frame with the whole recording (forward–backward).
    Smooth,
}

impl From<TemporalArg> for Temporal {
    fn from(t: TemporalArg) -> Self {
        match t {
            TemporalArg::Auto | TemporalArg::None => Self::None,
            TemporalArg::Filter => Self::Filter,
            TemporalArg::Smooth => Self::Smooth,
        }
    }
}

/// Options of the temporal model (sessions).
#[derive(Debug, Clone, clap::Args)]
pub struct TemporalArgs {
    /// Combine frames over time: `none` (each frame alone), `filter`
    /// (with the frames before), `smooth` (with the whole recording) or
    /// `auto` (`smooth` when the frames are a recording, closer together
    /// than a contact lasts; `none` for sets of unrelated frames).
    #[arg(long, value_enum, default_value = "auto")]
    pub temporal: TemporalArg,
    /// Rate at which contacts begin, 1/s (valid: [0, 1000]).
    #[arg(long, default_value_t = TemporalSettings::default().onset_per_s, value_parser = within(&limits::EVENT_RATE))]
    pub onset_rate: f64,
    /// Rate at which a contact ends, 1/s (its mean duration is the
    /// inverse; valid: [0, 1000]).
    #[arg(long, default_value_t = TemporalSettings::default().release_per_s, value_parser = within(&limits::EVENT_RATE))]
    pub release_rate: f64,
    /// RMS slide of a contact along each surface direction after one
    /// second, m/√s (valid: [0, 1]).
    #[arg(long, default_value_t = TemporalSettings::default().slide_m_per_sqrt_s, value_parser = within(&limits::SLIDE))]
    pub slide: f64,
    /// Rate at which a contact jumps to an unrelated place, 1/s (valid: [0, 1000]).
    #[arg(long, default_value_t = TemporalSettings::default().jump_per_s, value_parser = within(&limits::EVENT_RATE))]
    pub jump_rate: f64,
    /// The smoother's time step, s: frames closer together than this
    /// share one state, their evidence multiplied (0: a step per frame;
    /// valid: [0, 1]).
    #[arg(long, default_value_t = TemporalSettings::default().step_secs, value_parser = within(&limits::TIME_STEP))]
    pub time_step: f64,
}

impl TemporalArgs {
    /// The model's settings.
    pub fn settings(&self) -> TemporalSettings {
        TemporalSettings {
            onset_per_s: self.onset_rate,
            release_per_s: self.release_rate,
            slide_m_per_sqrt_s: self.slide,
            jump_per_s: self.jump_rate,
            step_secs: self.time_step,
        }
    }
}

/// Estimator options shared by `estimate` and `bench`: mapped straight
/// into the one [`EstimatorConfig`], whose defaults they show.
#[derive(Debug, Clone, clap::Args)]
pub struct EstimatorArgs {
    /// `exact` or `particles`.
    #[arg(long, value_enum, default_value = "exact")]
    pub mode: ModeArg,
    /// Particle sampling: `deterministic` (`--m` magnitudes per surface
    /// point) or `random` (`--particles` over the surface).
    #[arg(long, value_enum, default_value = "deterministic")]
    pub sampling: SamplingArg,
    /// Surface points over the candidate links (valid: 1 to 1000000)
    /// [default: 5000; with --live, 2500, so that a filtered frame keeps
    /// up with a 1 kHz arm on one thread].
    #[arg(long, value_parser = counted(&limits::SURFACE_POINTS))]
    pub points: Option<usize>,
    /// Random particles over the surface (particle mode, random
    /// sampling; valid: 1 to 10000000).
    #[arg(long, default_value_t = EstimatorConfig::default().particles, value_parser = counted(&limits::PARTICLES))]
    pub particles: usize,
    /// Magnitudes per point m (deterministic particles; valid: 1 to 1000).
    #[arg(long, default_value_t = EstimatorConfig::default().magnitudes_per_point, value_parser = counted(&limits::MAGNITUDES))]
    pub m: usize,
    /// Likelihood σ, N·m: one value, or one per sensed joint (comma
    /// separated; valid: [1e-4, 100] N·m); `auto`: learned per joint from
    /// a recording's free stretches and widened for their correlation over
    /// time (0.05 where there is nothing to learn from: frames alone).
    #[arg(long, value_delimiter = ',', default_value = "auto", value_parser = sigma_arg)]
    pub sigma: Vec<SigmaArg>,
    /// A recording's model error (inertials, joint friction, offsets):
    /// `auto` learns it from the recording's free motion and takes it off
    /// the torques (frames combined over time); `none` takes the torques
    /// as they are.
    #[arg(long, value_enum, default_value = "auto")]
    pub calibrate: CalibrateArg,
    /// The momentum observer's gain K behind the torques, 1/s (its lag is
    /// 1/K): `auto` estimates it, `none` says there is no lag (valid:
    /// (0, 10000] 1/s).
    #[arg(long, default_value = "auto", value_parser = gain_arg)]
    pub observer_gain: ObserverGain,
    /// Smallest push magnitude considered, N (valid: [0, 10000] N, not above --fmax).
    #[arg(long, default_value_t = DEFAULT_FORCE_RANGE_NEWTONS.0, value_parser = within(&limits::FORCE_MIN))]
    pub fmin: f64,
    /// Largest push magnitude considered, N (valid: (0, 10000] N).
    #[arg(long, default_value_t = DEFAULT_FORCE_RANGE_NEWTONS.1, value_parser = within(&limits::FORCE_MAX))]
    pub fmax: f64,
    /// Search coarse-to-fine in phases A/B/C.
    #[arg(long)]
    pub phases: bool,
    /// Sizes of phases A and B (valid: 1 to 1000000 each).
    #[arg(long, value_delimiter = ',', default_value = "200,1000", value_parser = counted(&limits::PHASE_POINTS))]
    pub phase_sizes: Vec<usize>,
    /// Keep clusters with P ≥ α `P_max` between phases (valid: [0, 0.99]).
    #[arg(long, default_value_t = EstimatorConfig::default().alpha, value_parser = within(&limits::ALPHA))]
    pub alpha: f64,
    /// Candidate links (comma separated); default: every link a revolute joint moves.
    #[arg(long, value_delimiter = ',')]
    pub links: Vec<String>,
    /// Seed of the surface sampling, the phase clustering and random
    /// particles (any whole number from 0 to 2^64 - 1).
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Treat each surface sample as a point (the thesis' model) instead
    /// of as the patch of surface it stands for (exact mode).
    #[arg(long)]
    pub points_only: bool,
    /// Worker threads (default: all cores; valid: 1 to 1024).
    #[arg(long, value_parser = counted(&limits::THREADS))]
    pub threads: Option<usize>,
    /// Friction μ: the refined contact's force gets a tangential part
    /// whose spread is μ times the push (0: frictionless); `auto`: 0 for
    /// frames alone, 0.2 over time (`--temporal filter|smooth`, where
    /// friction is taken only where a press says so; valid: [0, 2]).
    #[arg(long, default_value = "auto", value_parser = friction_arg)]
    pub friction: Friction,
    /// Memory a smoothed recording may take, MiB: half for the smoother's
    /// store, whatever the recording's length (valid: 64 to 1048576).
    #[arg(long, default_value_t = EstimatorConfig::default().memory_mib, value_parser = counted(&limits::MEMORY_MIB))]
    pub memory: usize,
    /// Most contacts looked for at once in a frame: 1, or 2 (a second push
    /// where the evidence asks for it; `estimate` then lists both in
    /// `contacts`).
    #[arg(long, default_value_t = 1, value_parser = counted(&limits::CONTACTS_AT_ONCE))]
    pub contacts: usize,
    /// Prior probability that a frame with contact has two (with
    /// `--contacts 2`; valid: 1e-6 to 0.5).
    #[arg(long, default_value_t = EstimatorConfig::default().pair.prior_two)]
    pub prior_two: f64,
}

/// One `--sigma` value.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SigmaArg {
    /// Learned from the recording.
    Auto,
    /// Given, N·m.
    Value(f64),
}

/// `--calibrate`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum CalibrateArg {
    /// Learned from the recording and taken off.
    Auto,
    /// The torques as they are.
    None,
}

/// Parses one `--sigma` value: `auto` or a σ within its range.
fn sigma_arg(text: &str) -> Result<SigmaArg, String> {
    if text.trim().eq_ignore_ascii_case("auto") {
        return Ok(SigmaArg::Auto);
    }
    within(&limits::SIGMA)(text)
        .map(SigmaArg::Value)
        .map_err(|e| format!("{e} (or give auto)"))
}

/// Parses `--observer-gain`: `auto`, `none` or a gain within its range.
pub fn gain_arg(text: &str) -> Result<ObserverGain, String> {
    match text.trim().to_ascii_lowercase().as_str() {
        "auto" => Ok(ObserverGain::Auto),
        "none" => Ok(ObserverGain::Without),
        _ => within(&limits::OBSERVER_GAIN)(text)
            .map(ObserverGain::PerSecond)
            .map_err(|e| format!("{e} (or give auto or none)")),
    }
}

/// Parses `--friction`: `auto` or a μ within its range.
fn friction_arg(text: &str) -> Result<Friction, String> {
    if text.trim().eq_ignore_ascii_case("auto") {
        return Ok(Friction::Auto);
    }
    within(&limits::FRICTION)(text)
        .map(Friction::Mu)
        .map_err(|e| format!("{e} (or give auto)"))
}

/// A configuration's error as the command line says it: by option.
pub fn option_error(e: &ConfigError) -> anyhow::Error {
    anyhow::anyhow!("{}: {e}", e.field().option())
}

impl EstimatorArgs {
    /// The options (and the temporal model's, `temporal`) as the one
    /// configuration, checked.
    pub fn config(&self, temporal: &TemporalArgs) -> Result<EstimatorConfig> {
        self.config_with(temporal, DEFAULT_SURFACE_POINTS)
    }

    /// [`EstimatorArgs::config`] for frames that arrive live: the surface
    /// points [`live_surface_points`] unless `--points` says.
    pub fn live_config(&self, temporal: &TemporalArgs) -> Result<EstimatorConfig> {
        self.config_with(temporal, live_surface_points(self.contacts))
    }

    fn config_with(&self, temporal: &TemporalArgs, default_points: usize) -> Result<EstimatorConfig> {
        let values: Vec<f64> = self
            .sigma
            .iter()
            .filter_map(|s| match s {
                SigmaArg::Value(v) => Some(*v),
                SigmaArg::Auto => None,
            })
            .collect();
        let sigma_auto = values.is_empty();
        if !sigma_auto && values.len() != self.sigma.len() {
            bail!("--sigma: give auto alone, or numbers");
        }
        let sigma = match values.as_slice() {
            [] => Sigma::All(DEFAULT_SIGMA_NEWTON_METRES),
            [s] => Sigma::All(*s),
            v => Sigma::PerJoint(v.to_vec()),
        };
        let mode = match (self.mode, self.sampling) {
            (ModeArg::Exact, _) => ModeKind::Exact,
            (ModeArg::Particles, SamplingArg::Deterministic) => ModeKind::ParticlesDeterministic,
            (ModeArg::Particles, SamplingArg::Random) => ModeKind::ParticlesRandom,
        };
        let [a, b] = self.phase_sizes.as_slice() else {
            bail!("--phase-sizes needs two numbers (A,B), got {}", self.phase_sizes.len());
        };
        let config = EstimatorConfig {
            sigma,
            force_range_newtons: (self.fmin, self.fmax),
            mode,
            particles: self.particles,
            magnitudes_per_point: self.m,
            particle_seed: self.seed,
            phases: self.phases,
            phase_sizes: [*a, *b],
            alpha: self.alpha,
            friction: self.friction,
            patches: !self.points_only,
            surface_points: self.points.unwrap_or(default_points),
            surface_seed: self.seed,
            temporal: temporal.settings(),
            torques: TorqueModel {
                sigma_auto,
                calibrate: self.calibrate == CalibrateArg::Auto,
                calibration: CalibrationSettings {
                    observer_gain: self.observer_gain,
                    ..CalibrationSettings::default()
                },
            },
            memory_mib: self.memory,
            contacts_at_once: self.contacts,
            pair: PairSettings {
                prior_two: self.prior_two,
                ..PairSettings::default()
            },
        };
        config.validate(None).map_err(|e| option_error(&e))?;
        Ok(config)
    }

    /// The candidate links on `robot`: `--links`, or every link a
    /// revolute joint moves.
    pub fn links(&self, robot: &Robot) -> Result<Vec<LinkId>> {
        if self.links.is_empty() {
            return Ok(robot.default_candidate_links());
        }
        Ok(self
            .links
            .iter()
            .map(|n| robot.link_id(n))
            .collect::<Result<Vec<_>, _>>()?)
    }

    /// The estimator `config` builds on `robot` for frames combined by
    /// `temporal`.
    pub fn estimator(&self, robot: &Robot, config: &EstimatorConfig, temporal: Temporal) -> Result<Estimator> {
        config
            .estimator(robot, self.links(robot)?, temporal)
            .map_err(|e| match e {
                BuildError::Config(e) => option_error(&e),
                other => other.into(),
            })
    }

    /// Runs `f` on a thread pool of `--threads` workers.
    pub fn with_threads<T: Send>(&self, f: impl FnOnce() -> T + Send) -> Result<T> {
        let mut builder = rayon::ThreadPoolBuilder::new();
        if let Some(t) = self.threads {
            builder = builder.num_threads(t);
        }
        Ok(builder.build()?.install(f))
    }
}
