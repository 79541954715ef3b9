//! Quiet frames: torques within noise of zero, estimated on a coarser
//! sampling of the same links.
//!
//! Most of a robot's frames carry no contact. Their torques are within
//! noise of zero, the frame's verdict is *no contact* before any posterior
//! is computed (the χ² test of [`crate::core::summary`]), nothing is
//! refined, and the posterior given a contact is broad: the places where a
//! push of the smallest magnitude would hide in the noise. Such a
//! posterior is smooth over the arm, and with patches (each sample's mass
//! is the likelihood integrated over its patch) a sampling a quarter as
//! dense gives the same masses per area of surface; evaluating it costs a
//! quarter as much. Each fine sample then takes its share of the coarse
//! sample that stands for it ([`QuietLevel::lift`]).
//!
//! What this changes, measured on the quiet frames of the `../shared`
//! dynamic examples (see the README): the per-link shares move by a few
//! percent, about as much as between two surface seeds at full density,
//! and the heatmap is as fine as the coarse sampling. Frames that carry a
//! contact never take this path.

use std::collections::HashMap;

use glam::DVec3;

use crate::core::estimator::{Posterior, phase_flag};
use crate::core::lanes;
use crate::core::robot::{LinkId, Robot};
use crate::core::surface::{Surface, SurfaceRequest};

/// Surfaces with fewer samples have no quiet level (they are fast as they
/// are, and a quarter of them would be too sparse on small links).
pub const QUIET_MIN_POINTS: usize = 2000;

/// The quiet level has this many times fewer samples.
pub const QUIET_THINNING: usize = 4;

/// A coarser sampling of the same links, and which coarse sample stands
/// for each fine one.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct QuietLevel {
    /// The coarse samples.
    pub surface: Surface,
    /// Per fine sample, the coarse sample standing for it: the nearest on
    /// the same link among those in its voxel and the 26 around it
    /// (voxels one coarse spacing wide), else the nearest on its link.
    pub parent: Vec<usize>,
    /// Per fine sample, its share of its parent's mass: its area over the
    /// area of all the fine samples of that parent.
    pub share: Vec<f64>,
    /// `ln` of each share, taken once here rather than in every lift.
    pub ln_share: Vec<f64>,
}

impl QuietLevel {
    /// The quiet level of `fine` (sampled for `request`): `None` where the
    /// surface is too small ([`QUIET_MIN_POINTS`]) or the coarse sampling
    /// misses a link of the fine one.
    #[must_use]
    pub fn new(robot: &Robot, request: &SurfaceRequest, fine: &Surface) -> Option<Self> {
        if fine.len() < QUIET_MIN_POINTS {
            return None;
        }
        let coarse_request = SurfaceRequest {
            total_points: request.total_points / QUIET_THINNING,
            // Its own draw: the coarse samples are not a subset of the fine
            // ones (a subset of an evenly spread set is not even).
            seed: request.seed.wrapping_add(0x9e37_79b9_7f4a_7c15),
            ..request.clone()
        };
        let surface = Surface::sample(robot, &coarse_request).ok()?;
        let parent = parents(fine, &surface)?;
        let mut children_area = vec![0.0; surface.len()];
        for (&p, &area) in parent.iter().zip(&fine.area_m2) {
            if let Some(total) = children_area.get_mut(p) {
                *total += area;
            }
        }
        let share: Vec<f64> = parent
            .iter()
            .zip(&fine.area_m2)
            .map(|(&p, &area)| {
                let total = children_area.get(p).copied().unwrap_or(0.0);
                if total > 0.0 { area / total } else { 0.0 }
            })
            .collect();
        let ln_share = share.iter().map(|s| s.ln()).collect();
        Some(Self {
            surface,
            parent,
            share,
            ln_share,
        })
    }

