//! The arm: links, joints and their meshes, forward kinematics, the
//! built-in robots and the joint torques of a push.
//! Imports `numerics` and `geometry`.

pub mod builtin;
pub mod kinematics;
pub mod model;
pub mod torque;
