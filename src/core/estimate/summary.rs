//! What a posterior says: the most probable contact, per-link shares
//! (Fig. 3.2a), the 90 % credible set, clusters with their dispersions
//! (eq. 3.1, 3.2) and whether the torques are explained at all.

use glam::DVec3;

use crate::core::estimate::phases::link_ranges;
use crate::core::estimate::posterior::Posterior;
use crate::core::estimate::refine::RefinedContact;
use crate::core::estimate::regions::regions;
use crate::core::numerics::lanes;
use crate::core::numerics::special::chi_square_survival;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::LinkId;
use crate::core::surface::sampling::Surface;

/// Above this chance of torques at least this large without a contact, we
/// say "no contact".
pub const NO_CONTACT_P: f64 = 0.01;

/// Below this chance of the best candidate's residual under the noise
/// model, we say no candidate explains the torques.
pub const POOR_FIT_P: f64 = 1e-6;

/// Points at least this fraction of the best are "probable" (the thesis
/// clusters particles with P ≥ 0.9 max).
pub const PROBABLE_FRACTION: f64 = 0.9;

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
    /// Force on the robot, N: the push along the normal plus any
    /// tangential force.
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
    /// Its points, in index order.
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
    /// The most probable contact: refined on the continuous surface when
    /// a refinement was given (then `map.point` is the sample whose patch
    /// holds it), else the most probable sample.
    pub map: ContactEstimate,
    /// The most probable sample (the grid's answer, before refinement).
    pub grid_map: ContactEstimate,
    /// Whether `map` was refined below the samples' resolution.
    pub refined: bool,
    /// Per link, sorted by link.
    pub per_link: Vec<LinkShare>,
    /// The 90 % credible set.
    pub credible90: CredibleSet,
    /// Clusters of probable points, most massive first.
    pub clusters: Vec<Cluster>,
    /// Goodness of fit.
    pub fit: Fit,
    /// The chance that there is a contact, from a temporal model (frames
    /// before, and after when smoothing); `None` for a frame alone, whose
    /// verdict comes from the χ² tests.
    pub contact_probability: Option<f64>,
}

impl ContactEstimate {
    /// The force's part along the surface (friction), world frame, N.
    #[must_use]
    pub fn tangential_world(&self) -> DVec3 {
        let n = self.inward_normal_world;
        self.force_world - n * self.force_world.dot(n)
    }

    /// The first of its numbers that is not finite, by name.
    fn non_finite(&self) -> Option<&'static str> {
        if !self.point_world.is_finite() {
            Some("point")
        } else if !self.force_world.is_finite() || !self.force_newtons.is_finite() {
            Some("force")
        } else if !self.inward_normal_world.is_finite() {
            Some("normal")
        } else if !self.probability.is_finite() {
            Some("probability")
        } else {
            None
        }
    }
}

impl Summary {
    /// The first number of the summary that is not finite, by the name
    /// the estimate's output gives it; `None` when every one is. An
    /// estimate is reported only when it is finite: a degenerate input
    /// (a σ far below the torques' own precision, a force range at the
    /// edge of the floating point) must be an error, never a NaN point.
    #[must_use]
    pub fn non_finite_field(&self) -> Option<&'static str> {
        if let Some(field) = self.map.non_finite() {
            return Some(field);
        }
        if let Some(field) = self.grid_map.non_finite() {
            return Some(match field {
                "point" => "grid.point",
                "force" => "grid.force",
                "normal" => "grid.normal",
                _ => "grid.probability",
            });
        }
        if self
            .per_link
            .iter()
            .any(|l| !(l.summed.is_finite() && l.max.is_finite()))
        {
            return Some("links.probability");
        }
        if !(self.credible90.radius_m.is_finite() && self.credible90.mass.is_finite()) {
            return Some("credible90_radius_m");
        }
        if self.clusters.iter().any(|c| {
            !(c.mass.is_finite()
                && c.mean_point_world.is_finite()
                && c.sigma_r_m.is_finite()
                && c.sigma_f_newtons.is_finite())
        }) {
            return Some("clusters");
        }
        if !(self.fit.p_value.is_finite() && self.fit.no_contact_p.is_finite() && !self.fit.best_residual_chi2.is_nan())
        {
            return Some("fit_p");
        }
        if self.contact_probability.is_some_and(|p| !p.is_finite()) {
            return Some("contact_probability");
        }
        None
    }
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

