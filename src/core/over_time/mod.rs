//! A session: the temporal model (filter, smoother in bounded stretches),
//! the frames run in parallel blocks, presses fitted as a whole, the torque
//! bias, the calibration of a real arm's model error, and a second contact.
//! Imports the rooms below it, `estimate` included.

pub mod bias;
pub mod calibration;
mod combine;
pub mod frame;
pub mod graph;
mod in_order;
mod jumps;
pub mod observer;
pub mod offsets;
pub mod pairs;
pub mod parallel;
mod pipeline;
pub mod press_queue;
pub mod presses;
pub mod sequence;
pub mod smoother;
pub mod starts;
pub mod stretches;
pub mod temporal;
