//! Every integration test, built as one binary: one link instead of one a
//! file, and `cargo test` spreads the slow tests of every file over the
//! cores instead of waiting for each file's slowest. Each file is a module;
//! `cargo test --test integration NAME` runs the tests whose path contains
//! NAME (a file's name runs that file). `tests/structure.rs` checks that
//! every file under `tests/` is declared here.

mod common;

mod app;
mod app_sessions;
mod app_torque_model;
mod app_two_contacts;
mod bad_files;
mod bad_urdf;
mod calibration;
mod cli;
mod cli_bench;
mod cli_live;
mod dynamics;
mod estimator;
mod extremes;
mod foxglove;
mod friction;
mod long_recording;
mod monkey;
mod observer;
mod observer_synth;
mod oracle;
mod press_gaps;
mod readme;
mod recordings;
mod scenes;
mod session;
mod session_bias;
mod slides;
mod structure;
mod teaching;
mod temporal;
mod two_contacts;
