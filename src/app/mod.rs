//! The desktop app (eframe/egui): a 3-D view of the robot, joint sliders,
//! click to push, the torques it causes and the live posterior heatmap.
//! The only place where egui, `render` and `io` meet.

pub mod bias;
pub mod calibration;
mod commands;
mod estimator_panel;
pub mod files;
mod foxglove;
pub mod heat;
mod inspect;
pub mod live;
pub mod mcap_preview;
mod menus;
mod model;
pub mod overlay;
mod plots;
pub mod recorder;
mod robot_panel;
mod session_panel;
mod start;
pub mod timeline;
mod topic_prompt;
mod torques;
mod view;
pub mod worker;

pub use commands::Command;
pub use model::*;
pub use start::*;
pub use view::robot_bounds;

use std::sync::Arc;

use eframe::egui;
use glam::{DVec3, Vec2};

use crate::core::config::estimator::{EstimatorConfig, Friction, ModeKind, Sigma};
use crate::core::estimate::settings::EstimatorSettings;
use crate::core::estimate::summary::Verdict;
use crate::core::over_time::sequence::Temporal;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{LinkId, Robot};
use crate::core::robot::torque::{joint_torques, with_sensor_noise};
use crate::core::surface::picking::Picker;
use crate::render::camera::OrbitCamera;
use crate::render::renderer::{Frame, Renderer};
use crate::render::scene::{ROBOT_GREY, grid_and_axes, robot_triangles};
use heat::{Heat, HeatLayer, Legend};
use overlay::{Marker, MarkerRole};
use worker::{Outcome, Request, Worker};

/// Newtons per point of drag when dragging a push (240 points: 30 N).
const PUSH_NEWTONS_PER_POINT: f64 = 0.125;

/// The push magnitude the observability map assumes when none is applied, N.
const OBSERVABILITY_PUSH_NEWTONS: f64 = 10.0;

/// One σ per joint from a list of one (for every joint) or one per joint.
fn per_joint(sigma: &[f64], joints: usize) -> Vec<f64> {
    if sigma.len() == joints {
        sigma.to_vec()
    } else {
        vec![sigma.first().copied().unwrap_or(0.1); joints]
    }
}

/// Points and particles evaluated, per phase when there are phases.
pub(crate) fn phase_report(phases: &[crate::core::estimate::posterior::PhaseReport]) -> String {
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

/// How far back the over-time contact's track reaches, s.
const TRACK_SECS: f64 = 1.0;

/// Most points of the track (a 1 kHz session's last second is thinned).
const TRACK_POINTS: usize = 200;

/// Which side panels are shown (View menu).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct PanelsShown {
    robot: bool,
    estimator: bool,
}

/// The app: the model, the estimate of the frame on screen, and the parts
/// that own their state and draw themselves (the view, the side panels,
/// the session and its timeline, live input, files and topics).
pub struct ProprioscopeApp {
    /// The user's model.
    pub model: Model,
    worker: Worker,
    generation: u64,
    /// The latest estimate shown.
    pub outcome: Option<Outcome>,
    robot_spec: String,
    /// The last failed open or save, shown until the next success.
    pub error: Option<String>,
    status: String,
    ctx: egui::Context,
    /// Estimates of session frames shown recently, by what they depend on.
    visited: std::collections::VecDeque<(EstimateInputs, Outcome)>,
    /// The estimate asked of the worker last, and what it depends on.
    pending: Option<(u64, EstimateInputs)>,
    /// Session frames shown again from `Self::visited` (for tests).
    pub visited_hits: usize,
    /// A scene, URDF or robot being opened in the background.
    opening: Option<worker::Background<AppStart>>,
    /// Side panels shown (View menu).
    panels: PanelsShown,
    /// The 3-D view.
    view: view::ViewPart,
    /// The robot panel.
    robot_panel: robot_panel::RobotPanel,
    /// The session on the timeline and its background estimation.
    pub session: timeline::SessionPart,
    /// A live source and its filter.
    live: live::LivePart,
    /// `--serve`: what the view shows, published to Foxglove.
    foxglove: foxglove::FoxglovePart,
    /// Files: paths typed, package folders, the recorder.
    pub files: files::Files,
    /// Recordings' topics chosen and asked for.
    pub topics: topic_prompt::TopicPrompts,
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
            worker: Worker::spawn(move || ctx.request_repaint()),
            generation: 0,
            outcome: None,
            robot_spec: String::new(),
            error: None,
            status: String::new(),
            ctx: cc.egui_ctx.clone(),
            visited: std::collections::VecDeque::new(),
            pending: None,
            visited_hits: 0,
            opening: None,
            panels: PanelsShown {
                robot: true,
                estimator: true,
            },
            view: view::ViewPart::new(picker, renderer),
            robot_panel: robot_panel::RobotPanel::default(),
            session: timeline::SessionPart::spawn(&cc.egui_ctx),
            live: live::LivePart::default(),
            foxglove: foxglove::FoxglovePart::default(),
            files: files::Files::default(),
            topics: topic_prompt::TopicPrompts::default(),
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
        app.files.robot_chosen = start.robot_chosen;
        app.files.package_paths = start.package_paths;
        if let Some(session) = start.session {
            app.session.first_frame = session.frame;
            app.open_session(&session.path, session.robot);
        }
        if let Some(address) = start.live {
            app.start_live(&address);
        }
        if let Some(address) = start.serve {
            app.foxglove = foxglove::FoxglovePart::start(&address);
            if let Some(e) = &app.foxglove.error {
                app.error = Some(e.clone());
            }
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
        let package_paths = self.files.package_paths.clone();
        let ctx = self.ctx.clone();
        self.opening = Some(worker::Background::spawn(
            target.to_owned(),
            move || open_target_with(Some(&owned), None, &package_paths).map_err(|e| format!("{e:#}")),
            move || ctx.request_repaint(),
        ));
    }

