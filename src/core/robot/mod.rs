//! The arm: links, joints and their meshes, forward kinematics, the
//! built-in robots, the joint torques of a push and the rigid-body
//! dynamics of the links' inertials.
//! Imports `numerics` and `geometry`.

pub mod builtin;
pub mod dynamics;
pub mod kinematics;
pub mod model;
pub mod spatial;
pub mod torque;
