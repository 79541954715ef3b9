//! Spatial (6-D) vectors and rigid-body inertia in Plücker coordinates at
//! the world origin: what the rigid-body dynamics of [`crate::core::robot::dynamics`]
//! are written in (Featherstone's notation: motion `(ω, v_O)`, force
//! `(n_O, f)`, `crm` and `crf` the motion and force cross products).
//!
//! A link's mass properties as its description gives them ([`Inertial`],
//! in the link frame) and their ten linear parameters (about the link
//! origin) also live here: the dynamics regressor is linear in them.

use glam::{DAffine3, DMat3, DVec3};

use crate::core::geometry::mesh::TriMesh;

/// A motion vector: angular velocity and the velocity of the body-fixed
/// point at the world origin (or their time derivatives, or a joint's screw).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Motion {
    /// Angular part, rad/s.
    pub angular: DVec3,
    /// Linear part at the world origin, m/s.
    pub linear: DVec3,
}

/// A force vector: the moment about the world origin and the force.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Force {
    /// Moment about the world origin, N·m.
    pub moment: DVec3,
    /// Force, N.
    pub force: DVec3,
}

impl Motion {
    /// A revolute joint's unit screw: rotation about `axis` through `point`.
    #[must_use]
    pub fn revolute(axis: DVec3, point: DVec3) -> Self {
        Self {
            angular: axis,
            linear: point.cross(axis),
        }
    }

    /// A prismatic joint's unit screw: translation along `axis`.
    #[must_use]
    pub fn prismatic(axis: DVec3) -> Self {
        Self {
            angular: DVec3::ZERO,
            linear: axis,
        }
    }

    /// `self · scale`.
    #[must_use]
    pub fn scaled(self, scale: f64) -> Self {
        Self {
            angular: self.angular * scale,
            linear: self.linear * scale,
        }
    }

    /// `self + other`.
    #[must_use]
    pub fn plus(self, other: Self) -> Self {
        Self {
            angular: self.angular + other.angular,
            linear: self.linear + other.linear,
        }
    }

    /// The motion cross product `crm(self) · other` (how `other`, carried
    /// by a body moving with `self`, changes).
    #[must_use]
    pub fn cross_motion(self, other: Self) -> Self {
        Self {
            angular: self.angular.cross(other.angular),
            linear: self.angular.cross(other.linear) + self.linear.cross(other.angular),
        }
    }

    /// The force cross product `crf(self) · force`.
    #[must_use]
    pub fn cross_force(self, force: Force) -> Force {
        Force {
            moment: self.angular.cross(force.moment) + self.linear.cross(force.force),
            force: self.angular.cross(force.force),
        }
    }

    /// The power `selfᵀ · force` (a joint torque when `self` is its screw).
    #[must_use]
    pub fn dot(self, force: Force) -> f64 {
        self.angular.dot(force.moment) + self.linear.dot(force.force)
    }
}

impl Force {
    /// `self + other`.
    #[must_use]
    pub fn plus(self, other: Self) -> Self {
        Self {
            moment: self.moment + other.moment,
            force: self.force + other.force,
        }
    }
}

/// A rigid body's inertia at the world origin: mass, first moment
/// `h = m c` and the rotational inertia about the origin. Sums of bodies
/// add parameter by parameter.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpatialInertia {
    /// Mass, kg.
    pub mass_kg: f64,
    /// First moment `m c` about the origin, kg·m.
    pub first_moment: DVec3,
    /// Rotational inertia about the origin, kg·m².
    pub rotational: DMat3,
}

impl Default for SpatialInertia {
    /// No body (glam's default matrix is the identity, not zero).
    fn default() -> Self {
        Self {
            mass_kg: 0.0,
            first_moment: DVec3::ZERO,
            rotational: DMat3::ZERO,
        }
    }
}

impl SpatialInertia {
    /// The momentum `I · motion`.
    #[must_use]
    pub fn apply(&self, motion: Motion) -> Force {
        Force {
            moment: self.rotational * motion.angular + self.first_moment.cross(motion.linear),
            force: motion.linear * self.mass_kg - self.first_moment.cross(motion.angular),
        }
    }

    /// `self + other`.
    #[must_use]
    pub fn plus(&self, other: &Self) -> Self {
        Self {
            mass_kg: self.mass_kg + other.mass_kg,
            first_moment: self.first_moment + other.first_moment,
            rotational: self.rotational + other.rotational,
        }
    }

    /// `(crf(v) I − I crm(v)) · motion`: how the momentum of `motion`
    /// changes as the body moves with `velocity`.
    #[must_use]
    pub fn rate_apply(&self, velocity: Motion, motion: Motion) -> Force {
        let carried = velocity.cross_force(self.apply(motion));
        let turned = self.apply(velocity.cross_motion(motion));
        Force {
            moment: carried.moment - turned.moment,
            force: carried.force - turned.force,
        }
    }

