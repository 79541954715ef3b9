//! What the arm is painted with: the heat of `core::paint::heat`, and the
//! layers a scene names.

pub use crate::core::paint::heat::*;

/// What the arm is painted with (as a scene file names it).
pub use crate::io::scene::Layer as HeatLayer;
