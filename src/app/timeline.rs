//! The session replay's UI: timeline, linked plots, session summary, and
//! the recorder of the interactive mode.

use std::path::{Path, PathBuf};
use std::sync::Arc;

use eframe::egui;

use super::{Command, Model, ProprioscopeApp, Replay, SPEED_RANGE, per_joint};
use crate::batch::{self, EstimateJob, FrameEstimate, LoadFailure, Loader, SessionData};
use crate::core::config::estimator::{EstimatorConfig, Sigma};
use crate::core::estimate::summary::Verdict;
use crate::core::over_time::sequence::{Temporal, automatic_temporal};
use crate::core::robot::model::{LinkId, Robot};

/// The session's part: the frames' background estimation (its worker,
/// the estimates so far, failures, what they were made with), the session
/// being loaded, its metrics and its torque bias.
pub struct SessionPart {
    pub(crate) worker: batch::SessionWorker,
    /// Background estimates of the session's frames (`None`: not yet).
    pub estimates: Vec<Option<FrameEstimate>>,
    /// How many of them are there (counted as they arrive, not per frame).
    pub(crate) done: usize,
    /// Frames whose estimate failed, with why.
    pub(crate) failures: std::collections::BTreeMap<usize, String>,
    /// Whether the pass over the second contacts is still to come.
    pub(crate) second_pending: bool,
    pub(crate) generation: u64,
    pub(crate) key: Option<SessionKey>,
    pub(crate) loader: Option<Loader>,
    /// The frame a session being loaded opens on.
    pub(crate) first_frame: Option<usize>,
    /// Whether the session shown is the first frames of the one being
    /// loaded: shown and estimated frame by frame, not yet as a whole.
    pub(crate) previewing: bool,
    /// The session's metrics, with the estimation run they belong to.
    pub(crate) metrics: Option<((u64, usize), Option<super::session_panel::SessionMetrics>)>,
    /// The session's torque bias, when it is taken off, with what it was
    /// estimated from.
    pub(crate) bias: Option<(super::bias::BiasKey, super::bias::BiasState)>,
    /// The session's calibration, with what it was made from.
    pub(crate) calibration: Option<(super::calibration::CalibrationKey, super::calibration::CalibrationState)>,
    /// A calibration from a free-motion recording or a file, used in
    /// place of one learned from the session.
    pub external_calibration: Option<Arc<super::calibration::ExternalCalibration>>,
    /// A calibration being learned from a free-motion recording.
    pub(crate) calibrating_from: Option<super::worker::Background<super::calibration::ExternalCalibration>>,
    /// When the estimation under way began (for the time it has left).
    pub(crate) started: Option<std::time::Instant>,
}

impl SessionPart {
    /// No session; its worker's thread started (it repaints `ctx`).
    pub(crate) fn spawn(ctx: &egui::Context) -> Self {
        let ctx = ctx.clone();
        Self {
            worker: batch::SessionWorker::spawn(move || ctx.request_repaint()),
            estimates: Vec::new(),
            done: 0,
            failures: std::collections::BTreeMap::new(),
            second_pending: false,
            generation: 0,
            key: None,
            loader: None,
            first_frame: None,
            previewing: false,
            metrics: None,
            bias: None,
            calibration: None,
            external_calibration: None,
            calibrating_from: None,
            started: None,
        }
    }
}

/// `secs` as "12 s", "3 min 5 s" or "2 h 4 min".
fn duration_text(secs: f64) -> String {
    let whole = secs.max(0.0).round() as u64;
    match whole {
        0..60 => format!("{whole} s"),
        60..3600 => format!("{} min {} s", whole / 60, whole % 60),
        _ => format!("{} h {} min", whole / 3600, whole % 3600 / 60),
    }
}

/// What the background estimation of a session depends on.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SessionKey {
    session: usize,
    /// While live: the live session's epoch (it grows in place, so its
    /// address says nothing).
    live_epoch: Option<u64>,
    config: EstimatorConfig,
    candidate_links: Vec<LinkId>,
    over_time: Temporal,
    bias_auto: bool,
    /// Whether the bias taken off is known (it is estimated on a thread:
    /// the frames are estimated once it is there).
    bias_known: bool,
    /// Whether the calibration is settled (made on a thread too; made,
    /// or known not to be possible).
    calibration_settled: bool,
}

