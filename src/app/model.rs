//! The user's model and the commands that change it: no egui here.

use super::*;

/// A push on the robot, kept in the link frame so that it moves with the arm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Push {
    /// The link pushed.
    pub link: LinkId,
    /// Contact point in the link frame, m.
    pub point_in_link: DVec3,
    /// The push's unit direction in the link frame: the inward normal for
    /// a click, any direction into the surface for a dragged push.
    pub inward_normal_in_link: DVec3,
    /// Magnitude, N.
    pub force_newtons: f64,
}

/// Everything the user can change; changed only by [`Command`]s.
#[derive(Debug, Clone)]
pub struct Model {
    /// The robot.
    pub robot: Arc<Robot>,
    /// Sensed joint positions, rad.
    pub q: Vec<f64>,
    /// The applied push.
    pub push: Option<Push>,
    /// Likelihood σ per sensed joint, N·m.
    pub sigma: Vec<f64>,
    /// Surface points over the candidate links.
    pub surface_points: usize,
    /// Links that can be touched: only these are sampled and evaluated.
    pub candidate_links: Vec<LinkId>,
    /// Sensor noise added to the push's torques, N·m.
    pub noise_sigma: f64,
    /// Seed of that noise.
    pub noise_seed: u64,
    /// Push magnitudes considered by the estimator, N.
    pub force_range_newtons: (f64, f64),
    /// Estimator mode and phases.
    pub estimator: EstimatorChoice,
    /// Seed of the surface sampling.
    pub surface_seed: u64,
    /// Positions of joints that are neither sensed nor fixed, by name.
    pub other_joints: Vec<(String, f64)>,
    /// The scene's title and description (saved with it).
    pub title: (String, String),
    /// How the posterior is shown (changing it re-runs nothing).
    pub view: ViewOptions,
    /// A recorded session being replayed: its current frame sets `q`, the
    /// measured torques and the true contact (shown as the push).
    pub replay: Option<Replay>,
    /// Why the last command was refused (a value outside its range,
    /// named with the range), until a command is applied.
    pub refused: Option<String>,
}

/// A session on the timeline.
#[derive(Debug, Clone)]
pub struct Replay {
    /// The session (good frames only).
    pub session: Arc<session::SessionData>,
    /// The frame shown (index into the good frames).
    pub frame: usize,
    /// Playing (else paused).
    pub playing: bool,
    /// Playback speed, 0.1–10× real time.
    pub speed: f64,
    /// Start over at the end.
    pub looping: bool,
    /// Session time the playback has reached, s.
    pub clock_secs: f64,
    /// How the session's frames are estimated: each alone, with the
    /// frames before (filtered) or with the whole session (smoothed).
    pub over_time: Temporal,
    /// Take each joint's torque bias, estimated from the session, off
    /// every frame (as `estimate --bias auto`).
    pub bias_auto: bool,
    /// How far a contact slides, filtered or smoothed: RMS along each
    /// surface direction after one second, m/√s (as `estimate --slide`).
    pub slide_m_per_sqrt_s: f64,
}

/// Slowest and fastest playback.
pub const SPEED_RANGE: (f64, f64) = (SPEED.min, SPEED.max);

/// The playback speed the timeline takes, × real time.
pub const SPEED: crate::core::config::limits::Range =
    crate::core::config::limits::Range::closed("playback speed", "× real time", 0.1, 10.0);

/// The slide length the timeline takes, m/√s: from contacts that barely
/// move to ones that wipe along a link.
pub const SLIDE: crate::core::config::limits::Range =
    crate::core::config::limits::Range::closed("slide", "m/√s", 0.001, 0.1);

/// The estimator's mode as the panel offers it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ModeChoice {
    /// Closed form per surface point.
    Exact,
    /// Thesis particles, m magnitudes per point.
    ParticlesDeterministic,
    /// Thesis particles, uniform random.
    ParticlesRandom,
}

