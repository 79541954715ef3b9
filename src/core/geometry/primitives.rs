//! Rounded solid primitives (spheres, cylinders, capsules, boxes): their
//! triangle meshes and exact signed distances.
//!
//! The built-in LWR is assembled from these, and URDF `<box>`, `<cylinder>`
//! and `<sphere>` geometry is tessellated with them.

use glam::{DAffine3, DQuat, DVec3};

use crate::core::geometry::mesh::TriMesh;

/// A solid shape in a link's frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Primitive {
    /// A ball.
    Sphere {
        /// Centre, m.
        center: DVec3,
        /// Radius, m.
        radius: f64,
    },
    /// A cylinder with flat caps from `from` to `to`.
    Cylinder {
        /// Centre of the first cap, m.
        from: DVec3,
        /// Centre of the second cap, m.
        to: DVec3,
        /// Radius, m.
        radius: f64,
    },
    /// A cylinder from `from` to `to` whose two rims are rounded with
    /// quarter circles of radius `fillet`, like a machined joint housing.
    RoundedCylinder {
        /// Centre of the first cap, m.
        from: DVec3,
        /// Centre of the second cap, m.
        to: DVec3,
        /// Radius, m.
        radius: f64,
        /// Rim rounding radius, m (at most the radius and half the length).
        fillet: f64,
    },
    /// A cylinder with hemispherical caps centred on `from` and `to`.
    Capsule {
        /// Centre of the first hemisphere, m.
        from: DVec3,
        /// Centre of the second hemisphere, m.
        to: DVec3,
        /// Radius, m.
        radius: f64,
    },
    /// A box.
    Cuboid {
        /// Rigid transform from the box's own frame (centred) to the link.
        link_from_box: DAffine3,
        /// Half the edge lengths, m.
        half_extents: DVec3,
    },
}

impl Primitive {
    /// Outward-wound triangle mesh with `segments` facets around the round parts.
    #[must_use]
    pub fn mesh(&self, segments: usize) -> TriMesh {
        let segments = segments.max(3);
        match *self {
            Self::Sphere { center, radius } => {
                sphere(radius, segments).transformed(&DAffine3::from_translation(center))
            }
            Self::Cylinder { from, to, radius } => {
                let length = from.distance(to);
                let profile = vec![(0.0, 0.0), (radius, 0.0), (radius, length), (0.0, length)];
                revolve(&profile, segments).transformed(&along(from, to))
            }
            Self::RoundedCylinder {
                from,
                to,
                radius,
                fillet,
            } => {
                let length = from.distance(to);
                let r = fillet.clamp(0.0, radius.min(0.5 * length));
                let steps = (segments / 4).max(2);
                let mut profile = vec![(0.0, 0.0)];
                for i in 0..=steps {
                    let theta = -std::f64::consts::FRAC_PI_2 + std::f64::consts::FRAC_PI_2 * i as f64 / steps as f64;
                    profile.push((radius - r + r * theta.cos(), r + r * theta.sin()));
                }
                for i in 0..=steps {
                    let theta = std::f64::consts::FRAC_PI_2 * i as f64 / steps as f64;
                    profile.push((radius - r + r * theta.cos(), length - r + r * theta.sin()));
                }
                profile.push((0.0, length));
                profile.dedup();
                revolve(&profile, segments).transformed(&along(from, to))
            }
            Self::Capsule { from, to, radius } => {
                let length = from.distance(to);
                let rings = segments / 2;
                let mut profile = Vec::with_capacity(2 * rings + 2);
                for k in 0..=rings {
                    let phi = -std::f64::consts::FRAC_PI_2 + std::f64::consts::FRAC_PI_2 * k as f64 / rings as f64;
                    profile.push((radius * phi.cos(), radius * phi.sin()));
                }
                for k in 0..=rings {
                    let phi = std::f64::consts::FRAC_PI_2 * k as f64 / rings as f64;
                    profile.push((radius * phi.cos(), length + radius * phi.sin()));
                }
                clean_poles(&mut profile);
                revolve(&profile, segments).transformed(&along(from, to))
            }
            Self::Cuboid {
                link_from_box,
                half_extents,
            } => cuboid(2.0 * half_extents).transformed(&link_from_box),
        }
    }

