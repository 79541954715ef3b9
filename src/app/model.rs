//! The user's model and the commands that change it: no egui here.

use super::{
    Arc, DVec3, EstimatorConfig, EstimatorSettings, LinkId, OrbitCamera, Robot, RobotPose, Sigma, Temporal,
    joint_torques, per_joint, with_sensor_noise,
};

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

/// Everything the user can change; changed only by `Command`s.
#[derive(Debug, Clone)]
pub struct Model {
    /// The robot.
    pub robot: Arc<Robot>,
    /// Sensed joint positions, rad.
    pub q: Vec<f64>,
    /// The applied push.
    pub push: Option<Push>,
    /// A second push at the same time (Shift+click): the sensors read the
    /// sum of both pushes' torques.
    pub second_push: Option<Push>,
    /// The estimator's configuration (σ one per sensed joint).
    pub config: EstimatorConfig,
    /// Links that can be touched: only these are sampled and evaluated.
    pub candidate_links: Vec<LinkId>,
    /// Sensor noise added to the push's torques, N·m.
    pub noise_sigma: f64,
    /// Seed of that noise.
    pub noise_seed: u64,
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
    pub session: Arc<crate::batch::SessionData>,
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
    /// σ per joint learned from the session (used while σ is learned,
    /// [`crate::core::config::estimator::TorqueModel::sigma_auto`]), N·m.
    pub learned_sigma: Option<Vec<f64>>,
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
        // The heat as Foxglove is sent it (`core::paint::heat::HeatStyle`).
        let style = crate::core::paint::heat::HeatStyle::default();
        Self {
            log_scale: style.log_scale,
            threshold: style.threshold,
            red_green: style.red_green,
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
    pub(crate) second_push: Option<Push>,
    pub(crate) config: EstimatorConfig,
    pub(crate) candidate_links: Vec<LinkId>,
    pub(crate) noise: (f64, u64),
    pub(crate) frame: Option<usize>,
    pub(crate) bias_auto: bool,
    pub(crate) other_joints: Vec<(String, f64)>,
}

/// Estimator and sensor settings to start the app with.
#[derive(Debug, Clone, PartialEq)]
pub struct StartSettings {
    /// The estimator's configuration.
    pub config: EstimatorConfig,
    /// Sensor noise σ, N·m, and its seed.
    pub noise: (f64, u64),
    /// Candidate links by name; `None`: every link a revolute joint moves.
    pub candidate_links: Option<Vec<LinkId>>,
    /// Positions of joints that are neither sensed nor fixed, by name.
    pub other_joints: Vec<(String, f64)>,
    /// How to show the posterior (`None`: keep the app's current choice).
    pub view: Option<ViewOptions>,
    /// The scene's title and description, kept for saving.
    pub title: (String, String),
    /// A second push, if the scene has one.
    pub second_push: Option<Push>,
}

impl Default for StartSettings {
    /// The configuration's defaults, 0.05 N·m of sensor noise.
    fn default() -> Self {
        Self {
            config: EstimatorConfig::default(),
            noise: (0.05, 1),
            candidate_links: None,
            other_joints: Vec::new(),
            view: None,
            title: (String::new(), String::new()),
            second_push: None,
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
            second_push: self.second_push,
            config: self.estimation_config(),
            candidate_links: self.candidate_links.clone(),
            noise: (self.noise_sigma, self.noise_seed),
            frame: self.replay.as_ref().map(|r| r.frame),
            bias_auto: self.replay.as_ref().is_some_and(|r| r.bias_auto),
            other_joints: self.other_joints.clone(),
        }
    }

    /// Likelihood σ per sensed joint in use, N·m: the one learned from
    /// the session while σ is learned and known, else the one set.
    #[must_use]
    pub fn sigma(&self) -> &[f64] {
        match self.learned_sigma() {
            Some(learned) => learned,
            None => self.set_sigma(),
        }
    }

    /// Likelihood σ per sensed joint as set (by hand, a scene or the
    /// defaults), N·m.
    #[must_use]
    pub fn set_sigma(&self) -> &[f64] {
        match &self.config.sigma {
            Sigma::PerJoint(v) => v,
            Sigma::All(s) => std::slice::from_ref(s),
        }
    }

    /// σ learned from the session, while it is used.
    #[must_use]
    pub fn learned_sigma(&self) -> Option<&[f64]> {
        self.replay
            .as_ref()
            .filter(|_| self.config.torques.sigma_auto)?
            .learned_sigma
            .as_deref()
    }

    /// The configuration the estimator runs with: the one set, with σ
    /// learned from the session while it is used.
    #[must_use]
    pub fn estimation_config(&self) -> EstimatorConfig {
        match self.learned_sigma() {
            Some(learned) => EstimatorConfig {
                sigma: Sigma::PerJoint(learned.to_vec()),
                ..self.config.clone()
            },
            None => self.config.clone(),
        }
    }

    /// The estimator's settings for frames combined by `temporal`.
    #[must_use]
    pub fn estimator_settings_for(&self, temporal: Temporal) -> EstimatorSettings {
        let joints = self.robot.sensed().len();
        // The commands keep the configuration valid, σ one per joint: the
        // fallback is never taken.
        self.estimation_config()
            .settings(joints, temporal)
            .unwrap_or_else(|_| EstimatorSettings::exact(per_joint(self.sigma(), joints)))
    }

