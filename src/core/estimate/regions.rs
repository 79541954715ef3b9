//! Connected regions of a posterior over the surface: samples grouped by
//! the surface's cells ([`crate::core::surface::sampling::Cells`]), cells joined
//! where they touch. The work is proportional to the samples given, with
//! no spatial search per update.

use glam::DVec3;

use crate::core::robot::model::LinkId;
use crate::core::surface::sampling::Surface;

/// A connected region of weighted samples on one link.
#[derive(Debug, Clone, PartialEq)]
pub struct Region {
    /// The link.
    pub link: LinkId,
    /// Summed weight of its samples.
    pub weight: f64,
    /// Weighted mean of its samples' positions, link frame, m.
    pub centre_in_link: DVec3,
    /// Its sample nearest the centre.
    pub central: usize,
    /// Its heaviest sample (the lowest index among equals).
    pub top: usize,
    /// Its samples, in the order given.
    pub members: Vec<usize>,
}

/// A cell whose region is not looked up yet.
const UNSEEN: u32 = u32::MAX;

/// A cell too light to join a region.
const INACTIVE: u32 = u32::MAX - 1;

fn root(parent: &mut [u32], mut i: u32) -> u32 {
    while parent[i as usize] != i {
        let grand = parent[parent[i as usize] as usize];
        parent[i as usize] = grand;
        i = grand;
    }
    i
}

/// The regions formed by `samples` weighted by `weight`, heaviest first.
/// Cells holding less than `min_cell_fraction` of the heaviest cell's
/// weight are left out (they neither join regions nor form them).
#[must_use]
pub fn regions(
    surface: &Surface,
    samples: &[usize],
    weight: impl Fn(usize) -> f64,
    min_cell_fraction: f64,
) -> Vec<Region> {
    let cells = &surface.cells;
    let n = cells.len();
    if n == 0 || samples.is_empty() {
        return Vec::new();
    }
    let cell_of = |k: usize| surface.cell.get(k).map(|&c| c as usize);
    let mut cell_weight = vec![0.0; n];
    for &k in samples {
        if let Some(c) = cell_of(k) {
            cell_weight[c] += weight(k);
        }
    }
    let heaviest = cell_weight.iter().copied().fold(0.0, f64::max);
    let floor = heaviest * min_cell_fraction;
    let is_active: Vec<bool> = cell_weight.iter().map(|&w| w > 0.0 && w >= floor).collect();
    let active = |c: usize| is_active.get(c).copied().unwrap_or(false);
    let mut parent: Vec<u32> = (0..n as u32).collect();
    for c in 0..n {
        if !active(c) {
            continue;
        }
        // Each pair once, from its lower cell (neighbours are mutual, and
        // each list is sorted).
        let around = cells.neighbours_of(c);
        let higher = around.partition_point(|&d| d as usize <= c);
        for &d in around.get(higher..).unwrap_or(&[]) {
            if active(d as usize) {
                let (a, b) = (root(&mut parent, c as u32), root(&mut parent, d));
                if a != b {
                    parent[a.max(b) as usize] = a.min(b);
                }
            }
        }
    }
    // Each active cell's region, numbered in the order of the cells (the
    // regions are sorted at the end, so the numbering does not show): a
    // sample then finds its region in one lookup.
    let mut slot = vec![UNSEEN; n];
    let mut region_of_cell = vec![INACTIVE; n];
    let mut out: Vec<Region> = Vec::new();
    for (c, region) in region_of_cell.iter_mut().enumerate() {
        if !active(c) {
            continue;
        }
        let r = root(&mut parent, c as u32) as usize;
        if slot[r] == UNSEEN {
            slot[r] = out.len() as u32;
            out.push(Region {
                link: cells.link[c],
                weight: 0.0,
                centre_in_link: DVec3::ZERO,
                central: 0,
                top: usize::MAX,
                members: Vec::new(),
            });
        }
        *region = slot[r];
    }
    // Per region: weight, weighted position sum, members and the top, in
    // the order the samples are given.
    let mut sums = vec![DVec3::ZERO; out.len()];
    let mut top_weight = vec![f64::NEG_INFINITY; out.len()];
    for &k in samples {
        let Some(&i) = cell_of(k).and_then(|c| region_of_cell.get(c)) else {
            continue;
        };
        let (Some(region), Some(sum), Some(top), Some(&point)) = (
            out.get_mut(i as usize),
            sums.get_mut(i as usize),
            top_weight.get_mut(i as usize),
            surface.point_in_link.get(k),
        ) else {
            continue;
        };
        let w = weight(k);
        region.weight += w;
        *sum += point * w;
        region.members.push(k);
        // The first sample is the top until a heavier one (or an equal one
        // with a lower index) comes.
        let heavier = region.top == usize::MAX
            || match w.total_cmp(top) {
                std::cmp::Ordering::Greater => true,
                std::cmp::Ordering::Equal => k < region.top,
                std::cmp::Ordering::Less => false,
            };
        if heavier {
            region.top = k;
            *top = w;
        }
    }
    for (region, sum) in out.iter_mut().zip(&sums) {
        region.centre_in_link = *sum / region.weight.max(f64::MIN_POSITIVE);
        let centre = region.centre_in_link;
        region.central = region
            .members
            .iter()
            .copied()
            .min_by(|&x, &y| {
                let d = |k: usize| surface.point_in_link[k].distance_squared(centre);
                d(x).total_cmp(&d(y)).then(x.cmp(&y))
            })
            .unwrap_or(region.top);
    }
    // (Every active cell holds a sample; this keeps the promise if not.)
    out.retain(|r| !r.members.is_empty());
    out.sort_by(|x, y| y.weight.total_cmp(&x.weight).then(x.top.cmp(&y.top)));
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::robot::builtin;
    use crate::core::surface::sampling::SurfaceRequest;

    #[test]
    fn two_separate_groups_make_two_regions_and_a_gap_of_light_cells_is_not_crossed() {
        let robot = builtin::lwr4plus_generated().unwrap();
        let link = robot.link_id("lwr_4_link").unwrap();
        let s = Surface::sample(
            &robot,
            &SurfaceRequest {
                links: vec![link],
                total_points: 600,
                seed: 3,
            },
        )
        .unwrap();
        // Weight falling off from two far-apart samples.
        let (a, b) = (
            0,
            (0..s.len())
                .max_by(|&x, &y| {
                    s.point_in_link[x]
                        .distance(s.point_in_link[0])
                        .total_cmp(&s.point_in_link[y].distance(s.point_in_link[0]))
                })
                .unwrap(),
        );
        let w = |k: usize| {
            let d = |c: usize| s.point_in_link[k].distance(s.point_in_link[c]);
            (-(d(a) / 0.02).powi(2)).exp() + 0.5 * (-(d(b) / 0.02).powi(2)).exp()
        };
        let all: Vec<usize> = (0..s.len()).collect();
        let r = regions(&s, &all, w, 1e-3);
        assert_eq!(r.len(), 2, "{:?}", r.iter().map(|x| x.weight).collect::<Vec<_>>());
        assert_eq!(r[0].top, a);
        assert_eq!(r[1].top, b);
        assert!(r[0].centre_in_link.distance(s.point_in_link[a]) < 0.02);
        assert!(r[0].weight > r[1].weight);
        // Everything weighted the same: one region, all members.
        let one = regions(&s, &all, |_| 1.0, 1e-3);
        assert_eq!(one.len(), 1);
        assert_eq!(one[0].members.len(), s.len());
    }
}
