//! Bounding volume hierarchy over a triangle mesh: exact ray casts (picking)
//! and signed crossing counts (is a point inside a set of closed shells?).

use glam::DVec3;

use crate::core::mesh::TriMesh;

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
}

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
        Self {
            nodes,
            order,
            corners,
        }
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

    /// Winding number of the surface about `p`, voted over three skew rays
    /// so that a ray grazing an edge or vertex does not decide alone.
    #[must_use]
    pub fn winding_number(&self, p: DVec3) -> i32 {
        const DIRS: [DVec3; 3] = [
            DVec3::new(0.573_462_9, 0.611_524_1, 0.545_123_7),
            DVec3::new(-0.704_918_3, 0.127_354_9, 0.697_721_1),
            DVec3::new(0.183_726_4, -0.892_615_5, -0.411_714_2),
        ];
        let mut w = DIRS.map(|d| self.crossings(p, d));
        w.sort_unstable();
        w[1]
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
    nodes.push(Node {
        lo,
        hi,
        start: offset as u32,
        count: len as u32,
        right: 0,
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
    use crate::core::primitives::{self, Primitive};
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
        assert!(bvh.ray_cast(DVec3::new(3.0, 0.0, 5.0), DVec3::NEG_Z, f64::INFINITY).is_none());
        assert!(bvh.ray_cast(DVec3::new(0.0, 0.0, 5.0), DVec3::Z, f64::INFINITY).is_none());
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
        assert_eq!(bvh.winding_number(DVec3::new(-3.0, 0.0, 1.0 + 1e-9)), 0);
    }

    #[test]
    fn winding_counts_overlapping_shells() {
        let mut mesh = Primitive::Sphere {
            center: DVec3::ZERO,
            radius: 1.0,
        }
        .mesh(32);
        mesh.append(
            &primitives::cuboid(DVec3::splat(1.0))
                .transformed(&DAffine3::from_translation(DVec3::new(0.8, 0.0, 0.0))),
        );
        let bvh = Bvh::new(&mesh);
        assert_eq!(bvh.winding_number(DVec3::new(-0.5, 0.0, 0.0)), 1);
        assert_eq!(bvh.winding_number(DVec3::new(0.6, 0.0, 0.0)), 2);
        assert_eq!(bvh.winding_number(DVec3::new(1.2, 0.0, 0.0)), 1);
        assert_eq!(bvh.winding_number(DVec3::new(2.0, 0.0, 0.0)), 0);
    }
}
