//! A session's torque bias in the app: estimated from the session (as
//! `estimate --bias auto`: each joint's mode over 30 s windows, with the
//! estimator's σ as the kernel) on a thread of its own (a second or more
//! on a long recording), kept until the session or σ changes, taken off
//! the frame shown and every frame estimated in the background.

use std::sync::Arc;

use super::{ProprioscopeApp, worker};
use crate::core::over_time::bias::estimate_drifting_bias;

/// Window over which a drifting bias is estimated, s (as `--bias-window`).
pub const BIAS_WINDOW_SECS: f64 = 30.0;

/// What a session's bias was estimated from.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct BiasKey {
    session: usize,
    sigma: Vec<f64>,
}

/// Per frame and joint, N·m; or why it could not be estimated.
pub(super) type SessionBias = Result<Arc<Vec<Vec<f64>>>, String>;

/// A session's bias: being estimated, or known.
pub(crate) enum BiasState {
    /// On its thread.
    Pending(worker::Background<Arc<Vec<Vec<f64>>>>),
    /// Done.
    Done(SessionBias),
}

impl ProprioscopeApp {
    /// Starts estimating the session's bias when it is asked for and not
    /// yet known (or being estimated) for this session and σ, collects it
    /// when it is done (and then estimates the frame shown again), and
    /// drops it when it is not asked for.
    pub(super) fn update_session_bias(&mut self) {
        let Some(replay) = self.model.replay.as_ref().filter(|r| r.bias_auto) else {
            self.session.bias = None;
            return;
        };
        let key = BiasKey {
            session: Arc::as_ptr(&replay.session) as usize,
            sigma: self.model.set_sigma().to_vec(),
        };
        match &self.session.bias {
            Some((k, BiasState::Done(_))) if *k == key => {}
            Some((k, BiasState::Pending(job))) if *k == key => {
                let Some(done) = job.poll() else {
                    return;
                };
                if let Err(e) = &done {
                    self.error = Some(format!("the torque bias could not be estimated: {e}"));
                }
                self.session.bias = Some((key, BiasState::Done(done)));
                self.request_estimate();
            }
            _ => {
                let session = replay.session.clone();
                let sigma = self.model.set_sigma().to_vec();
                let ctx = self.ctx.clone();
                let job = worker::Background::spawn(
                    "the torque bias".to_owned(),
                    move || {
                        let times: Vec<f64> = session.frames.iter().map(|f| f.t).collect();
                        let taus: Vec<&[f64]> = session.frames.iter().map(|f| f.tau.as_slice()).collect();
                        estimate_drifting_bias(&times, &taus, &sigma, BIAS_WINDOW_SECS)
                            .map(Arc::new)
                            .map_err(|e| e.to_string())
                    },
                    move || ctx.request_repaint(),
                );
                self.session.bias = Some((key, BiasState::Pending(job)));
            }
        }
    }

    /// Whether the bias is asked for and still being estimated.
    #[must_use]
    pub fn bias_pending(&self) -> bool {
        matches!(self.session.bias, Some((_, BiasState::Pending(_))))
    }

    /// The bias of session frame `frame`, when it is taken off.
    #[must_use]
    pub fn frame_bias(&self, frame: usize) -> Option<&[f64]> {
        self.session_bias()?.get(frame).map(Vec::as_slice)
    }

    /// The session's bias per frame, when it is taken off (and known).
    #[must_use]
    pub fn session_bias(&self) -> Option<&Arc<Vec<Vec<f64>>>> {
        match &self.session.bias {
            Some((_, BiasState::Done(Ok(bias)))) => Some(bias),
            _ => None,
        }
    }
}