    /// Signed distance from `p` to the surface, m (negative inside).
    #[must_use]
    pub fn signed_distance(&self, p: DVec3) -> f64 {
        match *self {
            Self::Sphere { center, radius } => p.distance(center) - radius,
            Self::Capsule { from, to, radius } => {
                let d = to - from;
                let t = if d.length_squared() > 0.0 {
                    ((p - from).dot(d) / d.length_squared()).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                p.distance(from + d * t) - radius
            }
            // A plain cylinder is a filleted one with no fillet.
            Self::Cylinder { from, to, radius } => Self::RoundedCylinder {
                from,
                to,
                radius,
                fillet: 0.0,
            }
            .signed_distance(p),
            Self::RoundedCylinder {
                from,
                to,
                radius,
                fillet,
            } => {
                let length = from.distance(to);
                let r = fillet.clamp(0.0, radius.min(0.5 * length));
                let axis = (to - from).normalize_or_zero();
                let rel = p - from;
                let along_axis = rel.dot(axis);
                let radial = (rel - axis * along_axis).length();
                let dr = radial - (radius - r);
                let dz = (along_axis - 0.5 * length).abs() - (0.5 * length - r);
                DVec3::new(dr.max(0.0), dz.max(0.0), 0.0).length() + dr.max(dz).min(0.0) - r
            }
            Self::Cuboid {
                link_from_box,
                half_extents,
            } => {
                let local = link_from_box.inverse().transform_point3(p);
                let q = local.abs() - half_extents;
                q.max(DVec3::ZERO).length() + q.max_element().min(0.0)
            }
        }
    }
}

/// A box of the given full edge lengths centred on the origin.
#[must_use]
pub fn cuboid(size: DVec3) -> TriMesh {
    let h = 0.5 * size;
    let positions = (0..8)
        .map(|i| {
            DVec3::new(
                if i & 1 == 0 { -h.x } else { h.x },
                if i & 2 == 0 { -h.y } else { h.y },
                if i & 4 == 0 { -h.z } else { h.z },
            )
        })
        .collect();
    let quads = [
        [0, 2, 3, 1], // -z
        [4, 5, 7, 6], // +z
        [0, 1, 5, 4], // -y
        [2, 6, 7, 3], // +y
        [0, 4, 6, 2], // -x
        [1, 3, 7, 5], // +x
    ];
    let triangles = quads
        .iter()
        .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
        .collect();
    TriMesh::new(positions, triangles)
}

/// A sphere of `radius` centred on the origin.
#[must_use]
pub fn sphere(radius: f64, segments: usize) -> TriMesh {
    let rings = (segments / 2).max(2);
    let mut profile: Vec<(f64, f64)> = (0..=rings)
        .map(|k| {
            let phi = -std::f64::consts::FRAC_PI_2 + std::f64::consts::PI * k as f64 / rings as f64;
            (radius * phi.cos(), radius * phi.sin())
        })
        .collect();
    clean_poles(&mut profile);
    revolve(&profile, segments)
}

/// Poles must have radius exactly 0 so that `revolve` closes them with fans.
fn clean_poles(profile: &mut [(f64, f64)]) {
    if let Some(first) = profile.first_mut() {
        first.0 = 0.0;
    }
    if let Some(last) = profile.last_mut() {
        last.0 = 0.0;
    }
}

/// The rigid transform taking +z to the direction `from → to`, origin at `from`.
fn along(from: DVec3, to: DVec3) -> DAffine3 {
    let dir = (to - from).normalize_or(DVec3::Z);
    DAffine3::from_rotation_translation(DQuat::from_rotation_arc(DVec3::Z, dir), from)
}

/// Surface of revolution about +z of a profile `(radius, z)` running from a
/// pole (radius 0) to a pole; consecutive equal rings make no triangles.
fn revolve(profile: &[(f64, f64)], segments: usize) -> TriMesh {
    let mut positions = Vec::new();
    let mut triangles = Vec::new();
    let n = profile.len();
    if n < 3 {
        return TriMesh::default();
    }
    // Index of ring k's first vertex; poles have one vertex.
    let mut ring_start = Vec::with_capacity(n);
    for (k, &(r, z)) in profile.iter().enumerate() {
        ring_start.push(positions.len() as u32);
        if k == 0 || k == n - 1 {
            positions.push(DVec3::new(0.0, 0.0, z));
        } else {
            for j in 0..segments {
                let theta = std::f64::consts::TAU * j as f64 / segments as f64;
                positions.push(DVec3::new(r * theta.cos(), r * theta.sin(), z));
            }
        }
    }
    let seg = segments as u32;
    for k in 0..n - 1 {
        for j in 0..seg {
            let jn = (j + 1) % seg;
            if k == 0 {
                let s = ring_start[0];
                let r1 = ring_start[1];
                triangles.push([s, r1 + jn, r1 + j]);
            } else if k == n - 2 {
                let t = ring_start[n - 1];
                let r0 = ring_start[k];
                triangles.push([t, r0 + j, r0 + jn]);
            } else {
                let (a, b) = (ring_start[k], ring_start[k + 1]);
                let same = profile[k] == profile[k + 1];
                if !same {
                    triangles.push([a + j, a + jn, b + jn]);
                    triangles.push([a + j, b + jn, b + j]);
                }
            }
        }
    }
    TriMesh::new(positions, triangles)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn all() -> Vec<Primitive> {
        vec![
            Primitive::Sphere {
                center: DVec3::new(0.1, 0.2, 0.3),
                radius: 0.07,
            },
            Primitive::Cylinder {
                from: DVec3::new(0.0, 0.0, 0.0),
                to: DVec3::new(0.0, 0.1, 0.2),
                radius: 0.06,
            },
            Primitive::Capsule {
                from: DVec3::new(0.0, 0.0, 0.1),
                to: DVec3::new(0.0, -0.05, 0.3),
                radius: 0.05,
            },
            Primitive::RoundedCylinder {
                from: DVec3::new(0.0, 0.0, 0.0),
                to: DVec3::new(0.0, 0.09, 0.0),
                radius: 0.06,
                fillet: 0.015,
            },
            Primitive::Cuboid {
                link_from_box: DAffine3::from_rotation_translation(
                    DQuat::from_rotation_x(0.4),
                    DVec3::new(0.0, 0.1, 0.0),
                ),
                half_extents: DVec3::new(0.1, 0.05, 0.02),
            },
        ]
    }

    #[test]
    fn meshes_are_closed_outward_and_match_closed_form_volume() {
        for p in all() {
            let mesh = p.mesh(64);
            let exact = match p {
                Primitive::Sphere { radius, .. } => 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3),
                Primitive::Cylinder { from, to, radius } => std::f64::consts::PI * radius * radius * from.distance(to),
                Primitive::Capsule { from, to, radius } => {
                    std::f64::consts::PI * radius * radius * from.distance(to)
                        + 4.0 / 3.0 * std::f64::consts::PI * radius.powi(3)
                }
                Primitive::Cuboid { half_extents, .. } => 8.0 * half_extents.x * half_extents.y * half_extents.z,
                Primitive::RoundedCylinder {
                    from,
                    to,
                    radius: big,
                    fillet: r,
                } => {
                    // Pappus: the cylinder less two rim rings, each the area
                    // between a quarter circle and its square swept around
                    // the axis at the radius of that area's centroid.
                    let pi = std::f64::consts::PI;
                    let ring_area = r * r * (1.0 - pi / 4.0);
                    let ring_radius = big - r * (10.0 - 3.0 * pi) / (12.0 - 3.0 * pi);
                    pi * big * big * from.distance(to) - 2.0 * 2.0 * pi * ring_radius * ring_area
                }
            };
            let v = mesh.signed_volume();
            // A 64-gon polyhedron underestimates a round solid by about 1 %.
            assert!(v > 0.0 && (v - exact).abs() < 0.02 * exact, "{p:?}: {v} vs {exact}");
            let mut oriented = mesh.clone();
            let report = oriented.orient_shells();
            assert_eq!(report.shells, 1, "{p:?}");
            assert_eq!(report.flipped, 0, "{p:?}");
            assert_eq!(report.degenerate, 0, "{p:?}");
            assert_eq!(report.boundary_edges, 0, "{p:?}");
        }
    }

