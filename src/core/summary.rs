//! What a posterior says: the most probable contact, per-link shares
//! (Fig. 3.2a), the 90 % credible set, clusters with their dispersions
//! (eq. 3.1, 3.2) and whether the torques are explained at all.

use std::collections::HashMap;

use glam::DVec3;

use crate::core::estimator::Posterior;
use crate::core::kinematics::RobotPose;
use crate::core::phases::link_ranges;
use crate::core::robot::LinkId;
use crate::core::special::chi_square_survival;
use crate::core::surface::Surface;

/// Above this chance of torques at least this large without a contact, we
/// say "no contact".
pub const NO_CONTACT_P: f64 = 0.01;

/// Below this chance of the best candidate's residual under the noise
/// model, we say no candidate explains the torques.
pub const POOR_FIT_P: f64 = 1e-6;

/// Points at least this fraction of the best are "probable" (the thesis
/// clusters particles with P ≥ 0.9 max).
pub const PROBABLE_FRACTION: f64 = 0.9;

/// At most this many probable points are clustered (the most probable).
const MAX_CLUSTERED: usize = 20_000;

/// The overall reading.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Verdict {
    /// A contact explains the torques.
    Contact,
    /// The torques are within noise of zero.
    NoContact,
    /// Even the best candidate leaves a residual the noise cannot explain
    /// (σ below the surface resolution, a contact off the candidate links,
    /// several contacts, or a model error).
    PoorFit,
}

/// One contact hypothesis in the world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ContactEstimate {
    /// Surface point index.
    pub point: usize,
    /// The link.
    pub link: LinkId,
    /// Contact point, m.
    pub point_world: DVec3,
    /// Inward unit normal.
    pub inward_normal_world: DVec3,
    /// Force on the robot, N: `f* n`.
    pub force_world: DVec3,
    /// Its magnitude, N.
    pub force_newtons: f64,
    /// Posterior mass of the point.
    pub probability: f64,
}

/// Probability per link (Fig. 3.2a).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkShare {
    /// The link.
    pub link: LinkId,
    /// Summed posterior mass of its points.
    pub summed: f64,
    /// Largest display value among its points.
    pub max: f64,
}

/// The smallest set of points holding 90 % of the mass.
#[derive(Debug, Clone, PartialEq)]
pub struct CredibleSet {
    /// Its points, most probable first.
    pub points: Vec<usize>,
    /// The mass they hold (≥ 0.9).
    pub mass: f64,
    /// Largest distance of a member from the set's weighted mean, m.
    pub radius_m: f64,
}

/// A group of probable points.
#[derive(Debug, Clone, PartialEq)]
pub struct Cluster {
    /// Member points.
    pub points: Vec<usize>,
    /// Links the members lie on, sorted.
    pub links: Vec<LinkId>,
    /// Summed posterior mass.
    pub mass: f64,
    /// Weighted mean position, m.
    pub mean_point_world: DVec3,
    /// Position dispersion `σ_r` (eq. 3.1), m.
    pub sigma_r_m: f64,
    /// Force dispersion `σ_F` (eq. 3.2), N.
    pub sigma_f_newtons: f64,
}

/// How well the best candidate explains the torques.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fit {
    /// Smallest `Σ (τ - f u)²/σ²` over candidates.
    pub best_residual_chi2: f64,
    /// Degrees of freedom of that residual (joints minus the fitted magnitude).
    pub dof: usize,
    /// Chance of a residual at least this large under the noise model.
    pub p_value: f64,
    /// Chance of torques at least this large without any contact.
    pub no_contact_p: f64,
}

/// Everything the estimator reports about one measurement.
#[derive(Debug, Clone, PartialEq)]
pub struct Summary {
    /// The overall reading.
    pub verdict: Verdict,
    /// The most probable contact.
    pub map: ContactEstimate,
    /// Per link, sorted by link.
    pub per_link: Vec<LinkShare>,
    /// The 90 % credible set.
    pub credible90: CredibleSet,
    /// Clusters of probable points, most massive first.
    pub clusters: Vec<Cluster>,
    /// Goodness of fit.
    pub fit: Fit,
}

/// The contact hypothesis of surface point `k`.
#[must_use]
pub fn contact_at(posterior: &Posterior, surface: &Surface, pose: &RobotPose, k: usize) -> ContactEstimate {
    let link = surface.link[k];
    let frame = pose.world_from_link[link];
    let normal = frame.transform_vector3(surface.inward_normal_in_link[k]);
    let f = posterior.force_newtons[k];
    ContactEstimate {
        point: k,
        link,
        point_world: frame.transform_point3(surface.point_in_link[k]),
        inward_normal_world: normal,
        force_world: normal * f,
        force_newtons: f,
        probability: posterior.probability[k],
    }
}