    /// The inertia of ten parameters given about a link's origin in its
    /// frame ([`Inertial::parameters`] order), placed by `world_from_link`.
    /// Linear in the parameters, which is what makes the regressor.
    #[must_use]
    pub fn from_link_parameters(parameters: &[f64; 10], world_from_link: &DAffine3) -> Self {
        let [m, hx, hy, hz, ixx, ixy, ixz, iyy, iyz, izz] = *parameters;
        let rotation = world_from_link.matrix3;
        let p = world_from_link.translation;
        let h_link_rotated = rotation * DVec3::new(hx, hy, hz);
        let about_link_origin =
            rotation * DMat3::from_cols_array(&[ixx, ixy, ixz, ixy, iyy, iyz, ixz, iyz, izz]) * rotation.transpose();
        // Moving the reference point from the link origin p to the world
        // origin: I_O = I_p − m [p]×² − [p]×[h']× − [h']×[p]× with h' the
        // rotated first moment (all linear in the parameters).
        let px = skew(p);
        let hx_rot = skew(h_link_rotated);
        let rotational = about_link_origin - px * px * m - px * hx_rot - hx_rot * px;
        Self {
            mass_kg: m,
            first_moment: p * m + h_link_rotated,
            rotational,
        }
    }
}

/// The matrix of `v ×`.
#[must_use]
pub fn skew(v: DVec3) -> DMat3 {
    DMat3::from_cols(
        DVec3::new(0.0, v.z, -v.y),
        DVec3::new(-v.z, 0.0, v.x),
        DVec3::new(v.y, -v.x, 0.0),
    )
}

/// A link's mass properties as a URDF `<inertial>` gives them, in the link frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Inertial {
    /// Mass, kg (0: a massless link).
    pub mass_kg: f64,
    /// Centre of mass in the link frame, m.
    pub com_in_link_m: DVec3,
    /// Rotational inertia about the centre of mass, in the link frame's axes, kg·m².
    pub inertia_about_com: DMat3,
}

/// Names of the ten inertial parameters of a link, in [`Inertial::parameters`] order.
pub const PARAMETER_NAMES: [&str; 10] = ["m", "mx", "my", "mz", "Ixx", "Ixy", "Ixz", "Iyy", "Iyz", "Izz"];

impl Default for Inertial {
    /// A massless link (glam's default matrix is the identity, not zero).
    fn default() -> Self {
        Self {
            mass_kg: 0.0,
            com_in_link_m: DVec3::ZERO,
            inertia_about_com: DMat3::ZERO,
        }
    }
}

impl Inertial {
    /// The ten parameters that the dynamics are linear in: mass, first
    /// moment `m c` and the rotational inertia about the link origin
    /// (`Ixx, Ixy, Ixz, Iyy, Iyz, Izz`), all in the link frame.
    #[must_use]
    pub fn parameters(&self) -> [f64; 10] {
        let m = self.mass_kg;
        let c = self.com_in_link_m;
        let shift = skew(c);
        let about_origin = self.inertia_about_com - shift * shift * m;
        let a = about_origin.to_cols_array_2d();
        [
            m,
            m * c.x,
            m * c.y,
            m * c.z,
            a[0][0],
            a[1][0],
            a[2][0],
            a[1][1],
            a[2][1],
            a[2][2],
        ]
    }

    /// The mass properties of a closed, outward-wound solid of uniform
    /// density (kg/m³), by the divergence theorem over the tetrahedra its
    /// triangles make with the origin; solids given together add (where
    /// they overlap, twice). A mesh that encloses no volume gives the zero
    /// inertial.
    #[must_use]
    pub fn of_solids(solids: &[TriMesh], density_kg_m3: f64) -> Self {
        let (mut volume, mut first, mut second) = (0.0, DVec3::ZERO, DMat3::ZERO);
        for mesh in solids {
            for [a, b, c] in mesh.triangle_corners() {
                let v = a.dot(b.cross(c)) / 6.0;
                let sum = a + b + c;
                volume += v;
                first += sum * (v / 4.0);
                // ∫ x xᵀ over the tetrahedron (0, a, b, c).
                let outer = |p: DVec3| DMat3::from_cols(p * p.x, p * p.y, p * p.z);
                second += (outer(a) + outer(b) + outer(c) + outer(sum)) * (v / 20.0);
            }
        }
        if volume <= 0.0 || !volume.is_finite() {
            return Self::default();
        }
        let mass_kg = density_kg_m3 * volume;
        let com = first / volume;
        let covariance = second * density_kg_m3;
        let trace = covariance.x_axis.x + covariance.y_axis.y + covariance.z_axis.z;
        let about_origin = DMat3::from_diagonal(DVec3::splat(trace)) - covariance;
        let shift = skew(com);
        Self {
            mass_kg,
            com_in_link_m: com,
            inertia_about_com: about_origin + shift * shift * mass_kg,
        }
    }

