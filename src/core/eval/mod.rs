//! Off the estimator's path: the metrics a session is scored by (frames,
//! slides' paths) and the session generator that draws presses with their truth.
//! Imports the rooms below it.

pub mod metrics;
pub mod slides;
pub mod synth;
