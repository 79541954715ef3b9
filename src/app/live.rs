//! A live session in the app: frames arriving over TCP or UDP fill the
//! timeline, and the view follows the newest frame unless the user has
//! moved back (then it stays, and *Follow newest* catches up).
//!
//! While live, the frame shown is estimated alone (the view's own
//! estimate) and, unless the user chose *each frame alone*, every frame is
//! also filtered as it arrives, with the frames before it, on a thread of
//! its own (what `estimate --live` writes; smoothing needs the frames
//! after, so it waits for the stream to stop). Once stopped, the frames
//! are an ordinary session, estimated as a whole.

use std::sync::Arc;

use eframe::egui;

use super::{Command, ProprioscopeApp};
use crate::batch::SessionData;
use crate::core::config::estimator::{DEFAULT_SURFACE_POINTS, live_surface_points};
use crate::io::live::{LiveEvent, LiveSource};
use crate::io::session::Frame;

/// Live input's part: the source listened to, the thread filtering its
/// frames, and the address typed in the Session menu.
pub(crate) struct LivePart {
    /// A live source being listened to.
    pub(crate) view: Option<LiveView>,
    /// The thread filtering a live session's frames as they arrive
    /// (started on first use).
    pub(crate) filter: Option<crate::batch::LiveFilterWorker>,
    /// The address typed in the Session menu for listening.
    pub(crate) address_input: String,
}

/// What the user asked in the live row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum LiveAsk {
    /// Show the newest frame as it arrives.
    FollowNewest,
    /// Stop listening (the frames received stay a session).
    Stop,
}

impl LivePart {
    /// The live row: where from, how many frames, the last thing said,
    /// `filter_note` (what the filter is doing), follow and stop. Follow
    /// is set here; what else the user asked is returned.
    pub(crate) fn ui(&mut self, ui: &mut egui::Ui, filter_note: Option<String>) -> Option<LiveAsk> {
        let live = self.view.as_mut()?;
        let mut asked = None;
        ui.horizontal(|ui| {
            ui.colored_label(
                egui::Color32::from_rgb(220, 40, 40),
                egui::RichText::new("LIVE").strong(),
            );
            let dropped = live.source.dropped_frames();
            ui.label(format!(
                "{}: {} frames{}{}",
                live.source.address,
                live.received,
                if live.skipped > 0 {
                    format!(", {} lines skipped", live.skipped)
                } else {
                    String::new()
                },
                if dropped > 0 {
                    format!(", {dropped} dropped (the app fell behind the stream)")
                } else {
                    String::new()
                }
            ));
            ui.label(egui::RichText::new(&live.last_note).weak());
            if let Some(note) = filter_note {
                ui.label(note);
            }
            if live.follow {
                ui.label("following the newest frame");
            } else if ui.button("Follow newest").clicked() {
                live.follow = true;
                asked = Some(LiveAsk::FollowNewest);
            }
            if ui.button("Stop live").clicked() {
                asked = Some(LiveAsk::Stop);
            }
        });
        asked
    }
}

impl Default for LivePart {
    fn default() -> Self {
        Self {
            view: None,
            filter: None,
            address_input: "127.0.0.1:7878".to_owned(),
        }
    }
}

/// A live source and what the app knows of it.
pub struct LiveView {
    source: LiveSource,
    /// Show the newest frame as it arrives.
    pub follow: bool,
    /// Joint names of the current sender's header, when given.
    joints: Vec<String>,
    /// The current sender.
    pub sender: Option<String>,
    /// Frames received (all senders).
    pub received: usize,
    /// Lines and frames not used, with the last reason.
    pub skipped: usize,
    /// The last thing said about the stream.
    pub last_note: String,
    /// Frames of the current sender not yet installed.
    pending: Vec<Frame>,
    /// The next frames start a new session (a new sender).
    fresh: bool,
    /// Counts the sessions this source started (a new sender starts one):
    /// what the filtered estimates are keyed on while the session grows.
    pub(super) epoch: u64,
    /// Frames of the current session handed to the filter so far.
    pub(super) filtered_sent: usize,
}

impl LiveView {
    /// Frames from `sender` start a new session: nothing of the last
    /// sender's carries over.
    fn start_segment(&mut self, sender: String) {
        self.sender = Some(sender);
        self.joints.clear();
        self.pending.clear();
        self.fresh = true;
    }
}

impl ProprioscopeApp {
    /// Listens on `address` (`host:port`, `tcp://…` or `udp://…`) for a
    /// live session on the current robot.
    pub fn start_live(&mut self, address: &str) {
        let ctx = self.ctx.clone();
        match LiveSource::listen(address, move || ctx.request_repaint()) {
            Ok(source) => {
                let mut note = format!("listening on {}", source.address);
                // A live frame has to be done before the next: a surface
                // left at the default becomes the live one (as `estimate
                // --live`; two contacts keep a file's); the N slider
                // still sets it.
                let live_points = live_surface_points(self.model.config.contacts_at_once);
                if self.model.config.surface_points == DEFAULT_SURFACE_POINTS && live_points != DEFAULT_SURFACE_POINTS {
                    self.apply(Command::SetSurfacePoints(live_points));
                    note = format!("{note}; {live_points} surface points, so that each frame keeps up live");
                }
                self.live.view = Some(LiveView {
                    source,
                    follow: true,
                    joints: Vec::new(),
                    sender: None,
                    received: 0,
                    skipped: 0,
                    last_note: note,
                    pending: Vec::new(),
                    fresh: true,
                    epoch: 0,
                    filtered_sent: 0,
                });
                self.live.filter = None;
            }
            Err(e) => self.error = Some(format!("could not listen: {e}")),
        }
    }

