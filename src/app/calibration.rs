//! A session's calibration in the app, as `estimate` makes it on
//! recordings ([`crate::batch::calibration`]): the model error learned
//! from the session itself on a thread of its own, or taken from a
//! free-motion recording or a calibration file; its correction taken off
//! the frame shown and every frame estimated in the background, and σ
//! per joint learned from what is left (while σ is automatic).

use std::path::PathBuf;
use std::sync::Arc;

use super::{Command, ProprioscopeApp, egui, worker};
use crate::batch::calibration::{corrected, learn, learned_sigma};
use crate::core::over_time::calibration::{Calibration, CalibrationError, CalibrationSettings};
use crate::core::over_time::sequence::Temporal;
use crate::core::over_time::temporal::is_continuous_recording;
use crate::io::calibration::CalibrationFile;

/// A calibration made elsewhere: from a free-motion recording, or read
/// from a calibration file.
#[derive(Debug, Clone, PartialEq)]
pub struct ExternalCalibration {
    /// Where it comes from.
    pub source: PathBuf,
    /// What it holds.
    pub calibration: Calibration,
}

/// What a session's calibration was made from.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct CalibrationKey {
    session: usize,
    calibrate: bool,
    settings: CalibrationSettings,
    external: Option<Arc<ExternalCalibration>>,
    /// The bias it was learned after (as `estimate` does: the bias off
    /// first), when the bias is taken off.
    bias: Option<usize>,
}

/// A session's calibration and what it does to its torques.
#[derive(Debug)]
pub struct SessionCalibration {
    /// The calibration (learned, or external).
    pub calibration: Calibration,
    /// Where it comes from: `None` for the session itself.
    pub source: Option<PathBuf>,
    /// Whether its correction is taken off the torques.
    pub applied: bool,
    /// Per frame and joint, what is taken off the measured torques (the
    /// bias too, when it is taken off), N·m.
    pub correction: Arc<Vec<Vec<f64>>>,
    /// σ per joint learned for frames alone, N·m.
    pub sigma_alone: Vec<f64>,
    /// ... for frames combined over time (widened for the correlation).
    pub sigma_over_time: Vec<f64>,
}

/// A session's calibration: being made, made, or why not.
pub(crate) enum CalibrationState {
    /// On its thread.
    Pending(worker::Background<Arc<SessionCalibration>>),
    /// Done.
    Done(Result<Arc<SessionCalibration>, String>),
}

impl ProprioscopeApp {
    /// Starts the session's calibration when it is asked for (calibrate
    /// or σ automatic, a session that is not live) and not yet made for
    /// this session and these settings; collects it when it is done
    /// (then estimates the frame shown again, and sets σ while it is
    /// automatic); drops it when it is not asked for.
    pub(super) fn update_session_calibration(&mut self) {
        let torques = self.model.config.torques;
        let wanted = torques.calibrate || torques.sigma_auto || self.session.external_calibration.is_some();
        let Some(replay) = self
            .model
            .replay
            .as_ref()
            .filter(|_| wanted && self.live.view.is_none())
        else {
            self.session.calibration = None;
            return;
        };
        if replay.bias_auto && self.bias_pending() {
            return;
        }
        let bias = if replay.bias_auto {
            self.session_bias().cloned()
        } else {
            None
        };
        let key = CalibrationKey {
            session: Arc::as_ptr(&replay.session) as usize,
            calibrate: torques.calibrate,
            settings: torques.calibration,
            external: self.session.external_calibration.clone(),
            bias: bias.as_ref().map(|b| Arc::as_ptr(b) as usize),
        };
        match &self.session.calibration {
            Some((k, CalibrationState::Done(_))) if *k == key => {}
            Some((k, CalibrationState::Pending(job))) if *k == key => {
                let Some(done) = job.poll() else {
                    return;
                };
                self.session.calibration = Some((key, CalibrationState::Done(done)));
                // Frames seen before were estimated on other torques.
                self.visited.clear();
                self.request_estimate();
            }
            _ => {
                let session = replay.session.clone();
                let robot = self.model.robot.clone();
                let ctx = self.ctx.clone();
                let external = key.external.clone();
                let (calibrate, settings) = (key.calibrate, key.settings);
                let temporal = self.model.config.temporal;
                let job = worker::Background::spawn(
                    "the calibration".to_owned(),
                    move || {
                        let times: Vec<f64> = session.frames.iter().map(|f| f.t).collect();
                        if !is_continuous_recording(&times, &temporal) {
                            return Err("not a recording (its frames are not evenly spaced in time)".to_owned());
                        }
                        let frames = (session.path.as_path(), session.frames.as_slice());
                        // The torques less the bias when it is taken off.
                        let measured: Vec<Vec<f64>> = session
                            .frames
                            .iter()
                            .enumerate()
                            .map(|(i, f)| match bias.as_ref().and_then(|b| b.get(i)) {
                                Some(b) => f.tau.iter().zip(b).map(|(t, b)| t - b).collect(),
                                None => f.tau.clone(),
                            })
                            .collect();
                        let calibration = match &external {
                            Some(e) => e.calibration.clone(),
                            None => {
                                learn(&robot, frames, &measured, &settings).map_err(|e| e.root_cause().to_string())?
                            }
                        };
                        let applied = external.is_some() || calibrate;
                        // What is taken off the session's own torques: the
                        // bias and the model error.
                        let left = if applied && calibration.found {
                            corrected(&robot, frames, &calibration, &measured).map_err(|e| format!("{e:#}"))?
                        } else {
                            measured
                        };
                        let correction = session
                            .frames
                            .iter()
                            .zip(&left)
                            .map(|(f, l)| f.tau.iter().zip(l).map(|(a, b)| a - b).collect())
                            .collect();
                        Ok(Arc::new(SessionCalibration {
                            sigma_alone: learned_sigma(&calibration, &session.frames, applied, false),
                            sigma_over_time: learned_sigma(&calibration, &session.frames, applied, true),
                            calibration,
                            source: external.map(|e| e.source.clone()),
                            applied,
                            correction: Arc::new(correction),
                        }))
                    },
                    move || ctx.request_repaint(),
                );
                self.session.calibration = Some((key, CalibrationState::Pending(job)));
            }
        }
        self.sync_learned_sigma();
    }

