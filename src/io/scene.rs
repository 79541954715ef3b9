//! Scene files (JSON, `"version": 1`): a robot in a configuration, the
//! links that can be touched, the surface resolution, an applied push,
//! sensor noise and the estimator settings.
//!
//! Unknown fields are rejected; every optional field has the default
//! documented on it.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::core::config::estimator::{
    DEFAULT_SIGMA_NEWTON_METRES, EstimatorConfig, Friction, ModeKind, Sigma as ConfigSigma,
};
use crate::core::config::limits;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{LinkId, Robot, RobotError};
use crate::core::robot::torque::{joint_torques, with_sensor_noise};
use crate::io::builtin::{LoadRobotError, load_robot};
use crate::io::urdf::{MeshSelection, UrdfOptions};

/// The scene format version this program reads and writes.
pub const SCENE_VERSION: u32 = 1;

/// A scene as stored.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scene {
    /// Always 1.
    pub version: u32,
    /// Short title. Default: empty.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub name: String,
    /// What the scene shows. Default: empty.
    #[serde(default, skip_serializing_if = "String::is_empty")]
    pub description: String,
    /// A built-in robot (`simple6`, `lwr4plus`) or a URDF path relative to
    /// the scene file.
    pub robot: String,
    /// Extra folders for `package://` URIs, relative to the scene file. Default: none.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub package_paths: Vec<String>,
    /// The joints with torque sensors, in the order of `q`. Default: every
    /// revolute and continuous joint, depth-first from the root.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensed_joints: Option<Vec<String>>,
    /// Positions of the sensed joints, rad (m for prismatic).
    pub q: Vec<f64>,
    /// Positions of other movable joints by name. Default: all 0.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub other_joints: BTreeMap<String, f64>,
    /// Links that can be touched. Default: every link with a surface that a
    /// revolute or continuous joint moves.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub candidate_links: Option<Vec<String>>,
    /// Surface samples over the candidate links. Default: 5000.
    #[serde(default = "default_surface_points")]
    pub surface_points: usize,
    /// Seed of the surface sampling. Default: 0.
    #[serde(default)]
    pub surface_seed: u64,
    /// The applied push. Default: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub push: Option<Push>,
    /// A second push, pressing at the same time: the sensors read the
    /// sum of both pushes' torques. Default: none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub second_push: Option<Push>,
    /// Sensor noise added to the push's torques. Default: none.
    #[serde(default)]
    pub noise: Noise,
    /// Estimator settings. Default: see [`EstimatorSettings`].
    #[serde(default)]
    pub estimator: EstimatorSettings,
    /// How the app shows the posterior. Default: the app's choice.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub view: Option<View>,
}

/// How the app shows the posterior (written when a scene is saved from it).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
#[allow(clippy::struct_excessive_bools)] // Independent display toggles, one checkbox each.
pub struct View {
    /// Log scale (else linear). Default: true.
    #[serde(default = "default_true")]
    pub log_scale: bool,
    /// Fraction of the scale below which the surface stays grey, 0–1. Default: 0.
    #[serde(default)]
    pub threshold: f64,
    /// The thesis' red-to-green map instead of viridis. Default: false.
    #[serde(default)]
    pub red_green: bool,
    /// Draw the candidate points. Default: false.
    #[serde(default)]
    pub candidate_points: bool,
    /// Draw every sensed joint's axis. Default: false.
    #[serde(default)]
    pub joint_axes: bool,
    /// What the arm is painted with. Default: the posterior.
    #[serde(default)]
    pub layer: Layer,
}

/// What the arm is painted with.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Layer {
    /// The posterior over the contact point.
    #[default]
    Posterior,
    /// How sharply the sensed joints would locate a push at each point.
    Observability,
    /// Each of two contacts' posterior given the other, together (where
    /// the estimator looks for two contacts; else the posterior).
    Contacts,
}

fn default_true() -> bool {
    true
}

/// `path` made absolute, with `.` and `name/..` steps taken out (by
/// name: links are not followed).
#[must_use]
pub fn normalized_path(path: &Path) -> PathBuf {
    use std::path::Component;
    let absolute = std::path::absolute(path).unwrap_or_else(|_| path.to_owned());
    let mut out = PathBuf::new();
    for c in absolute.components() {
        match c {
            Component::CurDir => {}
            Component::ParentDir => {
                if !out.pop() {
                    out.push(c);
                }
            }
            other => out.push(other),
        }
    }
    out
}

