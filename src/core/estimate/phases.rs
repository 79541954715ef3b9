//! Coarse-to-fine candidate sets for phases A/B/C (thesis §2.4,
//! Algorithm 1): B clusters the surface points C, A clusters B's
//! representatives; every representative is a member point, so it lies on
//! the surface.

use glam::DVec3;

use crate::core::numerics::rng::Rng;
use crate::core::robot::model::LinkId;
use crate::core::surface::sampling::Surface;

/// Iterations after which K-means stops even if labels still change.
const MAX_ITERATIONS: usize = 100;

/// K-means as in Algorithm 1: `k` distinct members chosen at random
/// (seeded), points assigned to the nearest centroid, each centroid moved
/// to the member nearest its cluster's mean, until no label changes.
/// Returns the centroids (indices into `points`, sorted) and each point's
/// label (an index into the centroids).
#[must_use]
pub fn kmeans_medoids(points: &[DVec3], k: usize, rng: &mut Rng) -> (Vec<usize>, Vec<usize>) {
    let n = points.len();
    if k >= n {
        return ((0..n).collect(), (0..n).collect());
    }
    if k == 0 {
        return (Vec::new(), Vec::new());
    }
    // Partial Fisher-Yates: k distinct random members.
    let mut order: Vec<usize> = (0..n).collect();
    for i in 0..k {
        let j = i + rng.below(n - i);
        order.swap(i, j);
    }
    let mut centroids: Vec<usize> = order[..k].to_vec();
    centroids.sort_unstable();
    let nearest = |centroids: &[usize], p: DVec3| {
        let mut best = (f64::INFINITY, 0);
        for (c, &ci) in centroids.iter().enumerate() {
            let d = points[ci].distance_squared(p);
            if d < best.0 {
                best = (d, c);
            }
        }
        best.1
    };
    let mut labels: Vec<usize> = points.iter().map(|p| nearest(&centroids, *p)).collect();
    for _ in 0..MAX_ITERATIONS {
        let mut sum = vec![DVec3::ZERO; k];
        let mut count = vec![0usize; k];
        for (p, &l) in points.iter().zip(&labels) {
            sum[l] += *p;
            count[l] += 1;
        }
        let mut best = vec![(f64::INFINITY, usize::MAX); k];
        for (i, (p, &l)) in points.iter().zip(&labels).enumerate() {
            let mean = sum[l] / count[l] as f64;
            let d = p.distance_squared(mean);
            if d < best[l].0 {
                best[l] = (d, i);
            }
        }
        for (c, b) in centroids.iter_mut().zip(&best) {
            if b.1 != usize::MAX {
                *c = b.1;
            }
        }
        let mut changed = false;
        for (p, l) in points.iter().zip(labels.iter_mut()) {
            let new = nearest(&centroids, *p);
            if new != *l {
                *l = new;
                changed = true;
            }
        }
        if !changed {
            break;
        }
    }
    // Sort centroids for a stable order and relabel.
    let mut sorted: Vec<(usize, usize)> = centroids.iter().copied().enumerate().map(|(c, i)| (i, c)).collect();
    sorted.sort_unstable();
    let mut new_label = vec![0; k];
    for (rank, &(_, old)) in sorted.iter().enumerate() {
        new_label[old] = rank;
    }
    (
        sorted.iter().map(|s| s.0).collect(),
        labels.iter().map(|l| new_label[*l]).collect(),
    )
}

/// The candidate sets of phases A, B and C for one surface.
#[derive(Debug, Clone, PartialEq)]
pub struct PhaseHierarchy {
    /// Surface indices of B's representatives.
    pub b_points: Vec<usize>,
    /// For every surface point, its B cluster (index into `b_points`).
    pub b_of_point: Vec<usize>,
    /// Surface indices of A's representatives.
    pub a_points: Vec<usize>,
    /// For every B cluster, its A cluster (index into `a_points`).
    pub a_of_b: Vec<usize>,
}