    /// The path a dialog gave; where no dialog could be shown, says so.
    fn picked(&mut self, picked: files::Picked) -> Option<std::path::PathBuf> {
        match picked {
            files::Picked::Path(path) => Some(path),
            files::Picked::Cancelled => None,
            files::Picked::Unavailable => {
                self.error = Some(files::NO_DIALOG.to_owned());
                None
            }
        }
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
                self.files.package_paths = start.package_paths;
                self.files.robot_chosen |= start.robot_chosen;
                self.replace_model(model, start.robot_spec);
            }
            Err(e) => self.error = Some(format!("could not open {target}: {e}")),
        }
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
        let tau = self.measured_less_bias(&pose);
        self.worker.request(Request {
            generation: self.generation,
            robot: self.model.robot.clone(),
            joint_positions: positions,
            tau,
            config: self.model.estimation_config(),
            links: self.model.candidate_links.clone(),
        });
    }

    /// The session frame's estimate from the frames together (filtered or
    /// smoothed), once the background has it.
    pub(super) fn over_time_estimate(&self) -> Option<crate::batch::FrameEstimate> {
        let replay = self.model.replay.as_ref()?;
        if replay.over_time == Temporal::None {
            return None;
        }
        self.session.estimates.get(replay.frame).copied().flatten()
    }

    /// The over-time contact's track over the last `TRACK_SECS` of the
    /// session up to the frame shown, while it stays on one link: each
    /// place taken into its link's frame at its own frame's pose, then
    /// into the world at the pose shown (so the track is where the contact
    /// went over the link, the arm's own motion left out); at most
    /// `TRACK_POINTS` points, oldest first.
    #[must_use]
    pub fn over_time_track(&self) -> Vec<DVec3> {
        let (Some(replay), Some(now)) = (self.model.replay.as_ref(), self.over_time_estimate()) else {
            return Vec::new();
        };
        if now.verdict == Verdict::NoContact {
            return Vec::new();
        }
        let frames = &replay.session.frames;
        let t_now = frames.get(replay.frame).map_or(0.0, |f| f.t);
        let first = frames.partition_point(|f| f.t < t_now - TRACK_SECS).min(replay.frame);
        let stride = (replay.frame - first).div_ceil(TRACK_POINTS).max(1);
        let pose_now = self.model.pose();
        let Some(world_now) = pose_now.world_from_link.get(now.link) else {
            return Vec::new();
        };
        let mut track = Vec::new();
        for j in (first..=replay.frame).rev().step_by(stride) {
            let (Some(Some(e)), Some(frame)) = (self.session.estimates.get(j), frames.get(j)) else {
                break;
            };
            if e.verdict == Verdict::NoContact || e.link != now.link {
                break;
            }
            let Ok(positions) = self.model.robot.joint_positions(&frame.q, &self.model.other_joints) else {
                break;
            };
            let pose = RobotPose::new(&self.model.robot, &positions);
            let Some(world_then) = pose.world_from_link.get(e.link) else {
                break;
            };
            track.push(world_now.transform_point3(world_then.inverse().transform_point3(e.point_world)));
        }
        track.reverse();
        track
    }

    /// What the view shows from outside its part (borrowing the model and
    /// the estimate, not the view).
    fn shown(&self) -> view::Shown<'_> {
        view::Shown {
            model: &self.model,
            outcome: self.current_outcome(),
            over_time: self.over_time_estimate(),
            track: self.over_time_track(),
            status: &self.status,
        }
    }

    /// The 3-D view's part drawn with what it shows (the model and the
    /// estimates borrowed beside the view, not through it).
    fn view_panel_ui(&mut self, ui: &mut egui::Ui, frame: &eframe::Frame) -> Vec<Command> {
        let shown = view::Shown {
            model: &self.model,
            outcome: self
                .outcome
                .as_ref()
                .filter(|o| Arc::ptr_eq(&o.robot, &self.model.robot)),
            over_time: self.over_time_estimate(),
            track: self.over_time_track(),
            status: &self.status,
        };
        self.view.ui(&shown, ui, frame)
    }

    /// The estimate of the frame on screen has arrived (a session may
    /// still be estimated behind it).
    #[must_use]
    pub fn is_frame_estimated(&self) -> bool {
        self.opening.is_none() && self.current_outcome().is_some_and(|o| o.generation == self.generation)
    }

    /// True when nothing is being opened or estimated: the frame on
    /// screen and, with a session, every frame of it.
    #[must_use]
    pub fn is_up_to_date(&self) -> bool {
        self.is_frame_estimated() && self.session_settled()
    }

    /// The torques the estimator is given: the measured ones, less the
    /// session's bias when it is taken off.
    #[must_use]
    pub fn measured_less_bias(&mut self, pose: &RobotPose) -> Vec<f64> {
        self.update_session_bias();
        self.update_session_calibration();
        let tau = self.model.measured_torques(pose);
        let correction = self.session_correction();
        match self
            .model
            .replay
            .as_ref()
            .and_then(|r| correction.as_ref()?.get(r.frame))
        {
            Some(c) => tau.iter().zip(c).map(|(t, b)| t - b).collect(),
            None => tau,
        }
    }

    /// Where `--serve` publishes to Foxglove (with the port it was given).
    #[must_use]
    pub fn foxglove_address(&self) -> Option<std::net::SocketAddr> {
        self.foxglove.address()
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
        self.view.picker = Picker::new(&model.robot);
        self.model = model;
        self.robot_spec = robot_spec;
        self.outcome = None;
        self.pending = None;
        self.visited.clear();
        self.view.hovered_joint = None;
        self.view.push_drag = None;
        self.view.drawn = None;
        self.view.fit_pending = true;
        self.session.key = None;
        self.session.estimates.clear();
        self.session.done = 0;
        self.session.failures.clear();
        self.session.metrics = None;
        self.error = None;
        self.request_estimate();
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
        self.poll_calibrating_from();
        self.update_session_estimates();
        let mut commands = self.playback_keys(ui.ctx());
        egui::Panel::top("menu").show(ui, |ui| self.menu_ui(ui));
        // Panels are sized from the window so that the 3-D view keeps at
        // least half of it both ways, from 1280×720 up.
        let window = ui.ctx().content_rect().size();
        let side_max = (0.25 * window.x).max(200.0);
        let in_session = self.model.replay.is_some() || self.live.view.is_some();
        // Below the menu and across the whole width: a session's timeline.
        if in_session {
            egui::Panel::bottom("timeline")
                .resizable(true)
                .min_size(150.0)
                .default_size((0.34 * window.y).clamp(170.0, 320.0))
                .max_size((0.4 * window.y).max(170.0))
                .show(ui, |ui| {
                    self.live_ui(ui);
                    commands.extend(self.timeline_ui(ui));
                });
        }
        if self.panels.robot {
            egui::Panel::left("robot")
                .resizable(true)
                .default_size(side_max.min(290.0))
                .max_size(side_max)
                .show(ui, |ui| {
                    egui::ScrollArea::vertical().show(ui, |ui| commands.extend(self.robot_panel.ui(ui, &self.model)));
                });
        }
        if self.panels.estimator {
            egui::Panel::right("estimator")
                .resizable(true)
                .default_size(side_max.min(320.0))
                .max_size(side_max)
                .show(ui, |ui| {
                    egui::ScrollArea::vertical().show(ui, |ui| {
                        // A recording's torque model first: it sets σ.
                        commands.extend(self.torque_model_ui(ui));
                        commands.extend(estimator_panel::EstimatorPanel::ui(
                            ui,
                            &self.model,
                            self.current_outcome(),
                        ));
                        self.session_summary_ui(ui);
                        // In a session the bottom belongs to the timeline.
                        if in_session {
                            egui::CollapsingHeader::new("Joint torques [N·m]")
                                .default_open(true)
                                .show(ui, |ui| {
                                    ui.set_height(190.0);
                                    self.torques_ui(ui);
                                });
                        }
                    });
                });
        }
        if !in_session {
            egui::Panel::bottom("torques")
                .resizable(true)
                .default_size((0.24 * window.y).clamp(150.0, 260.0))
                .max_size((0.3 * window.y).max(150.0))
                .show(ui, |ui| {
                    ui.label("Joint torques [N·m] (faded: the joint cannot sense the push)");
                    self.torques_ui(ui);
                });
        }
        egui::CentralPanel::default().show(ui, |ui| commands.extend(self.view_panel_ui(ui, frame)));
        self.topic_prompt_ui(&ui.ctx().clone());
        for command in commands {
            self.apply(command);
        }
        let ctx = ui.ctx().clone();
        self.record_tick(&ctx);
        let mut foxglove = std::mem::take(&mut self.foxglove);
        foxglove.publish(&self.shown());
        self.foxglove = foxglove;
    }
}
