//! The desktop app (eframe/egui): a 3-D view of the robot, joint sliders,
//! click to push, the torques it causes and the live posterior heatmap.
//! The only place where egui, `render` and `io` meet.

pub mod live;
pub mod session;
pub mod timeline;
pub mod worker;

/// Renders the app headless (Mesa's software Vulkan or a GPU, no window):
/// runs frames until the estimate for the current model has arrived, then
/// returns the image. The path of `proprioscope screenshot` and the UI tests.
pub fn render_headless(start: AppStart, size: [f32; 2]) -> Result<image::RgbaImage, String> {
    let mut harness = headless_harness(start, size);
    settle(&mut harness)?;
    // A session that failed to load in the background is an error here,
    // not a picture of the scene it would have replaced.
    if let Some(error) = &harness.state().error {
        return Err(error.clone());
    }
    harness.render()
}

/// The app in a headless harness (wgpu), not yet settled.
#[must_use]
pub fn headless_harness(start: AppStart, size: [f32; 2]) -> egui_kittest::Harness<'static, ProprioscopeApp> {
    egui_kittest::Harness::builder()
        .with_size(egui::vec2(size[0], size[1]))
        .wgpu()
        .build_eframe(move |cc| ProprioscopeApp::from_start(cc, start))
}

/// What the app opens on.
#[derive(Debug, Clone)]
pub struct AppStart {
    /// How the robot was named (built-in name or URDF path), for saving.
    pub robot_spec: String,
    /// The robot.
    pub robot: Robot,
    /// Sensed joint positions, rad.
    pub q: Vec<f64>,
    /// The push, if any.
    pub push: Option<Push>,
    /// Estimator and sensor settings.
    pub settings: StartSettings,
    /// A session to open once the app runs (loaded in the background).
    pub session: Option<timeline::SessionTarget>,
    /// Folders for `package://` URIs.
    pub package_paths: Vec<std::path::PathBuf>,
    /// An address to listen on for a live session.
    pub live: Option<String>,
}

/// Whether `path` is a recorded session: a CSV file, or JSON that says it
/// is a `contact-session`.
#[must_use]
pub fn is_session_file(path: &std::path::Path) -> bool {
    use std::io::Read as _;
    let extension = path.extension().map(|e| e.to_string_lossy().to_ascii_lowercase());
    match extension.as_deref() {
        Some("csv" | "mcap" | "bag") => true,
        Some("json") => {
            let mut head = [0u8; 512];
            let read = std::fs::File::open(path)
                .and_then(|mut f| f.read(&mut head))
                .unwrap_or(0);
            String::from_utf8_lossy(head.get(..read).unwrap_or_default()).contains("contact-session")
        }
        _ => false,
    }
}

/// The default scene (`None`), a scene file (`.json`, with its push and
/// settings), a URDF or a built-in robot name.
pub fn open_target(target: Option<&str>) -> anyhow::Result<AppStart> {
    open_target_with(target, None, &[])
}

/// [`open_target`], where `target` may also be a recorded session (opened
/// on the default scene, then loaded in the background), with a robot
/// override for sessions and folders for `package://` URIs.
pub fn open_target_with(
    target: Option<&str>,
    robot: Option<&str>,
    package_paths: &[std::path::PathBuf],
) -> anyhow::Result<AppStart> {
    use crate::io::builtin::load_robot;
    use crate::io::urdf::UrdfOptions;
    use std::path::Path;
    if let Some(t) = target
        && is_session_file(Path::new(t))
    {
        let mut start = open_target_with(None, None, package_paths)?;
        start.session = Some(timeline::SessionTarget {
            path: t.into(),
            robot: robot.map(str::to_owned),
            frame: None,
        });
        return Ok(start);
    }
    Ok(match target {
        None => {
            let robot = load_robot("lwr4plus", Path::new("."), &UrdfOptions::default())?;
            let (q, push) = ProprioscopeApp::default_scene(&robot);
            AppStart {
                robot_spec: "lwr4plus".to_owned(),
                robot,
                q,
                push,
                settings: StartSettings::default(),
                session: None,
                live: None,
                package_paths: package_paths.to_vec(),
            }
        }
        Some(t) if t.to_ascii_lowercase().ends_with(".json") => scene_start(Path::new(t), package_paths)?,
        Some(t) => {
            let options = UrdfOptions {
                package_paths: package_paths.to_vec(),
                ..UrdfOptions::default()
            };
            let robot = load_robot(t, Path::new("."), &options)?;
            let q = vec![0.0; robot.sensed().len()];
            AppStart {
                robot_spec: if crate::io::builtin::is_builtin(t) {
                    t.to_owned()
                } else {
                    absolute_spec(Path::new(t))
                },
                robot,
                q,
                push: None,
                settings: StartSettings::default(),
                session: None,
                live: None,
                package_paths: package_paths.to_vec(),
            }
        }
    })
}

/// What a scene file opens on: its robot, pose, push and every setting.
fn scene_start(path: &std::path::Path, package_paths: &[std::path::PathBuf]) -> anyhow::Result<AppStart> {
    use crate::io::scene::{Scene, Sigma};
    use std::path::Path;
    let loaded = Scene::read(path)?.load(path)?;
    let push = loaded.push.and_then(|p| {
        let link_from_world = loaded.pose.world_from_link[p.link].inverse();
        Some(Push {
            link: p.link,
            point_in_link: link_from_world.transform_point3(p.point_world),
            inward_normal_in_link: link_from_world.transform_vector3(p.force_world.try_normalize()?),
            force_newtons: p.force_world.length(),
        })
    });
    let e = &loaded.scene.estimator;
    let settings = StartSettings {
        sigma: match &e.sigma_newton_metres {
            Sigma::All(s) => vec![*s],
            Sigma::PerJoint(v) => v.clone(),
        },
        surface_points: loaded.scene.surface_points,
        noise: (loaded.scene.noise.sigma_newton_metres, loaded.scene.noise.seed),
        force_range_newtons: (e.force_min_newtons, e.force_max_newtons),
        candidate_links: loaded
            .scene
            .candidate_links
            .is_some()
            .then(|| loaded.candidate_links.clone()),
        estimator: EstimatorChoice::from_scene(e),
        surface_seed: loaded.scene.surface_seed,
        other_joints: loaded.scene.other_joints.iter().map(|(k, v)| (k.clone(), *v)).collect(),
        view: loaded.scene.view.map(|v| ViewOptions {
            log_scale: v.log_scale,
            threshold: v.threshold,
            red_green: v.red_green,
            show_points: v.candidate_points,
            show_axes: v.joint_axes,
        }),
        title: (loaded.scene.name.clone(), loaded.scene.description.clone()),
    };
    let folder = path.parent().unwrap_or(Path::new("."));
    let mut package_paths = package_paths.to_vec();
    package_paths.extend(
        loaded
            .scene
            .package_paths
            .iter()
            .map(|p| crate::io::scene::normalized_path(&folder.join(p))),
    );
    let spec = if crate::io::builtin::is_builtin(&loaded.scene.robot) {
        loaded.scene.robot.clone()
    } else {
        absolute_spec(&folder.join(&loaded.scene.robot))
    };
    Ok(AppStart {
        robot_spec: spec,
        q: loaded.scene.q.clone(),
        robot: loaded.robot,
        push,
        settings,
        session: None,
        live: None,
        package_paths,
    })
}

/// A URDF path as the app keeps it: absolute, so that a scene saved
/// anywhere can name it relative to itself.
fn absolute_spec(path: &std::path::Path) -> String {
    crate::io::scene::normalized_path(path).display().to_string()
}