    /// True when every number is finite and the mass is not negative.
    #[must_use]
    pub fn is_valid(&self) -> bool {
        self.mass_kg.is_finite()
            && self.mass_kg >= 0.0
            && self.com_in_link_m.is_finite()
            && self.inertia_about_com.is_finite()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn body() -> (Inertial, DAffine3) {
        let inertial = Inertial {
            mass_kg: 2.3,
            com_in_link_m: DVec3::new(0.01, -0.06, 0.12),
            inertia_about_com: DMat3::from_cols_array(&[
                0.02, 0.001, -0.002, 0.001, 0.004, 0.0005, -0.002, 0.0005, 0.015,
            ]),
        };
        let pose = DAffine3::from_rotation_translation(
            glam::DQuat::from_euler(glam::EulerRot::XYZ, 0.3, -0.7, 1.1),
            DVec3::new(0.2, -0.4, 0.9),
        );
        (inertial, pose)
    }

    /// The momentum from the parameters equals `m v_c` and `I_c ω + c × m v_c`
    /// computed from the centre of mass directly.
    #[test]
    fn momentum_from_parameters_matches_the_centre_of_mass_form() {
        let (inertial, pose) = body();
        let inertia = SpatialInertia::from_link_parameters(&inertial.parameters(), &pose);
        let omega = DVec3::new(0.4, -1.2, 0.7);
        let v_origin = DVec3::new(-0.3, 0.5, 0.2);
        let momentum = inertia.apply(Motion {
            angular: omega,
            linear: v_origin,
        });
        let c = pose.transform_point3(inertial.com_in_link_m);
        let v_c = v_origin + omega.cross(c);
        let i_c = pose.matrix3 * inertial.inertia_about_com * pose.matrix3.transpose();
        let linear = v_c * inertial.mass_kg;
        let angular = i_c * omega + c.cross(linear);
        assert!((momentum.force - linear).length() < 1e-12, "{momentum:?}");
        assert!((momentum.moment - angular).length() < 1e-12, "{momentum:?} {angular}");
    }

    /// A box's mass, centre and inertia in closed form.
    #[test]
    fn a_solid_box_has_the_closed_form_inertia() {
        use crate::core::geometry::primitives::Primitive;
        let (x, y, z) = (0.4, 0.2, 0.1);
        let mesh = Primitive::Cuboid {
            link_from_box: DAffine3::from_translation(DVec3::new(0.1, -0.2, 0.3)),
            half_extents: DVec3::new(x / 2.0, y / 2.0, z / 2.0),
        }
        .mesh(4);
        let inertial = Inertial::of_solids(&[mesh], 500.0);
        let m = 500.0 * x * y * z;
        assert!((inertial.mass_kg - m).abs() < 1e-12, "{inertial:?}");
        assert!((inertial.com_in_link_m - DVec3::new(0.1, -0.2, 0.3)).length() < 1e-12);
        let expected = DVec3::new(y * y + z * z, x * x + z * z, x * x + y * y) * (m / 12.0);
        let i = inertial.inertia_about_com;
        let diagonal = DVec3::new(i.x_axis.x, i.y_axis.y, i.z_axis.z);
        assert!((diagonal - expected).length() < 1e-12, "{diagonal} vs {expected}");
        assert!(i.x_axis.y.abs() < 1e-12 && i.x_axis.z.abs() < 1e-12 && i.y_axis.z.abs() < 1e-12);
    }

    /// `rate_apply` is the time derivative of the momentum of a fixed
    /// motion as the body moves (finite differences).
    #[test]
    fn the_inertia_rate_is_the_derivative_of_the_moving_bodys_momentum() {
        let (inertial, pose) = body();
        let velocity = Motion {
            angular: DVec3::new(0.3, 0.8, -0.5),
            linear: DVec3::new(0.1, -0.2, 0.4),
        };
        let fixed = Motion {
            angular: DVec3::new(-0.2, 0.1, 0.9),
            linear: DVec3::new(0.6, 0.3, -0.1),
        };
        let moved = |t: f64| {
            let rotation = glam::DQuat::from_scaled_axis(velocity.angular * t);
            // A body moving with twist V: x ↦ R x + (v_O t) to first order
            // about the origin; second order does not matter for the slope.
            let step = DAffine3::from_rotation_translation(rotation, velocity.linear * t);
            SpatialInertia::from_link_parameters(&inertial.parameters(), &(step * pose)).apply(fixed)
        };
        let h = 1e-6;
        let (ahead, behind) = (moved(h), moved(-h));
        let slope_moment = (ahead.moment - behind.moment) / (2.0 * h);
        let slope_force = (ahead.force - behind.force) / (2.0 * h);
        let rate = SpatialInertia::from_link_parameters(&inertial.parameters(), &pose).rate_apply(velocity, fixed);
        assert!((rate.moment - slope_moment).length() < 1e-6, "{rate:?} {slope_moment}");
        assert!((rate.force - slope_force).length() < 1e-6, "{rate:?} {slope_force}");
    }
}
