//! How far a press leaves a frame's place undetermined: the place's
//! covariance along the surface, and the credible ellipse it gives.

use glam::{DMat2, DVec2, DVec3};

/// The uncertainty of one frame's place given the whole press: the
/// Laplace approximation of the posterior at the fit, with γ free under
/// its prior (spread μ per direction) even where the frictionless fit is
/// reported. A press that drags while the arm is still cannot tell a
/// tangential force from a shifted place (on the LWR's link 4, three
/// joints see a push: a place 50–70 mm off explains a drag of 17 % of the
/// push as well as the truth does); the place's spread along that
/// direction is then what μ allows, and the credible region says so
/// instead of shrinking with every frame of the press.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaceSpread {
    /// The surface's two unit tangents at the place, link frame.
    pub tangents_in_link: [DVec3; 2],
    /// Covariance of the place along the two tangents, m².
    pub covariance_m2: DMat2,
}

impl PlaceSpread {
    /// The points within `level` (a squared Mahalanobis distance) of the
    /// place, a patch of radius `rho_m` around it counted in: `dᵀ (Σ +
    /// ρ² I)⁻¹ d ≤ level` for an offset `d` projected on the tangents.
    /// `None` where the matrix is singular or not finite.
    #[must_use]
    pub fn region(&self, rho_m: f64, level: f64) -> Option<PlaceRegion> {
        let widened = self.covariance_m2 + DMat2::IDENTITY * (rho_m * rho_m);
        let det = widened.determinant();
        (det.is_finite() && det > 0.0).then(|| PlaceRegion {
            tangents_in_link: self.tangents_in_link,
            inverse_m2: widened.inverse(),
            level,
        })
    }
}

/// An ellipse around a place along its surface ([`PlaceSpread::region`]),
/// its inverse formed once for the many points tested against it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaceRegion {
    tangents_in_link: [DVec3; 2],
    inverse_m2: DMat2,
    level: f64,
}

impl PlaceRegion {
    /// Whether the point `offset_in_link` from the place (projected on the
    /// place's tangents) lies in the region.
    #[must_use]
    pub fn contains(&self, offset_in_link: DVec3) -> bool {
        let [t0, t1] = self.tangents_in_link;
        let d = DVec2::new(t0.dot(offset_in_link), t1.dot(offset_in_link));
        d.dot(self.inverse_m2 * d) <= self.level
    }
}

#[cfg(test)]
mod tests {
    // Test helpers may unwrap: a panic is a failed test with its message.
    #![allow(clippy::unwrap_used)]

    use super::*;

    /// The region is the ellipse `dᵀ(Σ + ρ²I)⁻¹d ≤ level` along the
    /// place's tangents: its edge along each axis of a diagonal `Σ` at
    /// `√(level (σᵢ² + ρ²))`, the normal direction ignored; a singular
    /// matrix has none.
    #[test]
    fn a_place_region_is_the_ellipse_of_its_spread_and_patch() {
        let spread = PlaceSpread {
            tangents_in_link: [DVec3::X, DVec3::Y],
            covariance_m2: DMat2::from_diagonal(DVec2::new(0.02 * 0.02, 0.005 * 0.005)),
        };
        let (rho_m, level) = (0.003, 4.61);
        let region = spread.region(rho_m, level).unwrap();
        let edge_x = (level * (0.02f64.powi(2) + rho_m * rho_m)).sqrt();
        let edge_y = (level * (0.005f64.powi(2) + rho_m * rho_m)).sqrt();
        assert!(region.contains(DVec3::new(0.999 * edge_x, 0.0, 0.0)));
        assert!(!region.contains(DVec3::new(1.001 * edge_x, 0.0, 0.0)));
        assert!(region.contains(DVec3::new(0.0, -0.999 * edge_y, 0.5)));
        assert!(!region.contains(DVec3::new(0.0, -1.001 * edge_y, 0.0)));
        // Halfway along both axes: (½)² + (½)² ≤ 1.
        assert!(region.contains(DVec3::new(0.5 * edge_x, 0.5 * edge_y, 0.0)));
        assert!(!region.contains(DVec3::new(0.75 * edge_x, 0.75 * edge_y, 0.0)));
        let flat = PlaceSpread {
            covariance_m2: DMat2::ZERO,
            ..spread
        };
        assert!(flat.region(0.0, level).is_none());
        let not_finite = PlaceSpread {
            covariance_m2: DMat2::from_diagonal(DVec2::new(f64::NAN, 1.0)),
            ..spread
        };
        assert!(not_finite.region(rho_m, level).is_none());
    }
}
