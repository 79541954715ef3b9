//! Proprioscope: where a robot arm is touched, and how hard, from its joint
//! torque sensors alone.
//!
//! `core` is the numerical heart (no I/O), `io` reads and writes robots,
//! meshes, scenes, sessions and recordings, `batch` estimates whole
//! sessions off the caller's thread, `render` and `app` are the desktop
//! program. ARCHITECTURE.md draws the layers and the rooms of `core`.
//!
//! The entry points: a [`Robot`] (built in, or from a URDF with
//! [`io::builtin::load_robot`]), an [`EstimatorConfig`] (what the user
//! chooses, with the defaults), the [`Estimator`] it builds (one frame's
//! estimate from the joint torques), and a [`Session`] of frames
//! (estimated in order by [`core::over_time::sequence::estimate_sequence`]).

#[cfg(feature = "gui")]
pub mod app;
pub mod batch;
pub mod core;
pub mod io;
#[cfg(feature = "gui")]
pub mod render;

pub use core::config::estimator::EstimatorConfig;
pub use core::estimate::estimator::Estimator;
pub use core::robot::model::Robot;
pub use io::session::Session;
