//! Recording the interactive mode as a session, a frame at a fixed rate.

use std::path::Path;
use std::time::Instant;

use super::{Model, ProprioscopeApp, egui};
use crate::io::session::{ContactTruth, Frame, Recorder, Truth};

/// The first and second push.
type Pushes = (Option<super::Push>, Option<super::Push>);

/// While recording, a frame at least this often even when nothing moves.
pub const RECORD_RATE_HZ: f64 = 10.0;

/// A recording under way.
pub(crate) struct Recording {
    pub(super) recorder: Recorder,
    pub(super) started: Instant,
    /// What the last frame showed, and when it was written.
    pub(super) last: Option<(Vec<f64>, Pushes, Instant)>,
}

impl ProprioscopeApp {
    /// Starts recording the interactive mode into `path` (JSON).
    pub fn start_recording(&mut self, path: &Path) {
        let joints: Vec<String> = self
            .model
            .robot
            .sensed()
            .iter()
            .map(|&j| self.model.robot.joints[j].name.clone())
            .collect();
        // A URDF is named by its absolute path: the recording may live anywhere.
        let robot = if crate::io::builtin::is_builtin(&self.robot_spec) {
            self.robot_spec.clone()
        } else {
            std::fs::canonicalize(&self.robot_spec)
                .map_or_else(|_| self.robot_spec.clone(), |p| p.display().to_string())
        };
        match Recorder::create(path, &robot, &joints) {
            Ok(recorder) => {
                self.files.recording = Some(Recording {
                    recorder,
                    started: Instant::now(),
                    last: None,
                });
                self.error = None;
            }
            Err(e) => self.error = Some(e.to_string()),
        }
    }

    /// Stops recording and closes the file; the frames written.
    pub fn stop_recording(&mut self) -> Option<usize> {
        let recording = self.files.recording.take()?;
        match recording.recorder.finish() {
            Ok(frames) => Some(frames),
            Err(e) => {
                self.error = Some(e.to_string());
                None
            }
        }
    }

    /// Frames recorded so far, when recording.
    #[must_use]
    pub fn recorded_frames(&self) -> Option<usize> {
        self.files.recording.as_ref().map(|r| r.recorder.frames())
    }

    /// Writes a frame when the pose or push changed, or at the steady rate.
    pub(super) fn record_tick(&mut self, ctx: &egui::Context) {
        let Some(recording) = &mut self.files.recording else {
            return;
        };
        let model = &self.model;
        let now = Instant::now();
        let due = recording.last.as_ref().is_none_or(|(q, push, at)| {
            *q != model.q
                || *push != (model.push, model.second_push)
                || now.duration_since(*at).as_secs_f64() >= 1.0 / RECORD_RATE_HZ
        });
        ctx.request_repaint_after(std::time::Duration::from_secs_f64(1.0 / RECORD_RATE_HZ));
        if !due {
            return;
        }
        let frame = interactive_frame(model, now.duration_since(recording.started).as_secs_f64());
        if let Err(e) = recording.recorder.write(&frame) {
            self.error = Some(e.to_string());
            self.files.recording = None;
            return;
        }
        recording.last = Some((model.q.clone(), (model.push, model.second_push), now));
    }
}

/// The frame the recorder writes for the interactive mode at time `t`.
#[must_use]
pub fn interactive_frame(model: &Model, t: f64) -> Frame {
    let pose = model.pose();
    Frame {
        t,
        q: model.q.clone(),
        tau: model.measured_torques(&pose),
        truth: match model.push_world(&pose) {
            Some((link, point, force)) => Truth::Contact {
                link: model.robot.links[link].name.clone(),
                point: point.to_array(),
                force: force.to_array(),
            },
            None => Truth::NoContact,
        },
        // Both pushes where there are two (`truth` keeps the first).
        truth_all: match model.second_push_world(&pose) {
            Some(second) => model
                .push_world(&pose)
                .into_iter()
                .chain(Some(second))
                .map(|(link, point, force)| ContactTruth {
                    link: model.robot.links.get(link).map(|l| l.name.clone()).unwrap_or_default(),
                    point: point.to_array(),
                    force: force.to_array(),
                })
                .collect(),
            None => Vec::new(),
        },
    }
}
