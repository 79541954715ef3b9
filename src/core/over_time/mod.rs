//! A session: the temporal model of contacts (filter and smoother), the
//! presses fitted as a whole, the sequence of frames and the torque bias.
//! Imports the rooms below it, `estimate` included.

pub mod bias;
pub mod frame;
pub mod graph;
pub mod offsets;
pub mod presses;
pub mod sequence;
pub mod smoother;
pub mod temporal;