/// `target` written relative to the folder `base` (both normalized
/// first): how a saved scene names its robot and package folders so that
/// it opens from wherever the scene file is moved with them.
#[must_use]
pub fn relative_path(target: &Path, base: &Path) -> PathBuf {
    let (target, base) = (normalized_path(target), normalized_path(base));
    let t: Vec<_> = target.components().collect();
    let b: Vec<_> = base.components().collect();
    let common = t.iter().zip(&b).take_while(|(x, y)| x == y).count();
    if common == 0 {
        return target;
    }
    let mut out = PathBuf::new();
    for _ in common..b.len() {
        out.push("..");
    }
    for c in &t[common..] {
        out.push(c);
    }
    if out.as_os_str().is_empty() {
        PathBuf::from(".")
    } else {
        out
    }
}

fn default_surface_points() -> usize {
    EstimatorConfig::default().surface_points
}

/// A push on the robot. Give the point as `point_in_link` or `point_world`,
/// and the force as `force_world` (N) or `force_newtons` (along the inward
/// surface normal nearest the point).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Push {
    /// The link touched.
    pub link: String,
    /// Contact point in the link frame, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point_in_link: Option<[f64; 3]>,
    /// Contact point in the world (base) frame, m.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub point_world: Option<[f64; 3]>,
    /// Force applied to the robot, world frame, N.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_world: Option<[f64; 3]>,
    /// Magnitude of a push along the inward surface normal, N.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub force_newtons: Option<f64>,
}

/// Gaussian noise on the torque sensors.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Noise {
    /// Standard deviation per joint, N·m. Default: 0 (exact torques).
    #[serde(default)]
    pub sigma_newton_metres: f64,
    /// Seed of the noise. Default: 0.
    #[serde(default)]
    pub seed: u64,
}

/// Estimator mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// Per surface point, the likelihood maximised and integrated over the
    /// force magnitude in closed form.
    #[default]
    Exact,
    /// The thesis' particles.
    Particles,
}

/// How particles get their force magnitudes.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Sampling {
    /// `m` magnitudes per point (eq. 2.10).
    #[default]
    Deterministic,
    /// Uniform random points and magnitudes (§3.1.1, §3.1.2).
    Random,
}

/// One σ for all joints or one per joint, N·m.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Sigma {
    /// The same for every joint.
    All(f64),
    /// One per sensed joint.
    PerJoint(Vec<f64>),
}

impl Default for Sigma {
    fn default() -> Self {
        Self::All(DEFAULT_SIGMA_NEWTON_METRES)
    }
}

/// Coarse-to-fine phases A/B/C (§2.4).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Phases {
    /// Use them. Default: false.
    pub enabled: bool,
    /// Sizes of phases A and B (C is every point). Default: [200, 1000].
    pub sizes: [usize; 2],
    /// Keep clusters with P ≥ α·`P_max`. Default: 0.5.
    pub alpha: f64,
}

impl Default for Phases {
    fn default() -> Self {
        let config = EstimatorConfig::default();
        Self {
            enabled: config.phases,
            sizes: config.phase_sizes,
            alpha: config.alpha,
        }
    }
}

/// A scene's estimator section: the file's form of the
/// [`EstimatorConfig`], whose defaults fill what it leaves out.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EstimatorSettings {
    /// Default: exact.
    pub mode: Mode,
    /// Likelihood σ, N·m. Default: 0.05.
    pub sigma_newton_metres: Sigma,
    /// Particle sampling. Default: deterministic.
    pub sampling: Sampling,
    /// Number of particles N (random sampling). Default: 20000.
    pub particles: usize,
    /// Magnitudes per point m (deterministic sampling). Default: 5.
    pub magnitudes_per_point: usize,
    /// Default: off, sizes [200, 1000], α 0.5.
    pub phases: Phases,
    /// Smallest push considered, N. Default: 1.
    pub force_min_newtons: f64,
    /// Largest push considered, N. Default: 30.
    pub force_max_newtons: f64,
    /// Seed of random particles. Default: 0.
    pub particle_seed: u64,
    /// μ of the friction model: the tangential force's spread per newton
    /// of push (see `core::estimate::friction`). Default: 0, which leaves
    /// it to how frames are combined (none for a frame alone).
    pub friction: f64,
    /// Contacts looked for at once, 1 or 2 (two: the second contact's
    /// search and the evidence for it). Default: 1.
    pub contacts: usize,
}

impl Default for EstimatorSettings {
    fn default() -> Self {
        Self::from_config(&EstimatorConfig::default())
    }
}