    /// While σ is automatic, the σ learned for how frames are combined now.
    fn sync_learned_sigma(&mut self) {
        if !self.model.config.torques.sigma_auto {
            return;
        }
        let Some(replay) = &self.model.replay else {
            return;
        };
        let Some(done) = self.session_calibration() else {
            return;
        };
        let learned = if replay.over_time == Temporal::None {
            done.sigma_alone.clone()
        } else {
            done.sigma_over_time.clone()
        };
        if replay.learned_sigma.as_ref() != Some(&learned) {
            self.apply(Command::SetLearnedSigma(learned));
        }
    }

    /// Whether the calibration is asked for and still being made.
    #[must_use]
    pub fn calibration_pending(&self) -> bool {
        matches!(self.session.calibration, Some((_, CalibrationState::Pending(_))))
    }

    /// The session's calibration, once made.
    #[must_use]
    pub fn session_calibration(&self) -> Option<&Arc<SessionCalibration>> {
        match &self.session.calibration {
            Some((_, CalibrationState::Done(Ok(c)))) => Some(c),
            _ => None,
        }
    }

    /// Why the session's calibration could not be made, if it could not.
    #[must_use]
    pub fn calibration_failure(&self) -> Option<&str> {
        match &self.session.calibration {
            Some((_, CalibrationState::Done(Err(e)))) => Some(e),
            _ => None,
        }
    }

    /// What is taken off the session's torques per frame: the
    /// calibration's correction (bias included) where it is applied,
    /// else the bias when it is taken off.
    #[must_use]
    pub fn session_correction(&self) -> Option<Arc<Vec<Vec<f64>>>> {
        match self.session_calibration() {
            Some(c) if c.applied && c.calibration.found => Some(c.correction.clone()),
            _ => self.session_bias().cloned(),
        }
    }

    /// Whether what is taken off the torques is still being made.
    #[must_use]
    pub fn correction_pending(&self) -> bool {
        self.bias_pending() || self.calibration_pending()
    }