/// Summarises a posterior of `joints` sensed joints.
#[must_use]
pub fn summarize(posterior: &Posterior, surface: &Surface, pose: &RobotPose, joints: usize) -> Summary {
    let dof = joints.saturating_sub(1).max(1);
    let fit = Fit {
        best_residual_chi2: posterior.best_residual_chi2,
        dof,
        p_value: chi_square_survival(posterior.best_residual_chi2, dof),
        no_contact_p: chi_square_survival(posterior.no_contact_chi2, joints),
    };
    let verdict = if fit.no_contact_p > NO_CONTACT_P {
        Verdict::NoContact
    } else if fit.p_value < POOR_FIT_P {
        Verdict::PoorFit
    } else {
        Verdict::Contact
    };
    // Every link gets a share, also those with no mass; only the support
    // adds to them.
    let mut per_link: Vec<LinkShare> = link_ranges(&surface.link)
        .into_iter()
        .map(|(link, _)| LinkShare {
            link,
            summed: 0.0,
            max: 0.0,
        })
        .collect();
    per_link.sort_by_key(|s| s.link);
    per_link.dedup_by_key(|s| s.link);
    for &k in &posterior.support {
        let (Some(link), Some(&p), Some(&d)) = (
            surface.link.get(k),
            posterior.probability.get(k),
            posterior.display.get(k),
        ) else {
            continue;
        };
        if let Ok(i) = per_link.binary_search_by_key(link, |s| s.link)
            && let Some(share) = per_link.get_mut(i)
        {
            share.summed += p;
            share.max = share.max.max(d);
        }
    }
    let world = |k: usize| pose.point_to_world(surface.link[k], surface.point_in_link[k]);
    Summary {
        verdict,
        map: contact_at(posterior, surface, pose, posterior.map_point),
        per_link,
        credible90: credible_set(posterior, world, 0.9),
        clusters: clusters(posterior, surface, pose, world),
        fit,
    }
}

/// The smallest set of points holding `level` of the mass; `world` gives
/// a point's position.
#[must_use]
pub fn credible_set(posterior: &Posterior, world: impl Fn(usize) -> DVec3, level: f64) -> CredibleSet {
    // Points below 1e-18 of the largest hold less than 1e-12 together for
    // any surface we sample: they never enter a 90 % set, so skip sorting them.
    let top = posterior
        .support
        .iter()
        .map(|&k| posterior.probability[k])
        .fold(0.0, f64::max);
    // Sorting (probability, index) pairs reads no other array while
    // comparing.
    let mut order: Vec<(f64, usize)> = posterior
        .support
        .iter()
        .map(|&k| (posterior.probability[k], k))
        .filter(|&(p, _)| p > top * 1e-18)
        .collect();
    order.sort_unstable_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
    let mut mass = 0.0;
    let mut points = Vec::new();
    for (p, k) in order {
        points.push(k);
        mass += p;
        if mass >= level {
            break;
        }
    }
    let positions: Vec<DVec3> = points.iter().map(|&k| world(k)).collect();
    let mean = points
        .iter()
        .zip(&positions)
        .map(|(&k, p)| *p * posterior.probability[k])
        .sum::<DVec3>()
        / mass.max(f64::MIN_POSITIVE);
    let radius_m = positions.iter().map(|p| p.distance(mean)).fold(0.0, f64::max);
    CredibleSet { points, mass, radius_m }
}