/// A refined contact in the world; its `point` is the sample nearest it
/// on its link among those with mass (its start if none).
fn refined_estimate(r: &RefinedContact, posterior: &Posterior, surface: &Surface, pose: &RobotPose) -> ContactEstimate {
    placed_estimate(&PlacedContact::from(r), posterior, surface, pose)
}

/// A contact placed on the continuous surface by a search over more than
/// the samples (a frame's refinement, or a fit over a whole press:
/// [`crate::core::estimate::press`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlacedContact {
    /// The link.
    pub link: LinkId,
    /// Contact point, link frame, m.
    pub point_in_link: DVec3,
    /// Inward unit normal, link frame.
    pub inward_normal_in_link: DVec3,
    /// Push along the inward normal, N.
    pub force_newtons: f64,
    /// Tangential force, link frame, N.
    pub tangential_in_link: DVec3,
    /// The sample reported when none of its link's samples has mass.
    pub fallback_sample: usize,
    /// `Σ (τ - model)² / σ²` of the frame at this contact.
    pub residual_chi2: f64,
}

impl From<&RefinedContact> for PlacedContact {
    fn from(r: &RefinedContact) -> Self {
        Self {
            link: r.link,
            point_in_link: r.point_in_link,
            inward_normal_in_link: r.inward_normal_in_link,
            force_newtons: r.force_newtons,
            tangential_in_link: r.tangential_in_link,
            fallback_sample: r.start,
            residual_chi2: r.residual_chi2,
        }
    }
}

fn placed_estimate(r: &PlacedContact, posterior: &Posterior, surface: &Surface, pose: &RobotPose) -> ContactEstimate {
    let owner = posterior
        .support
        .iter()
        .copied()
        .filter(|&k| surface.link.get(k) == Some(&r.link))
        .min_by(|&x, &y| {
            let d = |k: usize| surface.point_in_link[k].distance_squared(r.point_in_link);
            d(x).total_cmp(&d(y)).then(x.cmp(&y))
        })
        .unwrap_or(r.fallback_sample);
    let frame = pose.world_from_link.get(r.link).copied().unwrap_or_default();
    let normal = frame.transform_vector3(r.inward_normal_in_link);
    let force_world = normal * r.force_newtons + frame.transform_vector3(r.tangential_in_link);
    ContactEstimate {
        point: owner,
        link: r.link,
        point_world: frame.transform_point3(r.point_in_link),
        inward_normal_world: normal,
        force_world,
        force_newtons: force_world.length(),
        probability: posterior.probability.get(owner).copied().unwrap_or(0.0),
    }
}

/// The fit test and the verdict of a frame with `joints` sensed joints:
/// of the refined contact's residual (its χ² and the sensed joints that
/// move its link) when there is one, else of the best sample's.
fn fit_and_verdict(
    posterior: &Posterior,
    joints: usize,
    refined: Option<(f64, usize)>,
    contact_probability: Option<f64>,
) -> (Fit, Verdict) {
    let (chi2, dof) = match refined {
        Some((chi2, sensing_joints)) => (chi2, joints.saturating_sub(sensing_joints.min(3))),
        None => (posterior.best_residual_chi2, joints.saturating_sub(1)),
    };
    let fit = Fit {
        best_residual_chi2: chi2,
        dof,
        p_value: if dof == 0 { 1.0 } else { chi_square_survival(chi2, dof) },
        no_contact_p: chi_square_survival(posterior.no_contact_chi2, joints),
    };
    let no_contact = match contact_probability {
        Some(p) => p < 0.5,
        None => fit.no_contact_p > NO_CONTACT_P,
    };
    (fit, verdict_of(no_contact, &fit))
}

/// *No contact* where there is none, else *poorly explained* or *contact*
/// by the fit test.
fn verdict_of(no_contact: bool, fit: &Fit) -> Verdict {
    if no_contact {
        Verdict::NoContact
    } else if fit.p_value < POOR_FIT_P {
        Verdict::PoorFit
    } else {
        Verdict::Contact
    }
}

