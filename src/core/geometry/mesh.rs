//! Triangle meshes in a link's frame: area, volume, shells and their orientation.

use std::collections::HashMap;

use glam::{DAffine3, DVec3};

/// Triangles whose area is below this (m²) are degenerate and skipped.
pub const DEGENERATE_AREA_M2: f64 = 1e-14;

/// An indexed triangle mesh; counter-clockwise triangles face outward when
/// the mesh is well formed (we check, see [`TriMesh::orient_shells`]).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TriMesh {
    /// Vertex positions, metres.
    pub positions: Vec<DVec3>,
    /// Vertex indices, three per triangle.
    pub triangles: Vec<[u32; 3]>,
}

/// What [`TriMesh::orient_shells`] found and changed.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct OrientReport {
    /// Connected shells (triangles sharing welded vertices).
    pub shells: usize,
    /// Shells whose triangles were wound inward and were flipped.
    pub flipped: usize,
    /// Triangles dropped as degenerate (zero area, repeated or non-finite vertices).
    pub degenerate: usize,
    /// Triangles dropped as repeats of an earlier one (the same three
    /// welded corners, in either winding): CAD exports repeat faces, and a
    /// repeated face would count its area twice and give every query near
    /// it one more triangle to test per copy.
    pub repeated: usize,
    /// Edges used by one triangle only: 0 for closed meshes.
    pub boundary_edges: usize,
}

impl TriMesh {
    /// A mesh from positions and triangles (indices are checked by `TriMesh::validate`).
    #[must_use]
    pub fn new(positions: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Self {
        Self { positions, triangles }
    }

    /// True when there are no triangles.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.triangles.is_empty()
    }

    /// The first triangle index that points past the vertex list, if any.
    #[must_use]
    pub fn first_bad_index(&self) -> Option<usize> {
        let n = self.positions.len();
        self.triangles.iter().position(|t| t.iter().any(|&i| i as usize >= n))
    }

    /// Corners of triangle `i`; `None` if `i` or one of its indices is out of range.
    #[must_use]
    pub fn corners(&self, i: usize) -> Option<[DVec3; 3]> {
        let t = self.triangles.get(i)?;
        Some([
            *self.positions.get(t[0] as usize)?,
            *self.positions.get(t[1] as usize)?,
            *self.positions.get(t[2] as usize)?,
        ])
    }

    /// Corners of a triangle given by its indices; `None` if one is out of range.
    #[must_use]
    pub fn corners_of(&self, t: &[u32; 3]) -> Option<[DVec3; 3]> {
        Some([
            *self.positions.get(t[0] as usize)?,
            *self.positions.get(t[1] as usize)?,
            *self.positions.get(t[2] as usize)?,
        ])
    }