/// Runs frames until the newest estimate has arrived (at most ~10 s).
pub fn settle(harness: &mut egui_kittest::Harness<'_, ProprioscopeApp>) -> Result<(), String> {
    for _ in 0..1000 {
        harness.step();
        if harness.state().is_up_to_date() {
            harness.run_steps(2);
            return Ok(());
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    Err("the estimate did not arrive within 10 s".to_owned())
}

use std::fmt::Write as _;
use std::sync::Arc;

use eframe::egui;
use glam::{DVec3, Vec2};

use crate::core::estimator::{EstimatorSettings, Mode};
use crate::core::kinematics::RobotPose;
use crate::core::picking::Picker;
use crate::core::pipeline::Temporal;
use crate::core::robot::{LinkId, Robot};
use crate::core::summary::Verdict;
use crate::core::surface::SurfaceRequest;
use crate::core::torque::{joint_torques, with_sensor_noise};
use crate::render::camera::OrbitCamera;
use crate::render::renderer::{Frame, Renderer};
use crate::render::scene::{ROBOT_GREY, arrow, grid_and_axes, red_green, robot_triangles, viridis};
use worker::{Outcome, Request, Worker};

/// One σ per joint from a list of one (for every joint) or one per joint.
fn per_joint(sigma: &[f64], joints: usize) -> Vec<f64> {
    if sigma.len() == joints {
        sigma.to_vec()
    } else {
        vec![sigma.first().copied().unwrap_or(0.1); joints]
    }
}

/// Points and particles evaluated, per phase when there are phases.
fn phase_report(phases: &[crate::core::estimator::PhaseReport]) -> String {
    if let [one] = phases {
        return format!("evaluated {} points, {} particles", one.points, one.particles);
    }
    let parts: Vec<String> = phases
        .iter()
        .zip(["A", "B", "C"])
        .map(|(p, name)| format!("{name}: {} points, {} particles", p.points, p.particles))
        .collect();
    format!("phases {}", parts.join("; "))
}

/// The scene files shipped in `scenes/` (relative to the working
/// directory), sorted; none when the folder is not there.
fn shipped_scenes() -> Vec<std::path::PathBuf> {
    let mut paths: Vec<std::path::PathBuf> = std::fs::read_dir("scenes")
        .map(|entries| {
            entries
                .filter_map(Result::ok)
                .map(|e| e.path())
                .filter(|p| p.extension().is_some_and(|e| e == "json"))
                .collect()
        })
        .unwrap_or_default();
    paths.sort();
    paths
}

/// Full estimates of this many recently shown session frames are kept, so
/// that stepping back shows them at once (each holds a few posterior
/// arrays over the surface, about 200 kB at 5000 points).
const VISITED_FRAMES: usize = 128;

/// Log-likelihood range shown by the heatmap, from yellow (the best) to
/// purple (e^-20 ≈ 2e-9 of it, and less).
const HEAT_DEPTH: f64 = 20.0;

/// A push on the robot, kept in the link frame so that it moves with the arm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Push {
    /// The link pushed.
    pub link: LinkId,
    /// Contact point in the link frame, m.
    pub point_in_link: DVec3,
    /// Inward unit normal in the link frame: the push's direction.
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
}

/// Slowest and fastest playback.
pub const SPEED_RANGE: (f64, f64) = (0.1, 10.0);

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
}

impl Default for ViewOptions {
    fn default() -> Self {
        Self {
            log_scale: true,
            threshold: 0.0,
            red_green: false,
            show_points: false,
            show_axes: false,
        }
    }
}

/// Everything the 3-D view's picture depends on.
#[derive(Debug, Clone, PartialEq)]
struct ViewKey {
    inputs: EstimateInputs,
    view: ViewOptions,
    generation: Option<u64>,
    hovered_joint: Option<usize>,
    camera: OrbitCamera,
    size: [u32; 2],
}

/// The parts of the [`Model`] an estimate depends on, to tell whether a
/// command calls for a new one.
#[derive(Debug, Clone, PartialEq)]
struct EstimateInputs {
    q: Vec<f64>,
    push: Option<Push>,
    sigma: Vec<f64>,
    surface_points: usize,
    candidate_links: Vec<LinkId>,
    noise: (f64, u64),
    estimator: EstimatorChoice,
    force_range_newtons: (f64, f64),
    frame: Option<usize>,
    surface_seed: u64,
    other_joints: Vec<(String, f64)>,
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

/// A change to the [`Model`], sent by the UI and applied in one place.
#[derive(Debug, Clone, Copy, PartialEq)]
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
    /// Remove the push.
    ClearPush,
    /// Set the likelihood σ of every joint, N·m.
    SetSigma(f64),
    /// Set one joint's likelihood σ, N·m.
    SetJointSigma(usize, f64),
    /// Set the surface resolution.
    SetSurfacePoints(usize),
    /// Make a link a candidate (true) or not.
    SetCandidate(LinkId, bool),
    /// Set the sensor noise, N·m.
    SetNoise(f64),
    /// Set the estimator's mode and phases.
    SetEstimator(EstimatorChoice),
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
    /// Set the playback speed (clamped to [`SPEED_RANGE`]).
    SetSpeed(f64),
    /// Loop at the end (true) or stop.
    SetLoop(bool),
    /// Estimate the session's frames alone, filtered or smoothed.
    SetOverTime(Temporal),
    /// Advance playback by this much wall-clock time, s.
    Tick(f64),
}

impl Model {
    /// Applies a command; true when something changed.
    pub fn apply(&mut self, command: Command) -> bool {
        let before = self.estimate_inputs();
        match command {
            Command::SetJoint(i, value) => {
                if let Some(q) = self.q.get_mut(i) {
                    *q = value;
                }
            }
            Command::ZeroJoints => self.q.iter_mut().for_each(|q| *q = 0.0),
            Command::RandomPose(seed) => {
                let mut rng = crate::core::rng::Rng::new(seed);
                for (q, &j) in self.q.iter_mut().zip(self.robot.sensed()) {
                    let (lo, hi) = self.robot.joints[j]
                        .limits
                        .map_or((-std::f64::consts::PI, std::f64::consts::PI), |l| (l.lower, l.upper));
                    *q = rng.uniform_in(lo, hi);
                }
            }
            Command::SetNoiseSeed(seed) => self.noise_seed = seed,
            Command::Push(push) => self.push = Some(push),
            Command::SetForce(f) => {
                if let Some(p) = self.push.as_mut() {
                    p.force_newtons = f.max(0.0);
                }
            }
            Command::ClearPush => self.push = None,
            Command::SetSigma(s) => self.sigma.iter_mut().for_each(|v| *v = s.max(1e-6)),
            Command::SetJointSigma(i, s) => {
                if let Some(v) = self.sigma.get_mut(i) {
                    *v = s.max(1e-6);
                }
            }
            Command::SetSurfacePoints(n) => self.surface_points = n.clamp(10, crate::core::surface::MAX_POINTS),
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
            Command::SetNoise(s) => self.noise_sigma = s.max(0.0),
            Command::SetEstimator(choice) => {
                self.estimator = EstimatorChoice {
                    particles: choice.particles.clamp(1, crate::core::estimator::MAX_PARTICLES),
                    magnitudes_per_point: choice
                        .magnitudes_per_point
                        .clamp(1, crate::core::estimator::MAX_MAGNITUDES),
                    alpha: choice.alpha.clamp(0.0, 0.99),
                    ..choice
                };
            }
            Command::SetForceRange(lo, hi) => {
                let lo = lo.max(0.0);
                self.force_range_newtons = (lo, hi.max(lo));
            }
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
            Command::SetSpeed(speed) => {
                if let Some(r) = &mut self.replay {
                    r.speed = speed.clamp(SPEED_RANGE.0, SPEED_RANGE.1);
                }
            }
            Command::SetLoop(on) => {
                if let Some(r) = &mut self.replay {
                    r.looping = on;
                }
            }
            Command::SetOverTime(temporal) => {
                if let Some(r) = &mut self.replay {
                    r.over_time = temporal;
                }
            }
            Command::Tick(dt_secs) => self.tick(dt_secs),
        }
        before != self.estimate_inputs()
    }