impl Summary {
    /// Reports `other`'s contact and fit test (a summary of the same
    /// frame by other means) as this summary's, the verdict following
    /// this summary's contact probability; shares, credible set and
    /// clusters stay.
    pub fn take_contact_of(&mut self, other: &Summary) {
        self.map = other.map;
        self.refined = other.refined;
        self.fit = other.fit;
        let no_contact = match self.contact_probability {
            Some(p) => p < 0.5,
            None => other.verdict == Verdict::NoContact,
        };
        self.verdict = verdict_of(no_contact, &self.fit);
    }

    /// Reports `placed` (found by a fit over more than this frame, see
    /// [`crate::core::estimate::press`]) as the contact, with the fit test and the
    /// verdict of its residual; `sensing_joints` of the `joints` sensed
    /// ones move its link. The posterior's summaries (shares, credible
    /// set, clusters) stay.
    pub fn place_contact(
        &mut self,
        placed: &PlacedContact,
        sensing_joints: usize,
        (posterior, surface, pose): (&Posterior, &Surface, &RobotPose),
        joints: usize,
    ) {
        let (fit, verdict) = fit_and_verdict(
            posterior,
            joints,
            Some((placed.residual_chi2, sensing_joints)),
            self.contact_probability,
        );
        self.map = placed_estimate(placed, posterior, surface, pose);
        self.refined = true;
        self.fit = fit;
        self.verdict = verdict;
    }
}

/// Summarises a posterior of `joints` sensed joints.
#[must_use]
pub fn summarize(posterior: &Posterior, surface: &Surface, pose: &RobotPose, joints: usize) -> Summary {
    summarize_refined(posterior, surface, pose, joints, None, None)
}

/// A refined contact for [`summarize_refined`]: the contact and how many
/// sensed joints move its link.
#[derive(Debug, Clone, Copy)]
pub struct Refinement<'a> {
    /// The contact.
    pub contact: &'a RefinedContact,
    /// Sensed joints that move its link.
    pub sensing_joints: usize,
}

/// [`summarize`], with the most probable contact refined on the
/// continuous surface: it is the reported contact, and the fit test uses
/// its residual with one degree of freedom per sensed joint less the
/// three it fits (two for the place, one for the magnitude; fewer when
/// fewer joints sense its link). With a `contact_probability` (from the
/// temporal model) the verdict is *no contact* below one half, whatever
/// the χ² test of this frame alone says.
#[must_use]
pub fn summarize_refined(
    posterior: &Posterior,
    surface: &Surface,
    pose: &RobotPose,
    joints: usize,
    refined: Option<Refinement>,
    contact_probability: Option<f64>,
) -> Summary {
    let (fit, verdict) = fit_and_verdict(
        posterior,
        joints,
        refined.map(|r| (r.contact.residual_chi2, r.sensing_joints)),
        contact_probability,
    );
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
    // The surface is grouped by link and the support is in index order: a
    // run of one link's points adds up in registers (through the shares
    // in memory each addition waited on the last one's store), and its
    // share is looked up once per run.
    let add_run = |per_link: &mut [LinkShare], (link, summed, max): (LinkId, f64, f64)| {
        if let Ok(i) = per_link.binary_search_by_key(&link, |s| s.link)
            && let Some(share) = per_link.get_mut(i)
        {
            share.summed += summed;
            share.max = share.max.max(max);
        }
    };
    let mut run: Option<(LinkId, f64, f64)> = None;
    for &k in &posterior.support {
        let (Some(&link), Some(&p), Some(&d)) = (
            surface.link.get(k),
            posterior.probability.get(k),
            posterior.display.get(k),
        ) else {
            continue;
        };
        match &mut run {
            Some((current, summed, max)) if *current == link => {
                *summed += p;
                *max = max.max(d);
            }
            _ => {
                if let Some(done) = run {
                    add_run(&mut per_link, done);
                }
                run = Some((link, 0.0 + p, 0.0_f64.max(d)));
            }
        }
    }
    if let Some(done) = run {
        add_run(&mut per_link, done);
    }
    let world = |k: usize| pose.point_to_world(surface.link[k], surface.point_in_link[k]);
    let grid_map = contact_at(posterior, surface, pose, posterior.map_point);
    let map = refined.map_or(grid_map, |r| refined_estimate(r.contact, posterior, surface, pose));
    Summary {
        verdict,
        map,
        grid_map,
        refined: refined.is_some(),
        per_link,
        credible90: credible_set(posterior, world, 0.9),
        // Without a contact there is nothing to cluster.
        clusters: if verdict == Verdict::NoContact {
            Vec::new()
        } else {
            clusters(posterior, surface, pose, world)
        },
        fit,
        contact_probability,
    }
}

