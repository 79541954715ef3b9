//! Whole sessions, headless: their robot, loading them in the background,
//! estimating every frame (alone or over time) off the caller's thread,
//! and their metrics. Shared by the command line and the app; no egui, so
//! that the CLI builds without the GUI stack (`--no-default-features`).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

pub mod calibration;
mod estimate;
mod latest;
mod live;
pub mod pairs;

pub use estimate::{EVERY_FRAME, EstimateJob, Estimated, SECOND_CONTACTS_DONE, SessionWorker};
pub use latest::{Background, Latest, Serving};
pub use live::{LiveFilterWorker, LiveJob};

use anyhow::{Context as _, Result, bail};
use glam::DVec3;

use crate::core::estimate::estimator::Update;
use crate::core::estimate::summary::Verdict;
use crate::core::eval::metrics::{FrameOutcome, Metrics, metrics, metrics_by_sensing_joints};
use crate::core::robot::model::{LinkId, Robot};
use crate::io::builtin::load_robot;
use crate::io::open::OpenError;
use crate::io::recording::{RecordingError, TopicChoice};
use crate::io::session::{Frame, FrameProblem, Session, Truth};
use crate::io::urdf::{MeshSelection, UrdfOptions};

/// The robot of a session: `robot` when given (a built-in name or a URDF
/// path), else the one the session names (relative to its file). Only the
/// meshes of `links` are loaded when some are named; the session's joint
/// names pick the sensed joints.
pub fn session_robot(
    session: &Session,
    robot: Option<&str>,
    package_paths: &[PathBuf],
    links: &[String],
) -> Result<Robot> {
    let (spec, base) = match (robot, &session.robot) {
        (Some(r), _) => (r.to_owned(), PathBuf::from(".")),
        (None, Some(r)) => (r.clone(), session.path.parent().unwrap_or(Path::new(".")).to_owned()),
        (None, None) => bail!(
            "{}: the session names no robot (a CSV session or a recording): give one with --robot",
            session.path.display()
        ),
    };
    let meshes = if links.is_empty() {
        MeshSelection::All
    } else {
        MeshSelection::Links(links.to_vec())
    };
    let options = UrdfOptions {
        package_paths: package_paths.to_vec(),
        meshes,
    };
    let mut robot = load_robot(&spec, &base, &options)?;
    if let Some(joints) = &session.joints {
        robot
            .set_sensed(joints)
            .with_context(|| format!("{}: field 'joints'", session.path.display()))?;
    }
    Ok(robot)
}

/// Whether `update`'s 90 % credible set holds a frame's true contact: the
/// sample whose patch holds it, the nearest of its link's samples on
/// `surface` (`None` without a known contact on a sampled link).
#[must_use]
pub fn credible_set_holds_truth(
    robot: &Robot,
    surface: &crate::core::surface::sampling::Surface,
    update: &crate::core::estimate::estimator::Update,
    truth: &Truth,
) -> Option<bool> {
    let (link, point_in_link) = truth_in_link(robot, &update.pose, truth)?;
    let owner = surface.owner(link, point_in_link)?;
    Some(update.summary.credible90.points.contains(&owner))
}

/// A frame's true contact as its link and its place in that link's frame
/// at `pose` (`None` without a known contact on one of the robot's links).
#[must_use]
pub fn truth_in_link(
    robot: &Robot,
    pose: &crate::core::robot::kinematics::RobotPose,
    truth: &Truth,
) -> Option<(LinkId, DVec3)> {
    let Truth::Contact { link, point, .. } = truth else {
        return None;
    };
    let link = robot.link_id(link).ok()?;
    let link_from_world = pose.world_from_link.get(link)?.inverse();
    Some((link, link_from_world.transform_point3(DVec3::from_array(*point))))
}

/// The errors of an estimate against a frame's truth (`None` without a
/// known contact).
#[must_use]
pub fn frame_outcome(robot: &Robot, estimate: &FrameEstimate, truth: &Truth) -> Option<FrameOutcome> {
    let Truth::Contact { link, point, force } = truth else {
        return None;
    };
    let sensing_joints = robot.link_id(link).map_or(0, |l| robot.sensing_joints(l));
    Some(FrameOutcome {
        sensing_joints,
        p_max: estimate.p_max,
        estimated_point: estimate.point_world,
        estimated_force: estimate.force_world,
        true_point: DVec3::from_array(*point),
        true_force: DVec3::from_array(*force),
        link_correct: robot.links.get(estimate.link).is_some_and(|l| l.name == *link),
        in_credible90: estimate.truth_in_credible90,
    })
}

