//! A link's surface as a continuous, smooth shell: the oriented triangle
//! mesh with crease-aware normals interpolated across each triangle, and
//! walks across its edges. Contacts live anywhere on it, not only at
//! sample points: this is where the estimate is refined below the
//! sampling's resolution.
//!
//! Why interpolated normals: a mesh is a tessellation of a smooth cover.
//! Its facets' normals jump by 10–20° between neighbours on a 6 cm tube,
//! and a push's torques depend on its direction, so facet normals would
//! make the likelihood jump at every edge (an artefact of the tessellation,
//! not of the arm). Normals averaged over the faces around each vertex
//! that meet it at less than [`CREASE_DEGREES`], then interpolated, vary
//! smoothly over smooth parts and keep real edges sharp.

use std::collections::HashMap;

use glam::DVec3;

use crate::core::geometry::mesh::{OrientReport, TriMesh, weld_map};

/// Faces meeting at a vertex at more than this angle keep their own
/// normals there (a crease, such as the rim of a housing).
pub const CREASE_DEGREES: f64 = 40.0;

/// No neighbour across an edge (an open boundary or a non-manifold edge).
pub const NO_NEIGHBOUR: u32 = u32::MAX;

/// A point on a [`SmoothMesh`]: a triangle and the barycentric weights of
/// its second and third corners (the first's is `1 - w1 - w2`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MeshPoint {
    /// Triangle index.
    pub triangle: u32,
    /// Weights of corners 1 and 2.
    pub weights: [f64; 2],
}

/// The surface around a point, in the link's frame: position, inward
/// normal, an orthonormal tangent basis, and how the push line
/// `(p × n, n)` changes per metre along each tangent.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SurfaceFrame {
    /// Position, m.
    pub point: DVec3,
    /// Inward unit normal (the push direction).
    pub inward_normal: DVec3,
    /// Unit tangents, orthogonal to each other.
    pub tangents: [DVec3; 2],
    /// `∂(p × n, n)/∂s_i` for a move of `s_i` metres along tangent i
    /// (moment part first).
    pub line_derivatives: [[f64; 6]; 2],
}

impl SurfaceFrame {
    /// The push line `(p × n, n)` as six numbers (moment first).
    #[must_use]
    pub fn line(&self) -> [f64; 6] {
        let m = self.point.cross(self.inward_normal);
        let n = self.inward_normal;
        [m.x, m.y, m.z, n.x, n.y, n.z]
    }
}

/// The push line of a point with a given inward normal and its
/// derivatives, given how position and normal change along two tangents.
fn line_derivatives(point: DVec3, inward: DVec3, dp: [DVec3; 2], dn: [DVec3; 2]) -> [[f64; 6]; 2] {
    let one = |i: usize| {
        let m = dp[i].cross(inward) + point.cross(dn[i]);
        [m.x, m.y, m.z, dn[i].x, dn[i].y, dn[i].z]
    };
    [one(0), one(1)]
}

/// An oriented triangle mesh with crease-aware corner normals and edge
/// neighbours.
#[derive(Debug, Clone, PartialEq)]
pub struct SmoothMesh {
    /// The mesh, every shell wound outward, degenerate triangles dropped.
    pub mesh: TriMesh,
    /// Outward unit normal at each corner of each triangle.
    pub corner_normals: Vec<[DVec3; 3]>,
    /// Per triangle, the triangle across the edge from corner i to corner
    /// i + 1 ([`NO_NEIGHBOUR`] if none).
    pub neighbours: Vec<[u32; 3]>,
    /// What orienting the shells found.
    pub report: OrientReport,
}

/// The corners `(triangle, angle)` around one vertex as `(face normal,
/// angle)`. Around a vertex of more than [`GROUPED_FROM`] corners, one
/// entry per distinct normal (to 1e-9, far below any crease) with the
/// angles summed, in the order the normals first appear; around the
/// others one entry per corner, so that their sums are formed in the
/// same order as ever (a regrouped sum moves the normals in their last
/// bits, and every estimate with them).
/// Corners around one vertex beyond which they are grouped by plane.
const GROUPED_FROM: usize = 64;