impl ProprioscopeApp {
    /// Starts opening a session (JSON or CSV) in the background; `robot`
    /// overrides the session's (a CSV session without one uses the current
    /// robot). On failure the error is shown and the current scene kept.
    pub fn open_session(&mut self, path: &Path, robot: Option<String>) {
        // A file that names no robot (CSV, recordings) is shown on the
        // robot the user chose; on the default robot it would be a guess.
        let robot = match robot {
            Some(r) => Some(r),
            None if crate::io::open::names_no_robot(path) => {
                if !self.files.robot_chosen {
                    self.error = Some(format!(
                        "{} names no robot (CSV sessions and recordings do not): open its robot first \
                         (Robot menu, or Scenes > Open scene or URDF), then the session; or run \
                         proprioscope view {} --robot URDF",
                        path.display(),
                        path.display()
                    ));
                    return;
                }
                Some(self.robot_spec.clone())
            }
            None => None,
        };
        let ctx = self.ctx.clone();
        // A recording's topics: as chosen for this file before, else as for
        // the last file whose topics were chosen (when they fit).
        let choice = self
            .topics
            .choices
            .get(path)
            .or(self.topics.last.as_ref())
            .cloned()
            .unwrap_or_default();
        self.session.loader = Some(Loader::spawn(
            path.to_owned(),
            robot,
            self.files.package_paths.clone(),
            choice,
            move || ctx.request_repaint(),
        ));
    }

    /// Installs a loaded session (or shows why it could not be loaded);
    /// meanwhile, a long file's first frames.
    pub(super) fn poll_loader(&mut self) {
        let Some(loader) = self.session.loader.as_ref() else {
            return;
        };
        let Some(result) = loader.poll() else {
            if let Some((data, robot, spec)) = loader.take_preview() {
                // The frame asked for is kept for the whole session.
                let wanted = self.session.first_frame;
                self.session.first_frame = wanted.map(|f| f.min(data.frames.len().saturating_sub(1)));
                self.install_session(data, robot, spec);
                self.session.first_frame = wanted;
                self.session.previewing = true;
            }
            return;
        };
        let path = self.session.loader.take().map(|l| l.path).unwrap_or_default();
        if std::mem::take(&mut self.session.previewing) {
            if result.is_ok() {
                // The whole session opens on the frame the preview was at.
                self.session.first_frame = self
                    .session
                    .first_frame
                    .or_else(|| self.model.replay.as_ref().map(|r| r.frame));
            } else {
                // A file that could not be read whole is not shown in part.
                self.close_session();
            }
        }
        match result {
            Ok((data, robot, spec)) => self.install_session(data, robot, spec),
            Err(LoadFailure::Failed(e)) => self.error = Some(format!("could not open session {}: {e}", path.display())),
            Err(LoadFailure::NeedsTopics(prompt)) => self.topics.prompt = Some(*prompt),
        }
    }

    pub(super) fn install_session(&mut self, data: SessionData, robot: Robot, spec: String) {
        let joints = robot.sensed().len();
        // As `estimate --temporal auto`.
        let times: Vec<f64> = data.frames.iter().map(|f| f.t).collect();
        let (over_time, _) = automatic_temporal(&times, &self.model.config.temporal);
        let candidate_links = robot.default_candidate_links();
        let q = data.frames.first().map_or_else(|| vec![0.0; joints], |f| f.q.clone());
        let old = &self.model;
        // The same robot keeps its `Arc`: the worker's sampled surface,
        // keyed by it, then serves the session's first frame at once
        // instead of sampling the surface again (a third of a second).
        let robot = if *old.robot == robot {
            old.robot.clone()
        } else {
            Arc::new(robot)
        };
        let model = Model {
            robot,
            q,
            push: None,
            second_push: None,
            // The largest σ of the robot before, for every joint of this one.
            config: EstimatorConfig {
                sigma: Sigma::PerJoint(per_joint(&[old.sigma().iter().copied().fold(0.0, f64::max)], joints)),
                ..old.config.clone()
            },
            candidate_links,
            noise_sigma: old.noise_sigma,
            noise_seed: old.noise_seed,
            other_joints: Vec::new(),
            title: (String::new(), String::new()),
            view: old.view,
            replay: Some(Replay {
                session: Arc::new(data),
                frame: 0,
                playing: false,
                speed: 1.0,
                looping: false,
                clock_secs: 0.0,
                over_time,
                bias_auto: false,
                learned_sigma: None,
            }),
            refused: None,
        };
        let first = self.session.first_frame.take().unwrap_or(0);
        let mut model = model;
        model.apply(Command::SetFrame(first));
        self.replace_model(model, spec);
    }

