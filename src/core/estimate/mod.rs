//! One frame: the contact model, the posterior over the samples (exact or
//! particles, in phases), the refinement on the continuous surface, the
//! friction model and a press's fit, the summary, regions, observability
//! and the `Estimator` that runs them. Imports the rooms below it.

pub mod contact;
pub mod estimator;
pub mod evidence;
pub mod explain;
pub mod friction;
mod kinetic;
pub mod measurement;
pub mod observability;
pub mod pair;
pub mod phases;
pub mod posterior;
pub mod press;
pub mod refine;
pub mod regions;
pub mod settings;
pub mod summary;
