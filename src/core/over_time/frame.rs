//! One frame of a session as the sequence, the presses and the generator
//! hand it on: its time, the arm's joint positions and the torques.

#[cfg(doc)]
use crate::core::robot::model::Robot;

/// One frame of a sequence.
#[derive(Debug, Clone, Copy)]
pub struct SequenceFrame<'a> {
    /// Time, s.
    pub t_secs: f64,
    /// Every joint's position (see [`Robot::joint_positions`]).
    pub joint_positions: &'a [f64],
    /// Measured torques, sensed order, N·m.
    pub tau: &'a [f64],
}
