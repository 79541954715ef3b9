//! Proprioscope: where a robot arm is touched, and how hard, from its joint
//! torque sensors alone.
//!
//! `core` is the numerical heart (no I/O), `io` reads and writes robots,
//! meshes and scenes, `batch` estimates whole sessions off the caller's thread, `render` and
//! `app` are the desktop program.

#[cfg(feature = "gui")]
pub mod app;
pub mod batch;
pub mod core;
pub mod io;
#[cfg(feature = "gui")]
pub mod render;
