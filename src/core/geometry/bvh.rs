//! Bounding volume hierarchy over a triangle mesh: exact ray casts (picking)
//! and signed crossing counts (is a point inside a set of closed shells?).

use glam::DVec3;

use crate::core::geometry::mesh::TriMesh;

const LEAF_SIZE: usize = 4;

/// Where a ray meets a triangle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RayHit {
    /// Distance along the ray, in units of the direction's length.
    pub t: f64,
    /// Index of the triangle hit.
    pub triangle: usize,
    /// Barycentric coordinates `(u, v)` of the hit; the point is
    /// `(1-u-v) a + u b + v c`.
    pub barycentric: (f64, f64),
    /// True when the ray enters through the triangle's outward side.
    pub front_face: bool,
}

#[derive(Debug, Clone, Copy)]
struct Node {
    lo: DVec3,
    hi: DVec3,
    /// For a leaf, the range in `order`; for an inner node, `start` is the
    /// index of the left child and `count` is 0 (the right child follows
    /// the left subtree, at `right`).
    start: u32,
    count: u32,
    right: u32,
    /// Sum of area-weighted outward normals (half the cross products).
    dipole: DVec3,
    /// Area-weighted centroid of the triangles below.
    center: DVec3,
    /// Distance from `center` to the farthest corner below.
    radius: f64,
}

/// A node farther than this many radii is approximated by its dipole in
/// [`Bvh::winding_number`] (error below 1e-2, far below the 0.5 threshold
/// of an inside test).
const FAR_RADII: f64 = 3.0;

/// A BVH over the triangles of one mesh (a copy of the corners is kept so
/// that the tree owns what it tests).
#[derive(Debug, Clone)]
pub struct Bvh {
    nodes: Vec<Node>,
    order: Vec<u32>,
    corners: Vec<[DVec3; 3]>,
}

impl Bvh {
    /// Builds the tree (median split on the longest axis of the centroids).
    #[must_use]
    pub fn new(mesh: &TriMesh) -> Self {
        let corners: Vec<[DVec3; 3]> = mesh.triangle_corners().collect();
        let centroids: Vec<DVec3> = corners.iter().map(|c| (c[0] + c[1] + c[2]) / 3.0).collect();
        let mut order: Vec<u32> = (0..corners.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * corners.len() / LEAF_SIZE + 1);
        if !corners.is_empty() {
            build(&mut nodes, &mut order, &corners, &centroids, 0, corners.len());
        }
        Self { nodes, order, corners }
    }

    /// Number of triangles in the tree.
    #[must_use]
    pub fn len(&self) -> usize {
        self.corners.len()
    }

    /// True when the tree holds no triangle.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.corners.is_empty()
    }

    /// The nearest hit with `t` in `(0, t_max]`, front or back face.
    #[must_use]
    pub fn ray_cast(&self, origin: DVec3, dir: DVec3, t_max: f64) -> Option<RayHit> {
        let mut best: Option<RayHit> = None;
        let mut limit = t_max;
        self.visit(origin, dir, |i, tri| {
            if let Some(hit) = intersect(origin, dir, tri, i)
                && hit.t <= limit
            {
                limit = hit.t;
                best = Some(hit);
            }
            limit
        });
        best
    }

    /// Signed count of surface crossings along the ray from `origin`:
    /// +1 for each exit through an outward-facing triangle, -1 for each
    /// entry. For closed, outward-wound shells this is the number of shells
    /// that contain `origin`.
    #[must_use]
    pub fn crossings(&self, origin: DVec3, dir: DVec3) -> i32 {
        let mut count = 0;
        self.visit(origin, dir, |i, tri| {
            if let Some(hit) = intersect(origin, dir, tri, i) {
                count += if hit.front_face { -1 } else { 1 };
            }
            f64::INFINITY
        });
        count
    }

    /// Generalised winding number of the surface about `p`: the signed
    /// solid angle it subtends over 4π. About 1 inside a closed
    /// outward-wound shell, 0 outside, fractional near holes of an open
    /// one, and the sum over overlapping shells; unlike ray parity it does
    /// not break on meshes with holes.
    #[must_use]
    pub fn winding_number(&self, p: DVec3) -> f64 {
        if self.nodes.is_empty() {
            return 0.0;
        }
        let mut total = 0.0;
        let mut stack: Vec<u32> = vec![0];
        while let Some(ni) = stack.pop() {
            let Some(node) = self.nodes.get(ni as usize) else {
                continue;
            };
            let r = node.center - p;
            let d = r.length();
            if d > FAR_RADII * node.radius && d > 0.0 {
                total += node.dipole.dot(r) / (d * d * d);
            } else if node.count > 0 {
                let range = node.start as usize..(node.start + node.count) as usize;
                for &tri in self.order.get(range).unwrap_or(&[]) {
                    if let Some(c) = self.corners.get(tri as usize) {
                        total += solid_angle(p, c);
                    }
                }
            } else {
                stack.push(node.right);
                stack.push(node.start);
            }
        }
        total / (4.0 * std::f64::consts::PI)
    }

    /// Calls `f(triangle, corners)` for each triangle whose box the ray
    /// meets before the distance `f` last returned.
    fn visit(&self, origin: DVec3, dir: DVec3, mut f: impl FnMut(usize, &[DVec3; 3]) -> f64) {
        if self.nodes.is_empty() {
            return;
        }
        let inv = DVec3::ONE / dir;
        let mut limit = f64::INFINITY;
        let mut stack: Vec<u32> = vec![0];
        while let Some(ni) = stack.pop() {
            let Some(node) = self.nodes.get(ni as usize) else {
                continue;
            };
            if !slab_hit(origin, inv, node.lo, node.hi, limit) {
                continue;
            }
            if node.count > 0 {
                let range = node.start as usize..(node.start + node.count) as usize;
                for &tri in self.order.get(range).unwrap_or(&[]) {
                    if let Some(c) = self.corners.get(tri as usize) {
                        limit = limit.min(f(tri as usize, c));
                    }
                }
            } else {
                stack.push(node.right);
                stack.push(node.start);
            }
        }
    }
}