    /// Leaves the session; the robot stays where the frame put it.
    pub fn close_session(&mut self) {
        // Closing a preview stops the file's loading.
        if std::mem::take(&mut self.session.previewing) {
            self.session.loader = None;
        }
        self.model.replay = None;
        self.visited.clear();
        self.session.key = None;
        self.session.estimates.clear();
        self.session.done = 0;
        self.session.failures.clear();
        self.request_estimate();
    }

    /// (Re)starts the background estimation when the session or the
    /// settings changed, and collects what it has done.
    pub(super) fn update_session_estimates(&mut self) {
        // A preview's frames are estimated one by one, as shown; the
        // session as a whole once it is all read.
        if self.session.previewing {
            return;
        }
        self.update_session_bias();
        self.update_session_calibration();
        let Some(replay) = &self.model.replay else {
            return;
        };
        // A live session grows every frame: filtered as its frames arrive
        // (or each alone as it is shown), as a whole once the stream stops.
        if self.live.view.is_some() {
            self.update_live_estimates();
            return;
        }
        let m = &self.model;
        let Some(key) = self.current_session_key() else {
            return;
        };
        if self.session.key.as_ref() != Some(&key) {
            self.session.generation += 1;
            self.session.estimates = vec![None; replay.session.frames.len()];
            self.session.done = 0;
            self.session.failures.clear();
            if self.correction_pending() {
                // Estimated once the bias or the calibration is known (the
                // key changes then).
                self.session.key = Some(key);
                return;
            }
            // Frames together, with two contacts looked for, end with a
            // pass over the second contacts.
            self.session.second_pending =
                replay.over_time != Temporal::None && m.estimation_config().contacts_at_once >= 2;
            self.session.worker.start(EstimateJob {
                generation: self.session.generation,
                robot: m.robot.clone(),
                session: replay.session.clone(),
                config: m.estimation_config(),
                links: m.candidate_links.clone(),
                first: replay.frame,
                over_time: replay.over_time,
                bias: self.session_correction(),
            });
            self.session.started = Some(std::time::Instant::now());
            self.session.key = Some(key);
        }
        let done: Vec<crate::batch::Estimated> = self.session.worker.drain().collect();
        self.record_estimates(done);
    }

    /// While live and not *each frame alone*: hands the frames that
    /// arrived to the live filter (all of them again when the settings
    /// changed or a new sender began), and collects what it has done.
    fn update_live_estimates(&mut self) {
        let Some(replay) = &self.model.replay else {
            return;
        };
        if replay.over_time == Temporal::None {
            // Each frame alone, as it is shown: nothing filtered is kept
            // (the plots would show it for the frames it reached).
            if self.session.key.take().is_some() {
                self.session.generation += 1;
                self.session.estimates.clear();
                self.session.done = 0;
                self.session.failures.clear();
            }
            return;
        }
        let Some(key) = self.current_session_key() else {
            return;
        };
        let Some(live) = self.live.view.as_mut() else {
            return;
        };
        let m = &self.model;
        let frames = &replay.session.frames;
        let ctx = self.ctx.clone();
        let worker = self
            .live
            .filter
            .get_or_insert_with(|| crate::batch::LiveFilterWorker::spawn(move || ctx.request_repaint()));
        if self.session.key.as_ref() != Some(&key) {
            self.session.generation += 1;
            self.session.estimates = vec![None; frames.len()];
            self.session.done = 0;
            self.session.failures.clear();
            worker.start(crate::batch::LiveJob {
                generation: self.session.generation,
                robot: m.robot.clone(),
                frames: frames.clone(),
                config: m.estimation_config(),
                links: m.candidate_links.clone(),
            });
            live.filtered_sent = frames.len();
            self.session.key = Some(key);
        } else if let Some(new) = frames.get(live.filtered_sent..).filter(|f| !f.is_empty()) {
            worker.append(new.to_vec());
            live.filtered_sent = frames.len();
            self.session.estimates.resize(frames.len(), None);
        }
        let done: Vec<crate::batch::Estimated> = worker.drain().collect();
        self.record_estimates(done);
    }

