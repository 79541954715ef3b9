//! Sessions drawn from the model itself, for tests and benchmarks with a
//! known truth: a robot moving slowly about a random pose, pressed now and
//! then at random places of its candidate links; each press ramps up,
//! holds, may slide and may carry friction, and ramps down; the sensors
//! add a per-joint bias and Gaussian noise. Deterministic per seed.

use glam::{DQuat, DVec3};

use crate::core::geometry::shell::{CREASE_DEGREES, MeshPoint, SurfaceFrame};
use crate::core::numerics::rng::Rng;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::over_time::observer::Lag;
use crate::core::robot::dynamics::{DynamicsError, RigidBodies};
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{LinkId, Robot, RobotError};
use crate::core::robot::spatial::Inertial;
use crate::core::robot::torque::joint_torques;
use crate::core::surface::cover::CoverTable;
use crate::core::surface::sampling::{Surface, SurfaceError, SurfaceRequest};

/// How a synthetic session is drawn.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthSettings {
    /// Length, s.
    pub duration_secs: f64,
    /// Frames per second.
    pub rate_hz: f64,
    /// Each press lasts uniformly this long, s (ramps included).
    pub press_secs: (f64, f64),
    /// Between presses, uniformly this long, s (also before the first).
    pub gap_secs: (f64, f64),
    /// Each press's peak normal force, uniform in this range, N.
    pub force_newtons: (f64, f64),
    /// Ramp up and down, s each.
    pub ramp_secs: f64,
    /// Each press slides at a speed uniform in `[slide_min_m_per_s, this]`, m/s, in a random
    /// tangent direction (fixed in the link's frame for the press, its part
    /// along the surface at each frame).
    pub slide_m_per_s: f64,
    /// The slowest a press slides, m/s (its speed is uniform in
    /// `[this, slide_m_per_s]`; 0: presses that barely move too).
    pub slide_min_m_per_s: f64,
    /// Each press's tangential force is this fraction of its normal
    /// force at most (uniform in `[0, this]`), in a random tangent direction
    /// (fixed in the link's frame for the press, as the slide's).
    pub friction: f64,
    /// Each joint's constant sensor offset is uniform in `[-this, this]`, N·m.
    pub bias_newton_metres: f64,
    /// Sensor noise, N·m (standard deviation, every joint).
    pub noise_newton_metres: f64,
    /// The joints swing about the pose by this much at most, rad (period 4 s).
    pub motion_rad: f64,
    /// A press's place is drawn again (up to 100 times) until its peak
    /// normal force at the start pose makes torques of at least this norm,
    /// N·m: presses the sensors can feel (a push through the axis of
    /// the only joint that moves a link makes no torque at all).
    pub min_torque_newton_metres: f64,
    /// The torques as a real arm reports them, through a momentum
    /// observer on a model whose inertials are wrong; `None`: `JᵀF` plus
    /// bias and noise.
    pub observer: Option<ObserverSim>,
    /// Kinetic friction of sliding presses: `Some((lo, hi))` draws each
    /// press's `μ_k` uniformly in it, and a press that slides then sticks
    /// at rest for its first and last quarter and slides in between with
    /// a tangential force of `μ_k` times its normal force along the slide
    /// (the direction the object moves over the surface). `None`: a press
    /// slides throughout, its tangential force drawn as `friction` says.
    pub kinetic_friction: Option<(f64, f64)>,
    /// Contacts that may press at once, 1 or 2. With 2, a second hand
    /// presses during each press of the first, on another link: it comes
    /// while the first holds and may stay after it lets go.
    pub contacts_at_once: usize,
    /// Draw no press where the next link covers the place at the starting
    /// pose ([`CoverTable`]): no hand reaches a face inside the
    /// neighbouring link's housing. Off by default, so that a seed draws
    /// the sessions the tests and `docs/validation.md` were measured on.
    pub avoid_covered: bool,
}