/// Estimator settings beyond σ and the resolution.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct EstimatorChoice {
    /// The mode.
    pub mode: ModeChoice,
    /// N for random particles.
    pub particles: usize,
    /// m for deterministic particles.
    pub magnitudes_per_point: usize,
    /// Phases A/B/C on.
    pub phases: bool,
    /// Sizes of phases A and B.
    pub phase_sizes: [usize; 2],
    /// α between phases.
    pub alpha: f64,
    /// Seed of random particles.
    pub particle_seed: u64,
    /// Friction μ (0: frictionless), when not `friction_auto`.
    pub friction: f64,
    /// Friction by how frames are combined
    /// ([`crate::core::over_time::sequence::Temporal::default_friction`]: 0 for a
    /// frame alone, [`crate::core::over_time::sequence::OVER_TIME_FRICTION`] filtered
    /// or smoothed), as `estimate --friction auto`.
    pub friction_auto: bool,
}

impl EstimatorChoice {
    /// The choice a scene's estimator section makes.
    #[must_use]
    pub fn from_scene(e: &crate::io::scene::EstimatorSettings) -> Self {
        use crate::io::scene as sc;
        Self {
            mode: match (e.mode, e.sampling) {
                (sc::Mode::Exact, _) => ModeChoice::Exact,
                (sc::Mode::Particles, sc::Sampling::Deterministic) => ModeChoice::ParticlesDeterministic,
                (sc::Mode::Particles, sc::Sampling::Random) => ModeChoice::ParticlesRandom,
            },
            particles: e.particles,
            magnitudes_per_point: e.magnitudes_per_point,
            phases: e.phases.enabled,
            phase_sizes: e.phases.sizes,
            alpha: e.phases.alpha,
            particle_seed: e.particle_seed,
            friction: e.friction,
            // A scene without a friction (0, the field's default) leaves
            // it to how the frames are combined.
            friction_auto: e.friction == 0.0,
        }
    }
}

impl Default for EstimatorChoice {
    fn default() -> Self {
        Self {
            mode: ModeChoice::Exact,
            particles: 20_000,
            magnitudes_per_point: 5,
            phases: false,
            phase_sizes: [200, 1000],
            alpha: 0.5,
            particle_seed: 0,
            friction: 0.0,
            friction_auto: true,
        }
    }
}

/// How the heatmap is drawn.
#[derive(Debug, Clone, Copy, PartialEq)]
#[allow(clippy::struct_excessive_bools)] // Independent display toggles, one checkbox each.
pub struct ViewOptions {
    /// Log scale (else linear in probability).
    pub log_scale: bool,
    /// Hide points below this fraction of the scale (0 shows all).
    pub threshold: f64,
    /// The thesis' red-to-green map instead of viridis.
    pub red_green: bool,
    /// Draw the candidate points (phase A red, B orange, the 90 % credible set white).
    pub show_points: bool,
    /// Draw every sensed joint's axis.
    pub show_axes: bool,
    /// The posterior, or the observability map.
    pub layer: super::heat::HeatLayer,
}

impl Default for ViewOptions {
    fn default() -> Self {
        Self {
            log_scale: true,
            threshold: 0.0,
            red_green: false,
            show_points: false,
            show_axes: false,
            layer: super::heat::HeatLayer::Posterior,
        }
    }
}

/// Everything the 3-D view's picture depends on.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ViewKey {
    pub(crate) inputs: EstimateInputs,
    pub(crate) view: ViewOptions,
    pub(crate) generation: Option<u64>,
    pub(crate) hovered_joint: Option<usize>,
    pub(crate) camera: OrbitCamera,
    pub(crate) size: [u32; 2],
}

/// The parts of the [`Model`] an estimate depends on, to tell whether a
/// command calls for a new one.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct EstimateInputs {
    pub(crate) q: Vec<f64>,
    pub(crate) push: Option<Push>,
    pub(crate) sigma: Vec<f64>,
    pub(crate) surface_points: usize,
    pub(crate) candidate_links: Vec<LinkId>,
    pub(crate) noise: (f64, u64),
    pub(crate) estimator: EstimatorChoice,
    pub(crate) force_range_newtons: (f64, f64),
    pub(crate) frame: Option<usize>,
    pub(crate) bias_auto: bool,
    pub(crate) surface_seed: u64,
    pub(crate) other_joints: Vec<(String, f64)>,
}