    /// Files estimates of session frames (those of the current generation).
    fn record_estimates(&mut self, estimated: Vec<crate::batch::Estimated>) {
        for done in estimated {
            if done.generation != self.session.generation {
                continue;
            }
            match done.estimate {
                Ok(e) => {
                    if let Some(slot) = self.session.estimates.get_mut(done.frame) {
                        self.session.done += usize::from(slot.is_none());
                        *slot = Some(e);
                    }
                }
                Err(_) if done.frame == crate::batch::SECOND_CONTACTS_DONE => {
                    self.session.second_pending = false;
                }
                Err(e) if done.frame == crate::batch::EVERY_FRAME => {
                    let frames = self.session.estimates.len();
                    for frame in 0..frames {
                        if self.session.estimates.get(frame).is_some_and(Option::is_none) {
                            self.session.failures.entry(frame).or_insert_with(|| e.clone());
                        }
                    }
                    self.error = Some(format!("the session could not be estimated: {e}"));
                }
                Err(e) => {
                    if self.session.estimates.get(done.frame).is_some_and(Option::is_none) {
                        self.session.failures.insert(done.frame, e);
                    }
                }
            }
        }
    }

    /// What the session's estimates depend on now (`None` without a session).
    fn current_session_key(&self) -> Option<SessionKey> {
        let m = &self.model;
        let replay = m.replay.as_ref()?;
        let live_epoch = self.live.view.as_ref().map(|l| l.epoch);
        Some(SessionKey {
            session: if live_epoch.is_some() {
                0
            } else {
                Arc::as_ptr(&replay.session) as usize
            },
            live_epoch,
            config: m.estimation_config(),
            candidate_links: m.candidate_links.clone(),
            over_time: replay.over_time,
            // Live frames are filtered as they come, bias and all; the
            // bias is taken off once the stream stops.
            bias_auto: replay.bias_auto && live_epoch.is_none(),
            bias_known: self.session_bias().is_some() && live_epoch.is_none(),
            calibration_settled: !self.calibration_pending() && live_epoch.is_none(),
        })
    }

    /// Whether a session file is being read.
    #[must_use]
    pub fn is_session_loading(&self) -> bool {
        self.session.loader.is_some()
    }

    /// Whether the session shown is the first frames of one still being
    /// read.
    #[must_use]
    pub fn is_session_preview(&self) -> bool {
        self.session.previewing
    }

    /// Frames estimated in the background so far.
    #[must_use]
    pub fn session_estimated(&self) -> usize {
        self.session.done
    }

    /// Session frames whose estimate failed, with why (frame → message).
    #[must_use]
    pub fn session_failures(&self) -> &std::collections::BTreeMap<usize, String> {
        &self.session.failures
    }

    /// Whether nothing is loading and every session frame is estimated
    /// (or failed: those are counted and listed, not waited for).
    pub(super) fn session_settled(&self) -> bool {
        self.session.loader.is_none()
            && (self.model.replay.is_none()
                // Live frames are estimated as shown, not as a whole.
                || self.live.view.is_some()
                || (self.session.key.is_some()
                    && self.session.key == self.current_session_key()
                    && self.session.done + self.session.failures.len() >= self.session.estimates.len()
                    && !self.session.second_pending))
    }