/// A real arm's external torque (see [`crate::core::over_time::observer`]):
/// the arm follows the drawn motion exactly (a stiff joint PD; the
/// observer's residual depends only on the motion), the plant's inertials
/// differ from the model's (the robot's), the joints have Coulomb and
/// viscous friction, and the observer of gain K reports
/// `r = lag_K(τ_ext + Y(q, q̇, q̈)(π_model − π_plant) − τ_friction + b + n)`,
/// the friction only where the torque is sensed on the motor side.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ObserverSim {
    /// The observer's gain K, 1/s.
    pub gain_per_s: f64,
    /// Each link's mass and rotational inertia in the plant are the model's
    /// times a factor uniform in `[1 − this, 1 + this]`.
    pub mass_error: f64,
    /// Each link's centre of mass in the plant is the model's moved by up
    /// to this, in a random direction, m.
    pub com_error_m: f64,
    /// Each joint's Coulomb friction is uniform in this range, N·m.
    pub coulomb_nm: (f64, f64),
    /// Each joint's viscous friction is uniform in this range, N·m·s/rad.
    pub viscous_nms_per_rad: (f64, f64),
    /// The sensed torque is the motor's (the friction reaches the
    /// observer) rather than the link's.
    pub motor_side: bool,
}

impl Default for ObserverSim {
    /// As the shared `MuJoCo` observer examples: K = 50/s, masses ±8 %,
    /// centres of mass off by up to 5 mm, link-side sensing; joint
    /// friction 0.2–0.5 N·m and 0.3–0.6 N·m·s/rad where sensed.
    fn default() -> Self {
        Self {
            gain_per_s: 50.0,
            mass_error: 0.08,
            com_error_m: 0.005,
            coulomb_nm: (0.2, 0.5),
            viscous_nms_per_rad: (0.3, 0.6),
            motor_side: false,
        }
    }
}

/// The Coulomb friction's speed scale in the simulated plant, rad/s (a
/// sharper switch than the calibration's model assumes).
const PLANT_STICTION_SPEED_RAD_S: f64 = 0.005;

/// The cosine of the angle (60°) past which a slide's heading, out of
/// the surface's plane or turned from the last frame's direction, gives
/// way to the direction carried on (see `Track::slide_direction`).
const CARRY_BELOW: f64 = 0.5;

impl Default for SynthSettings {
    /// Six seconds at 200 Hz; presses of 0.3–1.2 s, 0.3–1 s apart, of
    /// 5–25 N, ramping in 50 ms, making at least 0.5 N·m; no slide,
    /// friction or bias; σ = 0.05 N·m; the arm swinging by 0.2 rad.
    fn default() -> Self {
        Self {
            duration_secs: 6.0,
            rate_hz: 200.0,
            press_secs: (0.3, 1.2),
            gap_secs: (0.3, 1.0),
            force_newtons: (5.0, 25.0),
            ramp_secs: 0.05,
            slide_m_per_s: 0.0,
            slide_min_m_per_s: 0.0,
            friction: 0.0,
            bias_newton_metres: 0.0,
            noise_newton_metres: 0.05,
            motion_rad: 0.2,
            min_torque_newton_metres: 0.5,
            observer: None,
            kinetic_friction: None,
            contacts_at_once: 1,
            avoid_covered: false,
        }
    }
}

/// The contact of a synthetic frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SynthContact {
    /// The pressed link.
    pub link: LinkId,
    /// Where, link frame, m.
    pub point_in_link: DVec3,
    /// Where, world frame, m.
    pub point_world: DVec3,
    /// The whole force (normal and tangential), world frame, N.
    pub force_world: DVec3,
    /// Its normal part, N.
    pub normal_newtons: f64,
}

/// One synthetic frame.
#[derive(Debug, Clone, PartialEq)]
pub struct SynthFrame {
    /// Time, s.
    pub t_secs: f64,
    /// Sensed joints' positions, rad.
    pub q: Vec<f64>,
    /// Measured torques: the contact's, the bias and noise, N·m.
    pub tau: Vec<f64>,
    /// The contact, if any (the first hand's).
    pub contact: Option<SynthContact>,
    /// The second hand's contact, if any (sessions drawn with two
    /// contacts at once).
    pub second: Option<SynthContact>,
}