fn by_plane(face: &[DVec3], corners: Vec<(usize, f64)>) -> Vec<(DVec3, f64)> {
    // Most vertices meet a handful of planes: a scan of those is cheaper
    // than a map; past this many planes the map keeps a cone's tip linear.
    const SCANNED: usize = 16;
    if corners.len() <= GROUPED_FROM {
        return corners
            .into_iter()
            .map(|(t, angle)| (face.get(t).copied().unwrap_or(DVec3::ZERO), angle))
            .collect();
    }
    let key = |normal: DVec3| (normal * 1e9).round().to_array().map(|x| x as i64);
    let mut planes: Vec<([i64; 3], DVec3, f64)> = Vec::new();
    let mut index: HashMap<[i64; 3], usize> = HashMap::new();
    for (t, angle) in corners {
        let normal = face.get(t).copied().unwrap_or(DVec3::ZERO);
        let k = key(normal);
        let found = if planes.len() <= SCANNED {
            planes.iter().position(|p| p.0 == k)
        } else {
            if index.is_empty() {
                index.extend(planes.iter().enumerate().map(|(i, p)| (p.0, i)));
            }
            index.get(&k).copied()
        };
        if let Some(plane) = found.and_then(|i| planes.get_mut(i)) {
            plane.2 += angle;
        } else {
            if !index.is_empty() {
                index.insert(k, planes.len());
            }
            planes.push((k, normal, angle));
        }
    }
    planes.into_iter().map(|(_, normal, angle)| (normal, angle)).collect()
}

impl SmoothMesh {
    /// Orients `mesh`, finds edge neighbours and corner normals.
    #[must_use]
    pub fn new(mesh: &TriMesh) -> Self {
        let mut mesh = mesh.clone();
        let report = mesh.orient_shells();
        let weld = weld_map(&mesh.positions);
        let welded = |t: &[u32; 3]| t.map(|i| weld.get(i as usize).copied().unwrap_or(i));
        let face: Vec<DVec3> = (0..mesh.triangles.len())
            .map(|t| {
                mesh.corners(t)
                    .map_or(DVec3::ZERO, |c| (c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero())
            })
            .collect();
        // Edges by their welded end points: two triangles make a neighbour pair.
        let mut edges: HashMap<(u32, u32), Vec<(u32, usize)>> = HashMap::with_capacity(mesh.triangles.len() * 2);
        // Corners by welded vertex: (triangle, face normal, corner angle).
        let mut around: HashMap<u32, Vec<(usize, f64)>> = HashMap::with_capacity(mesh.positions.len());
        for (t, tri) in mesh.triangles.iter().enumerate() {
            let w = welded(tri);
            let corners = mesh.corners(t).unwrap_or([DVec3::ZERO; 3]);
            for k in 0..3 {
                let (a, b) = (w[k], w[(k + 1) % 3]);
                edges.entry((a.min(b), a.max(b))).or_default().push((t as u32, k));
                let (p, prev, next) = (corners[k], corners[(k + 2) % 3], corners[(k + 1) % 3]);
                let angle = (next - p).angle_between(prev - p);
                around
                    .entry(w[k])
                    .or_default()
                    .push((t, if angle.is_finite() { angle } else { 0.0 }));
            }
        }
        // Corners around a vertex grouped by their face's plane: a fan of
        // coplanar faces (a cylinder's cap, a CAD export's triangulated
        // flat) is one entry, so each corner below sums over the planes
        // around its vertex rather than over every face.
        let around: HashMap<u32, Vec<(DVec3, f64)>> = around
            .into_iter()
            .map(|(vertex, corners)| (vertex, by_plane(&face, corners)))
            .collect();
        let mut neighbours = vec![[NO_NEIGHBOUR; 3]; mesh.triangles.len()];
        for uses in edges.values() {
            if let [(t0, k0), (t1, k1)] = uses.as_slice() {
                neighbours[*t0 as usize][*k0] = *t1;
                neighbours[*t1 as usize][*k1] = *t0;
            }
        }
        let cos_crease = CREASE_DEGREES.to_radians().cos();
        let corner_normals = mesh
            .triangles
            .iter()
            .enumerate()
            .map(|(t, tri)| {
                let own = face[t];
                welded(tri).map(|w| {
                    let sum: DVec3 = around.get(&w).map_or(DVec3::ZERO, |list| {
                        list.iter()
                            .filter(|(normal, _)| normal.dot(own) >= cos_crease)
                            .map(|(normal, angle)| *normal * *angle)
                            .sum()
                    });
                    sum.try_normalize().unwrap_or(own)
                })
            })
            .collect();
        Self {
            mesh,
            corner_normals,
            neighbours,
            report,
        }
    }

    /// Number of triangles.
    #[must_use]
    pub fn len(&self) -> usize {
        self.mesh.triangles.len()
    }

    /// True without triangles.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.mesh.triangles.is_empty()
    }