/// The smallest set of points holding `level` of the mass; `world` gives
/// a point's position.
#[must_use]
pub fn credible_set(posterior: &Posterior, world: impl Fn(usize) -> DVec3, level: f64) -> CredibleSet {
    // Points below 1e-18 of the largest hold less than 1e-12 together for
    // any surface we sample: they never enter a 90 % set.
    let (points, mass) = most_probable_holding(&posterior.support, &posterior.probability, 1e-18, level);
    CredibleSet::holding(points, mass, &posterior.probability, world)
}

impl CredibleSet {
    /// The set of `points` (in index order) holding `mass` of
    /// `probability`, its radius measured with `world` (a point's
    /// position).
    fn holding(points: Vec<usize>, mass: f64, probability: &[f64], world: impl Fn(usize) -> DVec3) -> Self {
        let positions: Vec<DVec3> = points.iter().map(|&k| world(k)).collect();
        let mean = points
            .iter()
            .zip(&positions)
            .map(|(&k, p)| *p * probability.get(k).copied().unwrap_or(0.0))
            .sum::<DVec3>()
            / mass.max(f64::MIN_POSITIVE);
        // `sqrt` is monotone: the largest distance is the root of the largest square.
        let squared: Vec<f64> = positions.iter().map(|p| p.distance_squared(mean)).collect();
        let radius_m = lanes::max_or(&squared, 0.0).sqrt();
        Self { points, mass, radius_m }
    }

    /// This set with `more` points added (any order, repeats allowed),
    /// its mass and radius measured again.
    #[must_use]
    pub fn with_points(&self, more: &[usize], probability: &[f64], world: impl Fn(usize) -> DVec3) -> Self {
        let mut points: Vec<usize> = self.points.iter().chain(more).copied().collect();
        points.sort_unstable();
        points.dedup();
        let mass = points.iter().map(|&k| probability.get(k).copied().unwrap_or(0.0)).sum();
        Self::holding(points, mass, probability, world)
    }
}