    /// The posterior over the fine samples from `coarse`, the posterior
    /// over this level's samples: each fine sample takes its share of its
    /// parent's probability (renormalised over the coarse samples that
    /// stand for some fine one), likelihood and magnitude. The most
    /// probable fine sample is the map point; the fit and no-contact χ²
    /// and the phase reports (the samples actually evaluated) are the
    /// coarse posterior's.
    #[must_use]
    pub fn lift(&self, coarse: &Posterior) -> Posterior {
        let n = self.parent.len();
        let at = |values: &[f64], p: usize, fallback: f64| values.get(p).copied().unwrap_or(fallback);
        let mut probability: Vec<f64> = self
            .parent
            .iter()
            .zip(&self.share)
            .map(|(&p, &share)| at(&coarse.probability, p, 0.0) * share)
            .collect();
        // In order, as the posterior's own weights are summed.
        let total: f64 = probability.iter().sum();
        if total > 0.0 {
            let scale = 1.0 / total;
            for p in &mut probability {
                *p *= scale;
            }
        }
        let log_likelihood = self
            .parent
            .iter()
            .zip(&self.ln_share)
            .map(|(&p, &ln_share)| at(&coarse.log_likelihood, p, f64::NEG_INFINITY) + ln_share)
            .collect();
        let force_newtons = self.parent.iter().map(|&p| at(&coarse.force_newtons, p, 0.0)).collect();
        let support = lanes::positions_where(&probability, |p| p > 0.0);
        // The first of the most probable.
        let best = lanes::max_or(&probability, 0.0);
        let map_point = probability.iter().position(|p| p.total_cmp(&best).is_eq()).unwrap_or(0);
        Posterior {
            display: probability.clone(),
            probability,
            log_likelihood,
            force_newtons,
            phases: coarse.phases.clone(),
            phase_flags: vec![phase_flag::C; n],
            support,
            map_point,
            best_residual_chi2: coarse.best_residual_chi2,
            no_contact_chi2: coarse.no_contact_chi2,
        }
    }
}