impl EstimatorSettings {
    /// The section a scene writes for `config` (its surface's points and
    /// seed go to the scene's own fields; friction *auto* is written 0).
    #[must_use]
    pub fn from_config(config: &EstimatorConfig) -> Self {
        Self {
            mode: if config.mode == ModeKind::Exact {
                Mode::Exact
            } else {
                Mode::Particles
            },
            sigma_newton_metres: match &config.sigma {
                ConfigSigma::PerJoint(v) if v.windows(2).any(|w| w[0].total_cmp(&w[1]).is_ne()) => {
                    Sigma::PerJoint(v.clone())
                }
                ConfigSigma::PerJoint(v) => Sigma::All(v.first().copied().unwrap_or(DEFAULT_SIGMA_NEWTON_METRES)),
                ConfigSigma::All(s) => Sigma::All(*s),
            },
            sampling: if config.mode == ModeKind::ParticlesRandom {
                Sampling::Random
            } else {
                Sampling::Deterministic
            },
            particles: config.particles,
            magnitudes_per_point: config.magnitudes_per_point,
            phases: Phases {
                enabled: config.phases,
                sizes: config.phase_sizes,
                alpha: config.alpha,
            },
            force_min_newtons: config.force_range_newtons.0,
            force_max_newtons: config.force_range_newtons.1,
            particle_seed: config.particle_seed,
            friction: match config.friction {
                Friction::Auto => 0.0,
                Friction::Mu(mu) => mu,
            },
            contacts: config.contacts_at_once,
        }
    }
}

/// The largest friction μ accepted ([`limits::FRICTION`]).
pub const MAX_FRICTION: f64 = limits::FRICTION.max;

/// Why a scene could not be loaded.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// The file could not be read.
    #[error("{path}: cannot read the scene: {cause}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        cause: std::io::Error,
    },
    /// Not valid JSON, or not the scene schema.
    #[error("{path}:{line}:{column}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// Line of the error.
        line: usize,
        /// Column of the error.
        column: usize,
        /// What the parser says.
        message: String,
    },
    /// A field holds a value that makes no sense.
    #[error("{path}: field '{field}': {message}")]
    Invalid {
        /// The file.
        path: PathBuf,
        /// The field, dotted (`push.force_world`).
        field: String,
        /// What is wrong.
        message: String,
    },
    /// The robot could not be loaded.
    #[error("{path}: field 'robot': {cause}")]
    Robot {
        /// The scene file.
        path: PathBuf,
        /// What went wrong.
        cause: Box<LoadRobotError>,
    },
    /// The scene does not fit its robot.
    #[error("{path}: field '{field}': {cause}")]
    Model {
        /// The scene file.
        path: PathBuf,
        /// The field.
        field: String,
        /// What is wrong.
        cause: Box<RobotError>,
    },
}

/// A push resolved against the robot: link, point and force in the world.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ResolvedPush {
    /// The link touched.
    pub link: LinkId,
    /// Contact point, world frame, m.
    pub point_world: DVec3,
    /// Force applied to the robot, world frame, N.
    pub force_world: DVec3,
}

/// A scene with its robot loaded and posed.
#[derive(Debug, Clone)]
pub struct LoadedScene {
    /// The scene as read.
    pub scene: Scene,
    /// Its robot, sensed joints set.
    pub robot: Robot,
    /// Every joint's position.
    pub joint_positions: Vec<f64>,
    /// The posed robot.
    pub pose: RobotPose,
    /// The candidate links.
    pub candidate_links: Vec<LinkId>,
    /// The push, if any.
    pub push: Option<ResolvedPush>,
    /// The second push, if any.
    pub second_push: Option<ResolvedPush>,
}

impl LoadedScene {
    /// Exact torques of the pushes on the sensed joints, summed (zeros
    /// without a push).
    #[must_use]
    pub fn push_torques(&self) -> Vec<f64> {
        let mut tau = vec![0.0; self.robot.sensed().len()];
        for p in self.push.iter().chain(&self.second_push) {
            let one = joint_torques(&self.robot, &self.pose, p.link, p.point_world, p.force_world);
            for (t, x) in tau.iter_mut().zip(one) {
                *t += x;
            }
        }
        tau
    }

    /// What the sensors read: the push's torques plus the scene's noise.
    #[must_use]
    pub fn measured_torques(&self) -> Vec<f64> {
        with_sensor_noise(
            &self.push_torques(),
            self.scene.noise.sigma_newton_metres,
            self.scene.noise.seed,
        )
    }
}

