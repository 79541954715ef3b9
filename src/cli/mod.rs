//! Headless commands that run the estimator.

pub mod bench;
pub mod estimate;
pub mod live;
pub mod output;
pub mod synth;
pub mod topics;

use std::path::Path;

use anyhow::{Result, bail};
use glam::DVec3;
use proprioscope::core::config::limits::{self, CountRange, Range};
use proprioscope::core::estimate::settings::{DEFAULT_FORCE_RANGE_NEWTONS, EstimatorSettings};
use proprioscope::core::over_time::sequence::Temporal;
use proprioscope::core::over_time::temporal::TemporalSettings;
use proprioscope::core::robot::model::{LinkId, Robot};
use proprioscope::io::recording::{self, TopicChoice, is_recording};
use proprioscope::io::scene::{self as sc, Sigma};
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
}

impl TemporalArgs {
    /// The model's settings.
    pub fn settings(&self) -> TemporalSettings {
        TemporalSettings {
            onset_per_s: self.onset_rate,
            release_per_s: self.release_rate,
            slide_m_per_sqrt_s: self.slide,
            jump_per_s: self.jump_rate,
        }
    }
}

/// Estimator options shared by `estimate` and `bench`.
#[derive(Debug, Clone, clap::Args)]
pub struct EstimatorArgs {
    /// `exact` or `particles`.
    #[arg(long, value_enum, default_value = "exact")]
    pub mode: ModeArg,
    /// Particle sampling: `deterministic` or `random`.
    #[arg(long, value_enum, default_value = "deterministic")]
    pub sampling: SamplingArg,
    /// N: surface points in exact mode, particles in particle mode
    /// (valid: 1 to 1000000 surface points, 1 to 10000000 particles).
    #[arg(long, value_parser = counted(&limits::PARTICLES))]
    pub n: Option<usize>,
    /// Magnitudes per point m (deterministic particles; valid: 1 to 1000).
    #[arg(long, default_value_t = 5, value_parser = counted(&limits::MAGNITUDES))]
    pub m: usize,
    /// Surface points when N counts particles (random sampling; valid: 1
    /// to 1000000).
    #[arg(long, default_value_t = 5000, value_parser = counted(&limits::SURFACE_POINTS))]
    pub points: usize,
    /// Likelihood σ, N·m: one value, or one per sensed joint (comma
    /// separated; valid: [1e-4, 100] N·m).
    #[arg(long, value_delimiter = ',', default_value = "0.05", value_parser = within(&limits::SIGMA))]
    pub sigma: Vec<f64>,
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
    #[arg(long, default_value_t = 0.5, value_parser = within(&limits::ALPHA))]
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
    pub friction: FrictionArg,
}

/// `--friction`: a μ, or `auto`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum FrictionArg {
    /// By how frames are combined ([`Temporal::default_friction`]).
    Auto,
    /// This μ everywhere.
    Mu(f64),
}

impl FrictionArg {
    /// μ for frames combined by `temporal`.
    pub fn for_temporal(self, temporal: Temporal) -> f64 {
        match self {
            Self::Auto => temporal.default_friction(),
            Self::Mu(mu) => mu,
        }
    }
}

/// Parses `--friction`: `auto` or a finite number.
fn friction_arg(text: &str) -> Result<FrictionArg, String> {
    if text.trim().eq_ignore_ascii_case("auto") {
        return Ok(FrictionArg::Auto);
    }
    within(&limits::FRICTION)(text)
        .map(FrictionArg::Mu)
        .map_err(|e| format!("{e} (or give auto)"))
}

/// What the options ask for, resolved against a robot.
pub struct Resolved {
    /// Candidate links.
    pub links: Vec<LinkId>,
    /// Surface points.
    pub surface_points: usize,
    /// Estimator settings.
    pub settings: EstimatorSettings,
    /// Phase sizes when phases are on.
    pub phase_sizes: Option<[usize; 2]>,
}

impl EstimatorArgs {
    /// Resolves links, σ per joint and the mode for `robot`.
    pub fn resolve(&self, robot: &Robot) -> Result<Resolved> {
        let links = if self.links.is_empty() {
            robot.default_candidate_links()
        } else {
            self.links
                .iter()
                .map(|n| robot.link_id(n))
                .collect::<Result<Vec<_>, _>>()?
        };
        let joints = robot.sensed().len();
        let sigma = match self.sigma.as_slice() {
            [s] => Sigma::All(*s),
            v if v.len() == joints => Sigma::PerJoint(v.to_vec()),
            v => bail!(
                "--sigma has {} values; give one, or one per sensed joint ({joints})",
                v.len()
            ),
        };
        let (mode, sampling) = match (self.mode, self.sampling) {
            (ModeArg::Exact, _) => (sc::Mode::Exact, sc::Sampling::Deterministic),
            (ModeArg::Particles, SamplingArg::Deterministic) => (sc::Mode::Particles, sc::Sampling::Deterministic),
            (ModeArg::Particles, SamplingArg::Random) => (sc::Mode::Particles, sc::Sampling::Random),
        };
        let surface_points = match (self.mode, self.sampling) {
            (ModeArg::Exact, _) => self.n.unwrap_or(self.points),
            (ModeArg::Particles, SamplingArg::Deterministic) => {
                self.n.map_or(self.points, |n| n.div_ceil(self.m.max(1)))
            }
            (ModeArg::Particles, SamplingArg::Random) => self.points,
        };
        if let ModeArg::Exact = self.mode {
            limits::SURFACE_POINTS
                .check(surface_points)
                .map_err(|e| anyhow::anyhow!("--n: {e}"))?;
        }
        if self.fmin > self.fmax {
            bail!(
                "--fmin {} N is above --fmax {} N: the smallest push considered must not exceed the largest",
                self.fmin,
                self.fmax
            );
        }
        let phase_sizes = match (self.phases, self.phase_sizes.as_slice()) {
            (false, _) => None,
            (true, [a, b]) => Some([*a, *b]),
            (true, v) => bail!("--phase-sizes needs two numbers (A,B), got {}", v.len()),
        };
        // The options as a scene's estimator section: mapped to the core's
        // settings in one place, as scenes and the app are.
        let scene = sc::EstimatorSettings {
            mode,
            sigma_newton_metres: sigma,
            sampling,
            particles: self.n.unwrap_or(20_000),
            magnitudes_per_point: self.m.max(1),
            phases: sc::Phases {
                enabled: self.phases,
                sizes: phase_sizes.unwrap_or([200, 1000]),
                alpha: self.alpha,
            },
            force_min_newtons: self.fmin,
            force_max_newtons: self.fmax,
            particle_seed: self.seed,
            // Frames alone until the caller knows how frames are
            // combined (`FrictionArg::for_temporal`).
            friction: self.friction.for_temporal(Temporal::None),
        };
        let mut settings = scene.to_core(joints).map_err(|e| anyhow::anyhow!(e))?;
        settings.patches = !self.points_only;
        Ok(Resolved {
            links,
            surface_points,
            settings,
            phase_sizes,
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