    /// Shows session frame `i` (clamped to the last): its `q`, and its true
    /// contact as the push.
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
        let truth = frame.truth.clone();
        let positions = self.joint_positions();
        let pose = RobotPose::new(&self.robot, &positions);
        self.push = match truth {
            crate::io::session::Truth::Contact { link, point, force } => {
                self.robot.link_id(&link).ok().and_then(|link| {
                    let link_from_world = pose.world_from_link.get(link)?.inverse();
                    let force = DVec3::from_array(force);
                    Some(Push {
                        link,
                        point_in_link: link_from_world.transform_point3(DVec3::from_array(point)),
                        inward_normal_in_link: link_from_world.transform_vector3(force.try_normalize()?),
                        force_newtons: force.length(),
                    })
                })
            }
            _ => None,
        };
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
    fn estimate_inputs(&self) -> EstimateInputs {
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
            surface_seed: self.surface_seed,
            other_joints: self.other_joints.clone(),
        }
    }

    /// The core estimator's settings.
    #[must_use]
    pub fn estimator_settings(&self) -> EstimatorSettings {
        use crate::core::estimator::{ParticleSettings, Sampling};
        let e = self.estimator;
        EstimatorSettings {
            sigma: self.sigma.clone(),
            force_min_newtons: self.force_range_newtons.0,
            force_max_newtons: self.force_range_newtons.1,
            mode: match e.mode {
                ModeChoice::Exact => Mode::Exact,
                ModeChoice::ParticlesDeterministic => Mode::Particles(ParticleSettings {
                    sampling: Sampling::Deterministic {
                        magnitudes_per_point: e.magnitudes_per_point,
                    },
                }),
                ModeChoice::ParticlesRandom => Mode::Particles(ParticleSettings {
                    sampling: Sampling::Random {
                        count: e.particles,
                        seed: 7,
                    },
                }),
            },
            phase_alpha: e.phases.then_some(e.alpha),
            patches: true,
        }
    }

    /// Every joint's position.
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

/// The app.
pub struct ProprioscopeApp {
    /// The user's model.
    pub model: Model,
    camera: OrbitCamera,
    picker: Picker,
    worker: Worker,
    generation: u64,
    /// The latest estimate shown.
    pub outcome: Option<Outcome>,
    renderer: Option<Renderer>,
    texture: Option<egui::TextureId>,
    view_rect: Option<egui::Rect>,
    robot_spec: String,
    /// The last failed open or save, shown until the next success.
    pub error: Option<String>,
    /// The joint whose torque bar the pointer is over (sensed index).
    hovered_joint: Option<usize>,
    /// Seed of the last random pose.
    pose_seed: u64,
    /// What the view texture last showed: it is redrawn only when this changes.
    drawn: Option<ViewKey>,
    status: String,
    ctx: egui::Context,
    session_worker: session::SessionWorker,
    /// Background estimates of the session's frames (`None`: not yet).
    pub session_estimates: Vec<Option<session::FrameEstimate>>,
    /// How many of them are there (counted as they arrive, not per frame).
    session_done: usize,
    /// Frames whose estimate failed, with why.
    session_failures: std::collections::BTreeMap<usize, String>,
    session_generation: u64,
    session_key: Option<timeline::SessionKey>,
    loader: Option<session::Loader>,
    /// A live source being listened to.
    live: Option<live::LiveView>,
    /// The address typed in the Session menu for listening.
    live_address_input: String,
    /// A recording whose topics the user is asked to choose.
    pub topic_prompt: Option<session::TopicPrompt>,
    /// Topics chosen per recording, and the last choice (tried first on
    /// the next recording).
    topic_choices: std::collections::HashMap<std::path::PathBuf, crate::io::recording::TopicChoice>,
    last_topic_choice: Option<crate::io::recording::TopicChoice>,
    recording: Option<timeline::Recording>,
    /// Folders for `package://` URIs when opening URDFs and sessions.
    pub package_paths: Vec<std::path::PathBuf>,
    /// The frame a session being loaded opens on.
    first_frame: Option<usize>,
    /// Estimates of session frames shown recently, by what they depend on.
    visited: std::collections::VecDeque<(EstimateInputs, Outcome)>,
    /// The estimate asked of the worker last, and what it depends on.
    pending: Option<(u64, EstimateInputs)>,
    /// Session frames shown again from [`Self::visited`] (for tests).
    pub visited_hits: usize,
    /// The session's metrics, with the estimation run they belong to.
    session_metrics: Option<((u64, usize), Option<timeline::SessionMetrics>)>,
    /// A scene, URDF or robot being opened in the background.
    opening: Option<worker::Background<AppStart>>,
}

impl ProprioscopeApp {
    /// The app on `robot` at `q`, with an optional push, ready to draw.
    #[must_use]
    pub fn new(
        cc: &eframe::CreationContext<'_>,
        robot: Robot,
        q: Vec<f64>,
        push: Option<Push>,
        settings: StartSettings,
    ) -> Self {
        let ctx = cc.egui_ctx.clone();
        let renderer = cc
            .wgpu_render_state
            .as_ref()
            .map(|state| Renderer::new(&state.device, [640, 480]));
        let picker = Picker::new(&robot);
        let mut app = Self {
            model: Model::from_start(robot, q, push, settings, ViewOptions::default()),
            camera: OrbitCamera::default(),
            picker,
            worker: Worker::spawn(move || ctx.request_repaint()),
            generation: 0,
            outcome: None,
            renderer,
            texture: None,
            view_rect: None,
            robot_spec: String::new(),
            error: None,
            hovered_joint: None,
            pose_seed: 0,
            drawn: None,
            status: String::new(),
            session_worker: session::SessionWorker::spawn({
                let ctx = cc.egui_ctx.clone();
                move || ctx.request_repaint()
            }),
            ctx: cc.egui_ctx.clone(),
            session_estimates: Vec::new(),
            session_done: 0,
            session_failures: std::collections::BTreeMap::new(),
            session_generation: 0,
            session_key: None,
            loader: None,
            topic_prompt: None,
            live: None,
            live_address_input: "127.0.0.1:7878".to_owned(),
            topic_choices: std::collections::HashMap::new(),
            last_topic_choice: None,
            recording: None,
            package_paths: Vec::new(),
            first_frame: None,
            session_metrics: None,
            visited: std::collections::VecDeque::new(),
            pending: None,
            visited_hits: 0,
            opening: None,
        };
        app.request_estimate();
        app
    }

    /// The app on what [`open_target`] found.
    #[must_use]
    pub fn from_start(cc: &eframe::CreationContext<'_>, start: AppStart) -> Self {
        let spec = start.robot_spec.clone();
        let mut app = Self::new(cc, start.robot, start.q, start.push, start.settings);
        app.robot_spec = spec;
        app.package_paths = start.package_paths;
        if let Some(session) = start.session {
            app.first_frame = session.frame;
            app.open_session(&session.path, session.robot);
        }
        if let Some(address) = start.live {
            app.start_live(&address);
        }
        app
    }

    /// Opens a scene, URDF or built-in robot; on failure shows the error
    /// and keeps the current scene.
    pub fn open(&mut self, target: &str) {
        if is_session_file(std::path::Path::new(target)) {
            self.open_session(std::path::Path::new(target), None);
            return;
        }
        // Reading a URDF and its meshes can take seconds: on a thread of
        // its own, the current scene staying until it is there.
        let owned = target.to_owned();
        let package_paths = self.package_paths.clone();
        let ctx = self.ctx.clone();
        self.opening = Some(worker::Background::spawn(
            target.to_owned(),
            move || open_target_with(Some(&owned), None, &package_paths).map_err(|e| format!("{e:#}")),
            move || ctx.request_repaint(),
        ));
    }

    /// Whether a scene, URDF or robot is being opened in the background.
    #[must_use]
    pub fn is_opening(&self) -> bool {
        self.opening.is_some()
    }

    /// Installs a scene, URDF or robot opened in the background (or shows
    /// why it could not be opened).
    fn poll_opening(&mut self) {
        let Some(done) = self.opening.as_ref().and_then(worker::Background::poll) else {
            return;
        };
        let target = self.opening.take().map(|o| o.what).unwrap_or_default();
        match done {
            Ok(start) => {
                let model = Model::from_start(start.robot, start.q, start.push, start.settings, self.model.view);
                self.package_paths = start.package_paths;
                self.replace_model(model, start.robot_spec);
            }
            Err(e) => self.error = Some(format!("could not open {target}: {e}")),
        }
    }