impl PhaseHierarchy {
    /// Clusters each link's points separately (a cluster never spans two
    /// links), with `sizes = [A, B]` shared among links by point count.
    #[must_use]
    pub fn new(surface: &Surface, sizes: [usize; 2], seed: u64) -> Self {
        let mut rng = Rng::new(seed);
        let n = surface.len();
        let ranges = link_ranges(&surface.link);
        let mut b_points = Vec::new();
        let mut b_of_point = vec![0; n];
        let mut a_points = Vec::new();
        let mut a_of_b = Vec::new();
        for (_, range) in &ranges {
            let count = range.len();
            let share = |total: usize| ((total * count).div_ceil(n.max(1))).clamp(1, count);
            let points: Vec<DVec3> = surface.point_in_link[range.clone()].to_vec();
            let (b_centroids, b_labels) = kmeans_medoids(&points, share(sizes[1]), &mut rng);
            let b_offset = b_points.len();
            for (local, label) in b_labels.iter().enumerate() {
                b_of_point[range.start + local] = b_offset + label;
            }
            let b_reps: Vec<DVec3> = b_centroids.iter().map(|&c| points[c]).collect();
            b_points.extend(b_centroids.iter().map(|&c| range.start + c));
            let (a_centroids, a_labels) = kmeans_medoids(&b_reps, share(sizes[0]).min(b_reps.len()), &mut rng);
            let a_offset = a_points.len();
            a_of_b.extend(a_labels.iter().map(|l| a_offset + l));
            a_points.extend(a_centroids.iter().map(|&c| b_points[b_offset + c]));
        }
        Self {
            b_points,
            b_of_point,
            a_points,
            a_of_b,
        }
    }
}

/// The run of each link in a surface's link array, grouped by link as
/// [`Surface`] keeps it: `(link, index range)`.
#[must_use]
pub fn link_ranges(links: &[LinkId]) -> Vec<(LinkId, std::ops::Range<usize>)> {
    let mut out = Vec::new();
    let mut start = 0;
    while start < links.len() {
        let link = links[start];
        // Each link's points form one run (the surface is grouped by
        // link), so its end is found by bisection, not by a scan.
        let end = start + links[start..].partition_point(|l| *l == link);
        out.push((link, start..end));
        start = end;
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kmeans_finds_well_separated_groups_with_member_centroids() {
        let mut rng = Rng::new(3);
        let centres = [DVec3::ZERO, DVec3::new(10.0, 0.0, 0.0), DVec3::new(0.0, 10.0, 0.0)];
        let points: Vec<DVec3> = (0..300)
            .map(|i| centres[i % 3] + DVec3::new(rng.uniform(), rng.uniform(), rng.uniform()))
            .collect();
        let (centroids, labels) = kmeans_medoids(&points, 3, &mut Rng::new(1));
        assert_eq!(centroids.len(), 3);
        for i in 0..300 {
            for j in 0..300 {
                assert_eq!(labels[i] == labels[j], i % 3 == j % 3);
            }
        }
        // Each centroid is a member near its group's mean (0.5, 0.5, 0.5) offset.
        for &c in &centroids {
            let offset = points[c] - centres[c % 3];
            assert!((offset - DVec3::splat(0.5)).length() < 0.35, "{offset}");
        }
        assert_eq!(kmeans_medoids(&points, 3, &mut Rng::new(1)), (centroids, labels));
    }

    #[test]
    fn hierarchy_has_the_requested_sizes_and_nests() {
        let robot = crate::core::robot::builtin::lwr4plus_generated().unwrap();
        let surface = Surface::sample(
            &robot,
            &crate::core::surface::sampling::SurfaceRequest {
                links: robot.default_candidate_links(),
                total_points: 2000,
                seed: 1,
            },
        )
        .unwrap();
        let h = PhaseHierarchy::new(&surface, [50, 300], 7);
        assert!((300..=307).contains(&h.b_points.len()), "{}", h.b_points.len());
        assert!((50..=57).contains(&h.a_points.len()), "{}", h.a_points.len());
        for (i, &b) in h.b_of_point.iter().enumerate() {
            assert_eq!(
                surface.link[h.b_points[b]], surface.link[i],
                "clusters never span links"
            );
        }
        for (b, &a) in h.a_of_b.iter().enumerate() {
            assert_eq!(surface.link[h.a_points[a]], surface.link[h.b_points[b]]);
        }
        // Every B representative is its own cluster's member.
        for (b, &p) in h.b_points.iter().enumerate() {
            assert_eq!(h.b_of_point[p], b);
        }
    }
}