/// What the timeline keeps of one frame's estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameEstimate {
    /// The reading.
    pub verdict: Verdict,
    /// Link of the most probable contact.
    pub link: LinkId,
    /// Its point, world frame, m.
    pub point_world: DVec3,
    /// Its force, world frame, N.
    pub force_world: DVec3,
    /// The force's part along the surface (friction), world frame, N.
    pub tangential_world: DVec3,
    /// Its posterior mass.
    pub probability: f64,
    /// Its heatmap value (the best particle's share in particle mode).
    pub p_max: f64,
    /// Time the update took, ms.
    pub update_ms: f64,
    /// The chance of a contact from the frames estimated together (none
    /// for a frame alone).
    pub contact_probability: Option<f64>,
    /// Whether the 90 % credible set holds the frame's true contact (see
    /// [`credible_set_holds_truth`]; `None` without a known contact).
    pub truth_in_credible90: Option<bool>,
    /// The 90 % credible set's radius, m.
    pub credible90_radius_m: f64,
    /// With two contacts looked for over time, the frame's account of a
    /// second one (`None` where none was searched: no contact, or one
    /// that explains the torques).
    pub second: Option<pairs::PairSeen>,
}

impl FrameEstimate {
    /// The compact form of an update.
    #[must_use]
    pub fn of(update: &Update, update_ms: f64) -> Self {
        let map = &update.summary.map;
        Self {
            verdict: update.summary.verdict,
            link: map.link,
            point_world: map.point_world,
            force_world: map.force_world,
            tangential_world: map.tangential_world(),
            probability: map.probability,
            p_max: update.posterior.display.get(map.point).copied().unwrap_or(0.0),
            update_ms,
            contact_probability: update.summary.contact_probability,
            truth_in_credible90: None,
            credible90_radius_m: update.summary.credible90.radius_m,
            second: None,
        }
    }

    /// [`FrameEstimate::of`], with whether the 90 % credible set holds the
    /// frame's `truth` (its samples on `surface`).
    #[must_use]
    pub fn of_frame(
        robot: &Robot,
        surface: &crate::core::surface::sampling::Surface,
        update: &Update,
        update_ms: f64,
        truth: &Truth,
    ) -> Self {
        Self {
            truth_in_credible90: credible_set_holds_truth(robot, surface, update, truth),
            ..Self::of(update, update_ms)
        }
    }
}

/// A session opened in the app: its good frames, and the bad ones skipped.
#[derive(Debug, Clone)]
pub struct SessionData {
    /// The file.
    pub path: PathBuf,
    /// The frames that passed the checks, in file order.
    pub frames: Vec<Frame>,
    /// For each kept frame, its number in the file.
    pub file_frames: Vec<usize>,
    /// The frames skipped, with what is wrong with each.
    pub problems: Vec<FrameProblem>,
}

impl SessionData {
    /// The kept frame shown at session time `t` (the last at or before it).
    #[must_use]
    pub fn frame_at(&self, t: f64) -> usize {
        self.frames.partition_point(|f| f.t <= t).saturating_sub(1)
    }

    /// The kept frame nearest to session time `t`.
    #[must_use]
    pub fn nearest_frame(&self, t: f64) -> usize {
        let after = self.frames.partition_point(|f| f.t < t);
        match (after.checked_sub(1), self.frames.get(after)) {
            (Some(before), Some(next)) => {
                let before_t = self.frames.get(before).map_or(f64::NEG_INFINITY, |f| f.t);
                if t - before_t <= next.t - t { before } else { after }
            }
            (Some(before), None) => before,
            (None, _) => 0,
        }
    }
}

/// A loaded session, its robot, and how that robot is named (a built-in
/// name or a URDF path usable from the working directory).
pub type Loaded = (SessionData, Robot, String);

