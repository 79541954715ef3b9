//! One frame: the contact model, the posterior, the refinement, friction and a press's fit
//! (kinetic friction included), the summary and the `Estimator`. Imports the rooms below it.

pub mod contact;
pub mod estimator;
pub mod evidence;
pub mod explain;
pub mod friction;
pub mod kinetic;
pub mod measurement;
pub mod observability;
pub mod pair;
pub mod pair_grid;
pub mod pair_held;
pub mod pair_identifiable;
pub mod phases;
pub mod place_spread;
pub mod posterior;
pub mod press;
pub mod refine;
pub mod regions;
pub mod settings;
pub mod summary;