    /// Space plays or pauses, the arrow keys step, unless a text field or
    /// slider has the keyboard.
    pub(super) fn playback_keys(&self, ctx: &egui::Context) -> Vec<Command> {
        let Some(replay) = &self.model.replay else {
            return Vec::new();
        };
        if ctx.memory(|m| m.focused().is_some()) {
            return Vec::new();
        }
        let mut commands = Vec::new();
        ctx.input(|i| {
            if i.key_pressed(egui::Key::Space) {
                commands.push(Command::Play(!replay.playing));
            }
            if i.key_pressed(egui::Key::ArrowLeft) {
                commands.push(Command::StepFrames(-1));
            }
            if i.key_pressed(egui::Key::ArrowRight) {
                commands.push(Command::StepFrames(1));
            }
        });
        if replay.playing {
            let dt = ctx.input(|i| f64::from(i.stable_dt)).min(0.1);
            commands.push(Command::Tick(dt));
            ctx.request_repaint();
        }
        commands
    }

    /// The row's account of the frame on screen from the frames together.
    fn over_time_label_ui(&self, ui: &mut egui::Ui) {
        if let Some(e) = self.over_time_estimate() {
            let p = e.contact_probability.unwrap_or(0.0);
            let text = if e.verdict == Verdict::NoContact {
                format!("over time: no contact (p = {p:.2})")
            } else if let Some(two) = e.second.filter(|s| s.called) {
                let name = |link: LinkId| self.model.robot.links.get(link).map_or("?", |l| l.name.as_str());
                let [(a, _, fa), (b, _, fb)] = two.contacts;
                format!(
                    "over time: two contacts, {} {:.1} N and {} {:.1} N (p = {:.2})",
                    name(a),
                    fa.length(),
                    name(b),
                    fb.length(),
                    two.probability_two
                )
            } else {
                let link = self.model.robot.links.get(e.link).map_or("?", |l| l.name.as_str());
                format!("over time: {link}, {:.1} N (p = {p:.2})", e.force_world.length())
            };
            let hover = format!(
                "the white arrow: where the frames together place the contact; their 90 % credible set \
             lies within {:.0} mm of its centre (a press's own uncertainty included)",
                e.credible90_radius_m * 1e3
            );
            ui.colored_label(egui::Color32::from_rgb(90, 155, 255), text)
                .on_hover_text(hover);
        }
    }

    /// The timeline: transport, speed, loop, scrubbing, estimation
    /// progress, and the plots.
    pub(super) fn timeline_ui(&self, ui: &mut egui::Ui) -> Vec<Command> {
        let mut commands = Vec::new();
        let Some(replay) = &self.model.replay else {
            return commands;
        };
        // A panel keeps the height its content used: the timeline claims
        // all of it, or it would shrink a little every frame down to the
        // plots' least height and undo the user's resizing.
        ui.set_min_height(ui.available_height());
        let frames = &replay.session.frames;
        let last = frames.len().saturating_sub(1);
        ui.horizontal(|ui| {
            if ui.button("|<").on_hover_text("first frame").clicked() {
                commands.push(Command::SetFrame(0));
            }
            if ui.button("<").on_hover_text("previous frame (←)").clicked() {
                commands.push(Command::StepFrames(-1));
            }
            let label = if replay.playing { "Pause" } else { "Play" };
            if ui.button(label).on_hover_text("space").clicked() {
                commands.push(Command::Play(!replay.playing));
            }
            if ui.button(">").on_hover_text("next frame (Right arrow key)").clicked() {
                commands.push(Command::StepFrames(1));
            }
            if ui.button(">|").on_hover_text("last frame").clicked() {
                commands.push(Command::SetFrame(last));
            }
            let mut speed = replay.speed;
            if ui
                .add(
                    egui::Slider::new(&mut speed, SPEED_RANGE.0..=SPEED_RANGE.1)
                        .clamping(egui::SliderClamping::Never)
                        .logarithmic(true)
                        .suffix("×")
                        .text("speed"),
                )
                .changed()
            {
                commands.push(Command::SetSpeed(speed));
            }
            let mut looping = replay.looping;
            if ui.checkbox(&mut looping, "loop").changed() {
                commands.push(Command::SetLoop(looping));
            }
            commands.extend(Self::over_time_ui(
                ui,
                replay,
                self.model.config.temporal.slide_m_per_sqrt_s,
                self.bias_pending(),
            ));
            self.calibration_status_ui(ui);
            if let Some(frame) = frames.get(replay.frame) {
                let file_frame = replay.session.file_frames.get(replay.frame).copied().unwrap_or(0);
                ui.label(format!(
                    "t = {:.3} s, frame {} of {} (file frame {file_frame})",
                    frame.t,
                    replay.frame + 1,
                    frames.len()
                ));
            }
            self.over_time_label_ui(ui);
        });
        let mut frame = replay.frame;
        ui.spacing_mut().slider_width = (ui.available_width() - 80.0).max(100.0);
        if ui.add(egui::Slider::new(&mut frame, 0..=last).text("frame")).changed() {
            commands.push(Command::SetFrame(frame));
        }
        let done = self.session_estimated();
        if done < frames.len() && self.live.view.is_none() {
            // The time left at the pace so far (a smoothed session's
            // frames come a stretch at a time: an average of stretches).
            let elapsed_secs = self.session.started.map_or(0.0, |t| t.elapsed().as_secs_f64());
            let left = if done > 0 && elapsed_secs >= 1.0 {
                let secs = elapsed_secs * (frames.len() - done) as f64 / done as f64;
                format!(", about {} left", duration_text(secs))
            } else {
                String::new()
            };
            ui.add(
                egui::ProgressBar::new(done as f32 / frames.len().max(1) as f32).text(format!(
                    "estimating the session: {done} of {} frames{left}",
                    frames.len()
                )),
            );
        }
        if let Some(t) = self.session_plots_ui(ui, replay) {
            commands.push(Command::SetFrame(replay.session.nearest_frame(t)));
        }
        commands
    }