fn build(
    nodes: &mut Vec<Node>,
    order: &mut [u32],
    corners: &[[DVec3; 3]],
    centroids: &[DVec3],
    offset: usize,
    len: usize,
) -> u32 {
    let slice = &mut order[offset..offset + len];
    let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    let (mut clo, mut chi) = (lo, hi);
    for &t in slice.iter() {
        for p in &corners[t as usize] {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        clo = clo.min(centroids[t as usize]);
        chi = chi.max(centroids[t as usize]);
    }
    let index = nodes.len() as u32;
    let (mut dipole, mut weighted, mut area) = (DVec3::ZERO, DVec3::ZERO, 0.0);
    for &t in slice.iter() {
        let c = &corners[t as usize];
        let n = 0.5 * (c[1] - c[0]).cross(c[2] - c[0]);
        dipole += n;
        weighted += centroids[t as usize] * n.length();
        area += n.length();
    }
    let center = if area > 0.0 { weighted / area } else { 0.5 * (lo + hi) };
    let radius = slice
        .iter()
        .flat_map(|&t| corners[t as usize])
        .map(|p| p.distance(center))
        .fold(0.0, f64::max);
    nodes.push(Node {
        lo,
        hi,
        start: offset as u32,
        count: len as u32,
        right: 0,
        dipole,
        center,
        radius,
    });
    if len <= LEAF_SIZE {
        return index;
    }
    let extent = chi - clo;
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = len / 2;
    slice.select_nth_unstable_by(mid, |a, b| {
        centroids[*a as usize][axis].total_cmp(&centroids[*b as usize][axis])
    });
    let left = build(nodes, order, corners, centroids, offset, mid);
    let right = build(nodes, order, corners, centroids, offset + mid, len - mid);
    let node = &mut nodes[index as usize];
    node.start = left;
    node.count = 0;
    node.right = right;
    index
}

/// Signed solid angle of triangle `c` seen from `p` (Van Oosterom and
/// Strackee); positive when `p` is behind the outward face.
fn solid_angle(p: DVec3, c: &[DVec3; 3]) -> f64 {
    let (a, b, cc) = (c[0] - p, c[1] - p, c[2] - p);
    let (la, lb, lc) = (a.length(), b.length(), cc.length());
    let num = a.dot(b.cross(cc));
    let den = la * lb * lc + a.dot(b) * lc + a.dot(cc) * lb + b.dot(cc) * la;
    2.0 * num.atan2(den)
}

fn slab_hit(origin: DVec3, inv: DVec3, lo: DVec3, hi: DVec3, limit: f64) -> bool {
    let t1 = (lo - origin) * inv;
    let t2 = (hi - origin) * inv;
    // NaN (0 * inf on a slab face) is dropped by min/max, which keeps the box.
    let tmin = t1.min(t2).max_element().max(0.0);
    let tmax = t1.max(t2).min_element().min(limit);
    tmin <= tmax
}

/// Möller–Trumbore, both faces, hits with `t > 0`.
fn intersect(origin: DVec3, dir: DVec3, c: &[DVec3; 3], triangle: usize) -> Option<RayHit> {
    let e1 = c[1] - c[0];
    let e2 = c[2] - c[0];
    let pvec = dir.cross(e2);
    let det = e1.dot(pvec);
    if det.abs() < 1e-300 {
        return None;
    }
    let inv_det = 1.0 / det;
    let tvec = origin - c[0];
    let u = tvec.dot(pvec) * inv_det;
    if !(0.0..=1.0).contains(&u) {
        return None;
    }
    let qvec = tvec.cross(e1);
    let v = dir.dot(qvec) * inv_det;
    if v < 0.0 || u + v > 1.0 {
        return None;
    }
    let t = e2.dot(qvec) * inv_det;
    (t > 0.0).then_some(RayHit {
        t,
        triangle,
        barycentric: (u, v),
        // det > 0 means the ray runs against the outward normal e1 x e2.
        front_face: det > 0.0,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::primitives::{self, Primitive};
    use glam::DAffine3;

    #[test]
    fn hits_front_face_of_a_cube_at_the_right_distance() {
        let bvh = Bvh::new(&primitives::cuboid(DVec3::splat(2.0)));
        let hit = bvh.ray_cast(DVec3::new(0.3, 0.2, 5.0), DVec3::NEG_Z, f64::INFINITY);
        let hit = hit.unwrap_or(RayHit {
            t: -1.0,
            triangle: 0,
            barycentric: (0.0, 0.0),
            front_face: false,
        });
        assert!((hit.t - 4.0).abs() < 1e-12);
        assert!(hit.front_face);
    }

    #[test]
    fn misses_and_t_max_are_respected() {
        let bvh = Bvh::new(&primitives::cuboid(DVec3::splat(2.0)));
        assert!(
            bvh.ray_cast(DVec3::new(3.0, 0.0, 5.0), DVec3::NEG_Z, f64::INFINITY)
                .is_none()
        );
        assert!(
            bvh.ray_cast(DVec3::new(0.0, 0.0, 5.0), DVec3::Z, f64::INFINITY)
                .is_none()
        );
        assert!(bvh.ray_cast(DVec3::new(0.0, 0.0, 5.0), DVec3::NEG_Z, 3.9).is_none());
    }

    #[test]
    fn from_inside_the_hit_is_a_back_face() {
        let bvh = Bvh::new(&primitives::cuboid(DVec3::splat(2.0)));
        let hit = bvh.ray_cast(DVec3::ZERO, DVec3::X, f64::INFINITY);
        assert!(hit.is_some_and(|h| !h.front_face && (h.t - 1.0).abs() < 1e-12));
    }

    #[test]
    fn grazing_ray_along_a_face_plane_does_not_report_a_false_inside() {
        let bvh = Bvh::new(&primitives::cuboid(DVec3::splat(2.0)));
        // In the plane of the +z face, outside the cube.
        assert!(bvh.winding_number(DVec3::new(-3.0, 0.0, 1.0 + 1e-9)).abs() < 1e-6);
    }

    #[test]
    fn winding_counts_overlapping_shells() {
        let mut mesh = Primitive::Sphere {
            center: DVec3::ZERO,
            radius: 1.0,
        }
        .mesh(32);
        mesh.append(
            &primitives::cuboid(DVec3::splat(1.0)).transformed(&DAffine3::from_translation(DVec3::new(0.8, 0.0, 0.0))),
        );
        let bvh = Bvh::new(&mesh);
        let w = |x: f64| bvh.winding_number(DVec3::new(x, 0.0, 0.0));
        assert!((w(-0.5) - 1.0).abs() < 1e-2);
        assert!((w(0.6) - 2.0).abs() < 1e-2);
        assert!((w(1.2) - 1.0).abs() < 1e-2);
        assert!(w(2.0).abs() < 1e-2);
        assert!(w(30.0).abs() < 1e-2);
    }

    #[test]
    fn open_cup_has_a_fractional_winding_number_at_its_mouth() {
        // A closed cube without its top face: about 1 deep inside, about 0
        // far outside, about 1/2 at the centre of the missing face.
        let mut cup = primitives::cuboid(DVec3::splat(2.0));
        cup.triangles.truncate(2);
        cup.triangles
            .extend(primitives::cuboid(DVec3::splat(2.0)).triangles[4..].iter().copied());
        let bvh = Bvh::new(&cup);
        assert!((bvh.winding_number(DVec3::new(0.0, 0.0, -0.9)) - 0.9).abs() < 0.1);
        assert!((bvh.winding_number(DVec3::new(0.0, 0.0, 1.0)) - 0.5).abs() < 1e-9);
        assert!(bvh.winding_number(DVec3::new(0.0, 0.0, 5.0)).abs() < 0.05);
    }
}