impl Scene {
    /// Reads and checks a scene file (the robot is not loaded).
    pub fn read(path: &Path) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|cause| SceneError::Read {
            path: path.to_owned(),
            cause,
        })?;
        Self::parse(&text, path)
    }

    /// Parses and checks scene JSON; `path` names the source in errors.
    pub fn parse(text: &str, path: &Path) -> Result<Self, SceneError> {
        let scene: Self = serde_json::from_str(text).map_err(|e| {
            let mut message = e.to_string();
            // serde_json appends " at line L column C"; we lead with it.
            if let Some(i) = message.rfind(" at line ") {
                message.truncate(i);
            }
            if text.contains("NaN") || text.contains("Infinity") {
                message.push_str(" (NaN and Infinity are not JSON numbers)");
            }
            SceneError::Parse {
                path: path.to_owned(),
                line: e.line(),
                column: e.column(),
                message,
            }
        })?;
        scene.validate(path)?;
        Ok(scene)
    }

    /// The scene as pretty JSON.
    pub fn to_json(&self) -> Result<String, serde_json::Error> {
        serde_json::to_string_pretty(self)
    }

    fn validate(&self, path: &Path) -> Result<(), SceneError> {
        let invalid = |field: &str, message: String| invalid(path, field, message);
        if self.version != SCENE_VERSION {
            return Err(invalid(
                "version",
                format!(
                    "{} is not supported (this program reads version {SCENE_VERSION})",
                    self.version
                ),
            ));
        }
        for (i, &v) in self.q.iter().enumerate() {
            in_range(path, &format!("q[{i}]"), &limits::JOINT_POSITION, v)?;
        }
        for (name, &v) in &self.other_joints {
            in_range(path, &format!("other_joints.{name}"), &limits::JOINT_POSITION, v)?;
        }
        if let Some(push) = &self.push {
            push.validate(path, "push")?;
        }
        if let Some(push) = &self.second_push {
            push.validate(path, "second_push")?;
        }
        in_range(
            path,
            "noise.sigma_newton_metres",
            &limits::NOISE,
            self.noise.sigma_newton_metres,
        )?;
        if let Some(view) = &self.view {
            in_range(path, "view.threshold", &limits::THRESHOLD, view.threshold)?;
        }
        self.config()
            .validate(None)
            .map_err(|e| invalid(e.field().scene_field(), e.to_string()))
    }

    /// The scene's estimator configuration: its estimator section, its
    /// surface's points and seed, the temporal model's defaults. A
    /// friction of 0 (the field's default) leaves it to how frames are
    /// combined.
    #[must_use]
    pub fn config(&self) -> EstimatorConfig {
        let e = &self.estimator;
        EstimatorConfig {
            sigma: match &e.sigma_newton_metres {
                Sigma::All(s) => ConfigSigma::All(*s),
                Sigma::PerJoint(v) => ConfigSigma::PerJoint(v.clone()),
            },
            force_range_newtons: (e.force_min_newtons, e.force_max_newtons),
            mode: match (e.mode, e.sampling) {
                (Mode::Exact, _) => ModeKind::Exact,
                (Mode::Particles, Sampling::Deterministic) => ModeKind::ParticlesDeterministic,
                (Mode::Particles, Sampling::Random) => ModeKind::ParticlesRandom,
            },
            particles: e.particles,
            magnitudes_per_point: e.magnitudes_per_point,
            particle_seed: e.particle_seed,
            phases: e.phases.enabled,
            phase_sizes: e.phases.sizes,
            alpha: e.phases.alpha,
            friction: if e.friction == 0.0 {
                Friction::Auto
            } else {
                Friction::Mu(e.friction)
            },
            surface_points: self.surface_points,
            surface_seed: self.surface_seed,
            contacts_at_once: e.contacts,
            ..EstimatorConfig::default()
        }
    }

    /// Loads the robot (relative to `scene_path`'s folder), poses it and
    /// resolves the push.
    pub fn load(self, scene_path: &Path) -> Result<LoadedScene, SceneError> {
        let folder = scene_path.parent().unwrap_or(Path::new(".")).to_owned();
        let options = UrdfOptions {
            package_paths: self.package_paths.iter().map(|p| folder.join(p)).collect(),
            meshes: MeshSelection::All,
        };
        let mut robot = load_robot(&self.robot, &folder, &options).map_err(|cause| SceneError::Robot {
            path: scene_path.to_owned(),
            cause: Box::new(cause),
        })?;
        let model = |field: &str| {
            let field = field.to_owned();
            let path = scene_path.to_owned();
            move |cause| SceneError::Model {
                path,
                field,
                cause: Box::new(cause),
            }
        };
        if let Some(names) = &self.sensed_joints {
            robot.set_sensed(names).map_err(model("sensed_joints"))?;
        }
        self.config()
            .validate(Some(robot.sensed().len()))
            .map_err(|e| invalid(scene_path, e.field().scene_field(), e.to_string()))?;
        let others: Vec<(String, f64)> = self.other_joints.iter().map(|(k, v)| (k.clone(), *v)).collect();
        let joint_positions = robot.joint_positions(&self.q, &others).map_err(model("q"))?;
        let pose = RobotPose::new(&robot, &joint_positions);
        let candidate_links = match &self.candidate_links {
            Some(names) => names
                .iter()
                .map(|n| robot.link_id(n))
                .collect::<Result<Vec<_>, _>>()
                .map_err(model("candidate_links"))?,
            None => robot.default_candidate_links(),
        };
        let push = match &self.push {
            None => None,
            Some(p) => Some(resolve_push(&robot, &pose, p, scene_path, "push")?),
        };
        let second_push = match &self.second_push {
            None => None,
            Some(p) => Some(resolve_push(&robot, &pose, p, scene_path, "second_push")?),
        };
        Ok(LoadedScene {
            scene: self,
            robot,
            joint_positions,
            pose,
            candidate_links,
            push,
            second_push,
        })
    }
}