/// Estimator and sensor settings to start the app with.
#[derive(Debug, Clone, PartialEq)]
pub struct StartSettings {
    /// Likelihood σ, N·m: one value for every joint, or one per sensed joint.
    pub sigma: Vec<f64>,
    /// Surface points.
    pub surface_points: usize,
    /// Sensor noise σ, N·m, and its seed.
    pub noise: (f64, u64),
    /// Push magnitudes considered, N.
    pub force_range_newtons: (f64, f64),
    /// Candidate links by name; `None`: every link a revolute joint moves.
    pub candidate_links: Option<Vec<LinkId>>,
    /// Mode, particles and phases.
    pub estimator: EstimatorChoice,
    /// Seed of the surface sampling.
    pub surface_seed: u64,
    /// Positions of joints that are neither sensed nor fixed, by name.
    pub other_joints: Vec<(String, f64)>,
    /// How to show the posterior (`None`: keep the app's current choice).
    pub view: Option<ViewOptions>,
    /// The scene's title and description, kept for saving.
    pub title: (String, String),
}

impl Default for StartSettings {
    /// σ 0.1 N·m, 5000 points, 0.05 N·m of sensor noise, 1–30 N.
    fn default() -> Self {
        Self {
            sigma: vec![0.1],
            surface_points: 5000,
            noise: (0.05, 1),
            force_range_newtons: (1.0, 30.0),
            candidate_links: None,
            estimator: EstimatorChoice::default(),
            surface_seed: 0,
            other_joints: Vec::new(),
            view: None,
            title: (String::new(), String::new()),
        }
    }
}

impl Model {
    /// The torques the sensors read: the session frame's, or the push's
    /// with the sensor noise.
    #[must_use]
    pub fn measured_torques(&self, pose: &RobotPose) -> Vec<f64> {
        if let Some(frame) = self.replay.as_ref().and_then(|r| r.session.frames.get(r.frame)) {
            return frame.tau.clone();
        }
        with_sensor_noise(&self.applied_torques(pose), self.noise_sigma, self.noise_seed)
    }

    /// What the estimate depends on (view options excluded).
    pub(crate) fn estimate_inputs(&self) -> EstimateInputs {
        EstimateInputs {
            q: self.q.clone(),
            push: self.push,
            sigma: self.sigma.clone(),
            surface_points: self.surface_points,
            candidate_links: self.candidate_links.clone(),
            noise: (self.noise_sigma, self.noise_seed),
            estimator: self.estimator,
            force_range_newtons: self.force_range_newtons,
            frame: self.replay.as_ref().map(|r| r.frame),
            bias_auto: self.replay.as_ref().is_some_and(|r| r.bias_auto),
            surface_seed: self.surface_seed,
            other_joints: self.other_joints.clone(),
        }
    }

    /// The estimator settings as a scene file writes them: what the
    /// panel shows, mapped once (see [`crate::io::scene::EstimatorSettings::to_core`]).
    #[must_use]
    pub fn scene_estimator(&self) -> crate::io::scene::EstimatorSettings {
        use crate::io::scene as sc;
        let e = self.estimator;
        sc::EstimatorSettings {
            mode: if e.mode == ModeChoice::Exact {
                sc::Mode::Exact
            } else {
                sc::Mode::Particles
            },
            sigma_newton_metres: if self.sigma.iter().all(|v| (v - self.sigma[0]).abs() < 1e-15) {
                sc::Sigma::All(self.sigma.first().copied().unwrap_or(0.1))
            } else {
                sc::Sigma::PerJoint(self.sigma.clone())
            },
            sampling: if e.mode == ModeChoice::ParticlesRandom {
                sc::Sampling::Random
            } else {
                sc::Sampling::Deterministic
            },
            particles: e.particles,
            magnitudes_per_point: e.magnitudes_per_point,
            phases: sc::Phases {
                enabled: e.phases,
                sizes: e.phase_sizes,
                alpha: e.alpha,
            },
            force_min_newtons: self.force_range_newtons.0,
            force_max_newtons: self.force_range_newtons.1,
            particle_seed: e.particle_seed,
            // Auto is written as 0, which reads back as auto.
            friction: if e.friction_auto { 0.0 } else { e.friction },
        }
    }

    /// The core estimator's settings for frames combined by `temporal`
    /// (the friction follows it when `friction_auto`).
    #[must_use]
    pub fn estimator_settings_for(&self, temporal: crate::core::over_time::sequence::Temporal) -> EstimatorSettings {
        let mut settings = self.estimator_settings();
        if self.estimator.friction_auto && settings.mode == Mode::Exact {
            settings.friction = temporal.default_friction();
        }
        settings
    }

