//! A pair carried into a frame beside the frames that found it, where
//! one push alone explains the torques and so no pair was searched.
//!
//! A frame alone weighs a second contact against the whole surface: its
//! place is one of every place the arm has, and the Occam factor of that
//! prior (ln of the surface's area over the place's spread) is what keeps
//! a small second push below one contact that shifts to take it up. Over time the second contact is not
//! anywhere: a push that the frame beside holds is, in this frame, near
//! where that frame has it (the same contact, within the separation that
//! tells two contacts apart, [`PairSettings::separation_m`]). So the new
//! contact's prior here is the part of its link within that distance of
//! its place next door, uniform in area, and the other contact keeps the
//! whole surface as in [`super::pair::estimate_pair`]. Its evidence `Z₂`
//! is taken as there, without the factor 2 of the two labellings: the
//! contact near the place given is the new one. On the LWR that raises
//! the pair's evidence by 2.9–3.5 nats over the same pair in a frame
//! alone (about 4 nats of place, less the labellings' ln 2; the unit
//! test's four places).
//!
//! On the `../shared` two-contact example the link-7 probe's push rises
//! from nothing to 8 N over 18 frames while the link-5 probe holds; the
//! single contact explains those frames by drifting 10 mm along link 5,
//! and a frame alone finds the pair more probable only from about 8 N on.

use glam::DVec3;

use crate::core::estimate::contact::PosedSurface;
use crate::core::estimate::pair::{Conditional, PairEstimate, PairSettings, Placed, Search, minus};
use crate::core::estimate::phases::PhaseHierarchy;
use crate::core::estimate::posterior::{Posterior, estimate};
use crate::core::estimate::refine::refine_at;
use crate::core::estimate::settings::{EstimateError, EstimatorSettings};
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::LinkId;

/// Where a contact's place is believed to be before this frame's
/// torques: uniform over its link's surface within `radius_m` of a point.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NearPrior {
    /// The link.
    pub link: LinkId,
    /// The point, link frame, m.
    pub point_in_link: DVec3,
    /// How far from it, m.
    pub radius_m: f64,
}

impl NearPrior {
    fn holds(&self, link: LinkId, point_in_link: DVec3) -> bool {
        link == self.link && point_in_link.distance(self.point_in_link) <= self.radius_m
    }
}

/// A pair carried into a frame: its account, and the new contact's
/// Occam factor under its prior near where it was.
#[derive(Debug, Clone, PartialEq)]
pub struct HeldPair {
    /// The frame's two-contact account.
    pub account: PairEstimate,
    /// ln of the new contact's Occam factor: its evidence over its best
    /// likelihood, under [`NearPrior`] (the price of its place and
    /// magnitude).
    pub new_log_occam: f64,
}

/// The frame's two-contact account with both contacts started at `both`
/// (as the frame beside left them), `both[new]` the contact that arrives
/// or leaves: its place's prior is [`NearPrior`] about where `both` has
/// it, at the separation. `None` where no place near it is away from the
/// other contact, or `new` is not 0 or 1.
///
/// # Errors
/// As [`estimate`], for a remainder's posterior.
#[allow(clippy::too_many_arguments)]
pub fn estimate_pair_held(
    posed: &PosedSurface<'_>,
    pose: &RobotPose,
    tau: &[f64],
    settings: &EstimatorSettings,
    hierarchy: Option<&PhaseHierarchy>,
    single: &Posterior,
    pair: &PairSettings,
    both: &[Placed; 2],
    new: usize,
) -> Result<Option<HeldPair>, EstimateError> {
    let (Some(b), Some(a)) = (both.get(new), both.get(1 - new.min(1))) else {
        return Ok(None);
    };
    if new > 1 {
        return Ok(None);
    }
    let search = Search::new(posed, pose, tau, settings, hierarchy, pair);
    let log_evidence_one = search.log_evidence_one(single);
    let near = NearPrior {
        link: b.link,
        point_in_link: b.point_in_link,
        radius_m: pair.separation_m,
    };
    let (mut a, mut b) = (a.clone(), b.clone());
    if search.too_near(a.link, a.point_in_link, &b) {
        return Ok(None);
    }
    search.polish(&mut a, &mut b);
    let (Some(a_given_b), Some(b_given_a)) = (search.conditional(&b)?, conditional_near(&search, &a, &near)?) else {
        return Ok(None);
    };
    // The polished places are the pair's, as in a frame's own search,
    // while the new contact's stays within its prior's reach.
    if !near.holds(b.link, b.point_in_link) {
        b = b_given_a.placed.clone();
    }
    let residual = search.residual(&a, &b);
    let log_evidence_two = if settings.patches {
        let friction = search.pair_friction_gain(&a, &b);
        a_given_b.log_occam + b_given_a.log_occam - 0.5 * residual + friction
    } else {
        a_given_b.log_evidence + b_given_a.log_evidence + 0.5 * residual
    };
    let new_log_occam = b_given_a.log_occam;
    let a_given_b = Conditional { placed: a, ..a_given_b };
    let b_given_a = Conditional { placed: b, ..b_given_a };
    let account = search.account(
        single,
        log_evidence_one,
        (log_evidence_two, residual, [a_given_b, b_given_a]),
    );
    Ok(Some(HeldPair { account, new_log_occam }))
}

/// One contact given `other`, its place's prior `near`: the one-contact
/// posterior of the torques left, its best sample within the prior's
/// reach and away from `other` refined there (kept while it stays within
/// reach), its evidence over the prior's area.
fn conditional_near(
    search: &Search<'_>,
    other: &Placed,
    near: &NearPrior,
) -> Result<Option<Conditional>, EstimateError> {
    let surface = search.posed.surface;
    let left = minus(search.tau, &other.torques);
    let posterior = estimate(search.posed, &left, search.settings, search.hierarchy)?;
    let reach: Vec<usize> = (0..surface.len())
        .filter(|&k| match (surface.link.get(k), surface.point_in_link.get(k)) {
            (Some(&link), Some(&p)) => near.holds(link, p) && !search.too_near(link, p, other),
            _ => false,
        })
        .collect();
    let ln_prior_norm = if search.settings.patches {
        reach.iter().filter_map(|&k| surface.area_m2.get(k)).sum::<f64>().ln()
    } else {
        (reach.len() as f64).ln()
    };
    let likely: Vec<(usize, f64)> = reach
        .iter()
        .filter_map(|&k| posterior.log_likelihood.get(k).map(|&l| (k, l)))
        .filter(|(_, l)| l.is_finite())
        .collect();
    let Some(&(point, top)) = likely.iter().max_by(|x, y| x.1.total_cmp(&y.1).then(y.0.cmp(&x.0))) else {
        return Ok(None);
    };
    if !ln_prior_norm.is_finite() {
        return Ok(None);
    }
    let sum: f64 = likely.iter().map(|&(_, l)| (l - top).exp()).sum();
    let refined = search
        .settings
        .patches
        .then(|| {
            let link = surface.link.get(point).copied()?;
            let location = surface.location.get(point).copied()?;
            refine_at(
                search.posed.torque_model,
                surface,
                &search.measurement(&left),
                (link, location),
                point,
            )
        })
        .flatten()
        .filter(|r| near.holds(r.link, r.point_in_link) && !search.too_near(r.link, r.point_in_link, other));
    let log_evidence = top + sum.max(1.0).ln() - ln_prior_norm;
    Ok(Some(search.conditional_of(
        posterior,
        (point, top),
        log_evidence,
        refined,
    )))
}