    /// Learns a calibration from a recording of free motion at `path`
    /// (every frame fits, nothing is gated out) on the robot shown, and
    /// uses it for the session: on a thread of its own.
    pub fn calibrate_from(&mut self, path: PathBuf) {
        let robot = self.model.robot.clone();
        let robot_spec = self.robot_spec.clone();
        let packages = self.files.package_paths.clone();
        let settings = CalibrationSettings {
            free_motion: true,
            ..self.model.config.torques.calibration
        };
        let ctx = self.ctx.clone();
        self.session.calibrating_from = Some(worker::Background::spawn(
            format!("calibrating from {}", path.display()),
            move || {
                let (data, _, _) = crate::batch::load_session(
                    &path,
                    Some(&robot_spec),
                    &packages,
                    &crate::io::recording::TopicChoice::default(),
                    &|_| {},
                    &|_| {},
                )
                .map_err(|e| format!("{e:#}"))?;
                let measured: Vec<Vec<f64>> = data.frames.iter().map(|f| f.tau.clone()).collect();
                let calibration =
                    learn(&robot, (&path, &data.frames), &measured, &settings).map_err(|e| format!("{e:#}"))?;
                if !calibration.found {
                    return Err(format!(
                        "{}: no model error found beyond noise: nothing to take off",
                        path.display()
                    ));
                }
                Ok(ExternalCalibration {
                    source: path,
                    calibration,
                })
            },
            move || ctx.request_repaint(),
        ));
    }

