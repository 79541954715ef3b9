//! `proprioscope synth OUT`: writes a session drawn from the model itself
//! (presses that hold their place or slide, come and go, with friction,
//! bias and noise as asked), with its truth: data for `estimate` and the
//! app whose answer is known.

use std::path::PathBuf;

use anyhow::{Context as _, Result};
use proprioscope::core::eval::synth::{ObserverSim, SynthContact, SynthSettings, synthesize};
use proprioscope::core::robot::builtin;
use proprioscope::io::session::{ContactTruth, Frame, Recorder, Truth};

use proprioscope::core::config::limits;

use super::within;

/// Options of `synth`.
#[derive(Debug, clap::Args)]
pub struct SynthArgs {
    /// The session file to write (JSON).
    pub out: PathBuf,
    /// Length, s (valid: (0, 3600] s).
    #[arg(long, default_value_t = 6.0, value_parser = within(&limits::SECONDS))]
    pub seconds: f64,
    /// Frames per second (valid: (0, 10000] Hz).
    #[arg(long, default_value_t = 200.0, value_parser = within(&limits::RATE_HZ))]
    pub rate: f64,
    /// Seed of everything drawn.
    #[arg(long, default_value_t = 0)]
    pub seed: u64,
    /// Links pressed (names); default: every link a revolute joint moves.
    #[arg(long, value_delimiter = ',')]
    pub links: Vec<String>,
    /// Each press's tangential force is up to this fraction of its normal
    /// force (a random direction per press; valid: [0, 2]).
    #[arg(long, default_value_t = 0.0, value_parser = within(&limits::FRICTION))]
    pub friction: f64,
    /// Each joint's bias is drawn uniformly within ± this, N·m (valid: [0, 100]).
    #[arg(long, default_value_t = 0.0, value_parser = within(&limits::BIAS))]
    pub bias: f64,
    /// Each press slides at up to this speed, m/s (valid: [0, 1]).
    #[arg(long, default_value_t = 0.0, value_parser = within(&limits::SLIDE_SPEED))]
    pub slide: f64,
    /// And at least at this speed, m/s (valid: [0, 1], not above --slide).
    #[arg(long, default_value_t = 0.0, value_parser = within(&limits::SLIDE_SPEED))]
    pub slide_min: f64,
    /// Gaussian noise on every torque, N·m (valid: [0, 100]).
    #[arg(long, default_value_t = 0.05, value_parser = within(&limits::NOISE))]
    pub noise: f64,
    /// Torques as a real arm reports them: through a momentum observer of
    /// this gain, 1/s, on a model whose inertials are wrong (--noise is
    /// then the sensor's, before the observer; valid: (0, 10000] 1/s).
    #[arg(long, value_parser = within(&limits::OBSERVER_GAIN))]
    pub observer_gain: Option<f64>,
    /// With --observer-gain: the plant's masses and inertias differ from
    /// the model's by up to this fraction (valid: [0, 0.99]).
    #[arg(long, default_value_t = 0.08, requires = "observer_gain", value_parser = within(&limits::MODEL_ERROR))]
    pub model_error: f64,
    /// With --observer-gain: `link`-side torque sensing (the observer sees
    /// no joint friction) or `motor`-side (it sees Coulomb friction of
    /// 0.2–0.5 N·m and viscous of 0.3–0.6 N·m·s/rad per joint).
    #[arg(long, value_enum, default_value = "link", requires = "observer_gain")]
    pub sensing: Sensing,
    /// The joints swing about the pose by this much, rad, over 4 s
    /// (valid: [0, 3.2]).
    #[arg(long, default_value_t = 0.2, value_parser = within(&limits::SWING))]
    pub swing: f64,
    /// Kinetic friction of sliding presses, `LO,HI`: each press's `μ_k` is
    /// drawn in it, and a press that slides (--slide) sticks at rest for
    /// its first and last quarter and slides in between, dragging the arm
    /// along the slide with `μ_k` times its push (valid: [0, 2] each).
    #[arg(long, value_delimiter = ',', value_name = "LO,HI", value_parser = within(&limits::FRICTION))]
    pub kinetic_friction: Option<Vec<f64>>,
    /// Each press lasts a time drawn uniformly in `LO,HI`, s, its 50 ms
    /// ramps included (default 0.3,1.2). A press with kinetic friction
    /// slides for the middle half of it, so its slide is half the press
    /// times its speed: presses of 1.5–3 s at 2–10 cm/s slide 1.5–15 cm
    /// (valid: (0, 3600] s each).
    #[arg(long, value_delimiter = ',', value_name = "LO,HI", value_parser = within(&limits::SECONDS))]
    pub press_secs: Option<Vec<f64>>,
    /// Contacts that may press at once, 1 or 2. With 2, a second hand
    /// presses during each press on another link, coming while the first
    /// holds and staying a while after it lets go; every true contact is
    /// written in `truth_all`.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u8).range(1..=2))]
    pub contacts: u8,
    /// Draw no press on a face that the next link covers at the starting
    /// pose (a face inside the neighbouring link's housing, which no hand
    /// reaches); without it a seed draws the sessions of earlier versions.
    #[arg(long)]
    pub avoid_covered: bool,
}