/// Bytes of a JSON session read first for [`load_session`]'s preview
/// (about 2,500 frames of 7 joints: the first seconds of a 1 kHz
/// recording, read in milliseconds).
pub const PREVIEW_BYTES: usize = 1 << 20;

/// Bytes of a robot recording read first for the preview: more than a
/// JSON session's, since an MCAP's or a bag's messages come in chunks (a
/// chunk cut by the end is left out) beside other topics.
pub const PREVIEW_RECORDING_BYTES: usize = 8 << 20;

/// Reads a session, skipping its bad frames, with its robot (`robot`
/// overrides the session's; a CSV session needs one). A JSON session
/// longer than [`PREVIEW_BYTES`], or a recording longer than
/// [`PREVIEW_RECORDING_BYTES`], first gives `preview` its first frames
/// with the robot, to be shown while the rest is read.
pub fn load_session(
    path: &Path,
    robot: Option<&str>,
    package_paths: &[PathBuf],
    choice: &TopicChoice,
    progress: &dyn Fn(f64),
    preview: &dyn Fn(Loaded),
) -> Result<Loaded> {
    // The robot the preview loaded, for the same header.
    let mut early: Option<(Option<String>, Option<Vec<String>>, Robot)> = None;
    let preview_bytes = if crate::io::recording::is_recording(path) {
        PREVIEW_RECORDING_BYTES
    } else {
        PREVIEW_BYTES
    };
    if let Some((start, problems)) = Session::open_start(path, choice, preview_bytes) {
        let header = (start.robot.clone(), start.joints.clone());
        if let Ok(loaded) = with_robot(path, start, problems, robot, package_paths, None) {
            early = Some((header.0, header.1, loaded.1.clone()));
            preview(loaded);
        }
    }
    // The file is most of the work; the robot the last step. A choice
    // remembered from another recording that does not fit this one gives
    // way to what this file implies.
    let report = |f| progress(0.9 * f);
    let opened = match Session::open(path, choice, &report) {
        Err(OpenError::Recording(RecordingError::Choice { .. })) if *choice != TopicChoice::default() => {
            Session::open(path, &TopicChoice::default(), &report)
        }
        other => other,
    };
    let (session, problems) = opened?;
    let known = early.and_then(|(r, joints, robot)| (r == session.robot && joints == session.joints).then_some(robot));
    with_robot(path, session, problems, robot, package_paths, known)
}

/// A session read, with its robot (`known` when already loaded).
fn with_robot(
    path: &Path,
    session: Session,
    problems: Vec<FrameProblem>,
    robot: Option<&str>,
    package_paths: &[PathBuf],
    known: Option<Robot>,
) -> Result<Loaded> {
    let spec = match (robot, &session.robot) {
        (Some(r), _) => r.to_owned(),
        (None, Some(r)) if crate::io::builtin::is_builtin(r) => r.clone(),
        (None, Some(r)) => path.parent().unwrap_or(Path::new(".")).join(r).display().to_string(),
        (None, None) => String::new(),
    };
    let robot = match known {
        Some(known) => known,
        None => session_robot(&session, robot, package_paths, &[])?,
    };
    let joints = robot.sensed().len();
    if let Some(frame) = session.frames.first()
        && frame.q.len() != joints
    {
        bail!(
            "{}: frames have {} joint values but {} has {joints} sensed joints",
            path.display(),
            frame.q.len(),
            robot.name
        );
    }
    let file_frames = crate::io::session::kept_frame_numbers(session.frames.len(), &problems);
    Ok((
        SessionData {
            path: path.to_owned(),
            frames: session.frames,
            file_frames,
            problems,
        },
        robot,
        spec,
    ))
}

/// A recording whose topics the user must choose (the file leaves
/// several choices, or none that works by itself).
#[derive(Debug, Clone, PartialEq)]
pub struct TopicPrompt {
    /// The recording.
    pub path: PathBuf,
    /// The robot it is to be opened with.
    pub robot: Option<String>,
    /// Why the file's own choice did not do.
    pub message: String,
    /// Topics with joint names and positions.
    pub position_topics: Vec<String>,
    /// Every non-empty float array: topic and field.
    pub torque_sources: Vec<(String, String)>,
    /// The choice being made.
    pub choice: TopicChoice,
}