/// Probable points grouped: connected groups (neighbours closer than three
/// surface spacings) seed a weighted K-means, which settles the boundaries.
fn clusters(
    posterior: &Posterior,
    surface: &Surface,
    pose: &RobotPose,
    world: impl Fn(usize) -> DVec3,
) -> Vec<Cluster> {
    let top = posterior
        .support
        .iter()
        .map(|&k| posterior.display[k])
        .fold(0.0, f64::max);
    let mut probable: Vec<usize> = posterior
        .support
        .iter()
        .copied()
        .filter(|&k| top > 0.0 && posterior.display[k] >= PROBABLE_FRACTION * top)
        .collect();
    probable.sort_by(|&x, &y| posterior.display[y].total_cmp(&posterior.display[x]).then(x.cmp(&y)));
    probable.truncate(MAX_CLUSTERED);
    probable.sort_unstable();
    if probable.is_empty() {
        return Vec::new();
    }
    // Positions of the probable points only, indexed like the surface.
    let mut world_of: HashMap<usize, DVec3> = HashMap::with_capacity(probable.len());
    for &k in &probable {
        world_of.insert(k, world(k));
    }
    let world = |k: usize| world_of.get(&k).copied().unwrap_or_default();
    let link_distance = 3.0 * surface.spacing_m().max(1e-6);
    let component = connected_components(&probable, &world, link_distance);
    let groups = component.iter().copied().max().map_or(0, |m| m + 1);
    // Weighted K-means from the components' means.
    let weight = |k: usize| posterior.display[k];
    let mut centres = vec![DVec3::ZERO; groups];
    let mut totals = vec![0.0; groups];
    for (i, &k) in probable.iter().enumerate() {
        centres[component[i]] += world(k) * weight(k);
        totals[component[i]] += weight(k);
    }
    for (c, t) in centres.iter_mut().zip(&totals) {
        *c /= t.max(f64::MIN_POSITIVE);
    }
    let mut label = component;
    for _ in 0..20 {
        let mut changed = false;
        for (i, &k) in probable.iter().enumerate() {
            let nearest = (0..groups)
                .min_by(|&x, &y| {
                    world(k)
                        .distance_squared(centres[x])
                        .total_cmp(&world(k).distance_squared(centres[y]))
                })
                .unwrap_or(0);
            changed |= nearest != label[i];
            label[i] = nearest;
        }
        let mut sums = vec![(DVec3::ZERO, 0.0); groups];
        for (i, &k) in probable.iter().enumerate() {
            sums[label[i]].0 += world(k) * weight(k);
            sums[label[i]].1 += weight(k);
        }
        for (c, (s, t)) in centres.iter_mut().zip(&sums) {
            if *t > 0.0 {
                *c = *s / *t;
            }
        }
        if !changed {
            break;
        }
    }
    let mut out: Vec<Cluster> = (0..groups)
        .filter_map(|g| {
            let members: Vec<usize> = probable
                .iter()
                .zip(&label)
                .filter(|(_, l)| **l == g)
                .map(|(k, _)| *k)
                .collect();
            cluster_of(&members, posterior, surface, pose, &world)
        })
        .collect();
    out.sort_by(|x, y| y.mass.total_cmp(&x.mass).then(x.points.cmp(&y.points)));
    out
}

/// A cluster's statistics (eq. 3.1, 3.2), weighted by the display values;
/// `None` for no members.
fn cluster_of(
    members: &[usize],
    posterior: &Posterior,
    surface: &Surface,
    pose: &RobotPose,
    world: &impl Fn(usize) -> DVec3,
) -> Option<Cluster> {
    if members.is_empty() {
        return None;
    }
    let weight = |k: usize| posterior.display[k];
    let w: f64 = members.iter().map(|&k| weight(k)).sum::<f64>().max(f64::MIN_POSITIVE);
    let mean_r = members.iter().map(|&k| world(k) * weight(k)).sum::<DVec3>() / w;
    let forces: Vec<DVec3> = members
        .iter()
        .map(|&k| contact_at(posterior, surface, pose, k).force_world)
        .collect();
    let mean_f = members.iter().zip(&forces).map(|(&k, f)| *f * weight(k)).sum::<DVec3>() / w;
    let sigma_r = (members
        .iter()
        .map(|&k| weight(k) * world(k).distance_squared(mean_r))
        .sum::<f64>()
        / w)
        .sqrt();
    let sigma_f = (members
        .iter()
        .zip(&forces)
        .map(|(&k, f)| weight(k) * f.distance_squared(mean_f))
        .sum::<f64>()
        / w)
        .sqrt();
    let mut links: Vec<LinkId> = members.iter().map(|&k| surface.link[k]).collect();
    links.sort_unstable();
    links.dedup();
    Some(Cluster {
        mass: members.iter().map(|&k| posterior.probability[k]).sum(),
        points: members.to_vec(),
        links,
        mean_point_world: mean_r,
        sigma_r_m: sigma_r,
        sigma_f_newtons: sigma_f,
    })
}

/// Single-linkage components of `points` (indices into `world`) for
/// distance `d`; returns a component index per point.
fn connected_components(points: &[usize], world: &impl Fn(usize) -> DVec3, d: f64) -> Vec<usize> {
    let cell = |p: DVec3| {
        let c = (p / d).floor();
        (c.x as i64, c.y as i64, c.z as i64)
    };
    let mut grid: HashMap<(i64, i64, i64), Vec<usize>> = HashMap::new();
    for (i, &k) in points.iter().enumerate() {
        grid.entry(cell(world(k))).or_default().push(i);
    }
    let mut label = vec![usize::MAX; points.len()];
    let mut next = 0;
    for start in 0..points.len() {
        if label[start] != usize::MAX {
            continue;
        }
        label[start] = next;
        let mut stack = vec![start];
        while let Some(i) = stack.pop() {
            let p = world(points[i]);
            let (cx, cy, cz) = cell(p);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        for &j in grid.get(&(cx + dx, cy + dy, cz + dz)).map_or(&[][..], Vec::as_slice) {
                            if label[j] == usize::MAX && world(points[j]).distance(p) <= d {
                                label[j] = next;
                                stack.push(j);
                            }
                        }
                    }
                }
            }
        }
        next += 1;
    }
    label
}