/// `--sensing`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub enum Sensing {
    /// Joint torque sensors after the gearbox (LWR, iiwa, Panda).
    Link,
    /// Motor currents: the joints' friction is in the torque.
    Motor,
}

/// An option given as `LO,HI` (each value already checked against its
/// range): `None` where it is not given.
fn interval(option: &str, values: Option<&[f64]>) -> Result<Option<(f64, f64)>> {
    match values {
        None => Ok(None),
        Some(&[lo, hi]) if lo <= hi => Ok(Some((lo, hi))),
        Some(other) => anyhow::bail!("{option} {other:?}: give LO,HI with LO ≤ HI"),
    }
}

/// Runs the command.
pub fn run(args: &SynthArgs) -> Result<()> {
    let robot = builtin::lwr4plus_generated().context("the built-in LWR")?;
    let links = if args.links.is_empty() {
        robot.default_candidate_links()
    } else {
        args.links
            .iter()
            .map(|name| robot.link_id(name).with_context(|| format!("--links {name}")))
            .collect::<Result<Vec<_>>>()?
    };
    let kinetic_friction = interval("--kinetic-friction", args.kinetic_friction.as_deref())?;
    let defaults = SynthSettings::default();
    let press_secs = interval("--press-secs", args.press_secs.as_deref())?.unwrap_or(defaults.press_secs);
    let settings = SynthSettings {
        duration_secs: args.seconds,
        rate_hz: args.rate,
        friction: args.friction,
        bias_newton_metres: args.bias,
        slide_m_per_s: args.slide,
        slide_min_m_per_s: args.slide_min,
        noise_newton_metres: args.noise,
        motion_rad: args.swing,
        observer: args.observer_gain.map(|gain_per_s| ObserverSim {
            gain_per_s,
            mass_error: args.model_error,
            motor_side: args.sensing == Sensing::Motor,
            ..ObserverSim::default()
        }),
        contacts_at_once: usize::from(args.contacts),
        avoid_covered: args.avoid_covered,
        kinetic_friction,
        press_secs,
        ..defaults
    };
    let frames = synthesize(&robot, &links, &settings, args.seed)?;
    let joints: Vec<String> = robot.sensed_names().iter().map(|s| (*s).to_owned()).collect();
    let mut recorder = Recorder::create(&args.out, "lwr4plus", &joints)?;
    let truth_of = |c: &SynthContact| ContactTruth {
        link: robot.links.get(c.link).map(|l| l.name.clone()).unwrap_or_default(),
        point: c.point_world.to_array(),
        force: c.force_world.to_array(),
    };
    for f in &frames {
        // `truth` the first contact pressing; `truth_all` every one where
        // two press.
        let truth = match f.contacts().next().map(truth_of) {
            Some(ContactTruth { link, point, force }) => Truth::Contact { link, point, force },
            None => Truth::NoContact,
        };
        let truth_all = if f.contacts().count() > 1 {
            f.contacts().map(truth_of).collect()
        } else {
            Vec::new()
        };
        recorder.write(&Frame {
            t: f.t_secs,
            q: f.q.clone(),
            tau: f.tau.clone(),
            truth,
            truth_all,
        })?;
    }
    let written = recorder.finish()?;
    log::info!("{}: {written} frames", args.out.display());
    Ok(())
}