    /// Four plots over session time, sharing the x axis, with the current
    /// frame marked; returns the time clicked.
    /// How the frames are estimated over time, and the bias.
    fn over_time_ui(ui: &mut egui::Ui, replay: &Replay, slide_m_per_sqrt_s: f64, bias_pending: bool) -> Vec<Command> {
        let mut commands = Vec::new();
        let name = |t: Temporal| match t {
            Temporal::None => "each frame alone",
            Temporal::Filter => "filtered (frames before)",
            Temporal::Smooth => "smoothed (whole session)",
        };
        egui::ComboBox::new("over-time", "over time")
            .selected_text(name(replay.over_time))
            .show_ui(ui, |ui| {
                for t in [Temporal::None, Temporal::Filter, Temporal::Smooth] {
                    if ui.selectable_label(replay.over_time == t, name(t)).clicked() && replay.over_time != t {
                        commands.push(Command::SetOverTime(t));
                    }
                }
            })
            .response
            .on_hover_text(
                "how the session's frames are estimated: a contact lasts, so frames together say more than alone",
            );
        if replay.over_time != Temporal::None {
            // In cm/√s: the range reads 0.1–10 rather than 0.001–0.1. A
            // drag value: the row has no room for another slider.
            let mut slide_cm = slide_m_per_sqrt_s * 100.0;
            let hover = "how far a contact may slide, RMS along the surface after one second (as estimate --slide): \
                         1 cm/√s for presses that stay put, 2–3 for contacts that slide a few centimetres a second";
            ui.label("slide").on_hover_text(hover);
            if ui
                .add(
                    // No range: a typed value outside is refused, not clamped.
                    egui::DragValue::new(&mut slide_cm)
                        .speed(0.02)
                        .max_decimals(2)
                        .suffix(" cm/√s"),
                )
                .on_hover_text(hover)
                .changed()
            {
                commands.push(Command::SetSlide(slide_cm / 100.0));
            }
        }
        let mut bias_auto = replay.bias_auto;
        if ui
            .checkbox(&mut bias_auto, "take off bias")
            .on_hover_text(
                "each joint's torque offset (what it reads with nothing touching), estimated from the session over 30 s windows and taken off every frame, as estimate --bias auto",
            )
            .changed()
        {
            commands.push(Command::SetBias(bias_auto));
        }
        if bias_pending {
            ui.spinner();
            ui.label("estimating the bias");
        }
        commands
    }
}

/// `PathBuf` of a session given on the command line, with its robot.
#[derive(Debug, Clone)]
pub struct SessionTarget {
    /// The session file.
    pub path: PathBuf,
    /// Robot override.
    pub robot: Option<String>,
    /// The frame to show first (index into the good frames).
    pub frame: Option<usize>,
}