fn invalid(path: &Path, field: &str, message: String) -> SceneError {
    SceneError::Invalid {
        path: path.to_owned(),
        field: field.to_owned(),
        message,
    }
}

/// `value` of `field` within `range`, or the error that names both.
fn in_range(path: &Path, field: &str, range: &limits::Range, value: f64) -> Result<f64, SceneError> {
    range.check(value).map_err(|e| invalid(path, field, e.to_string()))
}

impl Push {
    /// Checks the push named `name` (its fields are named under it).
    fn validate(&self, path: &Path, name: &str) -> Result<(), SceneError> {
        let each = |field: &str, range: &limits::Range, v: &[f64; 3]| {
            for (axis, &x) in ["x", "y", "z"].iter().zip(v) {
                in_range(path, &format!("{field}.{axis}"), range, x)?;
            }
            Ok(())
        };
        match (&self.point_in_link, &self.point_world) {
            (Some(p), None) => each(&format!("{name}.point_in_link"), &limits::COORDINATE, p)?,
            (None, Some(p)) => each(&format!("{name}.point_world"), &limits::COORDINATE, p)?,
            _ => {
                return Err(invalid(
                    path,
                    name,
                    "give exactly one of point_in_link and point_world".to_owned(),
                ));
            }
        }
        match (&self.force_world, self.force_newtons) {
            (Some(f), None) => each(&format!("{name}.force_world"), &limits::FORCE_COMPONENT, f),
            (None, Some(f)) => in_range(path, &format!("{name}.force_newtons"), &limits::PUSH_NEWTONS, f).map(|_| ()),
            _ => Err(invalid(
                path,
                name,
                "give exactly one of force_world and force_newtons".to_owned(),
            )),
        }
    }
}

fn resolve_push(
    robot: &Robot,
    pose: &RobotPose,
    push: &Push,
    scene_path: &Path,
    name: &str,
) -> Result<ResolvedPush, SceneError> {
    let link = robot.link_id(&push.link).map_err(|cause| SceneError::Model {
        path: scene_path.to_owned(),
        field: format!("{name}.link"),
        cause: Box::new(cause),
    })?;
    let world_from_link = pose.world_from_link[link];
    let point_world = match (push.point_in_link, push.point_world) {
        (Some(p), _) => world_from_link.transform_point3(DVec3::from_array(p)),
        (None, Some(p)) => DVec3::from_array(p),
        (None, None) => DVec3::ZERO,
    };
    let force_world = match (push.force_world, push.force_newtons) {
        (Some(f), _) => DVec3::from_array(f),
        (None, Some(magnitude)) => {
            let point_in_link = world_from_link.inverse().transform_point3(point_world);
            let (_, frame) = crate::core::geometry::shell::SmoothMesh::new(&robot.links[link].mesh)
                .closest(point_in_link)
                .ok_or_else(|| SceneError::Invalid {
                    path: scene_path.to_owned(),
                    field: format!("{name}.force_newtons"),
                    message: format!(
                        "link '{}' has no mesh to take the surface normal from: give {name}.force_world",
                        push.link
                    ),
                })?;
            world_from_link.transform_vector3(frame.inward_normal) * magnitude
        }
        (None, None) => DVec3::ZERO,
    };
    Ok(ResolvedPush {
        link,
        point_world,
        force_world,
    })
}

#[cfg(test)]
#[path = "scene_tests.rs"]
mod tests;
