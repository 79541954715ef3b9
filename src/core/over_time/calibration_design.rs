//! The calibration's design: each frame's columns before the lag (the
//! dynamics regressor's base columns, each joint's friction and offset),
//! and the lagged rows the fit reads.

use super::{CalibrationError, CalibrationSettings, STICTION_SPEED_RAD_S, coulomb_shape};
use crate::core::over_time::observer::{Lag, frame_steps};
use crate::core::robot::dynamics::RigidBodies;

/// The prior on an inertial correction: this fraction of the model's
/// value, plus [`PRIOR_FLOOR`] by kind (kg, kg·m, kg·m²).
const PRIOR_RELATIVE: f64 = 0.3;
/// See [`PRIOR_RELATIVE`]; in [`crate::core::robot::spatial::PARAMETER_NAMES`] order.
const PRIOR_FLOOR: [f64; 10] = [0.2, 0.02, 0.02, 0.02, 0.01, 0.01, 0.01, 0.01, 0.01, 0.01];
/// The prior's standard deviation of a joint's Coulomb friction, N·m.
const PRIOR_COULOMB_NM: f64 = 1.0;
/// ... of its viscous friction, N·m·s/rad.
const PRIOR_VISCOUS_NMS: f64 = 1.0;
/// ... of its offset, N·m.
const PRIOR_OFFSET_NM: f64 = 0.3;

/// One frame's columns before the lag, row-major (joints × columns).
pub(super) struct Design {
    pub(super) base: Vec<usize>,
    /// The prior's standard deviation of each column's coefficient.
    pub(super) prior_sd: Vec<f64>,
    pub(super) columns: usize,
    pub(super) joints: usize,
    pub(super) rows: Vec<f32>,
    /// Each joint's Coulomb (lead s, transition speed rad/s).
    pub(super) shapes: Vec<(f64, f64)>,
}

impl Design {
    /// Every read frame's columns: the regressor's base columns, then per
    /// joint its Coulomb, viscous and offset columns (signs as the
    /// residual sees them).
    pub(super) fn new(
        bodies: &RigidBodies,
        settings: &CalibrationSettings,
        positions: &[Vec<f64>],
        velocities: &[Vec<f64>],
        accelerations: &[Vec<f64>],
    ) -> Result<Self, CalibrationError> {
        let joints = bodies.dof();
        let nominal = bodies.parameters();
        let has_inertials = bodies.moving_links().iter().any(|&l| nominal[l * 10] > 0.0);
        let base = if settings.inertial && has_inertials {
            bodies.base_columns()
        } else {
            Vec::new()
        };
        let columns = base.len() + 3 * joints;
        let all_columns = nominal.len();
        let mut rows = Vec::with_capacity(positions.len() * joints * columns);
        for ((q, qd), qdd) in positions.iter().zip(velocities).zip(accelerations) {
            let y = if base.is_empty() {
                Vec::new()
            } else {
                bodies.regressor(q, qd, qdd)?
            };
            for j in 0..joints {
                for &c in &base {
                    rows.push(y[j * all_columns + c] as f32);
                }
                for i in 0..joints {
                    let (coulomb, viscous, offset) = if i == j && settings.friction {
                        (coulomb_shape(qd[j], qdd[j], 0.0, STICTION_SPEED_RAD_S), -qd[j], 1.0)
                    } else if i == j {
                        (0.0, 0.0, 1.0)
                    } else {
                        (0.0, 0.0, 0.0)
                    };
                    rows.push(coulomb as f32);
                    rows.push(viscous as f32);
                    rows.push(offset as f32);
                }
            }
        }
        let mut prior_sd: Vec<f64> = base
            .iter()
            .map(|&c| PRIOR_RELATIVE * nominal[c].abs() + PRIOR_FLOOR[c % 10])
            .collect();
        for _ in 0..joints {
            prior_sd.extend([PRIOR_COULOMB_NM, PRIOR_VISCOUS_NMS, PRIOR_OFFSET_NM]);
        }
        Ok(Self {
            base,
            prior_sd,
            columns,
            joints,
            rows,
            shapes: vec![(0.0, STICTION_SPEED_RAD_S); joints],
        })
    }

    /// Where joint `j`'s Coulomb column sits in a frame's row block.
    pub(super) fn coulomb_index(&self, j: usize) -> usize {
        j * self.columns + self.base.len() + 3 * j
    }

    /// Reshapes joint `j`'s Coulomb column to `(lead, switch)`.
    pub(super) fn set_coulomb(
        &mut self,
        j: usize,
        shape: (f64, f64),
        velocities: &[Vec<f64>],
        accelerations: &[Vec<f64>],
    ) {
        let width = self.joints * self.columns;
        let at = self.coulomb_index(j);
        for ((row, v), a) in self.rows.chunks_exact_mut(width).zip(velocities).zip(accelerations) {
            row[at] = coulomb_shape(v[j], a[j], shape.0, shape.1) as f32;
        }
        self.shapes[j] = shape;
    }

    /// Hands `visit` each frame's number and its lagged columns (row-major
    /// per joint), in order. The rows are made as they are read: at 60,000
    /// frames of seven joints the whole matrix would be over 200 MB, held
    /// by the allocator long after the fit.
    pub(super) fn for_each_lagged(&self, times_secs: &[f64], gain: Option<f64>, mut visit: impl FnMut(usize, &[f64])) {
        let width = self.joints * self.columns;
        let mut lag = Lag::new(gain, width);
        let mut input = vec![0.0; width];
        for (k, (raw, (dt, restart))) in self.rows.chunks_exact(width).zip(frame_steps(times_secs)).enumerate() {
            if restart {
                lag.reset();
            }
            for (x, r) in input.iter_mut().zip(raw) {
                *x = f64::from(*r);
            }
            visit(k, lag.step(dt, &input));
        }
    }

    /// Frames [`Design::for_each_lagged`] visits: those the design holds
    /// and `times_secs` times.
    pub(super) fn lagged_frames(&self, times_secs: &[f64]) -> usize {
        let held = self.rows.len().checked_div(self.joints * self.columns).unwrap_or(0);
        held.min(times_secs.len())
    }
}