    #[test]
    fn mesh_vertices_lie_on_the_surface_of_the_distance_function() {
        for p in all() {
            for v in &p.mesh(48).positions {
                assert!(p.signed_distance(*v).abs() < 1e-12, "{p:?} {v}");
            }
        }
    }

    #[test]
    fn signed_distance_closed_forms() {
        let c = Primitive::Cylinder {
            from: DVec3::ZERO,
            to: DVec3::new(0.0, 0.0, 1.0),
            radius: 0.5,
        };
        assert!((c.signed_distance(DVec3::new(0.0, 0.0, 0.5)) + 0.5).abs() < 1e-15);
        assert!((c.signed_distance(DVec3::new(0.0, 0.0, 1.5)) - 0.5).abs() < 1e-15);
        assert!((c.signed_distance(DVec3::new(1.5, 0.0, 2.0)) - 2f64.sqrt()).abs() < 1e-15);
        let b = Primitive::Cuboid {
            link_from_box: DAffine3::IDENTITY,
            half_extents: DVec3::ONE,
        };
        assert!((b.signed_distance(DVec3::new(0.0, 0.0, 3.0)) - 2.0).abs() < 1e-15);
        assert!((b.signed_distance(DVec3::ZERO) + 1.0).abs() < 1e-15);
    }
}
