//! A session's torque bias in the app: estimated from the session (as
//! `estimate --bias auto`: each joint's mode over 30 s windows, with the
//! estimator's σ as the kernel), kept until the session or σ changes,
//! taken off the frame shown and every frame estimated in the background.

use std::sync::Arc;

use super::ProprioscopeApp;
use crate::core::bias::estimate_drifting_bias;

/// Window over which a drifting bias is estimated, s (as `--bias-window`).
pub const BIAS_WINDOW_SECS: f64 = 30.0;

/// What a session's bias was estimated from.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct BiasKey {
    session: usize,
    sigma: Vec<f64>,
}

/// Per frame and joint, N·m; or why it could not be estimated.
pub(super) type SessionBias = Result<Arc<Vec<Vec<f64>>>, String>;

impl ProprioscopeApp {
    /// Estimates the session's bias when it is asked for and not yet known
    /// for this session and σ; drops it when it is not asked for.
    pub(super) fn update_session_bias(&mut self) {
        let Some(replay) = self.model.replay.as_ref().filter(|r| r.bias_auto) else {
            self.session_bias = None;
            return;
        };
        let key = BiasKey {
            session: Arc::as_ptr(&replay.session) as usize,
            sigma: self.model.sigma.clone(),
        };
        if self.session_bias.as_ref().is_some_and(|(k, _)| *k == key) {
            return;
        }
        let frames = &replay.session.frames;
        let times: Vec<f64> = frames.iter().map(|f| f.t).collect();
        let taus: Vec<&[f64]> = frames.iter().map(|f| f.tau.as_slice()).collect();
        let bias = estimate_drifting_bias(&times, &taus, &self.model.sigma, BIAS_WINDOW_SECS)
            .map(Arc::new)
            .map_err(|e| e.to_string());
        if let Err(e) = &bias {
            self.error = Some(format!("the torque bias could not be estimated: {e}"));
        }
        self.session_bias = Some((key, bias));
    }

    /// The bias of session frame `frame`, when it is taken off.
    #[must_use]
    pub fn frame_bias(&self, frame: usize) -> Option<&[f64]> {
        let (_, bias) = self.session_bias.as_ref()?;
        bias.as_ref().ok()?.get(frame).map(Vec::as_slice)
    }

    /// The session's bias per frame, when it is taken off.
    #[must_use]
    pub fn session_bias(&self) -> Option<&Arc<Vec<Vec<f64>>>> {
        self.session_bias.as_ref()?.1.as_ref().ok()
    }
}