    /// The estimator's settings for a frame alone.
    #[must_use]
    pub fn estimator_settings(&self) -> EstimatorSettings {
        self.estimator_settings_for(Temporal::None)
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
        let mut config = settings.config;
        config.sigma = Sigma::PerJoint(match &config.sigma {
            Sigma::All(s) => vec![*s; joints],
            Sigma::PerJoint(v) => per_joint(v, joints),
        });
        Self {
            robot: Arc::new(robot),
            q,
            push,
            second_push: settings.second_push,
            config,
            candidate_links,
            noise_sigma: settings.noise.0,
            noise_seed: settings.noise.1,
            other_joints: settings.other_joints,
            title: settings.title,
            view: settings.view.unwrap_or(view),
            replay: None,
            refused: None,
        }
    }

    /// The push in the world: (link, point, force).
    #[must_use]
    pub fn push_world(&self, pose: &RobotPose) -> Option<(LinkId, DVec3, DVec3)> {
        self.push.and_then(|p| push_in_world(&p, pose))
    }

    /// The second push in the world: (link, point, force).
    #[must_use]
    pub fn second_push_world(&self, pose: &RobotPose) -> Option<(LinkId, DVec3, DVec3)> {
        self.second_push.and_then(|p| push_in_world(&p, pose))
    }

    /// Exact torques of the pushes, summed (zeros without one).
    #[must_use]
    pub fn applied_torques(&self, pose: &RobotPose) -> Vec<f64> {
        let mut tau = vec![0.0; self.robot.sensed().len()];
        for (link, point, force) in self.push_world(pose).into_iter().chain(self.second_push_world(pose)) {
            for (t, x) in tau.iter_mut().zip(joint_torques(&self.robot, pose, link, point, force)) {
                *t += x;
            }
        }
        tau
    }
}

/// A push in the world: (link, point, force); `None` where the pose has
/// no such link.
fn push_in_world(p: &Push, pose: &RobotPose) -> Option<(LinkId, DVec3, DVec3)> {
    let frame = pose.world_from_link.get(p.link)?;
    Some((
        p.link,
        frame.transform_point3(p.point_in_link),
        frame.transform_vector3(p.inward_normal_in_link) * p.force_newtons,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::app::Command;
    use crate::core::config::estimator::{Friction, ModeKind};
    use crate::core::over_time::sequence::{OVER_TIME_FRICTION, Temporal};

    fn model() -> Model {
        let robot = crate::core::robot::builtin::lwr4plus_generated().unwrap();
        let candidate_links = robot.default_candidate_links();
        Model {
            q: vec![0.0; 7],
            push: None,
            second_push: None,
            config: EstimatorConfig {
                sigma: Sigma::PerJoint(vec![0.1; 7]),
                surface_points: 1000,
                ..EstimatorConfig::default()
            },
            candidate_links,
            noise_sigma: 0.0,
            noise_seed: 1,
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
        assert!(m.sigma().iter().all(|s| (s - 0.3).abs() < 1e-15));
        assert!(m.apply(Command::SetJointSigma(2, 0.05)));
        assert!((m.sigma()[2] - 0.05).abs() < 1e-15 && (m.sigma()[1] - 0.3).abs() < 1e-15);
        assert!(
            !m.apply(Command::SetJointSigma(99, 0.05)),
            "no such joint: nothing changes"
        );
        assert_eq!(m.estimator_settings().sigma, m.sigma());
    }

    /// The panel's configuration written to a scene reads back as the same
    /// configuration, random particles' seed included, and maps to the
    /// core's settings once.
    #[test]
    fn the_panel_maps_to_the_estimator_as_a_scene_does() {
        use crate::io::scene::{EstimatorSettings as SceneEstimator, Scene};
        let mut m = model();
        m.config = EstimatorConfig {
            mode: ModeKind::ParticlesRandom,
            particles: 1234,
            phases: true,
            particle_seed: 3,
            friction: Friction::Mu(0.3),
            ..m.config.clone()
        };
        if let Sigma::PerJoint(v) = &mut m.config.sigma {
            v[2] = 0.3;
        }
        let scene = Scene {
            estimator: SceneEstimator::from_config(&m.config),
            surface_points: m.config.surface_points,
            surface_seed: m.config.surface_seed,
            ..Scene::parse(
                r#"{"version": 1, "robot": "lwr4plus", "q": [0, 0, 0, 0, 0, 0, 0]}"#,
                std::path::Path::new("s.json"),
            )
            .unwrap()
        };
        assert_eq!(scene.config(), m.config);
        match m.estimator_settings().mode {
            crate::core::estimate::settings::Mode::Particles(p) => assert_eq!(
                p.sampling,
                crate::core::estimate::settings::Sampling::Random { count: 1234, seed: 3 }
            ),
            crate::core::estimate::settings::Mode::Exact => panic!("random particles expected"),
        }
        assert!((m.estimator_settings().sigma[2] - 0.3).abs() < 1e-15);
        // Particle modes take no friction.
        assert!(m.estimator_settings_for(Temporal::Smooth).friction.abs() < 1e-15);
        m.config.mode = ModeKind::Exact;
        // A chosen μ holds however frames are combined.
        assert!((m.estimator_settings_for(Temporal::Smooth).friction - 0.3).abs() < 1e-15);
    }

    /// Friction auto (the default): none for a frame alone, the over-time
    /// μ filtered or smoothed, as `estimate --friction auto`; written to a
    /// scene as 0, which reads back as auto.
    #[test]
    fn auto_friction_follows_how_frames_are_combined() {
        let m = model();
        assert_eq!(m.config.friction, Friction::Auto);
        let mu = |t| m.estimator_settings_for(t).friction;
        assert!(mu(Temporal::None).abs() < 1e-15);
        assert!((mu(Temporal::Filter) - OVER_TIME_FRICTION).abs() < 1e-15);
        assert!((mu(Temporal::Smooth) - OVER_TIME_FRICTION).abs() < 1e-15);
        let scene = crate::io::scene::EstimatorSettings::from_config(&m.config);
        assert!(scene.friction.abs() < 1e-15);
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