    /// Reads a calibration file (as `estimate --calibration`) and uses it
    /// for the session.
    pub fn open_calibration(&mut self, path: PathBuf) {
        let links: Vec<String> = self.model.robot.links.iter().map(|l| l.name.clone()).collect();
        match CalibrationFile::read(&path, &links) {
            Ok(c) if c.joints == self.model.robot.sensed_names() => {
                self.session.external_calibration = Some(Arc::new(ExternalCalibration {
                    source: path,
                    calibration: c,
                }));
                self.error = None;
            }
            Ok(c) => {
                self.error = Some(
                    CalibrationError::OtherJoints {
                        calibrated: c.joints.join(", "),
                        robot: self.model.robot.sensed_names().join(", "),
                    }
                    .to_string(),
                );
            }
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    /// Writes the session's calibration to `path`.
    pub fn save_calibration(&mut self, path: &std::path::Path) {
        let Some(done) = self.session_calibration() else {
            self.error = Some("no calibration to save yet".to_owned());
            return;
        };
        let links = self.model.robot.links.iter().map(|l| l.name.clone()).collect();
        let file = CalibrationFile::new(&done.calibration, &self.robot_spec, links);
        self.error = file.write(path).err().map(|e| e.to_string());
    }

    /// Collects a calibration learned from a free-motion recording.
    pub(super) fn poll_calibrating_from(&mut self) {
        let Some(job) = &self.session.calibrating_from else {
            return;
        };
        let Some(done) = job.poll() else {
            return;
        };
        self.session.calibrating_from = None;
        match done {
            Ok(external) => {
                self.session.external_calibration = Some(Arc::new(external));
                self.error = None;
            }
            Err(e) => self.error = Some(e),
        }
    }

    /// Goes back to learning the calibration from the session itself.
    pub fn forget_external_calibration(&mut self) {
        self.session.external_calibration = None;
    }
}

impl ProprioscopeApp {
    /// The torque model of a session (σ learned, the calibration): its
    /// switches, where the calibration comes from, and per joint the
    /// residual before and after it and the σ learned.
    pub(super) fn torque_model_ui(&mut self, ui: &mut egui::Ui) -> Vec<Command> {
        let mut commands = Vec::new();
        if self.model.replay.is_none() || self.live.view.is_some() {
            return commands;
        }
        egui::CollapsingHeader::new("Torque model")
            .default_open(true)
            .show(ui, |ui| {
                let torques = self.model.config.torques;
                let mut sigma_auto = torques.sigma_auto;
                if ui
                    .checkbox(&mut sigma_auto, "σ learned from the session")
                    .on_hover_text(
                        "σ per joint from the frames surely free of contact, widened for how long the residual stays correlated (as estimate --sigma auto); moving σ by hand turns it off",
                    )
                    .changed()
                {
                    commands.push(Command::SetSigmaAuto(sigma_auto));
                }
                let mut calibrate = torques.calibrate;
                if ui
                    .checkbox(&mut calibrate, "take off the model error")
                    .on_hover_text(
                        "learn what the controller's dynamics model gets wrong (inertials, friction, offsets) and the observer's lag from the free stretches, and take it off every frame (as estimate --calibrate auto)",
                    )
                    .changed()
                {
                    commands.push(Command::SetCalibrate(calibrate));
                }
                self.calibration_source_ui(ui);
                if self.calibration_pending() || self.session.calibrating_from.is_some() {
                    ui.horizontal(|ui| {
                        ui.spinner();
                        ui.label("calibrating");
                    });
                }
                if let Some(why) = self.calibration_failure() {
                    ui.label(format!("not calibrated: {why}"));
                }
                if let Some(done) = self.session_calibration() {
                    calibration_table_ui(ui, &self.model.robot.sensed_names(), done, self.model.sigma());
                }
            });
        commands
    }

    /// Where the calibration comes from, and the buttons that change it.
    fn calibration_source_ui(&mut self, ui: &mut egui::Ui) {
        let source = self
            .session
            .external_calibration
            .as_ref()
            .map(|e| e.source.display().to_string());
        ui.label(match &source {
            Some(path) => format!("from {path}"),
            None => "learned from this session".to_owned(),
        });
        ui.horizontal_wrapped(|ui| {
            if ui
                .button("From free motion…")
                .on_hover_text("learn it from a recording of the arm moving with nothing touching it, and use it here")
                .clicked()
                && let Some(path) = self.picked(super::files::pick(|| {
                    rfd::FileDialog::new()
                        .add_filter("session or recording", &["json", "csv", "mcap", "bag"])
                        .pick_file()
                }))
            {
                self.calibrate_from(path);
            }
            if ui
                .button("Open…")
                .on_hover_text("a calibration file (as estimate --calibration)")
                .clicked()
                && let Some(path) = self.picked(super::files::pick(|| {
                    rfd::FileDialog::new().add_filter("calibration", &["json"]).pick_file()
                }))
            {
                self.open_calibration(path);
            }
            if self.session_calibration().is_some()
                && ui
                    .button("Save…")
                    .on_hover_text("write it as calibrate --out does")
                    .clicked()
                && let Some(path) = self.picked(super::files::pick(|| {
                    rfd::FileDialog::new()
                        .add_filter("calibration", &["json"])
                        .set_file_name("robot.calib.json")
                        .save_file()
                }))
            {
                self.save_calibration(&path);
            }
            if source.is_some() && ui.button("Learn from this session").clicked() {
                self.forget_external_calibration();
            }
        });
    }
}

/// The calibration's figures: the observer, and per joint the residual
/// before and after, the friction and the σ in use.
fn calibration_table_ui(ui: &mut egui::Ui, joints: &[&str], done: &SessionCalibration, sigma: &[f64]) {
    let c = &done.calibration;
    let gain = c
        .observer_gain_per_s
        .map_or_else(|| "no lag".to_owned(), |k| format!("observer gain {k} 1/s"));
    ui.label(format!(
        "{gain}; {} of {} frames free; {}",
        c.free_frames,
        c.frames_read,
        if c.found {
            if done.applied {
                "model error taken off"
            } else {
                "model error found, not taken off"
            }
        } else {
            "no model error beyond noise"
        }
    ));
    egui::Grid::new("calibration-table").striped(true).show(ui, |ui| {
        for head in ["joint", "RMS before", "after", "Coulomb", "σ in use"] {
            ui.label(head);
        }
        ui.end_row();
        for (j, name) in joints.iter().enumerate() {
            let cell = |v: Option<&f64>, digits: usize| v.map_or_else(|| "–".to_owned(), |v| format!("{v:.digits$}"));
            ui.label(*name);
            ui.label(cell(c.rms_before_nm.get(j), 3));
            ui.label(cell(c.rms_after_nm.get(j), 3));
            ui.label(cell(c.coulomb_nm.get(j), 2));
            ui.label(cell(sigma.get(j), 3));
            ui.end_row();
        }
    });
    ui.label("N·m; after: what the correction leaves, still lagged as the observer gives it");
}

impl ProprioscopeApp {
    /// One line on the timeline: the calibration being made, or what it did.
    pub(super) fn calibration_status_ui(&self, ui: &mut egui::Ui) {
        if self.calibration_pending() {
            ui.spinner();
            ui.label("calibrating");
        } else if let Some(done) = self.session_calibration()
            && done.calibration.found
        {
            let what = if done.applied {
                "model error taken off"
            } else {
                "model error found"
            };
            ui.label(match done.calibration.observer_gain_per_s {
                Some(k) => format!("{what} (observer {k} 1/s)"),
                None => what.to_owned(),
            })
            .on_hover_text("the estimator panel's Torque model shows it per joint");
        }
    }
}