    /// Iterator over all triangles' corners (triangles with bad indices are skipped).
    pub fn triangle_corners(&self) -> impl Iterator<Item = [DVec3; 3]> + '_ {
        (0..self.triangles.len()).filter_map(|i| self.corners(i))
    }

    /// Total surface area, m².
    #[must_use]
    pub fn area(&self) -> f64 {
        self.triangle_corners().map(|c| triangle_area(&c)).sum()
    }

    /// Signed enclosed volume, m³ (positive for a closed, outward-wound mesh).
    #[must_use]
    pub fn signed_volume(&self) -> f64 {
        self.triangle_corners().map(|[a, b, c]| a.dot(b.cross(c)) / 6.0).sum()
    }

    /// The mesh with every vertex mapped by `transform`; a transform that
    /// mirrors (negative determinant) also reverses the winding so that
    /// outward stays outward.
    #[must_use]
    pub fn transformed(&self, transform: &DAffine3) -> Self {
        let positions = self.positions.iter().map(|p| transform.transform_point3(*p)).collect();
        let triangles = if transform.matrix3.determinant() < 0.0 {
            self.triangles.iter().map(|t| [t[0], t[2], t[1]]).collect()
        } else {
            self.triangles.clone()
        };
        Self { positions, triangles }
    }

    /// Appends `other`'s triangles to this mesh.
    pub fn append(&mut self, other: &TriMesh) {
        let offset = self.positions.len() as u32;
        self.positions.extend_from_slice(&other.positions);
        self.triangles.extend(
            other
                .triangles
                .iter()
                .map(|t| [t[0] + offset, t[1] + offset, t[2] + offset]),
        );
    }

    /// Axis-aligned bounds `(min, max)`; `None` for a mesh without vertices.
    #[must_use]
    pub fn bounds(&self) -> Option<(DVec3, DVec3)> {
        let first = *self.positions.first()?;
        Some(
            self.positions
                .iter()
                .fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p))),
        )
    }

    /// Drops degenerate and repeated triangles and winds every connected
    /// shell outward.
    ///
    /// Real meshes come with either winding, with duplicated vertices per
    /// face (STL, DAE), with slivers and with repeated faces. Vertices are
    /// welded by position to find shells; a shell with negative signed
    /// volume is flipped.
    pub fn orient_shells(&mut self) -> OrientReport {
        let mut report = OrientReport::default();
        let weld = weld_map(&self.positions);
        let mut kept: Vec<[u32; 3]> = Vec::with_capacity(self.triangles.len());
        let mut seen: std::collections::HashSet<[u32; 3]> =
            std::collections::HashSet::with_capacity(self.triangles.len());
        for i in 0..self.triangles.len() {
            let (Some(c), Some(t)) = (self.corners(i), self.triangles.get(i)) else {
                report.degenerate += 1;
                continue;
            };
            let w = [weld[t[0] as usize], weld[t[1] as usize], weld[t[2] as usize]];
            let finite = c.iter().all(|p| p.is_finite());
            if !finite || w[0] == w[1] || w[1] == w[2] || w[0] == w[2] {
                report.degenerate += 1;
                continue;
            }
            if triangle_area(&c) < DEGENERATE_AREA_M2 {
                report.degenerate += 1;
                continue;
            }
            let mut corners = w;
            corners.sort_unstable();
            if !seen.insert(corners) {
                report.repeated += 1;
                continue;
            }
            kept.push(*t);
        }
        self.triangles = kept;

        // Union-find over welded vertices: triangles sharing one are in one shell.
        let mut parent: Vec<u32> = (0..self.positions.len() as u32).collect();
        for t in &self.triangles {
            let a = find(&mut parent, weld[t[0] as usize]);
            for &k in &t[1..] {
                let b = find(&mut parent, weld[k as usize]);
                if a != b {
                    parent[b as usize] = a;
                }
            }
        }
        let mut shell_of_root: HashMap<u32, usize> = HashMap::new();
        let mut shell_of_triangle = Vec::with_capacity(self.triangles.len());
        for t in &self.triangles {
            let root = find(&mut parent, weld[t[0] as usize]);
            let next = shell_of_root.len();
            shell_of_triangle.push(*shell_of_root.entry(root).or_insert(next));
        }
        report.shells = shell_of_root.len();
        // Signed volume about each shell's own area centroid: for a closed
        // shell the reference point does not matter, and for a shell with
        // small holes (common in visual meshes) the missing caps then add
        // little, whereas about a far origin they can flip the sign.
        let mut centroid = vec![(DVec3::ZERO, 0.0); report.shells];
        for (i, &s) in shell_of_triangle.iter().enumerate() {
            if let Some(c) = self.corners(i) {
                let area = triangle_area(&c);
                centroid[s].0 += (c[0] + c[1] + c[2]) / 3.0 * area;
                centroid[s].1 += area;
            }
        }
        let mut volume = vec![0.0; report.shells];
        for (i, &s) in shell_of_triangle.iter().enumerate() {
            if let Some(c) = self.corners(i) {
                let o = centroid[s].0 / centroid[s].1;
                let [a, b, cc] = c.map(|p| p - o);
                volume[s] += a.dot(b.cross(cc)) / 6.0;
            }
        }
        report.flipped = volume.iter().filter(|v| **v < 0.0).count();
        for (t, &s) in self.triangles.iter_mut().zip(&shell_of_triangle) {
            if volume[s] < 0.0 {
                t.swap(1, 2);
            }
        }
        let mut edge_use: HashMap<(u32, u32), u32> = HashMap::with_capacity(3 * self.triangles.len() / 2);
        for t in &self.triangles {
            let w = t.map(|i| weld[i as usize]);
            for k in 0..3 {
                let (a, b) = (w[k], w[(k + 1) % 3]);
                *edge_use.entry((a.min(b), a.max(b))).or_insert(0) += 1;
            }
        }
        report.boundary_edges = edge_use.values().filter(|n| **n == 1).count();
        report
    }

    /// The point of the mesh nearest to `p`, with the outward unit normal of
    /// its triangle; `None` for a mesh without usable triangles.
    #[must_use]
    pub fn closest_point(&self, p: DVec3) -> Option<(DVec3, DVec3)> {
        let mut best: Option<(f64, DVec3, DVec3)> = None;
        for c in self.triangle_corners() {
            let Some(n) = (c[1] - c[0]).cross(c[2] - c[0]).try_normalize() else {
                continue;
            };
            let q = closest_point_on_triangle(p, &c);
            let d = q.distance_squared(p);
            if best.is_none_or(|(bd, _, _)| d < bd) {
                best = Some((d, q, n));
            }
        }
        best.map(|(_, q, n)| (q, n))
    }
}

/// Area of a triangle, m².
#[must_use]
pub fn triangle_area(c: &[DVec3; 3]) -> f64 {
    0.5 * (c[1] - c[0]).cross(c[2] - c[0]).length()
}

