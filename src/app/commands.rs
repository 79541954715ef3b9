//! The commands the UI sends, and the one place where they change the
//! [`Model`] (playback included). No egui here.

use glam::DVec3;

use super::{EstimatorConfig, LinkId, Model, Push, Sigma, Temporal, ViewOptions};
use crate::core::config::limits;

/// A change to the [`Model`], sent by the UI and applied in one place.
#[derive(Debug, Clone, PartialEq)]
pub enum Command {
    /// Set sensed joint `index` to a position, rad.
    SetJoint(usize, f64),
    /// Every joint to 0.
    ZeroJoints,
    /// Every joint to a random position within its limits (seeded).
    RandomPose(u64),
    /// Set the seed of the sensor noise.
    SetNoiseSeed(u64),
    /// Apply a push.
    Push(Push),
    /// Set the push's magnitude, N.
    SetForce(f64),
    /// Remove the push (and a second one).
    ClearPush,
    /// Apply a second push at the same time (the estimator then looks for
    /// two contacts, and the view shows both contacts' posteriors).
    SecondPush(Push),
    /// Set the second push's magnitude, N.
    SetSecondForce(f64),
    /// Remove the second push.
    ClearSecondPush,
    /// Set the likelihood σ of every joint, N·m (on a session σ is then
    /// no longer learned).
    SetSigma(f64),
    /// Set one joint's likelihood σ, N·m (on a session σ is then no
    /// longer learned).
    SetJointSigma(usize, f64),
    /// σ per joint learned from the session, N·m (used while σ is
    /// learned; the σ set is kept).
    SetLearnedSigma(Vec<f64>),
    /// σ learned from the session (true) or as set.
    SetSigmaAuto(bool),
    /// Learn the model error from the session and take it off (true) or not.
    SetCalibrate(bool),
    /// Set the surface resolution.
    SetSurfacePoints(usize),
    /// Make a link a candidate (true) or not.
    SetCandidate(LinkId, bool),
    /// Set the sensor noise, N·m.
    SetNoise(f64),
    /// Set the estimator's configuration (mode, particles, phases,
    /// friction; the panel edits a copy and sends it whole).
    SetConfig(EstimatorConfig),
    /// Set the force range, N.
    SetForceRange(f64, f64),
    /// Set how the heatmap is drawn.
    SetView(ViewOptions),
    /// Show a session frame (index into its good frames).
    SetFrame(usize),
    /// Move this many frames (negative: back).
    StepFrames(i64),
    /// Play (true) or pause.
    Play(bool),
    /// Set the playback speed (within [`super::SPEED`]).
    SetSpeed(f64),
    /// Loop at the end (true) or stop.
    SetLoop(bool),
    /// Estimate the session's frames alone, filtered or smoothed.
    SetOverTime(Temporal),
    /// Take the session's estimated torque bias off its frames (true) or not.
    SetBias(bool),
    /// How far a contact slides over time, m/√s (within [`super::SLIDE`]).
    SetSlide(f64),
    /// Advance playback by this much wall-clock time, s.
    Tick(f64),
}

/// The replay's settings that `command` sets (the others: nothing).
fn set_replay(r: &mut super::Replay, command: &Command) {
    match *command {
        Command::SetSpeed(speed) => r.speed = speed,
        Command::SetLoop(on) => r.looping = on,
        Command::SetOverTime(temporal) => r.over_time = temporal,
        Command::SetBias(on) => r.bias_auto = on,
        _ => {}
    }
}

impl Model {
    /// Why `command` cannot be applied: a value outside its valid range
    /// (see [`crate::core::config::limits`]), named with the range. A typed value
    /// is refused whole rather than clamped: the panel keeps the value
    /// before and says why.
    #[must_use]
    pub fn refusal(&self, command: &Command) -> Option<String> {
        let why = |result: Result<f64, limits::OutOfRange>| result.err().map(|e| e.to_string());
        // The timeline's slide within its own span first.
        if let Command::SetSlide(slide) = *command
            && let Err(e) = super::SLIDE.check(slide)
        {
            return Some(e.to_string());
        }
        if let Some(config) = self.configured(command) {
            return config
                .validate(Some(self.robot.sensed().len()))
                .err()
                .map(|e| e.to_string());
        }
        match *command {
            Command::SetJoint(i, value) => self.joint_refusal(i, value),
            Command::SetForce(f) | Command::SetSecondForce(f) => why(limits::PUSH_NEWTONS.check(f)),
            Command::SetNoise(s) => why(limits::NOISE.check(s)),
            Command::SetView(view) => why(limits::THRESHOLD.check(view.threshold)),
            Command::SetSpeed(speed) => why(super::SPEED.check(speed)),
            Command::SetLearnedSigma(ref sigma) => {
                if sigma.len() != self.robot.sensed().len() {
                    return Some(format!(
                        "{} learned σ for {} sensed joints",
                        sigma.len(),
                        self.robot.sensed().len()
                    ));
                }
                sigma.iter().find_map(|s| why(limits::SIGMA.check(*s)))
            }
            _ => None,
        }
    }

