//! Off the estimator's path: the metrics a session is scored by (frames,
//! slides' paths, presses fitted from their truth) and the session
//! generator that draws presses with their truth.
//! Imports the rooms below it.

pub mod metrics;
pub mod press_gap;
pub mod slides;
pub mod synth;
