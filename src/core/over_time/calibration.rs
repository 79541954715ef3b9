//! The model error of a real arm's torques, learned from a recording.
//!
//! Without contact a momentum observer's residual is a lag
//! ([`crate::core::over_time::observer`]) of what the controller's model
//! gets wrong, and that error follows the motion:
//! `e = Y(q, q̇, q̈) δπ − F_c tanh(q̇ / v_s) − F_v q̇ + b`, with `Y` the
//! dynamics regressor over the base inertial parameters
//! ([`RigidBodies::base_columns`]), `δπ` their error, `F_c` and `F_v`
//! each joint's Coulomb and viscous friction (seen only where the torque
//! is sensed on the motor side) and `b` an offset per joint.
//!
//! The fit is least squares of the lagged columns against the residual
//! over the frames that are surely free, with Huber weights on each
//! frame's χ² and a ridge of 10⁻⁶ of each column's own information. Free
//! frames are found by alternating: the quietest 30 % of frames start it
//! (10 % where the readings show presses in most frames);
//! then a frame is free when its corrected residual's χ² over the joints
//! is below the 99.9 % point of a χ² (no contact explains it), and it is
//! not within 1/K before or 5/K after a frame that is not (the lag's
//! tail). The observer gain K is the one of a grid that fits best, or
//! given. A fit that does not cut the residual's variance by 10 % and by
//! three times what its columns would take from pure noise finds
//! nothing: its corrections are zero.
//!
//! What is left is described per joint by its RMS `σ` and its correlation
//! time: at 1 kHz a residual correlated over 20 ms is about 40 frames'
//! worth of one vote, and [`Calibration::sigma_over_time`] widens σ by the
//! square root of that count so that the filter and the smoother do not
//! take a thousand correlated frames for a thousand independent ones.

use rayon::prelude::*;

use crate::core::numerics::linalg::{LinalgError, solve_spd};
use crate::core::over_time::observer::{Unlag, differentiate, frame_steps, typical_step_secs};
use crate::core::robot::dynamics::{DynamicsError, RigidBodies};

/// Observer gains tried when the gain is not given, 1/s.
pub const OBSERVER_GAINS_PER_S: [f64; 13] = [
    5.0, 10.0, 15.0, 20.0, 30.0, 40.0, 50.0, 70.0, 100.0, 150.0, 200.0, 300.0, 500.0,
];

/// The joint speed at which the smooth Coulomb term reaches 76 % of its
/// value (`tanh(1)`) unless the fit finds another, rad/s.
pub const STICTION_SPEED_RAD_S: f64 = 0.01;

/// How long before and after its Coulomb term switches sign a joint's
/// friction counts as sticking when the calibration is applied, s.
pub const STICK_WINDOW_SECS: f64 = 0.03;

/// The share of a joint's squared residual that a Coulomb shape other
/// than the plain one (no lead, [`STICTION_SPEED_RAD_S`]) must take off
/// to be chosen.
const SHAPE_GAIN: f64 = 0.1;

/// Speeds tried for each joint's Coulomb transition, rad/s.
pub const COULOMB_SPEEDS_RAD_S: [f64; 4] = [0.003, 0.01, 0.03, 0.1];

/// Leads tried for each joint's Coulomb switch, s: the Coulomb term
/// follows the sign of `q̇ + lead·q̈`, the speed `lead` seconds ahead.
/// A joint whose friction sticks turns round when its net drive does,
/// which comes before its velocity turns (the more, the lighter the
/// link it moves); without a lead the residual steps by twice the
/// Coulomb value at every reversal until the velocity catches up.
pub const COULOMB_LEADS_SECS: [f64; 7] = [0.0, 0.01, 0.02, 0.04, 0.08, 0.16, 0.32];

/// The Coulomb column as the residual sees it (friction acts against
/// the motion): `−tanh((q̇ + lead·q̈) / speed)`.
#[must_use]
pub fn coulomb_shape(speed_rad_s: f64, acceleration_rad_s2: f64, lead_secs: f64, switch_rad_s: f64) -> f64 {
    -((speed_rad_s + lead_secs * acceleration_rad_s2) / switch_rad_s).tanh()
}

/// Most frames a fit reads (from the recording's start); the correction
/// then applies to every frame.
pub const MAX_FIT_FRAMES: usize = 60_000;

/// Below this RMS joint speed the arm is held, not moving, rad/s: a held
/// arm's model error is a constant that a long press would look like.
pub const MIN_RMS_SPEED_RAD_S: f64 = 0.02;

