//! What the user chooses: the valid range of every number, and the one
//! estimator configuration with its defaults and its validation.
//! Imports the rooms below it.

pub mod estimator;
pub mod limits;