    /// The core estimator's settings (for a frame alone).
    #[must_use]
    pub fn estimator_settings(&self) -> EstimatorSettings {
        let joints = self.robot.sensed().len();
        let mut scene = self.scene_estimator();
        // One σ per sensed joint (an invariant the monkey checks), so the
        // mapping cannot fail on the σ count, its only error.
        scene.sigma_newton_metres = crate::io::scene::Sigma::PerJoint(per_joint(&self.sigma, joints));
        match scene.to_core(joints) {
            Ok(settings) => settings,
            Err(_) => EstimatorSettings {
                sigma: vec![0.1; joints],
                force_min_newtons: self.force_range_newtons.0,
                force_max_newtons: self.force_range_newtons.1,
                mode: Mode::Exact,
                phase_alpha: None,
                patches: true,
                friction: 0.0,
            },
        }
    }

    /// The robot posed at the model's joint positions.
    #[must_use]
    pub fn pose(&self) -> RobotPose {
        RobotPose::new(&self.robot, &self.joint_positions())
    }

    /// Every joint's position (sensed from `q`, the others by name), rad.
    #[must_use]
    pub fn joint_positions(&self) -> Vec<f64> {
        self.robot
            .joint_positions(&self.q, &self.other_joints)
            .or_else(|_| self.robot.joint_positions(&self.q, &[]))
            .unwrap_or_else(|_| vec![0.0; self.robot.joints.len()])
    }

    /// The model a robot opens with: its configuration, push and settings
    /// (`view` when the settings name none).
    #[must_use]
    pub fn from_start(
        robot: Robot,
        q: Vec<f64>,
        push: Option<Push>,
        settings: StartSettings,
        view: ViewOptions,
    ) -> Self {
        let joints = robot.sensed().len();
        let candidate_links = settings
            .candidate_links
            .unwrap_or_else(|| robot.default_candidate_links());
        Self {
            robot: Arc::new(robot),
            q,
            push,
            sigma: per_joint(&settings.sigma, joints),
            surface_points: settings.surface_points,
            candidate_links,
            noise_sigma: settings.noise.0,
            noise_seed: settings.noise.1,
            force_range_newtons: settings.force_range_newtons,
            estimator: settings.estimator,
            surface_seed: settings.surface_seed,
            other_joints: settings.other_joints,
            title: settings.title,
            view: settings.view.unwrap_or(view),
            replay: None,
            refused: None,
        }
    }

    /// The push in the world: (point, force).
    #[must_use]
    pub fn push_world(&self, pose: &RobotPose) -> Option<(LinkId, DVec3, DVec3)> {
        let p = self.push?;
        let frame = pose.world_from_link[p.link];
        Some((
            p.link,
            frame.transform_point3(p.point_in_link),
            frame.transform_vector3(p.inward_normal_in_link) * p.force_newtons,
        ))
    }