impl TopicPrompt {
    /// The prompt for a recording, when `error` is about its topics.
    fn for_error(path: &Path, robot: Option<String>, error: &anyhow::Error) -> Option<Self> {
        let Some(OpenError::Recording(choice_error @ RecordingError::Choice { .. })) =
            error.downcast_ref::<OpenError>()
        else {
            return None;
        };
        let bytes = crate::io::recording::read_bytes(path).ok()?;
        let index = crate::io::recording::index(path, &bytes).ok()?;
        let position_topics: Vec<String> = index.position_topics().into_iter().map(str::to_owned).collect();
        // The likely torque arrays first (named external, then effort or
        // torque), then every other float array.
        let mut likely = index.torque_candidates();
        likely.sort_by_key(|c| std::cmp::Reverse(c.2));
        let mut torque_sources: Vec<(String, String)> = likely.into_iter().map(|(t, f, _)| (t, f)).collect();
        for topic in &index.topics {
            for (field, _) in topic.float_arrays() {
                let source = (topic.topic.clone(), field);
                if !torque_sources.contains(&source) {
                    torque_sources.push(source);
                }
            }
        }
        let choice = TopicChoice {
            q_topic: position_topics.first().cloned(),
            tau_topic: torque_sources.first().map(|(t, _)| t.clone()),
            tau_field: torque_sources.first().map(|(_, f)| f.clone()),
        };
        Some(Self {
            path: path.to_owned(),
            robot,
            message: choice_error.to_string(),
            position_topics,
            torque_sources,
            choice,
        })
    }
}

/// Why a session was not loaded.
#[derive(Debug, Clone, PartialEq)]
pub enum LoadFailure {
    /// It cannot be: why.
    Failed(String),
    /// A recording needs its topics chosen.
    NeedsTopics(Box<TopicPrompt>),
}

/// Loads a session on a thread of its own ([`Background`]: a panic while
/// reading is an error shown, not a load that never ends).
pub struct Loader {
    job: Background<Loaded, LoadFailure>,
    /// What is being loaded.
    pub path: PathBuf,
    /// When it started.
    pub started: Instant,
    /// How far it is, 0 to 1 (an `f64`'s bits).
    progress: Arc<std::sync::atomic::AtomicU64>,
    /// The file's first frames, until taken.
    preview: Arc<std::sync::Mutex<Option<Loaded>>>,
}

impl From<String> for LoadFailure {
    fn from(message: String) -> Self {
        Self::Failed(message)
    }
}

impl Loader {
    /// Starts loading; `wake` is called when done.
    pub fn spawn(
        path: PathBuf,
        robot: Option<String>,
        package_paths: Vec<PathBuf>,
        choice: TopicChoice,
        wake: impl Fn() + Send + Sync + 'static,
    ) -> Self {
        let thread_path = path.clone();
        let progress = Arc::new(std::sync::atomic::AtomicU64::new(0));
        let shared = progress.clone();
        let preview = Arc::new(std::sync::Mutex::new(None));
        let preview_slot = preview.clone();
        let wake = Arc::new(wake);
        let wake_preview = wake.clone();
        let job = Background::spawn(
            path.display().to_string(),
            move || {
                let report = |f: f64| shared.store(f.to_bits(), std::sync::atomic::Ordering::Relaxed);
                let show = |loaded: Loaded| {
                    if let Ok(mut slot) = preview_slot.lock() {
                        *slot = Some(loaded);
                    }
                    wake_preview();
                };
                load_session(&thread_path, robot.as_deref(), &package_paths, &choice, &report, &show).map_err(|e| {
                    match TopicPrompt::for_error(&thread_path, robot.clone(), &e) {
                        Some(prompt) => LoadFailure::NeedsTopics(Box::new(prompt)),
                        None => LoadFailure::Failed(format!("{e:#}")),
                    }
                })
            },
            move || wake(),
        );
        Self {
            job,
            path,
            started: Instant::now(),
            progress,
            preview,
        }
    }

