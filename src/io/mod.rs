//! Loading and saving: URDF and mesh files, the built-in robots' assets,
//! scenes, sessions and robot recordings, live sources, MCAP out and Foxglove. Each
//! reader has its own error type naming the file and element.

pub mod bag;
pub mod builtin;
pub mod calibration;
pub mod cdr;
pub mod foxglove;
pub mod guard;
pub mod inflate;
mod json_array;
pub mod live;
pub mod mcap_out;
pub mod mesh;
pub mod open;
pub mod recording;
pub mod rosmsg;
pub mod scene;
pub mod session;
pub mod urdf;