    /// The configuration a command sets (σ, the surface's points, the
    /// force range, the slide, or a whole configuration); `None` for the
    /// commands that leave it.
    fn configured(&self, command: &Command) -> Option<EstimatorConfig> {
        let mut config = self.config.clone();
        let joints = self.robot.sensed().len();
        match command {
            // σ set by hand on a session is no longer learned from it.
            Command::SetSigma(s) => {
                config.sigma = Sigma::PerJoint(vec![*s; joints]);
                config.torques.sigma_auto &= self.replay.is_none();
            }
            Command::SetJointSigma(i, s) => {
                let mut sigma = super::per_joint(self.sigma(), joints);
                *sigma.get_mut(*i)? = *s;
                config.sigma = Sigma::PerJoint(sigma);
                config.torques.sigma_auto &= self.replay.is_none();
            }
            Command::SetSigmaAuto(on) => config.torques.sigma_auto = *on,
            Command::SetCalibrate(on) => config.torques.calibrate = *on,
            Command::SetSurfacePoints(n) => config.surface_points = *n,
            Command::SetForceRange(lo, hi) => config.force_range_newtons = (*lo, *hi),
            Command::SetSlide(slide) => config.temporal.slide_m_per_sqrt_s = *slide,
            Command::SetConfig(c) => {
                config = c.clone();
                // The app keeps σ one per sensed joint.
                config.sigma = Sigma::PerJoint(match &c.sigma {
                    Sigma::All(s) => vec![*s; joints],
                    Sigma::PerJoint(v) => v.clone(),
                });
            }
            _ => return None,
        }
        Some(config)
    }

    /// The first setting of the model outside its valid range, if any
    /// (none can be: every command that sets one is checked).
    #[must_use]
    pub fn out_of_range(&self) -> Option<String> {
        if let Err(e) = self.config.validate(Some(self.robot.sensed().len())) {
            return Some(e.to_string());
        }
        let mut commands = vec![Command::SetNoise(self.noise_sigma), Command::SetView(self.view)];
        if let Some(r) = &self.replay {
            commands.extend([
                Command::SetSpeed(r.speed),
                Command::SetSlide(self.config.temporal.slide_m_per_sqrt_s),
            ]);
        }
        let joint = self
            .q
            .iter()
            .find_map(|&q| limits::JOINT_POSITION.check(q).err().map(|e| e.to_string()));
        joint.or_else(|| commands.iter().find_map(|c| self.refusal(c)))
    }

    /// Why sensed joint `i` cannot be put at `value`: outside
    /// [`limits::JOINT_POSITION`] or the joint's own limits.
    fn joint_refusal(&self, i: usize, value: f64) -> Option<String> {
        if let Err(e) = limits::JOINT_POSITION.check(value) {
            return Some(e.to_string());
        }
        let joint = self.robot.sensed().get(i).and_then(|&j| self.robot.joints.get(j))?;
        let l = joint.limits?;
        // A hair of slack: a value typed in degrees comes back in radians.
        let slack = 1e-9 * (1.0 + l.upper.abs().max(l.lower.abs()));
        (value < l.lower - slack || value > l.upper + slack).then(|| {
            if joint.kind.is_rotational() {
                format!(
                    "{:.3}° is outside the limits of {}: [{:.3}°, {:.3}°]",
                    value.to_degrees(),
                    joint.name,
                    l.lower.to_degrees(),
                    l.upper.to_degrees()
                )
            } else {
                format!(
                    "{value} m is outside the limits of {}: [{}, {}] m",
                    joint.name, l.lower, l.upper
                )
            }
        })
    }