    /// The file's first frames with the robot, once read and until taken
    /// (a long session's or recording's: see [`load_session`]).
    #[must_use]
    pub fn take_preview(&self) -> Option<Loaded> {
        self.preview.lock().ok()?.take()
    }

    /// How far loading is, 0 to 1.
    #[must_use]
    pub fn progress(&self) -> f64 {
        f64::from_bits(self.progress.load(std::sync::atomic::Ordering::Relaxed))
    }

    /// The result, once there.
    #[must_use]
    pub fn poll(&self) -> Option<Result<Loaded, LoadFailure>> {
        self.job.poll()
    }
}

/// The metrics of the frames with a known contact and an estimate: over
/// all of them, then by the number of joints that sense the touched link.
#[must_use]
pub fn session_metrics(
    robot: &Robot,
    session: &SessionData,
    estimates: &[Option<FrameEstimate>],
) -> Option<(Metrics, Vec<(usize, Metrics)>)> {
    let outcomes: Vec<FrameOutcome> = session
        .frames
        .iter()
        .zip(estimates)
        .filter_map(|(f, e)| frame_outcome(robot, e.as_ref()?, &f.truth))
        .collect();
    if outcomes.is_empty() {
        return None;
    }
    Some((metrics(&outcomes), metrics_by_sensing_joints(&outcomes)))
}

/// Metrics as JSON, for export.
#[must_use]
pub fn metrics_json(all: &Metrics, by_joints: &[(usize, Metrics)]) -> serde_json::Value {
    let one = |m: &Metrics| {
        serde_json::json!({
            "frames": m.frames,
            "position_error_median_m": m.position_median_m,
            "position_error_p90_m": m.position_p90_m,
            "force_error_median_newtons": m.force_median_newtons,
            "force_error_p90_newtons": m.force_p90_newtons,
            "link_accuracy": m.link_accuracy,
            "eps_r_m": m.eps_r_m,
            "eps_f_newtons": m.eps_f_newtons,
            "sigma_r_m": m.sigma_r_m,
            "credible90_held": m.credible90_held,
        })
    };
    serde_json::json!({
        "all": one(all),
        "by_sensing_joints": by_joints
            .iter()
            .map(|(k, m)| {
                let mut v = one(m);
                v["sensing_joints"] = serde_json::json!(k);
                v
            })
            .collect::<Vec<_>>(),
    })
}

/// At most `max` of `points`, evenly strided (plots of long sessions).
#[must_use]
pub fn thin(points: Vec<[f64; 2]>, max: usize) -> Vec<[f64; 2]> {
    let stride = points.len().div_ceil(max.max(1)).max(1);
    if stride == 1 {
        return points;
    }
    points.into_iter().step_by(stride).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn data(times: &[f64]) -> SessionData {
        SessionData {
            path: PathBuf::from("s.json"),
            frames: times
                .iter()
                .map(|&t| Frame {
                    t,
                    q: vec![],
                    tau: vec![],
                    truth: Truth::Unknown,
                    truth_all: Vec::new(),
                })
                .collect(),
            file_frames: (0..times.len()).collect(),
            problems: Vec::new(),
        }
    }

    #[test]
    fn frames_are_found_by_time() {
        let d = data(&[0.0, 0.1, 0.1, 0.5, 1.0]);
        assert_eq!(d.frame_at(-1.0), 0);
        assert_eq!(d.frame_at(0.05), 0);
        assert_eq!(d.frame_at(0.1), 2);
        assert_eq!(d.frame_at(0.7), 3);
        assert_eq!(d.frame_at(5.0), 4);
        assert_eq!(d.nearest_frame(0.2), 2);
        assert_eq!(d.nearest_frame(0.4), 3);
        assert_eq!(d.nearest_frame(9.0), 4);
        assert_eq!(d.nearest_frame(-9.0), 0);
    }

    #[test]
    fn thinning_keeps_at_most_the_asked_number() {
        let points: Vec<[f64; 2]> = (0..10_001).map(|i| [f64::from(i), 0.0]).collect();
        let thinned = thin(points, 1000);
        assert!(thinned.len() <= 1000 && thinned.len() > 900, "{}", thinned.len());
        assert_eq!(thinned.first(), Some(&[0.0, 0.0]));
    }
}