impl SynthFrame {
    /// Every contact pressing, the first hand's first.
    pub fn contacts(&self) -> impl Iterator<Item = &SynthContact> {
        self.contact.iter().chain(&self.second)
    }
}

/// Every joint's position at each of `frames` (see
/// [`Robot::joint_positions`]), for [`as_sequence`].
pub fn joint_positions(robot: &Robot, frames: &[SynthFrame]) -> Result<Vec<Vec<f64>>, RobotError> {
    frames.iter().map(|f| robot.joint_positions(&f.q, &[])).collect()
}

/// `frames` as a sequence to estimate
/// ([`crate::core::over_time::sequence::estimate_sequence`]), with every joint's
/// position from [`joint_positions`].
#[must_use]
pub fn as_sequence<'a>(frames: &'a [SynthFrame], positions: &'a [Vec<f64>]) -> Vec<SequenceFrame<'a>> {
    frames
        .iter()
        .zip(positions)
        .map(|(f, p)| SequenceFrame {
            t_secs: f.t_secs,
            joint_positions: p,
            tau: &f.tau,
        })
        .collect()
}

/// Why a session could not be drawn.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SynthError {
    /// A setting is out of range.
    #[error("synthetic session: {name} = {value} is out of range")]
    BadSetting {
        /// The setting.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// The dynamics of the simulated observer could not be evaluated.
    #[error(transparent)]
    Dynamics(#[from] DynamicsError),
    /// The candidate links could not be sampled.
    #[error(transparent)]
    Surface(#[from] SurfaceError),
}

/// Most frames a synthetic session may have.
pub const MAX_SYNTH_FRAMES: usize = 10_000_000;

impl SynthSettings {
    fn validate(&self) -> Result<usize, SynthError> {
        let bad = |name: &'static str, value: f64| Err(SynthError::BadSetting { name, value });
        for (name, value) in [
            ("duration", self.duration_secs),
            ("rate", self.rate_hz),
            ("ramp", self.ramp_secs),
            ("slide", self.slide_m_per_s),
            ("slowest slide", self.slide_min_m_per_s),
            ("friction", self.friction),
            ("bias", self.bias_newton_metres),
            ("noise", self.noise_newton_metres),
            ("motion", self.motion_rad),
            ("least torque", self.min_torque_newton_metres),
        ] {
            if !value.is_finite() || value < 0.0 {
                return bad(name, value);
            }
        }
        for (name, (lo, hi)) in [
            ("slide speeds", (self.slide_min_m_per_s, self.slide_m_per_s)),
            ("press duration", self.press_secs),
            ("gap", self.gap_secs),
            ("force", self.force_newtons),
            ("kinetic friction", self.kinetic_friction.unwrap_or((0.0, 0.0))),
        ] {
            if !(lo.is_finite() && hi.is_finite() && lo >= 0.0 && hi >= lo) {
                return bad(name, lo);
            }
        }
        if let Some(o) = &self.observer {
            for (name, value) in [
                ("observer gain", o.gain_per_s),
                ("mass error", o.mass_error),
                ("centre of mass error", o.com_error_m),
                ("Coulomb friction", o.coulomb_nm.0),
                ("viscous friction", o.viscous_nms_per_rad.0),
            ] {
                if !value.is_finite() || value < 0.0 {
                    return bad(name, value);
                }
            }
            if o.gain_per_s <= 0.0 || o.mass_error >= 1.0 {
                return bad("observer gain or mass error", o.gain_per_s);
            }
            for (name, (lo, hi)) in [
                ("Coulomb friction", o.coulomb_nm),
                ("viscous friction", o.viscous_nms_per_rad),
            ] {
                if !(hi.is_finite() && hi >= lo) {
                    return bad(name, hi);
                }
            }
        }
        if !(1..=2).contains(&self.contacts_at_once) {
            return bad("contacts at once", self.contacts_at_once as f64);
        }
        let frames = (self.duration_secs * self.rate_hz).floor();
        if !(1.0..=MAX_SYNTH_FRAMES as f64).contains(&frames) {
            return bad("frames (duration × rate)", frames);
        }
        Ok(frames as usize)
    }
}

/// One press: when, where, how hard, how it slides.
struct Press {
    start: f64,
    end: f64,
    peak: f64,
    sample: usize,
    slide_angle: f64,
    slide_speed: f64,
    friction: f64,
    friction_angle: f64,
    /// `μ_k` of a press that slides with kinetic friction (see
    /// [`SynthSettings::kinetic_friction`]).
    kinetic: Option<f64>,
}

impl Press {
    /// A press over `(start, end)` of `peak` newtons at `sample`, its
    /// slide and drag drawn from `rng` (in one order: both hands' presses
    /// draw them alike, and a seed's sessions stay as they were).
    fn drawn((start, end): (f64, f64), peak: f64, sample: usize, settings: &SynthSettings, rng: &mut Rng) -> Self {
        Self {
            start,
            end,
            peak,
            sample,
            slide_angle: rng.uniform_in(0.0, std::f64::consts::TAU),
            slide_speed: rng.uniform_in(settings.slide_min_m_per_s, settings.slide_m_per_s),
            friction: rng.uniform_in(0.0, settings.friction),
            friction_angle: rng.uniform_in(0.0, std::f64::consts::TAU),
            kinetic: settings.kinetic_friction.map(|(lo, hi)| rng.uniform_in(lo, hi)),
        }
    }

    /// Whether the press is sliding at `t`: throughout without kinetic
    /// friction; with it, between its first and last quarter.
    fn slides_at(&self, t: f64) -> bool {
        if self.kinetic.is_none() {
            return true;
        }
        let quarter = 0.25 * (self.end - self.start);
        t >= self.start + quarter && t < self.end - quarter
    }
}

/// The plant behind a simulated observer, and the observer's lag.
struct SimulatedObserver<'r> {
    model: RigidBodies<'r>,
    plant: RigidBodies<'r>,
    coulomb: Vec<f64>,
    viscous: Vec<f64>,
    motor_side: bool,
    lag: Lag,
}

impl<'r> SimulatedObserver<'r> {
    fn new(robot: &'r Robot, settings: &ObserverSim, rng: &mut Rng) -> Self {
        let model = RigidBodies::new(robot);
        let plant_parameters: Vec<f64> = robot
            .links
            .iter()
            .flat_map(|link| {
                let scale = rng.uniform_in(1.0 - settings.mass_error, 1.0 + settings.mass_error);
                let direction = DVec3::new(rng.normal(), rng.normal(), rng.normal()).normalize_or_zero();
                let shift = direction * rng.uniform_in(0.0, settings.com_error_m);
                Inertial {
                    mass_kg: link.inertial.mass_kg * scale,
                    com_in_link_m: link.inertial.com_in_link_m + shift,
                    inertia_about_com: link.inertial.inertia_about_com * scale,
                }
                .parameters()
            })
            .collect();
        let plant = model
            .clone()
            .with_parameters(&plant_parameters)
            .unwrap_or_else(|_| model.clone());
        let joints = robot.sensed().len();
        let (lo, hi) = settings.coulomb_nm;
        let coulomb = (0..joints).map(|_| rng.uniform_in(lo, hi)).collect();
        let (lo, hi) = settings.viscous_nms_per_rad;
        let viscous = (0..joints).map(|_| rng.uniform_in(lo, hi)).collect();
        Self {
            model,
            plant,
            coulomb,
            viscous,
            motor_side: settings.motor_side,
            lag: Lag::new(Some(settings.gain_per_s), joints),
        }
    }

    /// The observer's residual for a frame whose contact, bias and noise
    /// make `measured`.
    fn step(&mut self, q: &[f64], qd: &[f64], qdd: &[f64], measured: &[f64], dt: f64) -> Result<Vec<f64>, SynthError> {
        let ours = self.model.inverse_dynamics(q, qd, qdd)?;
        let theirs = self.plant.inverse_dynamics(q, qd, qdd)?;
        let input: Vec<f64> = (0..measured.len())
            .map(|j| {
                let friction = if self.motor_side {
                    self.coulomb[j] * (qd[j] / PLANT_STICTION_SPEED_RAD_S).tanh() + self.viscous[j] * qd[j]
                } else {
                    0.0
                };
                measured[j] + ours[j] - theirs[j] - friction
            })
            .collect();
        Ok(self.lag.step(dt, &input).to_vec())
    }
}

/// Presses one after another over the session, each at a place the
/// sensors can feel at `start_pose` (see
/// [`SynthSettings::min_torque_newton_metres`]) and that no neighbouring
/// link covers there (`covered`, sorted pool samples: no hand reaches a
/// face inside the next link).
fn draw_presses(
    robot: &Robot,
    pool: &Surface,
    covered: &[u32],
    start_pose: &RobotPose,
    settings: &SynthSettings,
    rng: &mut Rng,
) -> Vec<Press> {
    let felt = |sample: usize, peak: f64| -> f64 {
        let (Some(&link), Some(&p), Some(&n)) = (
            pool.link.get(sample),
            pool.point_in_link.get(sample),
            pool.inward_normal_in_link.get(sample),
        ) else {
            return 0.0;
        };
        let world = start_pose.world_from_link.get(link).copied().unwrap_or_default();
        let tau = joint_torques(
            robot,
            start_pose,
            link,
            world.transform_point3(p),
            world.transform_vector3(n) * peak,
        );
        tau.iter().map(|t| t * t).sum::<f64>().sqrt()
    };
    let mut presses = Vec::new();
    let mut t = rng.uniform_in(settings.gap_secs.0, settings.gap_secs.1);
    while t < settings.duration_secs && !pool.is_empty() {
        let length = rng.uniform_in(settings.press_secs.0, settings.press_secs.1);
        let peak = rng.uniform_in(settings.force_newtons.0, settings.force_newtons.1);
        let mut sample = rng.below(pool.len());
        for _ in 0..100 {
            if felt(sample, peak) >= settings.min_torque_newton_metres && !is_covered(covered, sample) {
                break;
            }
            sample = rng.below(pool.len());
        }
        presses.push(Press::drawn((t, t + length), peak, sample, settings, rng));
        t += length + rng.uniform_in(settings.gap_secs.0, settings.gap_secs.1).max(1e-3);
    }
    presses
}

/// The second hand's presses: one during each of `first`'s (whose
/// start it follows by 20–60 % of that press's length), of the same
/// spread of lengths and forces (ending at most half-way into the gap
/// after that press), on a link other than those of the first
/// hand's presses it overlaps (where the pool has one), not at a
/// `covered` sample (as [`draw_presses`]), never two at once.
fn draw_second_presses(
    pool: &Surface,
    covered: &[u32],
    first: &[Press],
    settings: &SynthSettings,
    rng: &mut Rng,
) -> Vec<Press> {
    let mut presses: Vec<Press> = Vec::new();
    for (k, p) in first.iter().enumerate() {
        let start = p.start + rng.uniform_in(0.2, 0.6) * (p.end - p.start);
        let length = rng.uniform_in(settings.press_secs.0, settings.press_secs.1);
        let peak = rng.uniform_in(settings.force_newtons.0, settings.force_newtons.1);
        // It outstays the first by half the gap after it at most: the arm
        // stays free between presses for about as long as with one hand
        // (a model error is learned from those frames).
        let next = first.get(k + 1).map_or(settings.duration_secs, |n| n.start);
        let end = (start + length)
            .min(p.end + 0.5 * (next - p.end).max(0.0))
            .min(settings.duration_secs);
        let busy = presses.last().is_some_and(|last| start < last.end + settings.ramp_secs);
        // The links of the first hand's presses it overlaps.
        let taken: Vec<Option<&LinkId>> = first
            .iter()
            .filter(|f| f.start < end && f.end > start)
            .map(|f| pool.link.get(f.sample))
            .collect();
        let mut sample = rng.below(pool.len().max(1));
        for _ in 0..100 {
            if !taken.contains(&pool.link.get(sample)) && !is_covered(covered, sample) {
                break;
            }
            sample = rng.below(pool.len().max(1));
        }
        let press = Press::drawn((start, end), peak, sample, settings, rng);
        if !busy && press.end > press.start && !pool.is_empty() {
            presses.push(press);
        }
    }
    presses
}

/// Whether pool sample `sample` is in the sorted list `covered`.
fn is_covered(covered: &[u32], sample: usize) -> bool {
    u32::try_from(sample).is_ok_and(|k| covered.binary_search(&k).is_ok())
}

/// One hand's presses over the session, and where its press is now.
struct Track {
    presses: Vec<Press>,
    index: usize,
    /// Where the press is now (it slides from here).
    place: Option<MeshPoint>,
    /// The press's slide and drag directions, link frame: drawn at its
    /// first frame as angles in the tangent plane there, then kept (the
    /// slide takes its part along the surface at each frame, and is
    /// carried over an edge as [`Track::slide_direction`] says). A mesh's
    /// tangents are its triangles' edges, so angles taken anew at every
    /// frame would turn both at every edge the slide crosses.
    heading: Option<(DVec3, DVec3)>,
    /// The slide's direction at the last frame and the inward normal
    /// there, link frame: carried over an edge where the heading would
    /// turn (see [`Track::slide_direction`]).
    carried: Option<(DVec3, DVec3)>,
}

impl Track {
    fn new(presses: Vec<Press>) -> Self {
        Self {
            presses,
            index: 0,
            place: None,
            heading: None,
            carried: None,
        }
    }

    /// The slide's direction in the tangent plane of `frame`: the press's
    /// heading's part along the surface; or the last frame's direction
    /// turned with the surface (the arc from its normal to this one),
    /// which then becomes the heading, where the place has just crossed
    /// a crease (its normal turned by more than
    /// [`CREASE_DEGREES`]), or where the
    /// heading's part is short (more than 60° out of the plane,
    /// [`CARRY_BELOW`]) or turns from the last direction by more than
    /// 60°. The heading alone, taken along the surface at every frame,
    /// flips where a slide runs over a rim onto a face, and runs along a
    /// crease that the slide meets at a slant: the place and its push
    /// would go back and forth over the edge frame by frame, turning by
    /// 40–90° each time, which no object sliding over an arm does.
    fn slide_direction(
        heading: &mut Option<(DVec3, DVec3)>,
        carried: &mut Option<(DVec3, DVec3)>,
        frame: &SurfaceFrame,
    ) -> DVec3 {
        let normal = frame.inward_normal;
        let on_surface = |v: DVec3| v - v.dot(normal) * normal;
        let Some((slide_in_link, drag_in_link)) = *heading else {
            return DVec3::ZERO;
        };
        let along = on_surface(slide_in_link);
        let direction = along.normalize_or_zero();
        let crease_cos = CREASE_DEGREES.to_radians().cos();
        let carried_on = carried.and_then(|(before, before_normal)| {
            let on = on_surface(DQuat::from_rotation_arc(before_normal, normal) * before).try_normalize()?;
            let creased = before_normal.dot(normal) < crease_cos;
            (creased || along.length() < CARRY_BELOW || direction.dot(on) < CARRY_BELOW).then_some(on)
        });
        let direction = match carried_on {
            Some(on) => {
                *heading = Some((on, drag_in_link));
                on
            }
            None => direction,
        };
        *carried = Some((direction, normal));
        direction
    }

    /// The contact at time `t` in `pose` (frames `dt_secs` apart), the
    /// press moved on by its slide.
    fn contact_at(
        &mut self,
        t: f64,
        dt_secs: f64,
        pose: &RobotPose,
        pool: &Surface,
        ramp_secs: f64,
    ) -> Option<SynthContact> {
        while self.presses.get(self.index).is_some_and(|p| t >= p.end) {
            self.index += 1;
            self.place = None;
            self.heading = None;
            self.carried = None;
        }
        let p = self.presses.get(self.index).filter(|p| t >= p.start)?;
        let ramp = ramp_secs.max(1e-9);
        let up = ((t - p.start) / ramp).min(1.0);
        let down = ((p.end - t) / ramp).min(1.0);
        let magnitude = p.peak * up.min(down).max(0.0);
        let link = pool.link.get(p.sample).copied()?;
        let shape = pool.shape(link)?;
        // Slide from where the press is now.
        let at = self.place.or_else(|| pool.location.get(p.sample).copied())?;
        let f = shape.frame(at)?;
        let (_, drag_in_link) = *self.heading.get_or_insert_with(|| {
            let towards = |angle: f64| f.tangents[0] * angle.cos() + f.tangents[1] * angle.sin();
            (towards(p.slide_angle), towards(p.friction_angle))
        });
        let direction = Self::slide_direction(&mut self.heading, &mut self.carried, &f);
        let sliding = p.slides_at(t) && p.slide_speed > 0.0;
        if sliding || p.kinetic.is_none() {
            self.place = Some(shape.walk(at, direction * (p.slide_speed * dt_secs)));
        }
        if magnitude <= 0.0 {
            return None;
        }
        // Sliding with kinetic friction: μ_k times the push along the
        // slide (the object moves that way over the arm, and drags it
        // along). Otherwise the drag as drawn, anywhere in the cone (for a
        // press that holds its place, the tangent direction of its
        // triangle).
        let tangential = match p.kinetic {
            Some(mu) if sliding => direction * mu,
            _ => drag_in_link * p.friction,
        };
        let world = pose.world_from_link.get(link).copied().unwrap_or_default();
        Some(SynthContact {
            link,
            point_in_link: f.point,
            point_world: world.transform_point3(f.point),
            force_world: world.transform_vector3(f.inward_normal + tangential) * magnitude,
            normal_newtons: magnitude,
        })
    }
}

/// Draws a session of `robot` pressed on `links`.
///
/// # Errors
/// [`SynthError`] for settings out of range or links without a surface.
pub fn synthesize(
    robot: &Robot,
    links: &[LinkId],
    settings: &SynthSettings,
    seed: u64,
) -> Result<Vec<SynthFrame>, SynthError> {
    synthesize_with_plant(robot, links, settings, seed).map(|(frames, _)| frames)
}

/// The simulated observer's plant: what a calibration should find.
#[derive(Debug, Clone, PartialEq)]
pub struct PlantTruth {
    /// Each joint's Coulomb friction, N·m.
    pub coulomb_nm: Vec<f64>,
    /// Each joint's viscous friction, N·m·s/rad.
    pub viscous_nms_per_rad: Vec<f64>,
    /// The model's inertial parameters minus the plant's, ten per link.
    pub inertial_error: Vec<f64>,
}

/// [`synthesize`], with the plant behind a simulated observer (`None`
/// without one).
#[allow(clippy::too_many_lines)] // One frame after another, read top to bottom.
pub fn synthesize_with_plant(
    robot: &Robot,
    links: &[LinkId],
    settings: &SynthSettings,
    seed: u64,
) -> Result<(Vec<SynthFrame>, Option<PlantTruth>), SynthError> {
    let frames = settings.validate()?;
    let mut rng = Rng::new(seed);
    let pool = Surface::sample_random(
        robot,
        &SurfaceRequest {
            links: links.to_vec(),
            total_points: 256.max(links.len()),
            seed: seed ^ 0x5eed_5eed,
        },
    )?;
    // The pose and its swing.
    let joints = robot.sensed().len();
    let (base, phase): (Vec<f64>, Vec<f64>) = robot
        .sensed()
        .iter()
        .map(|&j| {
            let (lo, hi) = robot
                .joints
                .get(j)
                .and_then(|joint| joint.limits)
                .map_or((-1.0, 1.0), |l| (l.lower, l.upper));
            let mid = 0.5 * (lo + hi);
            let half = 0.3 * (hi - lo);
            (
                rng.uniform_in(mid - half, mid + half),
                rng.uniform_in(0.0, std::f64::consts::TAU),
            )
        })
        .unzip();
    let bias: Vec<f64> = (0..joints)
        .map(|_| rng.uniform_in(-settings.bias_newton_metres, settings.bias_newton_metres))
        .collect();
    let start_positions = robot.joint_positions(&base, &[]).unwrap_or_default();
    let start_pose = RobotPose::new(robot, &start_positions);
    // Where asked, no hand presses a face that the next link covers.
    let covered = if settings.avoid_covered {
        CoverTable::build(robot, &pool.link, &pool.point_in_link, &pool.inward_normal_in_link)
            .covered_at(&start_positions)
    } else {
        Vec::new()
    };
    let presses = draw_presses(robot, &pool, &covered, &start_pose, settings, &mut rng);
    let dt = 1.0 / settings.rate_hz;
    let mut observer = settings.observer.map(|o| SimulatedObserver::new(robot, &o, &mut rng));
    // The second hand draws from a stream of its own: a one-contact
    // session of a seed is the same with or without this option.
    let second_presses = if settings.contacts_at_once >= 2 {
        draw_second_presses(&pool, &covered, &presses, settings, &mut Rng::new(seed ^ 0x2c0_17ac7))
    } else {
        Vec::new()
    };
    let mut hands = [Track::new(presses), Track::new(second_presses)];
    let mut out = Vec::with_capacity(frames);
    for i in 0..frames {
        let t = i as f64 * dt;
        let q: Vec<f64> = base
            .iter()
            .zip(&phase)
            .map(|(q0, ph)| q0 + settings.motion_rad * (std::f64::consts::TAU * t / 4.0 + ph).sin())
            .collect();
        let pose = RobotPose::new(robot, &robot.joint_positions(&q, &[]).unwrap_or_default());
        let [first, second] = &mut hands;
        let contact = first.contact_at(t, dt, &pose, &pool, settings.ramp_secs);
        let second = second.contact_at(t, dt, &pose, &pool, settings.ramp_secs);
        let mut tau = vec![0.0; joints];
        for c in contact.iter().chain(&second) {
            for (t, x) in tau
                .iter_mut()
                .zip(joint_torques(robot, &pose, c.link, c.point_world, c.force_world))
            {
                *t += x;
            }
        }
        for (t, b) in tau.iter_mut().zip(&bias) {
            *t += b + settings.noise_newton_metres * rng.normal();
        }
        if let Some(sim) = observer.as_mut() {
            let omega = std::f64::consts::TAU / 4.0;
            let (qd, qdd): (Vec<f64>, Vec<f64>) = phase
                .iter()
                .map(|ph| {
                    let angle = omega * t + ph;
                    (
                        settings.motion_rad * omega * angle.cos(),
                        -settings.motion_rad * omega * omega * angle.sin(),
                    )
                })
                .unzip();
            tau = sim.step(&q, &qd, &qdd, &tau, if i == 0 { 0.0 } else { dt })?;
        }
        out.push(SynthFrame {
            t_secs: t,
            q,
            tau,
            contact,
            second,
        });
    }
    let plant = observer.map(|sim| PlantTruth {
        inertial_error: sim
            .model
            .parameters()
            .iter()
            .zip(sim.plant.parameters())
            .map(|(a, b)| a - b)
            .collect(),
        coulomb_nm: sim.coulomb,
        viscous_nms_per_rad: sim.viscous,
    });
    Ok((out, plant))
}

#[cfg(test)]
#[path = "synth_tests.rs"]
mod tests;
