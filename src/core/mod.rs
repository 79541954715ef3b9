//! The numerical core: robot model, kinematics, surface sampling, torques.
//!
//! Pure math on `glam` f64 types, SI units, no I/O and no UI.

pub mod bias;
pub mod builtin;
pub mod bvh;
pub mod contact;
pub mod estimator;
pub mod fastmath;
pub mod friction;
pub mod kinematics;
pub mod lanes;
pub mod limits;
pub mod mesh;
pub mod metrics;
pub mod observability;
pub mod phases;
pub mod picking;
pub mod pipeline;
pub mod press;
pub mod primitives;
pub mod refine;
pub mod regions;
pub mod rng;
pub mod robot;
pub mod simd;
pub mod smooth;
pub mod special;
pub mod summary;
pub mod surface;
pub mod synth;
pub mod temporal;
pub mod torque;