    /// Applies a command; true when something changed. A command with a
    /// value outside its range changes nothing and leaves its reason in
    /// [`Model::refused`].
    // Taken by value: a command is made to be applied, `apply(Command::…)`.
    #[allow(clippy::needless_pass_by_value)]
    pub fn apply(&mut self, command: Command) -> bool {
        if let Some(why) = self.refusal(&command) {
            self.refused = Some(why);
            return false;
        }
        if let Some(config) = self.configured(&command) {
            let changed = config != self.config;
            self.config = config;
            self.refused = None;
            return changed && !matches!(command, Command::SetSlide(_));
        }
        if !matches!(command, Command::Tick(_)) {
            self.refused = None;
        }
        let before = self.estimate_inputs();
        match command {
            Command::SetJoint(i, value) => {
                if let Some(q) = self.q.get_mut(i) {
                    *q = value;
                }
            }
            Command::ZeroJoints => self.q.iter_mut().for_each(|q| *q = 0.0),
            Command::RandomPose(seed) => {
                let mut rng = crate::core::numerics::rng::Rng::new(seed);
                for (q, &j) in self.q.iter_mut().zip(self.robot.sensed()) {
                    let (lo, hi) = self.robot.joints[j]
                        .limits
                        .map_or((-std::f64::consts::PI, std::f64::consts::PI), |l| (l.lower, l.upper));
                    *q = rng.uniform_in(lo, hi);
                }
            }
            Command::SetNoiseSeed(seed) => self.noise_seed = seed,
            Command::Push(_)
            | Command::SetForce(_)
            | Command::ClearPush
            | Command::SecondPush(_)
            | Command::SetSecondForce(_)
            | Command::ClearSecondPush => self.apply_push(&command),
            Command::SetCandidate(link, on) => {
                let can_touch = self.robot.default_candidate_links().contains(&link);
                if on && can_touch && !self.candidate_links.contains(&link) {
                    self.candidate_links.push(link);
                    self.candidate_links.sort_unstable();
                } else if !on && self.candidate_links.len() > 1 {
                    // At least one link stays: an empty surface has no posterior.
                    self.candidate_links.retain(|l| *l != link);
                }
            }
            Command::SetNoise(s) => self.noise_sigma = s,
            Command::SetView(view) => self.view = view,
            Command::SetFrame(i) => self.show_frame(i),
            Command::StepFrames(by) => {
                if let Some(r) = &self.replay {
                    let last = r.session.frames.len().saturating_sub(1);
                    let target = i64::try_from(r.frame).unwrap_or(0).saturating_add(by).max(0);
                    self.show_frame(usize::try_from(target).unwrap_or(0).min(last));
                }
            }
            Command::Play(on) => {
                let at_end = self
                    .replay
                    .as_ref()
                    .is_some_and(|r| r.frame + 1 >= r.session.frames.len());
                if on && at_end {
                    self.show_frame(0);
                }
                if let Some(r) = &mut self.replay {
                    r.playing = on;
                }
            }
            Command::SetSpeed(_) | Command::SetLoop(_) | Command::SetOverTime(_) | Command::SetBias(_) => {
                if let Some(r) = &mut self.replay {
                    set_replay(r, &command);
                }
            }
            Command::Tick(dt_secs) => self.tick(dt_secs),
            Command::SetLearnedSigma(sigma) => {
                if let Some(r) = &mut self.replay {
                    r.learned_sigma = Some(sigma);
                }
            }
            // Applied above, as configurations.
            Command::SetSigma(_)
            | Command::SetJointSigma(..)
            | Command::SetSigmaAuto(_)
            | Command::SetCalibrate(_)
            | Command::SetSurfacePoints(_)
            | Command::SetForceRange(..)
            | Command::SetSlide(_)
            | Command::SetConfig(_) => {}
        }
        before != self.estimate_inputs()
    }

    /// Applies a command that sets, scales or clears a push.
    fn apply_push(&mut self, command: &Command) {
        match *command {
            Command::Push(push) => self.push = Some(push),
            Command::SetForce(f) => {
                if let Some(p) = self.push.as_mut() {
                    p.force_newtons = f;
                }
            }
            Command::ClearPush => {
                self.push = None;
                self.second_push = None;
            }
            Command::SecondPush(push) => {
                self.second_push = Some(push);
                // A second push is what the two-contact model is for.
                self.config.contacts_at_once = 2;
                self.view.layer = super::heat::HeatLayer::Contacts;
            }
            Command::SetSecondForce(f) => {
                if let Some(p) = self.second_push.as_mut() {
                    p.force_newtons = f;
                }
            }
            Command::ClearSecondPush => self.second_push = None,
            _ => {}
        }
    }

    /// Shows session frame `i` (clamped to the last): its `q`, and its true
    /// contacts as the pushes.
    fn show_frame(&mut self, i: usize) {
        let Some(replay) = &mut self.replay else {
            return;
        };
        let i = i.min(replay.session.frames.len().saturating_sub(1));
        let Some(frame) = replay.session.frames.get(i) else {
            return;
        };
        replay.frame = i;
        replay.clock_secs = frame.t;
        if frame.q.len() == self.q.len() {
            self.q.clone_from(&frame.q);
        }
        let truths = frame.true_contacts();
        let pose = self.pose();
        let mut pushes = truths.iter().filter_map(|truth| {
            self.robot.link_id(&truth.link).ok().and_then(|link| {
                let link_from_world = pose.world_from_link.get(link)?.inverse();
                let force = DVec3::from_array(truth.force);
                Some(Push {
                    link,
                    point_in_link: link_from_world.transform_point3(DVec3::from_array(truth.point)),
                    inward_normal_in_link: link_from_world.transform_vector3(force.try_normalize()?),
                    force_newtons: force.length(),
                })
            })
        });
        self.push = pushes.next();
        self.second_push = pushes.next();
    }

    /// Advances playback by `dt_secs` of wall-clock time.
    fn tick(&mut self, dt_secs: f64) {
        let Some(replay) = &mut self.replay else {
            return;
        };
        if !replay.playing {
            return;
        }
        let frames = &replay.session.frames;
        let (Some(first), Some(last)) = (frames.first().map(|f| f.t), frames.last().map(|f| f.t)) else {
            return;
        };
        let mut clock = replay.clock_secs + dt_secs.max(0.0) * replay.speed;
        if clock > last {
            if replay.looping {
                clock = first;
            } else {
                clock = last;
                replay.playing = false;
            }
        }
        let target = replay.session.frame_at(clock);
        let changed = target != replay.frame;
        if changed {
            self.show_frame(target);
        }
        if let Some(replay) = &mut self.replay {
            replay.clock_secs = clock;
        }
    }
}
