//! A session's torques under a calibration: learning it, taking the model
//! error off every frame and the σ that is left. Shared by `estimate`,
//! `calibrate` and the app's calibration step.

use anyhow::{Context as _, Result};

use crate::core::config::limits;
use crate::core::over_time::calibration::{Calibration, CalibrationSettings, calibrate};
use crate::core::over_time::observer::typical_step_secs;
use crate::core::robot::dynamics::RigidBodies;
use crate::core::robot::model::Robot;
use std::path::Path;

use crate::io::session::Frame;

/// Learns the calibration of `torques` (the session's frames', or what was made of
/// them: less the bias).
pub fn learn(
    robot: &Robot,
    (path, frames): (&Path, &[Frame]),
    torques: &[Vec<f64>],
    settings: &CalibrationSettings,
) -> Result<Calibration> {
    let times: Vec<f64> = frames.iter().map(|f| f.t).collect();
    let positions: Vec<Vec<f64>> = frames.iter().map(|f| f.q.clone()).collect();
    let names = robot.sensed_names().iter().map(|s| (*s).to_owned()).collect();
    calibrate(&RigidBodies::new(robot), names, &times, &positions, torques, settings)
        .with_context(|| format!("calibrating {}", path.display()))
}

/// `torques` (one vector per frame of the session at `path`) less the model error
/// that `calibration` predicts, with the observer's lag taken off.
pub fn corrected(
    robot: &Robot,
    (path, frames): (&Path, &[Frame]),
    calibration: &Calibration,
    torques: &[Vec<f64>],
) -> Result<Vec<Vec<f64>>> {
    let times: Vec<f64> = frames.iter().map(|f| f.t).collect();
    let positions: Vec<Vec<f64>> = frames.iter().map(|f| f.q.clone()).collect();
    calibration
        .corrected(&RigidBodies::new(robot), &times, &positions, torques)
        .with_context(|| format!("applying the calibration to {}", path.display()))
}

/// The σ per joint that `calibration` leaves on the `frames`' torques,
/// N·m, within the valid range: what is left after the correction when
/// it is `applied`, else the residual as it was; widened for its
/// correlation when frames are combined `over_time`.
#[must_use]
pub fn learned_sigma(calibration: &Calibration, frames: &[Frame], applied: bool, over_time: bool) -> Vec<f64> {
    let left = if applied {
        calibration.clone()
    } else {
        Calibration {
            sigma_nm: calibration.rms_before_nm.clone(),
            ..calibration.clone()
        }
    };
    let times: Vec<f64> = frames.iter().map(|f| f.t).collect();
    let learned = if over_time {
        left.sigma_over_time(1.0 / typical_step_secs(&times))
    } else {
        left.sigma_nm.clone()
    };
    learned
        .iter()
        .map(|s| s.clamp(limits::SIGMA.min, limits::SIGMA.max))
        .collect()
}
