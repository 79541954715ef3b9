//! Numbers alone: special functions, fast approximations, vector lanes
//! and the wide-unit dispatch, the seeded random generator, small dense
//! linear algebra.
//! Imports nothing of ours.

pub mod fastmath;
pub mod lanes;
pub mod linalg;
pub mod rng;
pub mod simd;
pub mod special;