    /// The current model as a scene file to be written at `scene_path`:
    /// everything the app shows, a URDF robot and package folders named
    /// relative to the scene's folder.
    #[must_use]
    pub fn to_scene(&self, scene_path: &std::path::Path) -> crate::io::scene::Scene {
        use crate::io::scene as sc;
        let m = &self.model;
        let positions = m.joint_positions();
        let pose = RobotPose::new(&m.robot, &positions);
        let folder = scene_path.parent().unwrap_or(std::path::Path::new("."));
        let relative = |p: &std::path::Path| sc::relative_path(p, folder).display().to_string();
        let builtin = crate::io::builtin::is_builtin(&self.robot_spec);
        sc::Scene {
            version: sc::SCENE_VERSION,
            name: m.title.0.clone(),
            description: m.title.1.clone(),
            robot: if builtin {
                self.robot_spec.clone()
            } else {
                relative(std::path::Path::new(&self.robot_spec))
            },
            package_paths: self.package_paths.iter().map(|p| relative(p)).collect(),
            sensed_joints: (!builtin).then(|| m.robot.sensed_names().into_iter().map(str::to_owned).collect()),
            q: m.q.clone(),
            other_joints: m.other_joints.iter().cloned().collect(),
            candidate_links: (m.candidate_links != m.robot.default_candidate_links()).then(|| {
                m.candidate_links
                    .iter()
                    .map(|&l| m.robot.links[l].name.clone())
                    .collect()
            }),
            surface_points: m.surface_points,
            surface_seed: m.surface_seed,
            push: m.push_world(&pose).map(|(link, point, force)| sc::Push {
                link: m.robot.links[link].name.clone(),
                point_in_link: None,
                point_world: Some(point.to_array()),
                force_world: Some(force.to_array()),
                force_newtons: None,
            }),
            noise: sc::Noise {
                sigma_newton_metres: m.noise_sigma,
                seed: m.noise_seed,
            },
            estimator: sc::EstimatorSettings {
                mode: if m.estimator.mode == ModeChoice::Exact {
                    sc::Mode::Exact
                } else {
                    sc::Mode::Particles
                },
                sigma_newton_metres: if m.sigma.iter().all(|v| (v - m.sigma[0]).abs() < 1e-15) {
                    sc::Sigma::All(m.sigma.first().copied().unwrap_or(0.1))
                } else {
                    sc::Sigma::PerJoint(m.sigma.clone())
                },
                sampling: if m.estimator.mode == ModeChoice::ParticlesRandom {
                    sc::Sampling::Random
                } else {
                    sc::Sampling::Deterministic
                },
                particles: m.estimator.particles,
                magnitudes_per_point: m.estimator.magnitudes_per_point,
                phases: sc::Phases {
                    enabled: m.estimator.phases,
                    sizes: m.estimator.phase_sizes,
                    alpha: m.estimator.alpha,
                },
                force_min_newtons: m.force_range_newtons.0,
                force_max_newtons: m.force_range_newtons.1,
            },
            view: Some(sc::View {
                log_scale: m.view.log_scale,
                threshold: m.view.threshold,
                red_green: m.view.red_green,
                candidate_points: m.view.show_points,
                joint_axes: m.view.show_axes,
            }),
        }
    }

    /// Writes the current scene as JSON.
    pub fn save(&mut self, path: &std::path::Path) {
        let result = self
            .to_scene(path)
            .to_json()
            .map_err(|e| e.to_string())
            .and_then(|json| std::fs::write(path, json).map_err(|e| e.to_string()));
        self.error = result.err().map(|e| format!("could not save {}: {e}", path.display()));
    }