/// Per fine sample, its coarse parent (see [`QuietLevel::parent`]);
/// `None` where a fine sample's link has no coarse sample.
fn parents(fine: &Surface, coarse: &Surface) -> Option<Vec<usize>> {
    let size = coarse.spacing_m().max(1e-6);
    let voxel = |p: DVec3| -> [i64; 3] {
        let v = (p / size).floor();
        // Link frames span metres: far inside i64.
        #[allow(clippy::cast_possible_truncation)]
        [v.x as i64, v.y as i64, v.z as i64]
    };
    let mut grid: HashMap<(LinkId, [i64; 3]), Vec<usize>> = HashMap::new();
    let mut on_link: HashMap<LinkId, Vec<usize>> = HashMap::new();
    for (j, (&link, &p)) in coarse.link.iter().zip(&coarse.point_in_link).enumerate() {
        grid.entry((link, voxel(p))).or_default().push(j);
        on_link.entry(link).or_default().push(j);
    }
    let nearest = |candidates: &mut dyn Iterator<Item = usize>, p: DVec3| -> Option<usize> {
        candidates
            .filter_map(|j| Some((j, coarse.point_in_link.get(j)?.distance_squared(p))))
            .min_by(|x, y| x.1.total_cmp(&y.1).then(x.0.cmp(&y.0)))
            .map(|(j, _)| j)
    };
    fine.link
        .iter()
        .zip(&fine.point_in_link)
        .map(|(&link, &p)| {
            let [x, y, z] = voxel(p);
            let mut around = (-1..=1).flat_map(|dx| {
                let grid = &grid;
                (-1..=1).flat_map(move |dy| {
                    (-1..=1).flat_map(move |dz| {
                        grid.get(&(link, [x + dx, y + dy, z + dz]))
                            .map_or(&[][..], Vec::as_slice)
                            .iter()
                            .copied()
                    })
                })
            });
            nearest(&mut around, p).or_else(|| nearest(&mut on_link.get(&link)?.iter().copied(), p))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::builtin;

    fn level(points: usize) -> (Robot, Surface, Option<QuietLevel>) {
        let robot = builtin::lwr4plus_generated().expect("built in");
        let request = SurfaceRequest {
            links: robot.default_candidate_links(),
            total_points: points,
            seed: 3,
        };
        let fine = Surface::sample(&robot, &request).expect("sampled");
        let quiet = QuietLevel::new(&robot, &request, &fine);
        (robot, fine, quiet)
    }

    #[test]
    fn small_surfaces_have_no_quiet_level() {
        assert!(level(QUIET_MIN_POINTS - 1).2.is_none());
    }

    #[test]
    fn parents_are_near_on_the_same_link_and_shares_add_up() {
        let (_, fine, quiet) = level(4000);
        let quiet = quiet.expect("a quiet level");
        let coarse = &quiet.surface;
        assert!(coarse.len() <= 4000 / QUIET_THINNING && coarse.len() >= 4000 / QUIET_THINNING - 10);
        // Against a brute-force nearest on the link: the parent is that
        // one, or within a coarse spacing of the sample.
        let spacing = coarse.spacing_m();
        let mut exact = 0;
        for (k, &p) in quiet.parent.iter().enumerate() {
            assert_eq!(coarse.link[p], fine.link[k]);
            let d = coarse.point_in_link[p].distance(fine.point_in_link[k]);
            let best = (0..coarse.len())
                .filter(|&j| coarse.link[j] == fine.link[k])
                .map(|j| coarse.point_in_link[j].distance(fine.point_in_link[k]))
                .fold(f64::INFINITY, f64::min);
            assert!(d <= best.max(spacing) + 1e-12, "sample {k}: {d} against {best}");
            exact += usize::from(d.total_cmp(&best).is_eq());
        }
        assert!(exact * 100 >= 95 * fine.len(), "{exact} of {} nearest", fine.len());
        let mut per_parent = vec![0.0; coarse.len()];
        for (&p, &s) in quiet.parent.iter().zip(&quiet.share) {
            per_parent[p] += s;
        }
        for total in per_parent {
            assert!(total == 0.0 || (total - 1.0).abs() < 1e-12, "{total}");
        }
    }

    #[test]
    fn a_lifted_posterior_keeps_each_parents_mass() {
        let (_, fine, quiet) = level(3000);
        let quiet = quiet.expect("a quiet level");
        let m = quiet.surface.len();
        // A coarse posterior with mass on every third sample.
        let weights: Vec<f64> = (0..m).map(|j| if j % 3 == 0 { 1.0 + j as f64 } else { 0.0 }).collect();
        let sum: f64 = weights.iter().sum();
        let coarse = Posterior {
            probability: weights.iter().map(|w| w / sum).collect(),
            display: Vec::new(),
            log_likelihood: weights.iter().map(|w| w.ln()).collect(),
            force_newtons: (0..m).map(|j| j as f64).collect(),
            phases: Vec::new(),
            phase_flags: Vec::new(),
            support: Vec::new(),
            map_point: 0,
            best_residual_chi2: 2.0,
            no_contact_chi2: 3.0,
        };
        let lifted = quiet.lift(&coarse);
        assert_eq!(lifted.probability.len(), fine.len());
        let total: f64 = lifted.probability.iter().sum();
        assert!((total - 1.0).abs() < 1e-12);
        // Every coarse sample with children keeps its mass, up to the
        // renormalisation over those.
        let mut per_parent = vec![0.0; m];
        for (k, &p) in quiet.parent.iter().enumerate() {
            per_parent[p] += lifted.probability[k];
            assert!(lifted.force_newtons[k].total_cmp(&(p as f64)).is_eq());
        }
        let kept: f64 = (0..m)
            .filter(|&j| per_parent[j] > 0.0 || quiet.parent.contains(&j))
            .map(|j| coarse.probability[j])
            .sum();
        for (j, (&mass, &was)) in per_parent.iter().zip(&coarse.probability).enumerate() {
            if quiet.parent.contains(&j) {
                assert!((mass - was / kept).abs() < 1e-12);
            }
        }
        let best = lifted.probability[lifted.map_point];
        assert!(lifted.probability.iter().all(|&p| p <= best));
        assert!(lifted.support.iter().all(|&k| lifted.probability[k] > 0.0));
        assert_eq!(
            lifted.support.len(),
            lifted.probability.iter().filter(|&&p| p > 0.0).count()
        );
        assert_eq!((lifted.best_residual_chi2, lifted.no_contact_chi2), (2.0, 3.0));
    }
}