    /// Stops listening; the frames received stay as a session.
    pub fn stop_live(&mut self) {
        self.live.view = None;
        // Its thread ends with the handle; the frames are estimated anew.
        self.live.filter = None;
        // Estimated as a whole from now on.
        self.session.key = None;
    }

    /// The address listened on, while live.
    #[must_use]
    pub fn live_address(&self) -> Option<&str> {
        self.live.view.as_ref().map(|l| l.source.address.as_str())
    }

    /// Takes what the live source sent since the last frame.
    pub(super) fn poll_live(&mut self) {
        let Some(live) = self.live.view.as_mut() else {
            return;
        };
        let width = self.model.robot.sensed().len();
        while let Ok(event) = live.source.events.try_recv() {
            match event {
                LiveEvent::Connected(from) => {
                    live.last_note = format!("{from}: connected");
                    live.start_segment(from);
                }
                LiveEvent::NewSender { from, previous } => {
                    live.last_note = format!("{from}: a new sender after {previous} went quiet: a new stream segment");
                    live.start_segment(from);
                }
                LiveEvent::Header { joints, .. } => live.joints = joints,
                LiveEvent::Frame(frame) if frame.q.len() == width && frame.tau.len() == width => {
                    live.received += 1;
                    live.pending.push(frame);
                }
                LiveEvent::Frame(frame) => {
                    live.skipped += 1;
                    live.last_note = format!(
                        "frame at t = {} skipped: {} joint values, the robot senses {width}",
                        frame.t,
                        frame.q.len()
                    );
                }
                LiveEvent::Bad(why) => {
                    live.skipped += 1;
                    live.last_note = why;
                }
                LiveEvent::Closed(why) => live.last_note = why,
                LiveEvent::Gap { from_t, to_t } => {
                    live.last_note = format!("no frame from t = {from_t:.3} to {to_t:.3} s");
                }
            }
        }
        if live.pending.is_empty() {
            return;
        }
        let frames = std::mem::take(&mut live.pending);
        let fresh = std::mem::replace(&mut live.fresh, false) || self.model.replay.is_none();
        let name = format!("live {}", live.source.address);
        let joints = live.joints.clone();
        if fresh {
            live.epoch += 1;
            live.filtered_sent = 0;
            let mut robot = (*self.model.robot).clone();
            if !joints.is_empty()
                && let Err(e) = robot.set_sensed(&joints)
            {
                self.error = Some(format!("{name}: the header's joints: {e}"));
                return;
            }
            let data = SessionData {
                path: name.into(),
                file_frames: (0..frames.len()).collect(),
                frames,
                problems: Vec::new(),
            };
            let spec = self.robot_spec.clone();
            self.session.first_frame = Some(data.frames.len().saturating_sub(1));
            self.install_session(data, robot, spec);
            // Live, only the frames before can be used (as `estimate
            // --live`): filtered, unless the user picks each frame alone.
            if let Some(replay) = self.model.replay.as_mut() {
                replay.over_time = crate::core::over_time::sequence::Temporal::Filter;
            }
            return;
        }
        let Some(replay) = self.model.replay.as_mut() else {
            return;
        };
        let shown_last = replay.frame + 1 >= replay.session.frames.len();
        // Usually nothing else holds the live session, so the frames are
        // appended in place (else the session is copied once; its
        // filtered estimates are keyed on the live epoch, not the copy).
        let data = Arc::make_mut(&mut replay.session);
        let start = data.frames.len();
        data.file_frames.extend(start..start + frames.len());
        data.frames.extend(frames);
        let last = data.frames.len().saturating_sub(1);
        if let Some(live) = self.live.view.as_mut() {
            // Moving back from the newest frame stops following.
            live.follow &= shown_last;
            if live.follow {
                self.apply(Command::SetFrame(last));
            }
        }
    }

    /// How far the live filter has got, while frames are estimated over time.
    fn live_filter_note(&self) -> Option<String> {
        use crate::core::over_time::sequence::Temporal;
        let replay = self.model.replay.as_ref()?;
        let pending = replay
            .session
            .frames
            .len()
            .saturating_sub(self.session.done + self.session.failures.len());
        let what = match replay.over_time {
            Temporal::None => return None,
            Temporal::Filter => "filtered as they arrive",
            Temporal::Smooth => "filtered as they arrive, smoothed once stopped",
        };
        Some(if pending > 0 {
            format!("{what} ({pending} to go)")
        } else {
            what.to_owned()
        })
    }

    /// The live row above the timeline (see [`LivePart::ui`]), and what
    /// the user asked there applied.
    pub(super) fn live_ui(&mut self, ui: &mut egui::Ui) {
        let note = self.live_filter_note();
        match self.live.ui(ui, note) {
            Some(LiveAsk::FollowNewest) => {
                let last = self
                    .model
                    .replay
                    .as_ref()
                    .map_or(0, |r| r.session.frames.len().saturating_sub(1));
                self.apply(Command::SetFrame(last));
            }
            Some(LiveAsk::Stop) => self.stop_live(),
            None => {}
        }
    }
}