    fn menu_ui(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("Scenes", |ui| {
                if ui.button("Open scene or URDF…").clicked() {
                    ui.close();
                    if let Some(path) = rfd::FileDialog::new()
                        .add_filter("scene or URDF", &["json", "urdf"])
                        .pick_file()
                    {
                        self.open(&path.display().to_string());
                    }
                }
                if ui
                    .button("Add package folder…")
                    .on_hover_text("a folder where package:// mesh URIs of URDFs are looked up")
                    .clicked()
                {
                    ui.close();
                    if let Some(folder) = rfd::FileDialog::new().pick_folder() {
                        self.package_paths.push(folder);
                    }
                }
                if ui.button("Save scene…").clicked() {
                    ui.close();
                    if let Some(path) = rfd::FileDialog::new().add_filter("scene", &["json"]).save_file() {
                        self.save(&path);
                    }
                }
                ui.separator();
                for path in shipped_scenes() {
                    let name = path
                        .file_stem()
                        .map(|s| s.to_string_lossy().into_owned())
                        .unwrap_or_default();
                    if ui.button(name).clicked() {
                        ui.close();
                        self.open(&path.display().to_string());
                    }
                }
            });
            self.session_menu_ui(ui);
            ui.menu_button("Robot", |ui| {
                for name in crate::core::builtin::BUILTIN_NAMES {
                    if ui.button(name).clicked() {
                        ui.close();
                        self.open(name);
                    }
                }
            });
            if let Some(error) = &self.error {
                ui.colored_label(egui::Color32::LIGHT_RED, error);
            }
        });
    }

    /// The built-in LWR in a bent pose with a push on its upper arm (link
    /// 3, which only three joints sense: the posterior shows a band of
    /// equally good contacts, the point of the method).
    #[must_use]
    pub fn default_scene(robot: &Robot) -> (Vec<f64>, Option<Push>) {
        let q = vec![0.3, 0.6, -0.4, -1.2, 0.5, 0.9, 0.2];
        let positions = robot.joint_positions(&q, &[]).unwrap_or_default();
        let pose = RobotPose::new(robot, &positions);
        let picker = Picker::new(robot);
        let push = robot.link_id("lwr_3_link").ok().and_then(|l3| {
            let centre = pose.point_to_world(l3, DVec3::new(0.0, 0.0, 0.1));
            let origin = centre + DVec3::new(1.0, 0.6, 0.1);
            picker.pick(&pose, origin, centre - origin, &[l3]).map(|hit| Push {
                link: hit.link,
                point_in_link: hit.point_in_link,
                inward_normal_in_link: pose.world_from_link[hit.link]
                    .inverse()
                    .transform_vector3(hit.inward_normal_world),
                force_newtons: 15.0,
            })
        });
        (q, push)
    }

    /// Applies a command and, if it changed the model, re-estimates.
    pub fn apply(&mut self, command: Command) {
        if self.model.apply(command) {
            self.request_estimate();
        }
    }

    fn request_estimate(&mut self) {
        let inputs = self.model.estimate_inputs();
        self.generation += 1;
        // A session frame seen before with these settings: its estimate is kept.
        if self.model.replay.is_some()
            && let Some((_, outcome)) = self.visited.iter().find(|(k, _)| *k == inputs)
        {
            self.outcome = Some(Outcome {
                generation: self.generation,
                ..outcome.clone()
            });
            self.visited_hits += 1;
            return;
        }
        self.pending = Some((self.generation, inputs));
        let positions = self.model.joint_positions();
        let pose = RobotPose::new(&self.model.robot, &positions);
        let tau = self.model.measured_torques(&pose);
        self.worker.request(Request {
            generation: self.generation,
            robot: self.model.robot.clone(),
            joint_positions: positions,
            tau,
            surface: SurfaceRequest {
                links: self.model.candidate_links.clone(),
                total_points: self.model.surface_points,
                seed: self.model.surface_seed,
            },
            settings: self.model.estimator_settings(),
            phase_sizes: self.model.estimator.phases.then_some(self.model.estimator.phase_sizes),
        });
    }

    /// Where a link's origin region appears in the window (the centre of
    /// its sampled surface, projected), for tests and tours.
    #[must_use]
    pub fn pixel_of_link(&self, name: &str) -> Option<egui::Pos2> {
        let link = self.model.robot.link_id(name).ok()?;
        let positions = self.model.joint_positions();
        let pose = RobotPose::new(&self.model.robot, &positions);
        let rect = self.view_rect?;
        let mesh = &self.model.robot.links[link].mesh;
        let (lo, hi) = mesh.bounds()?;
        let centre = pose.point_to_world(link, 0.5 * (lo + hi));
        // Aim at the centre, then walk towards the eye until the ray hits this link.
        let size = Vec2::new(rect.width(), rect.height());
        let pixel = self.camera.project(centre.as_vec3(), size)?;
        let (origin, dir) = self.camera.ray(pixel, size);
        let hit = self.picker.pick(&pose, origin.as_dvec3(), dir.as_dvec3(), &[])?;
        (hit.link == link).then(|| rect.min + egui::vec2(pixel.x, pixel.y))
    }

    /// The newest estimate for the current model has arrived.
    #[must_use]
    pub fn is_up_to_date(&self) -> bool {
        self.opening.is_none()
            && self.current_outcome().is_some_and(|o| o.generation == self.generation)
            && self.session_settled()
    }

    /// The model's invariants (what the monkey test checks after every
    /// action): one q and one σ per sensed joint, all finite; candidate
    /// links, the push's link and the shown estimate of this robot; the
    /// session frame within the session.
    pub fn check_invariants(&self) -> Result<(), String> {
        let m = &self.model;
        let joints = m.robot.sensed().len();
        if m.q.len() != joints || m.sigma.len() != joints {
            return Err(format!(
                "{} q and {} σ for {joints} sensed joints",
                m.q.len(),
                m.sigma.len()
            ));
        }
        if !m.q.iter().chain(&m.sigma).all(|v| v.is_finite()) {
            return Err(format!("non-finite q {:?} or σ {:?}", m.q, m.sigma));
        }
        let links = m.robot.links.len();
        if m.candidate_links.is_empty() || m.candidate_links.iter().any(|&l| l >= links) {
            return Err(format!("candidate links {:?} of {links}", m.candidate_links));
        }
        if let Some(p) = m.push
            && (p.link >= links || !p.force_newtons.is_finite() || !p.point_in_link.is_finite())
        {
            return Err(format!("push {p:?} on a robot of {links} links"));
        }
        if let Some(o) = self.current_outcome()
            && let Ok(u) = &o.update
            && (u.summary.map.link >= links || u.posterior.probability.iter().any(|p| !p.is_finite()))
        {
            return Err("the shown estimate does not fit the robot".to_owned());
        }
        if let Some(r) = &m.replay
            && !r.session.frames.is_empty()
            && r.frame >= r.session.frames.len()
        {
            return Err(format!("frame {} of {}", r.frame, r.session.frames.len()));
        }
        Ok(())
    }

    /// Where the 3-D view was last drawn in the window.
    #[must_use]
    pub fn view_rect(&self) -> Option<egui::Rect> {
        self.view_rect
    }

    /// How the robot was named when opened: a built-in name or the
    /// URDF's absolute path.
    #[must_use]
    pub fn robot_spec(&self) -> &str {
        &self.robot_spec
    }

    /// The estimate shown: the latest one, if it was made for the current
    /// robot (anything drawn from an estimate reads it through here).
    #[must_use]
    pub fn current_outcome(&self) -> Option<&Outcome> {
        self.outcome
            .as_ref()
            .filter(|o| Arc::ptr_eq(&o.robot, &self.model.robot))
    }

    /// Replaces the whole model, robot included: the one place where a
    /// robot changes. Everything derived from the previous robot (its
    /// estimate, the frames estimated, the picker, the hovered joint, the
    /// drawn view) is dropped or rebuilt here, and a new estimate asked for.
    pub(crate) fn replace_model(&mut self, model: Model, robot_spec: String) {
        self.picker = Picker::new(&model.robot);
        self.model = model;
        self.robot_spec = robot_spec;
        self.outcome = None;
        self.pending = None;
        self.visited.clear();
        self.hovered_joint = None;
        self.drawn = None;
        self.session_key = None;
        self.session_estimates.clear();
        self.session_done = 0;
        self.session_failures.clear();
        self.session_metrics = None;
        self.error = None;
        self.request_estimate();
    }

    fn robot_panel_ui(&mut self, ui: &mut egui::Ui) -> Vec<Command> {
        let mut commands = Vec::new();
        ui.heading(&self.model.robot.name);
        ui.label("Joints (degrees)");
        for (i, &j) in self.model.robot.sensed().iter().enumerate() {
            let joint = &self.model.robot.joints[j];
            let (lo, hi) = joint
                .limits
                .map_or((-180.0, 180.0), |l| (l.lower.to_degrees(), l.upper.to_degrees()));
            let mut deg = self.model.q[i].to_degrees();
            if ui.add(egui::Slider::new(&mut deg, lo..=hi).text(&joint.name)).changed() {
                commands.push(Command::SetJoint(i, deg.to_radians()));
            }
        }
        ui.horizontal(|ui| {
            if ui.button("Zero pose").clicked() {
                commands.push(Command::ZeroJoints);
            }
            if ui.button("Random pose").clicked() {
                self.pose_seed += 1;
                commands.push(Command::RandomPose(self.pose_seed));
            }
        });
        ui.separator();
        ui.label("Push (click the arm)");
        match self.model.push {
            Some(p) => {
                let mut f = p.force_newtons;
                if ui
                    .add(egui::Slider::new(&mut f, 0.0..=30.0).text("force [N]"))
                    .changed()
                {
                    commands.push(Command::SetForce(f));
                }
                let positions = self.model.joint_positions();
                let pose = RobotPose::new(&self.model.robot, &positions);
                let at = pose.point_to_world(p.link, p.point_in_link);
                ui.label(format!(
                    "on {} at ({:.3}, {:.3}, {:.3}) m",
                    self.model.robot.links[p.link].name, at.x, at.y, at.z
                ));
                if ui.button("Clear push").clicked() {
                    commands.push(Command::ClearPush);
                }
            }
            None => {
                ui.label("none");
            }
        }
        ui.separator();
        ui.label("Links that can be touched");
        for link in self.model.robot.default_candidate_links() {
            let mut on = self.model.candidate_links.contains(&link);
            if ui.checkbox(&mut on, &self.model.robot.links[link].name).changed() {
                commands.push(Command::SetCandidate(link, on));
            }
        }
        ui.separator();
        let mut seed = self.model.noise_seed;
        if ui.add(egui::DragValue::new(&mut seed).prefix("noise seed ")).changed() {
            commands.push(Command::SetNoiseSeed(seed));
        }
        let mut noise = self.model.noise_sigma;
        if ui
            .add(egui::Slider::new(&mut noise, 0.0..=0.5).text("sensor noise σ [N·m]"))
            .changed()
        {
            commands.push(Command::SetNoise(noise));
        }
        commands
    }

    fn estimator_panel_ui(&mut self, ui: &mut egui::Ui) -> Vec<Command> {
        let mut commands = Vec::new();
        ui.heading("Estimator");
        let mut sigma = self.model.sigma.iter().copied().fold(0.0, f64::max);
        if ui
            .add(
                egui::Slider::new(&mut sigma, 0.005..=1.0)
                    .logarithmic(true)
                    .text("σ [N·m]"),
            )
            .changed()
        {
            commands.push(Command::SetSigma(sigma));
        }
        egui::CollapsingHeader::new("σ per joint").show(ui, |ui| {
            for (i, value) in self.model.sigma.iter().enumerate() {
                let mut v = *value;
                let name = &self.model.robot.joints[self.model.robot.sensed()[i]].name;
                if ui
                    .add(
                        egui::DragValue::new(&mut v)
                            .range(0.001..=10.0)
                            .speed(0.001)
                            .prefix(format!("{name}: ")),
                    )
                    .changed()
                {
                    commands.push(Command::SetJointSigma(i, v));
                }
            }
        });
        let mut points = self.model.surface_points;
        if ui
            .add(
                egui::Slider::new(&mut points, 200..=50_000)
                    .logarithmic(true)
                    .text("N (surface points)"),
            )
            .changed()
        {
            commands.push(Command::SetSurfacePoints(points));
        }
        commands.extend(self.estimator_options_ui(ui));
        commands.extend(self.view_options_ui(ui));
        ui.separator();
        self.summary_ui(ui);
        commands
    }

    /// What the latest estimate says.
    fn summary_ui(&self, ui: &mut egui::Ui) {
        match self.current_outcome() {
            Some(o) => match &o.update {
                Ok(u) => {
                    let s = &u.summary;
                    ui.label(format!(
                        "update: {:.2} ms ({:.0} Hz)",
                        o.update_ms,
                        1e3 / o.update_ms.max(1e-3)
                    ));
                    ui.label(phase_report(&u.posterior.phases));
                    ui.label(match s.verdict {
                        Verdict::Contact => "contact".to_owned(),
                        Verdict::NoContact => "no contact: torques within noise".to_owned(),
                        Verdict::PoorFit => "no candidate explains these torques".to_owned(),
                    });
                    ui.label(format!(
                        "most probable: {} ({:.1} %), {:.1} N",
                        self.model.robot.links[s.map.link].name,
                        s.map.probability * 100.0,
                        s.map.force_newtons
                    ));
                    ui.label(format!(
                        "90 % credible set: {} points, radius {:.0} mm",
                        s.credible90.points.len(),
                        s.credible90.radius_m * 1e3
                    ));
                    let positions = self.model.joint_positions();
                    let pose = RobotPose::new(&self.model.robot, &positions);
                    if let Some((_, point, force)) = self.model.push_world(&pose) {
                        ui.label(format!(
                            "error: {:.0} mm, {:.1} N",
                            s.map.point_world.distance(point) * 1e3,
                            s.map.force_world.distance(force)
                        ));
                    }
                    if !s.clusters.is_empty() {
                        ui.label("Clusters of probable contacts (P ≥ 0.9 max)");
                        for (i, c) in s.clusters.iter().take(5).enumerate() {
                            ui.label(format!(
                                "{}: {} points, σ_r {:.0} mm, σ_F {:.1} N",
                                i + 1,
                                c.points.len(),
                                c.sigma_r_m * 1e3,
                                c.sigma_f_newtons
                            ));
                        }
                    }
                    ui.separator();
                    ui.label("Probability per link (bar: summed; max: its best point)");
                    for share in &s.per_link {
                        ui.add(egui::ProgressBar::new(share.summed as f32).text(format!(
                            "{} {:.1} % (max {:.1e})",
                            self.model.robot.links[share.link].name,
                            share.summed * 100.0,
                            share.max
                        )));
                    }
                }
                Err(e) => {
                    ui.colored_label(egui::Color32::LIGHT_RED, e);
                }
            },
            None => {
                ui.label("estimating…");
            }
        }
    }

    /// Mode, particles, phases and force range.
    fn estimator_options_ui(&self, ui: &mut egui::Ui) -> Vec<Command> {
        let mut choice = self.model.estimator;
        egui::ComboBox::from_label("mode")
            .selected_text(match choice.mode {
                ModeChoice::Exact => "exact",
                ModeChoice::ParticlesDeterministic => "particles, deterministic",
                ModeChoice::ParticlesRandom => "particles, random",
            })
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut choice.mode, ModeChoice::Exact, "exact");
                ui.selectable_value(
                    &mut choice.mode,
                    ModeChoice::ParticlesDeterministic,
                    "particles, deterministic",
                );
                ui.selectable_value(&mut choice.mode, ModeChoice::ParticlesRandom, "particles, random");
            });
        match choice.mode {
            ModeChoice::Exact => {}
            ModeChoice::ParticlesDeterministic => {
                ui.add(egui::Slider::new(&mut choice.magnitudes_per_point, 1..=20).text("m (magnitudes per point)"));
            }
            ModeChoice::ParticlesRandom => {
                ui.add(
                    egui::Slider::new(&mut choice.particles, 1000..=200_000)
                        .logarithmic(true)
                        .text("N (particles)"),
                );
            }
        }
        ui.checkbox(&mut choice.phases, "phases A/B/C");
        if choice.phases {
            ui.add(egui::Slider::new(&mut choice.alpha, 0.0..=0.99).text("α"));
            ui.horizontal(|ui| {
                ui.add(
                    egui::DragValue::new(&mut choice.phase_sizes[0])
                        .range(10..=5000)
                        .prefix("A: "),
                );
                ui.add(
                    egui::DragValue::new(&mut choice.phase_sizes[1])
                        .range(10..=20000)
                        .prefix("B: "),
                );
                ui.label("points");
            });
        }
        let (mut lo, mut hi) = self.model.force_range_newtons;
        let mut commands = Vec::new();
        ui.horizontal(|ui| {
            let a = ui.add(
                egui::DragValue::new(&mut lo)
                    .range(0.0..=1000.0)
                    .speed(0.1)
                    .prefix("F min "),
            );
            let b = ui.add(
                egui::DragValue::new(&mut hi)
                    .range(0.0..=1000.0)
                    .speed(0.1)
                    .prefix("F max "),
            );
            ui.label("N");
            if a.changed() || b.changed() {
                commands.push(Command::SetForceRange(lo, hi));
            }
        });
        if choice != self.model.estimator {
            commands.push(Command::SetEstimator(choice));
        }
        commands
    }

    /// Renders the 3-D view into its texture and shows it in `rect`.
    fn paint_view(&mut self, ui: &egui::Ui, frame: &eframe::Frame, rect: egui::Rect) {
        let pixels = rect.size() * ui.ctx().pixels_per_point();
        let size = [pixels.x.round() as u32, pixels.y.round() as u32];
        // The vertex lists and the GPU pass are redone only when something
        // they show has changed, not every frame.
        let key = ViewKey {
            inputs: self.model.estimate_inputs(),
            view: self.model.view,
            generation: self.current_outcome().map(|o| o.generation),
            hovered_joint: self.hovered_joint,
            camera: self.camera,
            size,
        };
        let scene = (self.drawn.as_ref() != Some(&key)).then(|| self.scene_frame());
        match (frame.wgpu_render_state(), self.renderer.as_mut()) {
            (Some(state), Some(renderer)) => {
                let resized = renderer.resize(&state.device, size);
                if let Some(scene) = &scene {
                    renderer.render(&state.device, &state.queue, &self.camera, scene);
                    self.drawn = Some(key);
                }
                let mut egui_renderer = state.renderer.write();
                match self.texture {
                    None => {
                        self.texture = Some(egui_renderer.register_native_texture(
                            &state.device,
                            renderer.color_view(),
                            wgpu::FilterMode::Linear,
                        ));
                    }
                    Some(id) if resized => {
                        egui_renderer.update_egui_texture_from_wgpu_texture(
                            &state.device,
                            renderer.color_view(),
                            wgpu::FilterMode::Linear,
                            id,
                        );
                    }
                    Some(_) => {}
                }
                if let Some(id) = self.texture {
                    let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
                    ui.painter().image(id, rect, uv, egui::Color32::WHITE);
                }
            }
            _ => {
                ui.painter().text(
                    rect.center(),
                    egui::Align2::CENTER_CENTER,
                    "no GPU renderer",
                    egui::FontId::default(),
                    egui::Color32::GRAY,
                );
            }
        }
        ui.painter().text(
            rect.left_bottom() + egui::vec2(8.0, -8.0),
            egui::Align2::LEFT_BOTTOM,
            if self.over_time_estimate().is_some() {
                "arrows, 2 cm/N: red the push, green this frame's best, blue over time"
            } else {
                "arrows, 2 cm/N: red the push, green the most probable contact"
            },
            egui::FontId::default(),
            egui::Color32::LIGHT_GRAY,
        );
        if !self.status.is_empty() {
            ui.painter().text(
                rect.left_top() + egui::vec2(8.0, 8.0),
                egui::Align2::LEFT_TOP,
                &self.status,
                egui::FontId::default(),
                egui::Color32::LIGHT_GRAY,
            );
        }
    }

    /// What the candidate under the pointer would explain: its force and
    /// the torques it produces beside the measured ones.
    fn candidate_tooltip(&self, pos: egui::Pos2, rect: egui::Rect) -> Option<String> {
        let outcome = self.current_outcome()?;
        let update = outcome.update.as_ref().ok()?;
        let surface = &outcome.estimator.surface;
        let size = Vec2::new(rect.width(), rect.height());
        let local = pos - rect.min;
        let (origin, dir) = self.camera.ray(Vec2::new(local.x, local.y), size);
        let hit = self.picker.pick(&update.pose, origin.as_dvec3(), dir.as_dvec3(), &[])?;
        let k = (0..surface.len())
            .filter(|&k| surface.link[k] == hit.link)
            .min_by(|&a, &b| {
                surface.point_in_link[a]
                    .distance_squared(hit.point_in_link)
                    .total_cmp(&surface.point_in_link[b].distance_squared(hit.point_in_link))
            })?;
        let contact = crate::core::summary::contact_at(&update.posterior, surface, &update.pose, k);
        let produced = joint_torques(
            &self.model.robot,
            &update.pose,
            contact.link,
            contact.point_world,
            contact.force_world,
        );
        let measured = self.model.measured_torques(&update.pose);
        let mut text = format!(
            "{}: P = {:.2e}, best push {:.1} N\njoint   produces   measured",
            self.model.robot.links[contact.link].name, contact.probability, contact.force_newtons
        );
        for (i, (p, m)) in produced.iter().zip(&measured).enumerate() {
            let _ = write!(text, "\n{:>5}   {:>8.3}   {:>8.3}", i + 1, p, m);
        }
        Some(text)
    }

    /// Scale, threshold, colour map and candidate points.
    fn view_options_ui(&self, ui: &mut egui::Ui) -> Vec<Command> {
        let mut view = self.model.view;
        ui.separator();
        ui.label("Heatmap");
        ui.horizontal(|ui| {
            ui.radio_value(&mut view.log_scale, true, "log");
            ui.radio_value(&mut view.log_scale, false, "linear");
            ui.separator();
            ui.radio_value(&mut view.red_green, false, "viridis");
            ui.radio_value(&mut view.red_green, true, "red-green");
        });
        ui.label(if view.log_scale {
            "yellow: the most probable; purple: e^-20 of it and less"
        } else {
            "yellow: the most probable; purple: zero"
        });
        ui.add(egui::Slider::new(&mut view.threshold, 0.0..=0.99).text("hide below"));
        ui.checkbox(
            &mut view.show_points,
            "candidate points (A red, B orange, 90 % set white)",
        );
        ui.checkbox(
            &mut view.show_axes,
            "joint axes (hover a torque bar: its axis and lever arm)",
        );
        if view == self.model.view {
            Vec::new()
        } else {
            vec![Command::SetView(view)]
        }
    }

    fn torques_ui(&mut self, ui: &mut egui::Ui) {
        use egui_plot::{Bar, BarChart, Legend, Plot};
        // In a session the push shown is the recorded true contact.
        let applied_name = if self.model.replay.is_some() {
            "true contact"
        } else {
            "applied"
        };
        let positions = self.model.joint_positions();
        let pose = RobotPose::new(&self.model.robot, &positions);
        let applied = self.model.applied_torques(&pose);
        let measured = self.model.measured_torques(&pose);
        let explained: Option<Vec<f64>> = self.current_outcome().and_then(|o| o.update.as_ref().ok()).map(|u| {
            let m = u.summary.map;
            joint_torques(&self.model.robot, &pose, m.link, m.point_world, m.force_world)
        });
        let path = self
            .model
            .push
            .map(|p| self.model.robot.path_joints(p.link))
            .unwrap_or_default();
        let bars = |values: &[f64], offset: f64, colour: egui::Color32| -> Vec<Bar> {
            values
                .iter()
                .enumerate()
                .map(|(i, v)| {
                    let senses = self.model.robot.sensed().get(i).is_some_and(|j| path.contains(j));
                    Bar::new(i as f64 + 1.0 + offset, *v).width(0.25).fill(if senses {
                        colour
                    } else {
                        colour.gamma_multiply(0.3)
                    })
                })
                .collect()
        };
        let hovered = Plot::new("torques")
            .legend(Legend::default())
            .height(ui.available_height().max(120.0))
            .show(ui, |plot| {
                let series = [
                    (
                        applied_name,
                        Some(&applied),
                        -0.27,
                        egui::Color32::from_rgb(90, 140, 230),
                    ),
                    ("measured", Some(&measured), 0.0, egui::Color32::from_rgb(230, 160, 60)),
                    (
                        "explained by the estimate",
                        explained.as_ref(),
                        0.27,
                        egui::Color32::from_rgb(110, 200, 120),
                    ),
                ];
                for (name, values, offset, colour) in series {
                    if let Some(values) = values {
                        plot.bar_chart(BarChart::new(name, bars(values, offset, colour)).color(colour));
                    }
                }
                plot.pointer_coordinate().map(|p| p.x.round() as i64 - 1)
            })
            .inner;
        self.hovered_joint = hovered
            .and_then(|j| usize::try_from(j).ok())
            .filter(|&j| j < applied.len());
    }

    /// The sensed joints' axes (all with the toggle; the hovered one in
    /// yellow with its lever arm to the push).
    fn joint_axes(&self, pose: &RobotPose, lines: &mut Vec<crate::render::renderer::LineVertex>) {
        let view = self.model.view;
        let cyan = [0.3, 0.9, 1.0, 1.0];
        for (i, &j) in self.model.robot.sensed().iter().enumerate() {
            let hovered = self.hovered_joint == Some(i);
            if !(view.show_axes || hovered) {
                continue;
            }
            let o = pose.joint_origin_world(j);
            let a = pose.joint_axis_world(&self.model.robot, j);
            let colour = if hovered { [1.0, 1.0, 0.2, 1.0] } else { cyan };
            crate::render::scene::line(lines, (o - a * 0.2).as_vec3(), (o + a * 0.2).as_vec3(), colour);
            if hovered && let Some((_, point, _)) = self.model.push_world(pose) {
                // The lever: from the axis to the contact, at right angles to the axis.
                let foot = o + a * a.dot(point - o);
                crate::render::scene::line(lines, foot.as_vec3(), point.as_vec3(), [1.0, 1.0, 0.2, 1.0]);
            }
        }
    }

    /// The posed robot with its heatmap, the push and the estimate.
    fn scene_frame(&self) -> Frame {
        let positions = self.model.joint_positions();
        let pose = RobotPose::new(&self.model.robot, &positions);
        let mut frame = Frame::default();
        let heat = self
            .current_outcome()
            .and_then(|o| o.update.as_ref().ok().map(|u| (o, u)));
        let top = heat.map_or(f64::NEG_INFINITY, |(_, u)| {
            u.posterior
                .log_likelihood
                .iter()
                .copied()
                .fold(f64::NEG_INFINITY, f64::max)
        });
        let view = self.model.view;
        let display_top = heat.map_or(0.0, |(_, u)| u.posterior.display.iter().copied().fold(0.0, f64::max));
        // Log scale: the best point is 1, e^-HEAT_DEPTH of it and less 0;
        // linear: the display value over the largest.
        let scale = |u: &crate::core::pipeline::Update, k: usize| -> f64 {
            if view.log_scale {
                (1.0 + (u.posterior.log_likelihood[k] - top) / HEAT_DEPTH).clamp(0.0, 1.0)
            } else if display_top > 0.0 {
                u.posterior.display[k] / display_top
            } else {
                0.0
            }
        };
        let paint = |t: f64| {
            if view.red_green {
                red_green(t as f32)
            } else {
                viridis(t as f32)
            }
        };
        let color = |link: LinkId, vertex: usize| -> [f32; 4] {
            let Some((o, u)) = heat else { return ROBOT_GREY };
            match o.nearest.get(link).and_then(|v| v.get(vertex)) {
                Some(weights) if !weights.is_empty() && top.is_finite() => {
                    let t: f64 = weights.iter().map(|&(k, w)| w * scale(u, k)).sum();
                    if t < view.threshold { ROBOT_GREY } else { paint(t) }
                }
                _ => ROBOT_GREY,
            }
        };
        robot_triangles(&self.model.robot, &pose, &color, &mut frame.triangles);
        grid_and_axes(1.0, 0.1, &mut frame.lines);
        if let Some((_, point, force)) = self.model.push_world(&pose) {
            arrow(
                &mut frame.lines,
                point,
                force,
                0.02 * force.length().max(1.0),
                [1.0, 0.35, 0.25, 1.0],
            );
        }
        self.joint_axes(&pose, &mut frame.lines);
        if let (true, Some((o, u))) = (view.show_points, heat) {
            let surface = &o.estimator.surface;
            let in_set: std::collections::HashSet<usize> = u.summary.credible90.points.iter().copied().collect();
            for k in 0..surface.len() {
                let flags = u.posterior.phase_flags[k];
                let colour = if in_set.contains(&k) {
                    [1.0, 1.0, 1.0, 1.0]
                } else if flags & crate::core::estimator::phase_flag::A != 0 {
                    [0.95, 0.2, 0.2, 1.0]
                } else if flags & crate::core::estimator::phase_flag::B != 0 {
                    [1.0, 0.6, 0.1, 1.0]
                } else {
                    paint(scale(u, k))
                };
                let world_from_link = pose.world_from_link[surface.link[k]];
                let p = world_from_link.transform_point3(surface.point_in_link[k]);
                let n = world_from_link.transform_vector3(surface.inward_normal_in_link[k]);
                // A short hair standing out of the surface at each candidate.
                crate::render::scene::line(&mut frame.lines, p.as_vec3(), (p - n * 0.012).as_vec3(), colour);
            }
        }
        self.estimate_arrows(heat.map(|(_, u)| u), &mut frame.lines);
        frame
    }

    /// The frame's most probable contact (green) and, over time, the
    /// frames' together (blue).
    fn estimate_arrows(
        &self,
        update: Option<&crate::core::pipeline::Update>,
        lines: &mut Vec<crate::render::renderer::LineVertex>,
    ) {
        if let Some(u) = update {
            let m = u.summary.map;
            arrow(
                lines,
                m.point_world,
                m.force_world,
                0.02 * m.force_newtons.max(1.0),
                [0.3, 1.0, 0.5, 1.0],
            );
        }
        if let Some(e) = self.over_time_estimate()
            && e.verdict != Verdict::NoContact
        {
            arrow(
                lines,
                e.point_world,
                e.force_world,
                0.02 * e.force_world.length().max(1.0),
                [0.35, 0.6, 1.0, 1.0],
            );
        }
    }

    /// The session frame's estimate from the frames together (filtered or
    /// smoothed), once the background has it.
    pub(super) fn over_time_estimate(&self) -> Option<session::FrameEstimate> {
        let replay = self.model.replay.as_ref()?;
        if replay.over_time == Temporal::None {
            return None;
        }
        self.session_estimates.get(replay.frame).copied().flatten()
    }

    fn view_ui(&mut self, ui: &mut egui::Ui, frame: &eframe::Frame) -> Vec<Command> {
        let mut commands = Vec::new();
        let rect = ui.available_rect_before_wrap();
        self.view_rect = Some(rect);
        let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
        let size = Vec2::new(rect.width(), rect.height());
        if response.dragged_by(egui::PointerButton::Primary) {
            let d = response.drag_delta();
            self.camera.orbit(Vec2::new(d.x, d.y));
        }
        if response.dragged_by(egui::PointerButton::Secondary) || response.dragged_by(egui::PointerButton::Middle) {
            let d = response.drag_delta();
            self.camera.pan(Vec2::new(d.x, d.y), size);
        }
        if let Some(hover) = response.hover_pos() {
            let scroll = ui.input(|i| i.smooth_scroll_delta.y);
            if scroll != 0.0 {
                let local = hover - rect.min;
                self.camera
                    .zoom_towards((-scroll * 0.002).exp(), Vec2::new(local.x, local.y), size);
            }
        }
        if ui.input(|i| i.key_pressed(egui::Key::R)) {
            self.camera = OrbitCamera::default();
        }
        let pick_at = |pos: egui::Pos2, camera: &OrbitCamera| {
            let local = pos - rect.min;
            let (origin, dir) = camera.ray(Vec2::new(local.x, local.y), size);
            let positions = self.model.joint_positions();
            let pose = RobotPose::new(&self.model.robot, &positions);
            self.picker
                .pick(&pose, origin.as_dvec3(), dir.as_dvec3(), &[])
                .map(|hit| (hit, pose))
        };
        if let Some(pos) = response.hover_pos()
            && !response.dragged()
            && let Some(text) = self.candidate_tooltip(pos, rect)
        {
            response.clone().on_hover_text(text);
        }
        if response.double_clicked() {
            if let Some((hit, _)) = response.interact_pointer_pos().and_then(|p| pick_at(p, &self.camera)) {
                self.camera.centre_on(hit.point_world.as_vec3());
            }
        } else if response.clicked()
            && let Some((hit, pose)) = response.interact_pointer_pos().and_then(|p| pick_at(p, &self.camera))
        {
            let force = self.model.push.map_or(15.0, |p| p.force_newtons);
            commands.push(Command::Push(Push {
                link: hit.link,
                point_in_link: hit.point_in_link,
                inward_normal_in_link: pose.world_from_link[hit.link]
                    .inverse()
                    .transform_vector3(hit.inward_normal_world),
                force_newtons: force,
            }));
        }
        self.paint_view(ui, frame, rect);
        commands
    }
}