    /// The outward unit normal of triangle `t`'s plane.
    #[must_use]
    pub fn face_normal(&self, t: usize) -> DVec3 {
        self.mesh
            .corners(t)
            .map_or(DVec3::ZERO, |c| (c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero())
    }

    /// Position of a mesh point, m.
    #[must_use]
    pub fn point(&self, at: MeshPoint) -> Option<DVec3> {
        let c = self.mesh.corners(at.triangle as usize)?;
        let [w1, w2] = at.weights;
        Some(c[0] * (1.0 - w1 - w2) + c[1] * w1 + c[2] * w2)
    }

    /// The surface frame at a mesh point: the interpolated inward normal
    /// and the push line's derivatives along two tangents of the triangle.
    #[must_use]
    pub fn frame(&self, at: MeshPoint) -> Option<SurfaceFrame> {
        let t = at.triangle as usize;
        let c = self.mesh.corners(t)?;
        let normals = self.corner_normals.get(t)?;
        let [w1, w2] = at.weights;
        let point = c[0] * (1.0 - w1 - w2) + c[1] * w1 + c[2] * w2;
        let (e1, e2) = (c[1] - c[0], c[2] - c[0]);
        let face = e1.cross(e2).try_normalize()?;
        let summed = normals[0] * (1.0 - w1 - w2) + normals[1] * w1 + normals[2] * w2;
        let length = summed.length();
        // Corner normals more than 90° apart can cancel: use the face's.
        let (outward, dm) = if length > 1e-6 {
            (summed / length, [normals[1] - normals[0], normals[2] - normals[0]])
        } else {
            (face, [DVec3::ZERO; 2])
        };
        let t1 = e1.try_normalize()?;
        let t2 = face.cross(t1);
        // Weights per metre along each tangent: [e1 e2] dw = t_i.
        let g = [[e1.dot(t1), e2.dot(t1)], [e1.dot(t2), e2.dot(t2)]];
        let det = g[0][0] * g[1][1] - g[0][1] * g[1][0];
        if det.abs() < f64::MIN_POSITIVE {
            return None;
        }
        let dw = |i: usize| -> [f64; 2] {
            // Solve g dw = unit vector i (row i of the tangent basis).
            let rhs = if i == 0 { [1.0, 0.0] } else { [0.0, 1.0] };
            [
                (rhs[0] * g[1][1] - g[0][1] * rhs[1]) / det,
                (g[0][0] * rhs[1] - g[1][0] * rhs[0]) / det,
            ]
        };
        let dn = |i: usize| -> DVec3 {
            let [d1, d2] = dw(i);
            let dm = dm[0] * d1 + dm[1] * d2;
            // Derivative of m/|m|, inward (negated).
            let d_out = (dm - outward * outward.dot(dm)) / length.max(1e-6);
            -d_out
        };
        let inward = -outward;
        let dn = [dn(0), dn(1)];
        Some(SurfaceFrame {
            point,
            inward_normal: inward,
            tangents: [t1, t2],
            line_derivatives: line_derivatives(point, inward, [t1, t2], dn),
        })
    }

    /// The point of the mesh nearest `p` and the surface frame there;
    /// `None` for a mesh without usable triangles.
    #[must_use]
    pub fn closest(&self, p: DVec3) -> Option<(MeshPoint, SurfaceFrame)> {
        let mut best: Option<(f64, usize, DVec3)> = None;
        for t in 0..self.len() {
            let Some(c) = self.mesh.corners(t) else { continue };
            let q = crate::core::geometry::mesh::closest_point_on_triangle(p, &c);
            let d = q.distance_squared(p);
            if best.is_none_or(|(bd, _, _)| d < bd) {
                best = Some((d, t, q));
            }
        }
        let (_, t, q) = best?;
        let c = self.mesh.corners(t)?;
        let at = MeshPoint {
            triangle: t as u32,
            weights: barycentric_weights(q, &c),
        };
        Some((at, self.frame(at)?))
    }

    /// Moves from `at` by `step` (m, in the link frame; its part normal
    /// to the current triangle is dropped) along the surface: straight
    /// within a triangle, unfolded across each edge into the neighbour's
    /// plane. Stops at an open edge.
    #[must_use]
    pub fn walk(&self, at: MeshPoint, step: DVec3) -> MeshPoint {
        let mut at = at;
        let mut step = step;
        for _ in 0..256 {
            let t = at.triangle as usize;
            let Some(c) = self.mesh.corners(t) else { return at };
            let (e1, e2) = (c[1] - c[0], c[2] - c[0]);
            let Some(face) = e1.cross(e2).try_normalize() else {
                return at;
            };
            step -= face * face.dot(step);
            if step.length_squared() < 1e-30 {
                return at;
            }
            // Weight changes of the step: [e1 e2] d = step (least squares).
            let (g11, g12, g22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
            let (r1, r2) = (e1.dot(step), e2.dot(step));
            let det = g11 * g22 - g12 * g12;
            if det.abs() < f64::MIN_POSITIVE {
                return at;
            }
            let d = [(r1 * g22 - g12 * r2) / det, (g11 * r2 - g12 * r1) / det];
            let w = [1.0 - at.weights[0] - at.weights[1], at.weights[0], at.weights[1]];
            let dw = [-d[0] - d[1], d[0], d[1]];
            // The first barycentric weight to reach 0 along the step.
            let mut exit: Option<(f64, usize)> = None;
            for k in 0..3 {
                if dw[k] < 0.0 {
                    let s = (-w[k] / dw[k]).max(0.0);
                    if s < 1.0 && exit.is_none_or(|(best, _)| s < best) {
                        exit = Some((s, k));
                    }
                }
            }
            let Some((s, k)) = exit else {
                return MeshPoint {
                    triangle: at.triangle,
                    weights: [at.weights[0] + d[0], at.weights[1] + d[1]],
                };
            };
            // On the edge opposite corner k: between corners k+1 and k+2,
            // which is edge index (k + 1) % 3 in `neighbours`.
            let mut on = [w[0] + s * dw[0], w[1] + s * dw[1], w[2] + s * dw[2]];
            on[k] = 0.0;
            let edge = (k + 1) % 3;
            let next = self.neighbours.get(t).map_or(NO_NEIGHBOUR, |n| n[edge]);
            let here = MeshPoint {
                triangle: at.triangle,
                weights: [on[1], on[2]],
            };
            if next == NO_NEIGHBOUR {
                return here;
            }
            let Some(point) = self.point(here) else { return here };
            let Some(nc) = self.mesh.corners(next as usize) else {
                return here;
            };
            let Some(next_face) = (nc[1] - nc[0]).cross(nc[2] - nc[0]).try_normalize() else {
                return here;
            };
            // Unfold the rest of the step about the shared edge.
            let rest = step * (1.0 - s);
            let axis = (c[(edge + 1) % 3] - c[edge]).normalize_or_zero();
            let along = axis * axis.dot(rest);
            let across = rest - along;
            // Old triangle: `axis × face` points out of it across the edge;
            // the neighbour runs the edge the other way, so `axis ×
            // next_face` points into it.
            let magnitude = across.dot(axis.cross(face));
            step = along + axis.cross(next_face) * magnitude;
            at = MeshPoint {
                triangle: next,
                weights: barycentric_weights(point, &nc),
            };
        }
        at
    }
}

/// Weights of corners 1 and 2 of the point of triangle `c`'s plane
/// nearest `p`, clamped into the triangle.
#[must_use]
pub fn barycentric_weights(p: DVec3, c: &[DVec3; 3]) -> [f64; 2] {
    let (e1, e2, d) = (c[1] - c[0], c[2] - c[0], p - c[0]);
    let (g11, g12, g22) = (e1.dot(e1), e1.dot(e2), e2.dot(e2));
    let (r1, r2) = (e1.dot(d), e2.dot(d));
    let det = g11 * g22 - g12 * g12;
    if det.abs() < f64::MIN_POSITIVE {
        return [0.0, 0.0];
    }
    let w1 = ((r1 * g22 - g12 * r2) / det).max(0.0);
    let w2 = ((g11 * r2 - g12 * r1) / det).max(0.0);
    let sum = w1 + w2;
    if sum > 1.0 { [w1 / sum, w2 / sum] } else { [w1, w2] }
}

/// The surface frame of a point on a segment link (the thesis' simple
/// robot): the push is perpendicular to the segment at angle `theta`
/// around it; tangent 1 runs along the segment, tangent 2 turns the
/// normal, scaled so that `radius_m` of it is one radian.
#[must_use]
pub fn segment_frame(segment: [DVec3; 2], along_m: f64, theta: f64, radius_m: f64) -> SurfaceFrame {
    let axis = (segment[1] - segment[0]).normalize_or(DVec3::Z);
    let (u, v) = axis.any_orthonormal_pair();
    let point = segment[0] + axis * along_m;
    let inward = u * theta.cos() + v * theta.sin();
    let turn = (v * theta.cos() - u * theta.sin()) / radius_m.max(1e-9);
    SurfaceFrame {
        point,
        inward_normal: inward,
        tangents: [axis, (v * theta.cos() - u * theta.sin())],
        line_derivatives: line_derivatives(point, inward, [axis, DVec3::ZERO], [DVec3::ZERO, turn]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::primitives::Primitive;

    fn cylinder() -> SmoothMesh {
        SmoothMesh::new(
            &Primitive::Cylinder {
                from: DVec3::ZERO,
                to: DVec3::new(0.0, 0.0, 0.3),
                radius: 0.06,
            }
            .mesh(48),
        )
    }

    #[test]
    fn normals_on_a_cylinder_side_are_radial_and_caps_stay_flat() {
        let m = cylinder();
        for t in 0..m.len() {
            let face = m.face_normal(t);
            for w in [[0.2, 0.3], [0.5, 0.5], [0.0, 0.0], [0.1, 0.8]] {
                let at = MeshPoint {
                    triangle: t as u32,
                    weights: w,
                };
                let f = m.frame(at).unwrap();
                let p = f.point;
                if face.z.abs() > 0.99 {
                    // A cap: its normal is the cap's, also at the rim.
                    assert!((f.inward_normal + face).length() < 1e-9, "{t} {w:?}");
                } else {
                    let radial = DVec3::new(p.x, p.y, 0.0).normalize();
                    // Interpolated between corner normals 7.5° apart: within 1°.
                    assert!(f.inward_normal.dot(-radial) > 1f64.to_radians().cos(), "{t} {w:?}");
                }
            }
        }
    }

    #[test]
    fn line_derivatives_match_finite_differences() {
        let m = cylinder();
        for t in (0..m.len()).step_by(7) {
            let at = MeshPoint {
                triangle: t as u32,
                weights: [0.25, 0.35],
            };
            let f = m.frame(at).unwrap();
            for (i, tangent) in f.tangents.iter().enumerate() {
                let h = 1e-6;
                let moved = m.walk(at, *tangent * h);
                let back = m.walk(at, -*tangent * h);
                let (l1, l0) = (m.frame(moved).unwrap().line(), m.frame(back).unwrap().line());
                for c in 0..6 {
                    let fd = (l1[c] - l0[c]) / (2.0 * h);
                    assert!(
                        (fd - f.line_derivatives[i][c]).abs() < 1e-5 * (1.0 + fd.abs()),
                        "triangle {t}, tangent {i}, component {c}: {fd} vs {}",
                        f.line_derivatives[i][c]
                    );
                }
            }
        }
    }

    #[test]
    fn walking_around_a_cylinder_keeps_to_its_surface_and_comes_back() {
        let m = cylinder();
        // Start on the side, walk once around the circumference in steps.
        let start_t = (0..m.len()).find(|&t| m.face_normal(t).z.abs() < 0.1).unwrap();
        let mut at = MeshPoint {
            triangle: start_t as u32,
            weights: [0.3, 0.3],
        };
        let p0 = m.point(at).unwrap();
        let circumference =
            std::f64::consts::TAU * 0.06 * (std::f64::consts::PI / 48.0).sin() / (std::f64::consts::PI / 48.0);
        let steps = 200;
        for _ in 0..steps {
            // Horizontal in the triangle's plane: a geodesic of the prism.
            let tangent = DVec3::Z.cross(m.face_normal(at.triangle as usize)).normalize();
            at = m.walk(at, tangent * (circumference / f64::from(steps)));
            let q = m.point(at).unwrap();
            // On the side: 6 cm from the axis, within the chord sag.
            let r = (q.x * q.x + q.y * q.y).sqrt();
            assert!(
                r <= 0.06 + 1e-9 && r > 0.06 * (std::f64::consts::PI / 48.0).cos() - 1e-9,
                "{r}"
            );
        }
        let p1 = m.point(at).unwrap();
        assert!(p1.distance(p0) < 1e-6, "{p0} -> {p1}");
    }

    #[test]
    fn segment_frames_turn_the_normal_about_the_axis() {
        let seg = [DVec3::ZERO, DVec3::new(0.0, 0.0, 1.0)];
        let f = segment_frame(seg, 0.4, 0.3, 0.05);
        let h = 1e-6;
        let (g, b) = (
            segment_frame(seg, 0.4, 0.3 + h / 0.05, 0.05),
            segment_frame(seg, 0.4, 0.3 - h / 0.05, 0.05),
        );
        for c in 0..6 {
            let fd = (g.line()[c] - b.line()[c]) / (2.0 * h);
            assert!((fd - f.line_derivatives[1][c]).abs() < 1e-6, "{c}");
        }
        let (g, b) = (
            segment_frame(seg, 0.4 + h, 0.3, 0.05),
            segment_frame(seg, 0.4 - h, 0.3, 0.05),
        );
        for c in 0..6 {
            let fd = (g.line()[c] - b.line()[c]) / (2.0 * h);
            assert!((fd - f.line_derivatives[0][c]).abs() < 1e-6, "{c}");
        }
    }
}