/// The point of triangle `c` nearest to `p` (Voronoi regions of the corners,
/// edges and face).
#[must_use]
pub fn closest_point_on_triangle(p: DVec3, c: &[DVec3; 3]) -> DVec3 {
    let [a, b, cc] = *c;
    let ab = b - a;
    let ac = cc - a;
    let ap = p - a;
    let d1 = ab.dot(ap);
    let d2 = ac.dot(ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return a;
    }
    let bp = p - b;
    let d3 = ab.dot(bp);
    let d4 = ac.dot(bp);
    if d3 >= 0.0 && d4 <= d3 {
        return b;
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return a + ab * (d1 / (d1 - d3));
    }
    let cp = p - cc;
    let d5 = ab.dot(cp);
    let d6 = ac.dot(cp);
    if d6 >= 0.0 && d5 <= d6 {
        return cc;
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return a + ac * (d2 / (d2 - d6));
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return b + (cc - b) * ((d4 - d3) / ((d4 - d3) + (d5 - d6)));
    }
    let denom = va + vb + vc;
    if denom.abs() < f64::MIN_POSITIVE {
        return a;
    }
    a + ab * (vb / denom) + ac * (vc / denom)
}

/// For each vertex, the index of the first vertex at the same position
/// (quantised to 1 µm, far below any feature of an arm).
pub(crate) fn weld_map(positions: &[DVec3]) -> Vec<u32> {
    let mut first: HashMap<[i64; 3], u32> = HashMap::with_capacity(positions.len());
    positions
        .iter()
        .enumerate()
        .map(|(i, p)| {
            let key = [
                (p.x * 1e6).round() as i64,
                (p.y * 1e6).round() as i64,
                (p.z * 1e6).round() as i64,
            ];
            *first.entry(key).or_insert(i as u32)
        })
        .collect()
}

fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        let grand = parent[parent[x as usize] as usize];
        parent[x as usize] = grand;
        x = grand;
    }
    x
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::geometry::primitives;

    #[test]
    fn cube_area_and_volume_are_exact() {
        let cube = primitives::cuboid(DVec3::new(0.1, 0.2, 0.3));
        assert!((cube.area() - 2.0 * (0.02 + 0.06 + 0.03)).abs() < 1e-15);
        assert!((cube.signed_volume() - 0.006).abs() < 1e-15);
    }

    #[test]
    fn inward_shell_is_flipped_and_degenerate_triangles_dropped() {
        let mut cube = primitives::cuboid(DVec3::ONE);
        for t in &mut cube.triangles {
            t.swap(1, 2);
        }
        assert!(cube.signed_volume() < 0.0);
        let mut other =
            primitives::cuboid(DVec3::ONE).transformed(&DAffine3::from_translation(DVec3::new(5.0, 0.0, 0.0)));
        // A sliver and a triangle with a repeated vertex.
        other.positions.push(DVec3::new(9.0, 0.0, 0.0));
        other.positions.push(DVec3::new(9.0, 1e-9, 1e-9));
        let n = other.positions.len() as u32;
        other.triangles.push([0, n - 2, n - 1]);
        other.triangles.push([1, 1, 2]);
        cube.append(&other);
        let report = cube.orient_shells();
        assert_eq!(report.shells, 2);
        assert_eq!(report.flipped, 1);
        assert_eq!(report.degenerate, 2);
        assert!((cube.signed_volume() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn repeated_faces_are_dropped_once_in_either_winding() {
        let mut cube = primitives::cuboid(DVec3::ONE);
        let first = cube.triangles[0];
        let area = cube.area();
        // The same face again, reversed, and on copies of its vertices.
        cube.triangles.extend(std::iter::repeat_n(first, 1000));
        cube.triangles.push([first[0], first[2], first[1]]);
        let n = cube.positions.len() as u32;
        let copies: Vec<DVec3> = first.iter().map(|&i| cube.positions[i as usize]).collect();
        cube.positions.extend(copies);
        cube.triangles.push([n, n + 1, n + 2]);
        let report = cube.orient_shells();
        assert_eq!(report.repeated, 1002);
        assert_eq!(report.degenerate, 0);
        assert_eq!(cube.triangles.len(), 12);
        assert!((cube.area() - area).abs() < 1e-12);
        assert_eq!(report.boundary_edges, 0);
    }

    #[test]
    fn mirroring_keeps_outward_winding() {
        let cube = primitives::cuboid(DVec3::ONE);
        let mirrored = cube.transformed(&DAffine3::from_scale(DVec3::new(-1.0, 1.0, 1.0)));
        assert!((mirrored.signed_volume() - 1.0).abs() < 1e-12);
    }

    #[test]
    fn closest_point_on_a_cube_face_and_corner() {
        let cube = primitives::cuboid(DVec3::splat(2.0));
        let (q, n) = cube.closest_point(DVec3::new(0.2, 0.3, 5.0)).unwrap_or_default();
        assert!((q - DVec3::new(0.2, 0.3, 1.0)).length() < 1e-12);
        assert!((n - DVec3::Z).length() < 1e-12);
        let (q, _) = cube.closest_point(DVec3::new(3.0, 3.0, 3.0)).unwrap_or_default();
        assert!((q - DVec3::ONE).length() < 1e-12);
    }
}
