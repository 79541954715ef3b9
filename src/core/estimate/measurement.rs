//! One frame's measurement as the searches on the continuous surface read
//! it: the torques, their weights, the push magnitudes considered and the
//! friction setting (shared by the refinement and the friction model).

/// What the refinement and the friction model need of one measurement.
#[derive(Debug, Clone, Copy)]
pub struct Measurement<'a> {
    /// Measured torques, sensed order, N·m.
    pub tau: &'a [f64],
    /// `1/σ²` per sensed joint.
    pub weights: &'a [f64],
    /// Push magnitudes considered, N.
    pub force_range_newtons: (f64, f64),
    /// μ of the friction model ([`crate::core::estimate::friction`]); 0: frictionless.
    /// With friction the search minimises the marginal model's `-2 ln L`
    /// (the tangential force integrated out) instead of the residual, so
    /// that the place, not only the force, is the friction model's.
    pub friction: f64,
}