/// The fewest free frames a fit needs.
pub const MIN_FREE_FRAMES: usize = 50;

/// How the observer's gain is known.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ObserverGain {
    /// Estimated from the recording (the best fit of a grid, or no lag).
    Auto,
    /// Given, 1/s.
    PerSecond(f64),
    /// The torques carry no lag (a sensor read directly).
    Without,
}

/// What a calibration fits.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CalibrationSettings {
    /// The observer's gain.
    pub observer_gain: ObserverGain,
    /// Fit corrections to the base inertial parameters (where the robot
    /// has inertials).
    pub inertial: bool,
    /// Fit each joint's Coulomb and viscous friction.
    pub friction: bool,
    /// Every frame is free motion (a recording made to calibrate): no
    /// gate, every frame fits.
    pub free_motion: bool,
}

impl Default for CalibrationSettings {
    fn default() -> Self {
        Self {
            observer_gain: ObserverGain::Auto,
            inertial: true,
            friction: true,
            free_motion: false,
        }
    }
}

/// Why a calibration could not be made or applied.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalibrationError {
    /// Too few frames.
    #[error("calibrating needs at least {needed} frames, got {frames}")]
    TooFewFrames {
        /// Frames given.
        frames: usize,
        /// Frames needed.
        needed: usize,
    },
    /// Too few frames without contact.
    #[error("only {free} of {frames} frames look free of contact ({needed} needed): record a stretch of free motion")]
    TooFewFree {
        /// Free frames found.
        free: usize,
        /// Frames read.
        frames: usize,
        /// Free frames needed.
        needed: usize,
    },
    /// The arm barely moves: nothing that depends on the motion can be
    /// told from a contact held as long.
    #[error(
        "the arm barely moves (RMS joint speed {rms_speed_rad_s:.4} rad/s, below {MIN_RMS_SPEED_RAD_S} rad/s): there is no motion to learn the model error from"
    )]
    NoMotion {
        /// The recording's RMS joint speed, rad/s.
        rms_speed_rad_s: f64,
    },
    /// A frame's vectors have the wrong length.
    #[error("frame {frame}: {got} values for {expected} joints")]
    WrongLength {
        /// Frame number (0-based).
        frame: usize,
        /// Values in it.
        got: usize,
        /// Sensed joints.
        expected: usize,
    },
    /// Time goes backwards or is not finite.
    #[error("frame {frame}: time {t_secs} s is before the previous frame's or not finite")]
    BadTime {
        /// Frame number (0-based).
        frame: usize,
        /// Its time, s.
        t_secs: f64,
    },
    /// The calibration is for another robot's joints.
    #[error("the calibration is for joints {calibrated}, the robot has {robot}")]
    OtherJoints {
        /// The calibration's joints.
        calibrated: String,
        /// The robot's sensed joints.
        robot: String,
    },
    /// A given gain is not a positive finite number.
    #[error("observer gain {value} 1/s: must be a finite number > 0")]
    BadGain {
        /// The value given.
        value: f64,
    },
    /// The dynamics could not be evaluated.
    #[error(transparent)]
    Dynamics(#[from] DynamicsError),
    /// The fit's normal equations could not be solved.
    #[error("the calibration fit failed: {0}")]
    Solve(#[from] LinalgError),
}

/// What was learned of a robot's torques: the corrections, and the noise left.
#[derive(Debug, Clone, PartialEq)]
pub struct Calibration {
    /// The sensed joints it is for, in order.
    pub joints: Vec<String>,
    /// The observer's gain, 1/s (`None`: no lag).
    pub observer_gain_per_s: Option<f64>,
    /// Corrections `δπ` to every link's ten inertial parameters (the
    /// model's minus the arm's, in the base columns; empty when none
    /// were fitted).
    pub inertial_corrections: Vec<f64>,
    /// Each joint's Coulomb friction, N·m.
    pub coulomb_nm: Vec<f64>,
    /// Each joint's Coulomb lead ([`COULOMB_LEADS_SECS`]), s.
    pub coulomb_lead_secs: Vec<f64>,
    /// Each joint's Coulomb transition speed ([`COULOMB_SPEEDS_RAD_S`]), rad/s.
    pub coulomb_switch_rad_s: Vec<f64>,
    /// Each joint's viscous friction, N·m·s/rad.
    pub viscous_nms_per_rad: Vec<f64>,
    /// Each joint's constant offset, N·m.
    pub offset_nm: Vec<f64>,
    /// Each joint's residual RMS left on free frames, with the observer's
    /// lag taken off (what the estimator's σ is made of), N·m.
    pub sigma_nm: Vec<f64>,
    /// Each joint's residual RMS left on free frames, as the observer
    /// gives it (lagged: comparable with `rms_before_nm`), N·m.
    pub rms_after_nm: Vec<f64>,
    /// Each joint's residual correlation time (integrated), s.
    pub correlation_secs: Vec<f64>,
    /// Each joint's free-frame RMS before the correction, N·m.
    pub rms_before_nm: Vec<f64>,
    /// Frames the fit read, and how many of them were free.
    pub frames_read: usize,
    /// Free frames among them.
    pub free_frames: usize,
    /// True when the fit cut the residual by more than noise would: the
    /// corrections are then applied; otherwise they are zero.
    pub found: bool,
}

/// Per frame, one value per joint.
type PerFrame = Vec<Vec<f64>>;

impl Calibration {
    /// The correction that does nothing, with `sigma_nm` for every joint.
    #[must_use]
    pub fn none(joints: Vec<String>, sigma_nm: Vec<f64>) -> Self {
        let n = joints.len();
        Self {
            joints,
            observer_gain_per_s: None,
            inertial_corrections: Vec::new(),
            coulomb_nm: vec![0.0; n],
            coulomb_lead_secs: vec![0.0; n],
            coulomb_switch_rad_s: vec![STICTION_SPEED_RAD_S; n],
            viscous_nms_per_rad: vec![0.0; n],
            offset_nm: vec![0.0; n],
            correlation_secs: vec![0.0; n],
            rms_before_nm: sigma_nm.clone(),
            rms_after_nm: sigma_nm.clone(),
            sigma_nm,
            frames_read: 0,
            free_frames: 0,
            found: false,
        }
    }

    /// σ per joint for frames combined over time at `rate_hz`: the
    /// residual's σ widened by the square root of how many frames its
    /// correlation spans (at least 1).
    #[must_use]
    pub fn sigma_over_time(&self, rate_hz: f64) -> Vec<f64> {
        self.sigma_nm
            .iter()
            .zip(&self.correlation_secs)
            .map(|(s, c)| s * (c * rate_hz).max(1.0).sqrt())
            .collect()
    }

    /// Every frame's torques with the observer's lag taken off, less the
    /// model error this calibration predicts. `positions` are the sensed
    /// joints' (the robot's `q`).
    pub fn corrected(
        &self,
        bodies: &RigidBodies,
        times_secs: &[f64],
        positions: &[Vec<f64>],
        torques: &[Vec<f64>],
    ) -> Result<Vec<Vec<f64>>, CalibrationError> {
        let n = bodies.dof();
        if self.joints.len() != n {
            return Err(CalibrationError::OtherJoints {
                calibrated: self.joints.join(", "),
                robot: n.to_string(),
            });
        }
        check_frames(times_secs, positions, torques, n)?;
        if !self.found {
            return Ok(torques.to_vec());
        }
        let (model_error, coulomb) = self.model_error(bodies, times_secs, positions)?;
        let sticking = self.sticking(times_secs, positions);
        let unlagged = unlag_all(self.observer_gain_per_s, times_secs, torques);
        Ok(unlagged
            .into_iter()
            .zip(model_error)
            .zip(coulomb)
            .zip(sticking)
            .map(|(((t, e), c), stick)| {
                (0..n)
                    .map(|j| {
                        if stick[j] {
                            // Sticking, the friction is whatever the rest
                            // leaves, up to its Coulomb value.
                            let rest = t[j] - (e[j] - c[j]);
                            let bound = self.coulomb_nm[j].abs();
                            rest - rest.clamp(-bound, bound)
                        } else {
                            t[j] - e[j]
                        }
                    })
                    .collect()
            })
            .collect())
    }

    /// Per frame and joint: whether the Coulomb term is within
    /// [`STICK_WINDOW_SECS`] of switching sign, where its timing is least
    /// sure and the friction may hold any value within its bound.
    fn sticking(&self, times_secs: &[f64], positions: &[Vec<f64>]) -> Vec<Vec<bool>> {
        let n = self.joints.len();
        let (velocities, accelerations) = differentiate(times_secs, positions);
        let mut out = vec![vec![false; n]; positions.len()];
        for j in 0..n {
            let lead = self.coulomb_lead_secs.get(j).copied().unwrap_or(0.0);
            let argument: Vec<f64> = velocities
                .iter()
                .zip(&accelerations)
                .map(|(v, a)| v[j] + lead * a[j])
                .collect();
            let switches: Vec<f64> = (1..argument.len())
                .filter(|&k| (argument[k] > 0.0) != (argument[k - 1] > 0.0))
                .map(|k| 0.5 * (times_secs[k] + times_secs[k - 1]))
                .collect();
            let mut next = 0;
            for (k, t) in times_secs.iter().enumerate() {
                while next < switches.len() && switches[next] < t - STICK_WINDOW_SECS {
                    next += 1;
                }
                if next < switches.len() && switches[next] <= t + STICK_WINDOW_SECS {
                    out[k][j] = true;
                }
            }
        }
        out
    }

    /// The model error at every frame, before the observer's lag.
    fn model_error(
        &self,
        bodies: &RigidBodies,
        times_secs: &[f64],
        positions: &[Vec<f64>],
    ) -> Result<(PerFrame, PerFrame), CalibrationError> {
        let n = bodies.dof();
        let (velocities, accelerations) = differentiate(times_secs, positions);
        let mut coulomb_parts = Vec::with_capacity(positions.len());
        let corrected_model = if self.inertial_corrections.is_empty() {
            None
        } else {
            Some(bodies.clone().with_parameters(&self.inertial_corrections)?)
        };
        let mut out = Vec::with_capacity(positions.len());
        for k in 0..positions.len() {
            let mut error = match &corrected_model {
                // `Y δπ`: inverse dynamics of a model whose parameters are
                // the corrections (it is linear in them).
                Some(model) => model.inverse_dynamics(&positions[k], &velocities[k], &accelerations[k])?,
                None => vec![0.0; n],
            };
            let mut coulomb = vec![0.0; n];
            for j in 0..n {
                let (v, a) = (velocities[k][j], accelerations[k][j]);
                let lead = self.coulomb_lead_secs.get(j).copied().unwrap_or(0.0);
                let switch = self
                    .coulomb_switch_rad_s
                    .get(j)
                    .copied()
                    .unwrap_or(STICTION_SPEED_RAD_S);
                coulomb[j] = self.coulomb_nm[j] * coulomb_shape(v, a, lead, switch);
                error[j] += coulomb[j] - self.viscous_nms_per_rad[j] * v + self.offset_nm[j];
            }
            out.push(error);
            coulomb_parts.push(coulomb);
        }
        Ok((out, coulomb_parts))
    }
}

/// Every frame of `lagged` with the lag of `gain` taken off, restarting
/// after gaps.
fn unlag_all(gain: Option<f64>, times_secs: &[f64], lagged: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let mut unlag = Unlag::new(gain);
    frame_steps(times_secs)
        .into_iter()
        .zip(lagged)
        .map(|((dt, restart), y)| {
            if restart {
                unlag.reset();
            }
            unlag.step(dt, y)
        })
        .collect()
}

fn check_frames(
    times_secs: &[f64],
    positions: &[Vec<f64>],
    torques: &[Vec<f64>],
    joints: usize,
) -> Result<(), CalibrationError> {
    for (k, ((t, q), tau)) in times_secs.iter().zip(positions).zip(torques).enumerate() {
        for values in [q, tau] {
            if values.len() != joints {
                return Err(CalibrationError::WrongLength {
                    frame: k,
                    got: values.len(),
                    expected: joints,
                });
            }
        }
        if !t.is_finite() || (k > 0 && *t < times_secs[k - 1]) {
            return Err(CalibrationError::BadTime { frame: k, t_secs: *t });
        }
    }
    if positions.len() != times_secs.len() || torques.len() != times_secs.len() {
        return Err(CalibrationError::WrongLength {
            frame: positions.len().min(torques.len()),
            got: 0,
            expected: joints,
        });
    }
    Ok(())
}

/// A fit at one gain: the coefficients, and each frame's residual.
struct Fit {
    gain: Option<f64>,
    coefficients: Vec<f64>,
    residuals: Vec<Vec<f64>>,
    /// Each joint's weighted squared residual on the free frames.
    joint_sse: Vec<f64>,
    /// The coefficients' covariance (the inverse of the normal matrix
    /// with the prior), row-major.
    covariance: Vec<f64>,
}

/// Fits the columns at `gain` over the `free` frames with `weights`.
fn fit_at(
    design: &Design,
    times_secs: &[f64],
    torques: &[Vec<f64>],
    free: &[bool],
    weights: &[f64],
    sigma: &[f64],
    gain: Option<f64>,
) -> Result<Fit, CalibrationError> {
    let step = typical_step_secs(times_secs);
    let (p, n) = (design.columns, design.joints);
    let mut normal = vec![0.0; p * p];
    let mut rhs = vec![0.0; p];
    // Neighbouring frames of a long 1 kHz recording carry nearly the same
    // lagged columns: beyond 20,000 frames, every few frames make one row.
    let stride = design.lagged_frames(times_secs).div_ceil(20_000).max(1);
    design.for_each_lagged(times_secs, gain, |k, row| {
        if k % stride != 0 || !free.get(k).copied().unwrap_or(false) {
            return;
        }
        let (Some(&weight), Some(tau)) = (weights.get(k), torques.get(k)) else {
            return;
        };
        for j in 0..n {
            let w = weight / (sigma[j] * sigma[j]);
            let a = &row[j * p..(j + 1) * p];
            let r = tau[j];
            for (c1, &x1) in a.iter().enumerate() {
                if x1 == 0.0 {
                    continue;
                }
                rhs[c1] += w * x1 * r;
                for (c2, &x2) in a.iter().enumerate().skip(c1) {
                    normal[c1 * p + c2] += w * x1 * x2;
                }
            }
        }
    });
    // Rows within one correlation time of the lag are one vote, not many.
    let correlated = gain.map_or(1.0, |k| {
        let pole = (1.0 - k * step).clamp(0.0, 1.0 - 1e-9);
        ((1.0 + pole) / (1.0 - pole) / stride as f64).max(1.0)
    });
    for c1 in 0..p {
        rhs[c1] /= correlated;
        for c2 in c1..p {
            normal[c1 * p + c2] /= correlated;
        }
    }
    for c1 in 0..p {
        for c2 in 0..c1 {
            normal[c1 * p + c2] = normal[c2 * p + c1];
        }
        normal[c1 * p + c1] += 1.0 / (design.prior_sd[c1] * design.prior_sd[c1]);
    }
    let coefficients = solve_spd(&normal, &rhs)?;
    let mut covariance = vec![0.0; p * p];
    let mut unit = vec![0.0; p];
    for c in 0..p {
        unit.iter_mut()
            .enumerate()
            .for_each(|(i, u)| *u = f64::from(u8::from(i == c)));
        for (i, v) in solve_spd(&normal, &unit)?.into_iter().enumerate() {
            covariance[i * p + c] = v;
        }
    }
    let mut per_joint = vec![0.0; n];
    let mut residuals: Vec<Vec<f64>> = Vec::with_capacity(torques.len());
    design.for_each_lagged(times_secs, gain, |k, row| {
        let Some(tau) = torques.get(k) else {
            return;
        };
        let counted = free.get(k).copied().unwrap_or(false) && k % stride == 0;
        let weight = weights.get(k).copied().unwrap_or(0.0);
        residuals.push(
            (0..n)
                .map(|j| {
                    let a = &row[j * p..(j + 1) * p];
                    let e = tau[j] - a.iter().zip(&coefficients).map(|(x, c)| x * c).sum::<f64>();
                    if counted {
                        per_joint[j] += weight * e * e;
                    }
                    e
                })
                .collect(),
        );
    });
    Ok(Fit {
        gain,
        coefficients,
        residuals,
        joint_sse: per_joint,
        covariance,
    })
}

/// The fit at the observer's gain. The gain is one for every joint, but
/// the joints do not tell it alike: where the columns capture a joint's
/// model error, its error has a minimum at the true gain and grows on
/// both sides; where they do not (a friction that sticks at reversals),
/// less lag lets the fit follow the misfit, and the error only falls
/// toward the highest gain. So the gain is the joint minimum inside the
/// grid that stands out most (its error at least 5 % lower than the
/// worst on either side); without one, after the first round, the knee
/// of the joints' error over the grid ([`knee`]), else the lowest sum
/// over joints of the logarithm of the error.
fn best_gain(fits: Vec<Fit>, before: &[Option<f64>]) -> Option<Fit> {
    let joints = fits.first()?.joint_sse.len();
    let last = fits.len().checked_sub(1)?;
    let mut chosen: Option<(usize, f64)> = None;
    for j in 0..joints {
        let sse: Vec<f64> = fits.iter().map(|f| f.joint_sse[j].max(1e-300)).collect();
        let Some(at) = (0..sse.len()).min_by(|&a, &b| sse[a].total_cmp(&sse[b])) else {
            continue;
        };
        if at == 0 || at == last {
            continue;
        }
        let left = sse[..at].iter().fold(0.0_f64, |m, v| m.max(*v));
        let right = sse[at + 1..].iter().fold(0.0_f64, |m, v| m.max(*v));
        let prominence = (left.min(right) / sse[at]) - 1.0;
        if prominence >= 0.05 && chosen.is_none_or(|(_, p)| prominence > p) {
            chosen = Some((at, prominence));
        }
    }
    let at = if let Some((at, _)) = chosen {
        at
    } else if !before.is_empty()
        && let Some(at) = knee(&fits)
    {
        at
    } else {
        let score = |f: &Fit| f.joint_sse.iter().map(|v| v.max(1e-300).ln()).sum::<f64>();
        (0..fits.len()).min_by(|&a, &b| score(&fits[a]).total_cmp(&score(&fits[b])))?
    };
    fits.into_iter().nth(at)
}

/// The least gain whose fit is within [`KNEE`] of the best, each joint's
/// error over its least, averaged with weights by how much the joint's
/// error changes over the grid: more gain always fits a little better
/// (less lag lets the fit follow its misfit), so the error falls steeply
/// up to the observer's gain and barely after it; joints whose error
/// hardly depends on the gain say nothing of it. `None` when no joint's
/// error changes.
fn knee(fits: &[Fit]) -> Option<usize> {
    let joints = fits.first()?.joint_sse.len();
    let (mut weights, mut least) = (vec![0.0; joints], vec![0.0; joints]);
    for j in 0..joints {
        let sse = fits.iter().map(|f| f.joint_sse[j].max(1e-300));
        let (lo, hi) = sse.fold((f64::INFINITY, 0.0_f64), |(lo, hi), v| (lo.min(v), hi.max(v)));
        least[j] = lo;
        weights[j] = hi / lo - 1.0;
    }
    let total: f64 = weights.iter().sum();
    if total <= 1e-6 {
        return None;
    }
    fits.iter().position(|f| {
        let ratio: f64 = (0..joints)
            .map(|j| weights[j] * f.joint_sse[j].max(1e-300) / least[j])
            .sum::<f64>()
            / total;
        ratio <= 1.0 + KNEE
    })
}

/// How far above the best fit the knee of the gain may lie.
const KNEE: f64 = 0.01;

/// Learns the model error of the torques (see the module docs).
#[allow(clippy::too_many_lines)] // One alternation of fit and gate, read top to bottom.
/// `positions` and `torques` are the sensed joints' per frame.
pub fn calibrate(
    bodies: &RigidBodies,
    joint_names: Vec<String>,
    times_secs: &[f64],
    positions: &[Vec<f64>],
    torques: &[Vec<f64>],
    settings: &CalibrationSettings,
) -> Result<Calibration, CalibrationError> {
    let n = bodies.dof();
    let needed = 2 * MIN_FREE_FRAMES;
    if times_secs.len() < needed {
        return Err(CalibrationError::TooFewFrames {
            frames: times_secs.len(),
            needed,
        });
    }
    check_frames(times_secs, positions, torques, n)?;
    if let ObserverGain::PerSecond(k) = settings.observer_gain
        && !(k.is_finite() && k > 0.0)
    {
        return Err(CalibrationError::BadGain { value: k });
    }
    let read = times_secs.len().min(MAX_FIT_FRAMES);
    let (times, positions, torques) = (&times_secs[..read], &positions[..read], &torques[..read]);
    let (velocities, accelerations) = differentiate(times, positions);
    let rms_speed_rad_s = (velocities.iter().flatten().map(|v| v * v).sum::<f64>() / (read * n).max(1) as f64).sqrt();
    if rms_speed_rad_s < MIN_RMS_SPEED_RAD_S && !settings.free_motion {
        return Err(CalibrationError::NoMotion { rms_speed_rad_s });
    }
    let mut design = Design::new(bodies, settings, positions, &velocities, &accelerations)?;
    // Contacts give χ² in the thousands; a margin of 2 σ over the 99.9 %
    // point keeps the free frames whose residual is merely heavy-tailed.
    let threshold = 4.0 * chi_square_quantile(1e-3, n);
    let huber = chi_square_quantile(1e-2, n);
    // Start from the quietest share of frames, each joint scaled by its
    // reading's lower quartile: where contacts fill most of a recording
    // (two hands taking turns), a joint's median reading is a contact's,
    // and a joint scaled by it lets contacts that load mostly that joint
    // pass for quiet.
    let scale = reading_scale(torques, n);
    let loudness: Vec<f64> = torques
        .iter()
        .map(|t| t.iter().zip(&scale).map(|(x, s)| (x / s).powi(2)).sum())
        .collect();
    let share = quiet_share(torques, &scale);
    let mut sorted = loudness.clone();
    sorted.sort_by(f64::total_cmp);
    let quiet = quiet_point(&sorted, share);
    let mut free: Vec<bool> = loudness.iter().map(|l| settings.free_motion || *l <= quiet).collect();
    let mut sigma = scale.clone();
    let mut weights = vec![1.0; read];
    let gains: Vec<Option<f64>> = match settings.observer_gain {
        // No lag at all is a choice to make, not to find: a direct sensor's
        // white noise fits the highest gain of the grid as well.
        ObserverGain::Auto => OBSERVER_GAINS_PER_S.iter().map(|k| Some(*k)).collect(),
        ObserverGain::PerSecond(k) => vec![Some(k)],
        ObserverGain::Without => vec![None],
    };
    let mut gain = gains[0];
    let mut best: Option<Fit> = None;
    for round in 0..9 {
        let search = round == 0 || round == 5;
        let candidates: Vec<Option<f64>> = if search { gains.clone() } else { vec![gain] };
        // The gain is found with the plain Coulomb term; only then is
        // each joint's Coulomb term shaped at that gain, since a lead in
        // the friction can stand in for less lag in the observer.
        let shape = settings.friction && round >= 6;
        let fits = if shape {
            let mut fits = Vec::with_capacity(candidates.len());
            for g in candidates {
                let fit = fit_at(&design, times, torques, &free, &weights, &sigma, g)?;
                let search = ShapeSearch {
                    times_secs: times,
                    velocities: &velocities,
                    accelerations: &accelerations,
                    free: &free,
                    weights: &weights,
                };
                for (j, s) in best_coulomb_shapes(&design, &fit, &search)?.into_iter().enumerate() {
                    design.set_coulomb(j, s, &velocities, &accelerations);
                }
                fits.push(fit_at(&design, times, torques, &free, &weights, &sigma, g)?);
            }
            fits
        } else {
            // The gains of a search are fitted apart, on every core: the
            // two rounds that fit the whole grid take most of the time a
            // calibration takes.
            candidates
                .par_iter()
                .map(|&g| fit_at(&design, times, torques, &free, &weights, &sigma, g))
                .collect::<Result<Vec<Fit>, CalibrationError>>()?
        };
        let before = if round > 0 { vec![gain] } else { Vec::new() };
        let Some(fit) = best_gain(fits, &before) else {
            break;
        };
        gain = fit.gain;
        // σ of the gate from the quietest frames under the last σ
        // (widened by the truncation of a χ² at their share): the frames
        // the gate lets in must not set its scale, or a long contact that
        // the fit half absorbs widens σ until it is let in whole.
        sigma = gate_sigma(&fit.residuals, &sigma, share);
        let spread = prediction_spread(&design, times, &fit);
        let chi2: Vec<f64> = fit
            .residuals
            .iter()
            .zip(&spread)
            .map(|(e, v)| e.iter().zip(&sigma).zip(v).map(|((x, s), v)| x * x / (s * s + v)).sum())
            .collect();
        weights = chi2.iter().map(|z| if *z <= huber { 1.0 } else { huber / z }).collect();
        // The quietest frames always stay: a first fit that generalises
        // badly must not talk the gate out of every free frame.
        let mut ranked = chi2.clone();
        ranked.sort_by(f64::total_cmp);
        let floor = quiet_point(&ranked, share);
        free = free_frames(times, &chi2, threshold, gain)
            .iter()
            .zip(&chi2)
            .map(|(f, z)| settings.free_motion || *f || *z <= floor)
            .collect();
        best = Some(fit);
    }
    let Some(fit) = best else {
        return Err(CalibrationError::TooFewFree {
            free: 0,
            frames: read,
            needed: MIN_FREE_FRAMES,
        });
    };
    let free_count = free.iter().filter(|f| **f).count();
    if free_count < MIN_FREE_FRAMES {
        return Err(CalibrationError::TooFewFree {
            free: free_count,
            frames: read,
            needed: MIN_FREE_FRAMES,
        });
    }
    let runs = |values: &dyn Fn(usize) -> f64| free_runs(&free, values);
    let step = typical_step_secs(times);
    let before: Vec<(f64, f64)> = (0..n).map(|j| runs(&|k| torques[k][j])).collect();
    let after: Vec<(f64, f64)> = (0..n).map(|j| runs(&|k| fit.residuals[k][j])).collect();
    // The residual with the lag taken off: what the estimator will see.
    let unlagged = unlag_all(gain, times, &fit.residuals);
    let white: Vec<(f64, f64)> = (0..n).map(|j| runs(&|k| unlagged[k][j])).collect();
    // Does the fit beat what its columns would take from noise alone?
    let sse_before: f64 = (0..n).map(|j| before[j].0.powi(2) / sigma[j].powi(2)).sum();
    let sse_after: f64 = (0..n).map(|j| after[j].0.powi(2) / sigma[j].powi(2)).sum();
    let correlation = after.iter().map(|a| a.1).sum::<f64>() / n as f64;
    let effective_rows = (free_count * n) as f64 / correlation.max(1.0);
    let cut = 1.0 - sse_after / sse_before.max(1e-300);
    // Noise alone would take about p / N of the variance (N the rows'
    // effective count); a residual correlated over many frames leaves few
    // effective rows, so the bar stops at half the variance.
    let found = cut > 0.1_f64.max((3.0 * design.columns as f64 / effective_rows).min(0.5));
    let names = joint_names;
    if !found {
        // Nothing is taken off, so the frames free of contact can be read
        // from the readings themselves, found afresh from the quietest
        // ones; where the gate's free frames read far wider than those on
        // some joint, presses crowd them, and the readings' are kept.
        let quietest = quiet_point(&sorted, CROWDED_SHARE);
        let start = loudness.iter().map(|l| *l <= quietest).collect();
        let readings = (!settings.free_motion)
            .then(|| free_readings(times, torques, start, (threshold, gain, CROWDED_SHARE)))
            .flatten()
            .map(|free| {
                let before: Vec<(f64, f64)> = (0..n).map(|j| free_runs(&free, &|k| torques[k][j])).collect();
                (free, before)
            });
        let widest = readings.as_ref().map_or(1.0, |(_, quiet)| {
            before
                .iter()
                .zip(quiet)
                .map(|(b, q)| b.0 / q.0.max(1e-12))
                .fold(0.0, f64::max)
        });
        log::debug!("calibration: the gate's free frames' RMS over the readings', widest {widest:.2}");
        let (free_count, before) = match readings {
            Some((free, quiet)) if widest > CROWDED_FREE_RATIO => (free.iter().filter(|f| **f).count(), quiet),
            _ => (free_count, before),
        };
        let mut none = Calibration::none(names, before.iter().map(|b| b.0.max(1e-4)).collect());
        none.rms_before_nm = before.iter().map(|b| b.0).collect();
        none.correlation_secs = before.iter().map(|b| b.1 * step).collect();
        none.frames_read = read;
        none.free_frames = free_count;
        none.observer_gain_per_s = gain;
        return Ok(none);
    }
    let mut inertial_corrections = Vec::new();
    if !design.base.is_empty() {
        inertial_corrections = vec![0.0; bodies.parameters().len()];
        for (i, &c) in design.base.iter().enumerate() {
            inertial_corrections[c] = fit.coefficients[i];
        }
    }
    let friction = &fit.coefficients[design.base.len()..];
    Ok(Calibration {
        joints: names,
        observer_gain_per_s: gain,
        inertial_corrections,
        coulomb_nm: (0..n).map(|j| friction[3 * j]).collect(),
        coulomb_lead_secs: design.shapes.iter().map(|s| s.0).collect(),
        coulomb_switch_rad_s: design.shapes.iter().map(|s| s.1).collect(),
        viscous_nms_per_rad: (0..n).map(|j| friction[3 * j + 1]).collect(),
        offset_nm: (0..n).map(|j| friction[3 * j + 2]).collect(),
        sigma_nm: white.iter().map(|a| a.0.max(1e-4)).collect(),
        rms_after_nm: after.iter().map(|a| a.0).collect(),
        correlation_secs: white.iter().map(|a| a.1 * step).collect(),
        rms_before_nm: before.iter().map(|b| b.0).collect(),
        frames_read: read,
        free_frames: free_count,
        found,
    })
}

#[path = "calibration_design.rs"]
mod design;
#[path = "calibration_free.rs"]
mod free;
use design::Design;
use free::{
    CROWDED_FREE_RATIO, CROWDED_SHARE, chi_square_quantile, free_frames, free_readings, free_runs, gate_sigma,
    quiet_point, quiet_share, reading_scale,
};
#[path = "calibration_shapes.rs"]
mod shapes;
use shapes::{ShapeSearch, best_coulomb_shapes, prediction_spread};

#[cfg(test)]
#[path = "calibration_tests.rs"]
mod tests;