    /// Exact torques of the push (zeros without one).
    #[must_use]
    pub fn applied_torques(&self, pose: &RobotPose) -> Vec<f64> {
        match self.push_world(pose) {
            Some((link, point, force)) => joint_torques(&self.robot, pose, link, point, force),
            None => vec![0.0; self.robot.sensed().len()],
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::over_time::sequence::{OVER_TIME_FRICTION, Temporal};

    fn model() -> Model {
        let robot = crate::core::robot::builtin::lwr4plus_generated().unwrap();
        let candidate_links = robot.default_candidate_links();
        Model {
            q: vec![0.0; 7],
            push: None,
            sigma: vec![0.1; 7],
            surface_points: 1000,
            candidate_links,
            noise_sigma: 0.0,
            noise_seed: 1,
            force_range_newtons: (1.0, 30.0),
            estimator: EstimatorChoice::default(),
            surface_seed: 0,
            other_joints: Vec::new(),
            title: (String::new(), String::new()),
            view: ViewOptions::default(),
            replay: None,
            refused: None,
            robot: Arc::new(robot),
        }
    }

    #[test]
    fn sigma_commands_set_all_joints_or_one() {
        let mut m = model();
        assert!(m.apply(Command::SetSigma(0.3)));
        assert!(m.sigma.iter().all(|s| (s - 0.3).abs() < 1e-15));
        assert!(m.apply(Command::SetJointSigma(2, 0.05)));
        assert!((m.sigma[2] - 0.05).abs() < 1e-15 && (m.sigma[1] - 0.3).abs() < 1e-15);
        assert!(
            !m.apply(Command::SetJointSigma(99, 0.05)),
            "no such joint: nothing changes"
        );
        assert_eq!(m.estimator_settings().sigma, m.sigma);
    }

    /// The panel's settings reach the core through the scene's mapping:
    /// a scene written from them maps to the very same settings, random
    /// particles' seed included, and reads back as the same choice.
    #[test]
    fn the_panel_maps_to_the_estimator_as_a_scene_does() {
        let mut m = model();
        m.estimator = EstimatorChoice {
            mode: ModeChoice::ParticlesRandom,
            particles: 1234,
            phases: true,
            particle_seed: 3,
            friction: 0.3,
            friction_auto: false,
            ..EstimatorChoice::default()
        };
        m.sigma[2] = 0.3;
        let scene = m.scene_estimator();
        assert_eq!(m.estimator_settings(), scene.to_core(7).unwrap());
        assert_eq!(EstimatorChoice::from_scene(&scene), m.estimator);
        match m.estimator_settings().mode {
            Mode::Particles(p) => assert_eq!(
                p.sampling,
                crate::core::estimate::settings::Sampling::Random { count: 1234, seed: 3 }
            ),
            Mode::Exact => panic!("random particles expected"),
        }
        assert!((m.estimator_settings().sigma[2] - 0.3).abs() < 1e-15);
        assert!((m.estimator_settings().friction - 0.3).abs() < 1e-15);
        // A chosen μ holds however frames are combined.
        assert!((m.estimator_settings_for(Temporal::Smooth).friction - 0.3).abs() < 1e-15);
    }

    /// Friction auto (the default): none for a frame alone, the over-time
    /// μ filtered or smoothed, as `estimate --friction auto`; written to a
    /// scene as 0, which reads back as auto.
    #[test]
    fn auto_friction_follows_how_frames_are_combined() {
        let m = model();
        assert!(m.estimator.friction_auto);
        let mu = |t| m.estimator_settings_for(t).friction;
        assert!(mu(Temporal::None).abs() < 1e-15);
        assert!((mu(Temporal::Filter) - OVER_TIME_FRICTION).abs() < 1e-15);
        assert!((mu(Temporal::Smooth) - OVER_TIME_FRICTION).abs() < 1e-15);
        assert!(m.estimator_settings().friction.abs() < 1e-15);
        let scene = m.scene_estimator();
        assert!(scene.friction.abs() < 1e-15);
        assert_eq!(EstimatorChoice::from_scene(&scene), m.estimator);
    }

    #[test]
    fn view_commands_change_no_estimate_input() {
        let mut m = model();
        let view = ViewOptions {
            log_scale: false,
            ..ViewOptions::default()
        };
        assert!(!m.apply(Command::SetView(view)));
        assert_eq!(m.view, view);
    }

    #[test]
    fn at_least_one_candidate_link_stays_and_only_touchable_links_join() {
        let mut m = model();
        let all = m.candidate_links.clone();
        for &l in &all {
            m.apply(Command::SetCandidate(l, false));
        }
        assert_eq!(m.candidate_links.len(), 1);
        assert!(
            !m.apply(Command::SetCandidate(0, true)),
            "the base is not a touchable link"
        );
        let kept = m.candidate_links[0];
        let other = *all.iter().find(|&&l| l != kept).unwrap();
        assert!(m.apply(Command::SetCandidate(other, true)));
        assert_eq!(m.candidate_links.len(), 2);
        assert!(
            !m.apply(Command::SetCandidate(other, true)),
            "ticking twice changes nothing"
        );
    }

    #[test]
    fn random_poses_are_seeded() {
        let (mut a, mut b) = (model(), model());
        a.apply(Command::RandomPose(3));
        b.apply(Command::RandomPose(3));
        assert_eq!(a.q, b.q);
        b.apply(Command::RandomPose(4));
        assert_ne!(a.q, b.q);
    }
}