/// The fewest of the points `indices` (probabilities `probability[k]`)
/// whose probabilities add up to at least `level` (all of them if they
/// hold less), in index order, and that sum: the most probable ones, ties
/// broken by the lower index. Points with probability ≤ `relative_floor`
/// times the largest, ≤ 0 or NaN are never taken.
///
/// In time linear in the points, without sorting them: they are bucketed
/// by the top 16 bits of their probability (sign, exponent and four bits
/// of mantissa: for positive numbers the bits order as the values do, so
/// every point of a bucket is more probable than every point of a lower
/// one). One pass finds the largest and the least, the next gives each
/// point its bucket and counts each bucket's mass; whole buckets are taken
/// from the top while they hold less than `level`; a last pass collects
/// them, and the points of the bucket that crosses the level are chosen
/// by [`take_most_probable`]. (Sorting them all would cost most of a
/// broad posterior's update.) The sum adds whole buckets, each summed in
/// the order given, then what the crossing bucket adds.
fn most_probable_holding(indices: &[usize], probability: &[f64], relative_floor: f64, level: f64) -> (Vec<usize>, f64) {
    // The top 16 bits: the cast keeps them all.
    #[allow(clippy::cast_possible_truncation)]
    let key = |p: f64| (p.to_bits() >> 48) as u32;
    // Each listed point's probability, 0 where it is never taken (≤ 0,
    // NaN, not in `probability`): the passes below then run without a
    // branch per point that depends on the data (in a broad posterior
    // such branches miss half the time, and cost most of this function).
    let values: Vec<f64> = indices
        .iter()
        .map(|&k| probability.get(k).copied().filter(|&p| p > 0.0).unwrap_or(0.0))
        .collect();
    let top = lanes::max_or(&values, 0.0);
    let low = lanes::min_positive(&values);
    let floor = top * relative_floor;
    if !(top > 0.0 && top > floor) {
        return (Vec::new(), 0.0);
    }
    let high = key(top);
    // The bucket of the floor or of the least probable, whichever is higher.
    let low = key(low.max(floor));
    // Bucket b holds the points of key `high - b`: bucket 0 the most
    // probable. What is not taken goes in bucket `untaken`, one past the
    // `crossing` of a level above the total.
    let buckets_taken = high.saturating_sub(low) + 1;
    let untaken = buckets_taken + 1;
    let mut bucket_mass = vec![0.0; untaken as usize + 1];
    // A plain loop over `u32`s: the compiler vectorises it.
    let mut buckets = vec![0_u32; values.len()];
    for (b, &p) in buckets.iter_mut().zip(&values) {
        let taken_bucket = high.saturating_sub(key(p)).min(buckets_taken - 1);
        *b = if p > floor { taken_bucket } else { untaken };
    }
    for (&b, &p) in buckets.iter().zip(&values) {
        if let Some(m) = bucket_mass.get_mut(b as usize) {
            *m += p;
        }
    }
    // Buckets before `crossing` are taken whole.
    let mut crossing = buckets_taken;
    let mut mass = 0.0;
    for (b, &m) in (0..buckets_taken).zip(&bucket_mass) {
        if mass + m >= level {
            crossing = b;
            break;
        }
        mass += m;
    }
    let mut taken = vec![0; indices.len()];
    let mut count = 0;
    let mut last: Vec<(f64, usize)> = Vec::new();
    for ((&k, &b), &p) in indices.iter().zip(&buckets).zip(&values) {
        // Written always, kept when taken: no branch to mispredict.
        if let Some(slot) = taken.get_mut(count) {
            *slot = k;
        }
        count += usize::from(b < crossing);
        if b == crossing {
            last.push((p, k));
        }
    }
    taken.truncate(count);
    let mut picked = Vec::new();
    mass += take_most_probable(&mut last, level - mass, &mut picked);
    picked.sort_unstable();
    taken.extend(picked);
    // Two sorted runs where `indices` is sorted: the stable sort merges
    // them in linear time.
    #[allow(clippy::stable_sort_primitive)]
    taken.sort();
    (taken, mass)
}

/// Moves into `taken` the fewest, most probable of `items` (probability,
/// index; ties to the lower index) whose probabilities add up to at least
/// `need`, and returns their sum. In expected linear time: each step
/// splits the items at their median (the upper half gathered by
/// selection, not sorted) and goes on in the half that crosses `need`,
/// taking the upper one whole where it does not; the last few are sorted
/// and taken one by one. (In a flat posterior the crossing bucket of
/// [`most_probable_holding`] holds hundreds of points, most of which are
/// never taken.)
fn take_most_probable(items: &mut [(f64, usize)], need: f64, taken: &mut Vec<usize>) -> f64 {
    const SORT_BELOW: usize = 32;
    let order = |x: &(f64, usize), y: &(f64, usize)| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1));
    let mut added = 0.0;
    let mut rest = items;
    while added < need && !rest.is_empty() {
        if rest.len() <= SORT_BELOW {
            rest.sort_unstable_by(order);
            for &(p, k) in rest.iter() {
                if added >= need {
                    break;
                }
                taken.push(k);
                added += p;
            }
            break;
        }
        let mid = rest.len() / 2;
        rest.select_nth_unstable_by(mid, order);
        let (upper, lower) = rest.split_at_mut(mid);
        let upper_mass: f64 = upper.iter().map(|x| x.0).sum();
        if added + upper_mass >= need {
            rest = upper;
        } else {
            added += upper_mass;
            taken.extend(upper.iter().map(|x| x.1));
            rest = lower;
        }
    }
    added
}

/// Probable points grouped into connected regions of the surface's cells
/// (a region is a patch of touching cells holding probable points).
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
    let probable: Vec<usize> = posterior
        .support
        .iter()
        .copied()
        .filter(|&k| top > 0.0 && posterior.display[k] >= PROBABLE_FRACTION * top)
        .collect();
    let weight = |k: usize| posterior.display[k];
    let mut out: Vec<Cluster> = regions(surface, &probable, weight, 0.0)
        .into_iter()
        .filter_map(|r| cluster_of(&r.members, posterior, surface, pose, &world))
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

#[cfg(test)]
#[path = "summary_tests.rs"]
mod tests;