impl eframe::App for ProprioscopeApp {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        // An estimate of another robot (still in flight when the robot
        // changed) is dropped: its links are not this robot's.
        if let Some(outcome) = self
            .worker
            .latest()
            .filter(|o| Arc::ptr_eq(&o.robot, &self.model.robot))
        {
            if self.model.replay.is_some()
                && let Some((_, inputs)) = self.pending.take_if(|(g, _)| *g == outcome.generation)
            {
                if self.visited.len() >= VISITED_FRAMES {
                    self.visited.pop_front();
                }
                self.visited.push_back((inputs, outcome.clone()));
            }
            // Never replace a newer estimate (one shown from the visited frames).
            if self.outcome.as_ref().is_none_or(|o| o.generation < outcome.generation) {
                self.outcome = Some(outcome);
            }
        }
        self.status = if let Some(opening) = &self.opening {
            format!("opening {}…", opening.what)
        } else if self.is_up_to_date() {
            String::new()
        } else {
            "estimating…".to_owned()
        };
        self.poll_loader();
        self.poll_live();
        self.poll_opening();
        self.update_session_estimates();
        let mut commands = self.playback_keys(ui.ctx());
        egui::Panel::top("menu").show(ui, |ui| self.menu_ui(ui));
        // Below the menu and across the whole width: a session's timeline.
        if self.model.replay.is_some() || self.live.is_some() {
            egui::Panel::bottom("timeline")
                .resizable(true)
                .min_size(260.0)
                .default_size(300.0)
                .show(ui, |ui| {
                    self.live_ui(ui);
                    commands.extend(self.timeline_ui(ui));
                });
        }
        egui::Panel::left("robot").show(ui, |ui| commands.extend(self.robot_panel_ui(ui)));
        egui::Panel::right("estimator").show(ui, |ui| {
            egui::ScrollArea::vertical().show(ui, |ui| {
                commands.extend(self.estimator_panel_ui(ui));
                self.session_summary_ui(ui);
            });
        });
        egui::Panel::bottom("torques").resizable(true).show(ui, |ui| {
            ui.label(if self.model.replay.is_some() {
                "Joint torques [N·m]: of the true contact, measured (the frame's), explained by the estimate (faded: the joint cannot sense the contact)"
            } else {
                "Joint torques [N·m]: applied, measured, explained by the estimate (faded: the joint cannot sense the push)"
            });
            self.torques_ui(ui);
        });
        egui::CentralPanel::default().show(ui, |ui| commands.extend(self.view_ui(ui, frame)));
        self.topic_prompt_ui(&ui.ctx().clone());
        for command in commands {
            self.apply(command);
        }
        let ctx = ui.ctx().clone();
        self.record_tick(&ctx);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn model() -> Model {
        let robot = crate::core::builtin::lwr4plus_generated().unwrap();
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
