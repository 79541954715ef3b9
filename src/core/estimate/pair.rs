//! Two contacts in one frame: whether the torques need a second push, and
//! where each push is given the other.
//!
//! The torques of two contacts add: `τ = f_A u_A + f_B u_B + noise`. With
//! one contact fixed, the other's likelihood over the surface is the
//! one-contact model of the torques left over, so each contact's
//! posterior *given the other* comes from the frame's own estimator
//! ([`estimate`]) run on the remainder, patches, magnitude range and all.
//! The search alternates: the second contact given the single contact's
//! place, the first given that, the second again ([`PAIR_ROUNDS`]).
//!
//! The number of contacts is chosen by the evidence, not by a χ²
//! threshold. With `Z₁(τ)` the one-contact marginal likelihood (the
//! frame's posterior normaliser over the surface prior), the two-contact
//! marginal likelihood is taken in product form,
//!
//! `Z₂ ≈ 2 · Z₁(τ − t_B̂) · Z₁(τ − t_Â) / L(Â, B̂)`,
//!
//! exact when the log-likelihood has no cross term between the two
//! contacts' parameters (each `Z₁` of a remainder integrates one contact's
//! place and magnitude with the other at its mode; dividing by the peak
//! likelihood keeps the peak once; the 2 counts the two labellings). So
//! each contact pays its own Occam factor: the share of its prior place
//! and magnitude that the torques left to it allow. The posterior
//! probability of two contacts (given one at least) is then
//! `π₂ Z₂ / (π₂ Z₂ + (1 − π₂) Z₁)` with the prior `π₂`
//! ([`PairSettings::prior_two`]).
//!
//! Where the torques cannot tell a pair's six unknowns apart, the pair
//! says why ([`crate::core::estimate::pair_identifiable`]).

use glam::DVec3;

use crate::core::estimate::contact::PosedSurface;
use crate::core::estimate::friction::friction_fits;
use crate::core::estimate::measurement::Measurement;
use crate::core::estimate::pair_grid::coarse_pair;
pub use crate::core::estimate::pair_identifiable::{COLLINEAR_COSINE, FELT_SIGMAS, Unidentifiable};
use crate::core::estimate::pair_identifiable::{sensing, unidentifiable_by_joints};
use crate::core::estimate::phases::PhaseHierarchy;
use crate::core::estimate::posterior::{Posterior, estimate};
use crate::core::estimate::refine::{RefinedContact, refine, refine_at};
use crate::core::estimate::settings::{EstimateError, EstimatorSettings};
use crate::core::estimate::summary::{CredibleSet, credible_set};
use crate::core::geometry::shell::MeshPoint;
use crate::core::numerics::special::logistic;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::LinkId;
use crate::core::robot::torque::weighted_dot;

/// Conditional searches after the single contact's at most: the second
/// contact given the first, the first given the second, the second
/// again, until one is found where it was ([`PAIR_SETTLED_M`]).
pub const PAIR_ROUNDS: usize = 7;

/// The alternation ends once a contact found again lies within this of
/// where it was found the round before on the same link, m: the polish
/// on the continuous surface takes it from there.
pub const PAIR_SETTLED_M: f64 = 0.005;

/// Whether `now` is `before` found again: the same link, within
/// [`PAIR_SETTLED_M`].
fn settled(before: &Placed, now: &Placed) -> bool {
    before.link == now.link && before.point_in_link.distance(now.point_in_link) <= PAIR_SETTLED_M
}

/// Rounds of the continuous polish of both places at most.
pub const POLISH_ROUNDS: usize = 20;

/// The polish ends when a round lowers the pair's χ² by less than this.
pub const POLISH_CHI2: f64 = 1e-2;

/// Prior probability that a frame with contact has two, when nobody says.
/// A person with both hands on the arm, or an arm leaning on a table while
/// pushed, is ordinary use; one in ten contact frames is a prior that a
/// pair must earn by its evidence.
pub const DEFAULT_PRIOR_TWO: f64 = 0.1;

/// Two contacts on the same link are told apart only this far apart, m:
/// nearer, a "second" contact is the first one's push split in two. So
/// are two on links across a joint, where a search apart finds a pair
/// about as probable ([`SPLIT_EVIDENCE_NATS`]).
pub const DEFAULT_SEPARATION_M: f64 = 0.05;

/// A pair found the separation apart replaces a pair split across a
/// joint when it is at most this much less probable, in nats: the torques
/// barely tell the two apart (on the `../shared` two-contact example, 0
/// kept split pairs 45–55 mm from the probes at four surface seeds of ten
/// that 3 and 6 replace alike; `docs/decisions.md`, session 69).
pub const SPLIT_EVIDENCE_NATS: f64 = 3.0;

/// How two contacts are looked for.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairSettings {
    /// Prior probability that a frame with contact has two (0 < π₂ < 1).
    pub prior_two: f64,
    /// Closest two contacts may be, m: on one link always; across a
    /// joint where a pair apart is about as probable.
    pub separation_m: f64,
}

impl Default for PairSettings {
    fn default() -> Self {
        Self {
            prior_two: DEFAULT_PRIOR_TWO,
            separation_m: DEFAULT_SEPARATION_M,
        }
    }
}

/// One of two contacts, given the other.
#[derive(Debug, Clone, PartialEq)]
pub struct PairContact {
    /// Where it is (refined on the continuous surface given the other
    /// contact) and its push.
    pub placed: Placed,
    /// The same place, world frame, m.
    pub point_world: DVec3,
    /// Its push on the robot, world frame, N.
    pub force_world: DVec3,
    /// Its 90 % credible set given the other contact.
    pub credible90: CredibleSet,
    /// Its posterior given the other contact: each surface sample's
    /// probability of being its place (empty where a caller keeps only
    /// the summary, as a whole session's pass does).
    pub probability: Vec<f64>,
}

/// What a frame says about two contacts.
#[derive(Debug, Clone, PartialEq)]
pub struct PairEstimate {
    /// The two contacts, the one nearer the single contact's place first.
    pub contacts: [PairContact; 2],
    /// ln of the one-contact marginal likelihood (relative to the bare
    /// noise model's normaliser, as the posterior's log-likelihoods).
    pub log_evidence_one: f64,
    /// ln of the two-contact marginal likelihood, on the same scale.
    pub log_evidence_two: f64,
    /// Probability of two contacts given at least one, with the prior.
    pub probability_two: f64,
    /// `Σ (τ − t_A − t_B)² / σ²` at the pair's places and magnitudes.
    pub residual_chi2: f64,
    /// Sensed joints that feel either contact.
    pub sensing_joints: usize,
    /// Why the torques cannot tell the pair's six unknowns apart (see the
    /// module docs); `None` where they can.
    pub unidentifiable: Option<Unidentifiable>,
}

impl PairEstimate {
    /// Whether the torques can tell the pair's six unknowns apart.
    #[must_use]
    pub fn identifiable(&self) -> bool {
        self.unidentifiable.is_none()
    }

    /// ln of the evidence ratio `Z₂ / Z₁` (without the prior).
    #[must_use]
    pub fn log_evidence_ratio(&self) -> f64 {
        self.log_evidence_two - self.log_evidence_one
    }

    /// Whether two contacts are the better account: more probable than
    /// one, and identifiable.
    #[must_use]
    pub fn has_two(&self) -> bool {
        self.identifiable() && self.probability_two > 0.5
    }
}

/// Why a pair settings value is refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PairSettingsError {
    /// The prior is not strictly between 0 and 1.
    #[error("the prior probability of two contacts must be strictly between 0 and 1, got {value}")]
    Prior {
        /// The value given.
        value: f64,
    },
    /// The separation is negative or not finite.
    #[error("the separation of two contacts must be a finite length ≥ 0 m, got {value}")]
    Separation {
        /// The value given.
        value: f64,
    },
}

impl PairSettings {
    /// Checks the values.
    ///
    /// # Errors
    /// [`PairSettingsError`] naming the bad value.
    pub fn validate(&self) -> Result<(), PairSettingsError> {
        if !(self.prior_two > 0.0 && self.prior_two < 1.0) {
            return Err(PairSettingsError::Prior { value: self.prior_two });
        }
        if !(self.separation_m.is_finite() && self.separation_m >= 0.0) {
            return Err(PairSettingsError::Separation {
                value: self.separation_m,
            });
        }
        Ok(())
    }
}

/// A contact's place and push, as the search holds it.
#[derive(Debug, Clone, PartialEq)]
pub struct Placed {
    /// The sample it stands on or started from.
    pub point: usize,
    /// Its link.
    pub link: LinkId,
    /// Where on the link's continuous surface (`None`: the sample's place,
    /// on a link without one).
    pub location: Option<MeshPoint>,
    /// Contact point, link frame, m.
    pub point_in_link: DVec3,
    /// Inward unit normal there, link frame: the push's direction.
    pub inward_normal_in_link: DVec3,
    /// Push magnitude along the inward normal, N.
    pub force_newtons: f64,
    /// Its torques (sensed order), N·m.
    pub torques: Vec<f64>,
}

/// Where the search for two contacts starts.
#[derive(Debug, Clone, PartialEq, Default)]
pub enum PairStart {
    /// Nothing known: the best pair of a coarse grid.
    #[default]
    Unknown,
    /// One contact believed held at a sample with a magnitude (e.g. where
    /// it pressed alone before the other came).
    One {
        /// The sample.
        point: usize,
        /// Its magnitude, N.
        force_newtons: f64,
    },
    /// Both contacts as an earlier frame left them.
    Both(Box<[Placed; 2]>),
}

/// A push that explained an earlier frame alone, as the frames after it
/// may still hold it: its link, and its place and force in that link's
/// frame (the tangential part included).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeldPush {
    /// Its link.
    pub link: LinkId,
    /// Contact point, link frame, m.
    pub point_in_link: DVec3,
    /// Force on the robot, link frame, N.
    pub force_in_link: DVec3,
}

/// Where one search of a frame's pair begins: both places, or one
/// place that the alternation starts from.
enum Seed {
    Pair([Placed; 2]),
    From(Placed),
}

/// One contact with the other held: where, and ln of the one-contact
/// evidence of the torques left to it, with its posterior.
pub(super) struct Conditional {
    pub(super) placed: Placed,
    pub(super) log_evidence: f64,
    /// ln of its Occam factor: the evidence over its best sample's
    /// likelihood (the share of its prior place and magnitude the torques
    /// left to it allow).
    pub(super) log_occam: f64,
    pub(super) posterior: Posterior,
}

/// A pair searched: `(ln Z₂, residual χ², contacts)`.
pub(super) type Best = (f64, f64, [Conditional; 2]);

/// What the search of one frame reads.
#[derive(Clone)]
pub(super) struct Search<'a> {
    pub(super) posed: &'a PosedSurface<'a>,
    pub(super) tau: &'a [f64],
    pub(super) settings: &'a EstimatorSettings,
    pub(super) hierarchy: Option<&'a PhaseHierarchy>,
    pub(super) pair: &'a PairSettings,
    pub(super) weights: Vec<f64>,
    pub(super) ln_prior_norm: f64,
    pub(super) pose: &'a RobotPose,
    /// Whether the separation holds across links too (else on one link).
    pub(super) across_links: bool,
}

/// `x − y`, element by element.
pub(super) fn minus(x: &[f64], y: &[f64]) -> Vec<f64> {
    x.iter().zip(y).map(|(a, b)| a - b).collect()
}

impl Search<'_> {
    fn force_range(&self) -> (f64, f64) {
        (self.settings.force_min_newtons, self.settings.force_max_newtons)
    }

    fn chi2(&self, left: &[f64]) -> f64 {
        weighted_dot(&self.weights, left, left)
    }

    /// The pair's residual χ².
    pub(super) fn residual(&self, a: &Placed, b: &Placed) -> f64 {
        self.chi2(&minus(&minus(self.tau, &a.torques), &b.torques))
    }

    pub(super) fn too_near(&self, link: LinkId, point_in_link: DVec3, other: &Placed) -> bool {
        if link == other.link {
            return point_in_link.distance(other.point_in_link) < self.pair.separation_m;
        }
        let here = self.pose.point_to_world(link, point_in_link);
        let there = self.pose.point_to_world(other.link, other.point_in_link);
        self.across_links && here.distance(there) < self.pair.separation_m
    }

    pub(super) fn measurement<'m>(&'m self, left: &'m [f64]) -> Measurement<'m> {
        Measurement {
            tau: left,
            weights: &self.weights,
            force_range_newtons: self.force_range(),
            friction: 0.0,
        }
    }

    /// How much the friction model (μ = the settings' friction) raises
    /// the likelihood of `one` with `other`'s torques taken away (`other`
    /// `None`: alone), in nats; 0 where it does not.
    fn friction_gain(&self, one: &Placed, other: Option<&Placed>) -> f64 {
        let left = other.map_or_else(|| self.tau.to_vec(), |o| minus(self.tau, &o.torques));
        self.friction_on(one, &left).map_or(0.0, |(_, gain)| gain)
    }

    /// The friction model's force of `one` on the torques `left` (its
    /// torques) and how much it raises the likelihood over a push along
    /// the normal, in nats; `None` without friction or where it does not
    /// raise it.
    fn friction_on(&self, one: &Placed, left: &[f64]) -> Option<(Vec<f64>, f64)> {
        let mu = self.settings.friction;
        if mu.is_nan() || mu <= 0.0 {
            return None;
        }
        let measurement = Measurement {
            friction: mu,
            ..self.measurement(left)
        };
        let place = (one.point_in_link, one.inward_normal_in_link);
        let fits = friction_fits(self.posed.torque_model, one.link, place, &measurement, mu)?;
        let (force, gain) = (fits.with, fits.gain);
        let force_in_link = one.inward_normal_in_link * force.normal_newtons + force.tangential_in_link;
        let torques = self
            .posed
            .torque_model
            .torques(one.link, one.point_in_link, force_in_link);
        (gain > 0.0).then_some((torques, 0.5 * gain))
    }

    /// How much friction at both contacts of a pair raises its
    /// likelihood, in nats: the first's gain with the second's push taken
    /// away, then the second's with the first's frictional force taken
    /// away, in the order that gains more. Each contact's gain alone,
    /// summed, would count twice what both can explain of the same misfit
    /// (on the `../shared` link 6 slide, pairs whose pushes missed the
    /// torques by χ² 2,816 came out 1,329 nats above one contact).
    pub(super) fn pair_friction_gain(&self, a: &Placed, b: &Placed) -> f64 {
        let one_way = |first: &Placed, second: &Placed| match self.friction_on(first, &minus(self.tau, &second.torques))
        {
            Some((torques, gain)) => {
                gain + self
                    .friction_on(second, &minus(self.tau, &torques))
                    .map_or(0.0, |(_, g)| g)
            }
            None => self.friction_gain(second, Some(first)),
        };
        one_way(a, b).max(one_way(b, a))
    }

    /// ln `Z₁`. With patches the one contact's evidence is, as each of
    /// the pair's, its Occam factor from the samples times its peak on the
    /// continuous surface (with friction, raised by what its tangential
    /// force explains). The samples' own peak is the patch model's, linear
    /// in the offset across a patch: a misfit that no place of the surface
    /// removes is taken up there by offsets beyond the surface's reach.
    pub(super) fn log_evidence_one(&self, single: &Posterior) -> f64 {
        let surface = self.posed.surface;
        let first = single.map_point;
        let peak_from_samples = self
            .settings
            .patches
            .then(|| refine(self.posed.torque_model, surface, single, &self.measurement(self.tau)))
            .flatten()
            .map_or(0.0, |r| {
                let area = surface.ln_area.get(first).copied().unwrap_or(0.0);
                let samples_peak = single.log_likelihood.get(first).map_or(f64::NEG_INFINITY, |l| l - area);
                let peak = -0.5 * r.residual_chi2 + self.friction_gain(&self.refined(&r), None);
                peak - samples_peak
            });
        log_evidence(single, self.ln_prior_norm) + peak_from_samples
    }

    /// Why the pair `a`, `b`, felt by `sensing_joints` sensed joints,
    /// cannot be told apart by the torques
    /// ([`crate::core::estimate::pair_identifiable`]).
    pub(super) fn unidentifiable(&self, sensing_joints: usize, a: &Placed, b: &Placed) -> Option<Unidentifiable> {
        let friction = self.settings.friction > 0.0;
        unidentifiable_by_joints(
            self.posed.torque_model,
            &self.weights,
            friction,
            sensing_joints,
            (a.link, &a.torques),
            (b.link, &b.torques),
        )
        .or_else(|| {
            (friction && (self.explains_alone(a) || self.explains_alone(b))).then_some(Unidentifiable::OneExplains)
        })
    }

    /// Whether `one` alone, with the friction model's force at its place,
    /// leaves a residual χ² no larger than the joints' count: what the
    /// noise alone gives on average.
    pub(super) fn explains_alone(&self, one: &Placed) -> bool {
        self.friction_on(one, self.tau)
            .is_some_and(|(torques, _)| self.chi2(&minus(self.tau, &torques)) <= self.tau.len() as f64)
    }

    /// Sample `k` pushed with `f` newtons.
    pub(super) fn at_sample(&self, k: usize, f: f64) -> Placed {
        let surface = self.posed.surface;
        let link = surface.link.get(k).copied().unwrap_or_default();
        let point_in_link = surface.point_in_link.get(k).copied().unwrap_or_default();
        let normal = surface.inward_normal_in_link.get(k).copied().unwrap_or_default();
        Placed {
            point: k,
            link,
            location: surface.location.get(k).copied(),
            point_in_link,
            inward_normal_in_link: normal,
            force_newtons: f,
            torques: self.posed.torque_model.torques(link, point_in_link, normal * f),
        }
    }

    /// A refined contact from sample `start`.
    pub(super) fn refined(&self, r: &RefinedContact) -> Placed {
        Placed {
            point: r.start,
            link: r.link,
            location: Some(r.location),
            point_in_link: r.point_in_link,
            inward_normal_in_link: r.inward_normal_in_link,
            force_newtons: r.force_newtons,
            torques: self.posed.torque_model.torques(
                r.link,
                r.point_in_link,
                r.inward_normal_in_link * r.force_newtons,
            ),
        }
    }

    /// One contact given `other`: the one-contact posterior of the torques
    /// left, its contact refined on the continuous surface where that stays
    /// away from `other` (else its best sample away from it).
    pub(super) fn conditional(&self, other: &Placed) -> Result<Option<Conditional>, EstimateError> {
        let surface = self.posed.surface;
        let left = minus(self.tau, &other.torques);
        let posterior = estimate(self.posed, &left, self.settings, self.hierarchy)?;
        let away = |k: usize| match (surface.link.get(k), surface.point_in_link.get(k)) {
            (Some(&link), Some(&p)) => !self.too_near(link, p, other),
            _ => false,
        };
        let support: Vec<usize> = posterior.support.iter().copied().filter(|&k| away(k)).collect();
        let by_likelihood = |x: &(usize, f64), y: &(usize, f64)| x.1.total_cmp(&y.1).then(y.0.cmp(&x.0));
        let likely = |k: usize| {
            posterior
                .log_likelihood
                .get(k)
                .map(|&l| (k, l))
                .filter(|(_, l)| l.is_finite())
        };
        // Outside the support every point is below e^-60 of the best:
        // when all of it lies near the other contact, look among the rest.
        let best = support
            .iter()
            .filter_map(|&k| likely(k))
            .max_by(by_likelihood)
            .or_else(|| {
                (0..surface.len())
                    .filter(|&k| away(k))
                    .filter_map(likely)
                    .max_by(by_likelihood)
            });
        let Some((point, top)) = best else {
            return Ok(None);
        };
        let sum: f64 = support
            .iter()
            .filter_map(|&k| posterior.log_likelihood.get(k))
            .map(|&l| (l - top).exp())
            .sum();
        let refined = self
            .settings
            .patches
            .then(|| refine(self.posed.torque_model, surface, &posterior, &self.measurement(&left)))
            .flatten()
            .filter(|r| !self.too_near(r.link, r.point_in_link, other));
        let log_evidence = top + sum.max(1.0).ln() - self.ln_prior_norm;
        Ok(Some(self.conditional_of(
            posterior,
            (point, top),
            log_evidence,
            refined,
        )))
    }

    /// One contact's conditional account from its posterior: its best
    /// sample `point` (of log-likelihood `top`), its evidence, and its
    /// place refined on the continuous surface (`None`: the sample's).
    pub(super) fn conditional_of(
        &self,
        posterior: Posterior,
        (point, top): (usize, f64),
        log_evidence: f64,
        refined: Option<RefinedContact>,
    ) -> Conditional {
        let area = if self.settings.patches {
            self.posed.surface.ln_area.get(point).copied().unwrap_or(0.0)
        } else {
            0.0
        };
        let placed = match refined {
            Some(r) => self.refined(&r),
            None => self.at_sample(point, posterior.force_newtons.get(point).copied().unwrap_or(0.0)),
        };
        Conditional {
            placed,
            log_evidence,
            log_occam: log_evidence - (top - area),
            posterior,
        }
    }

    /// `one` refined from where it is with `other`'s torques taken away;
    /// kept (true) when that lowers the pair's residual below `residual`.
    fn step(&self, one: &mut Placed, other: &Placed, residual: &mut f64) -> bool {
        let left = minus(self.tau, &other.torques);
        let Some(location) = one.location else {
            return false;
        };
        let Some(r) = refine_at(
            self.posed.torque_model,
            self.posed.surface,
            &self.measurement(&left),
            (one.link, location),
            one.point,
        ) else {
            return false;
        };
        let moved = self.refined(&r);
        let after = self.chi2(&minus(&left, &moved.torques));
        if after < *residual && !self.too_near(moved.link, moved.point_in_link, other) {
            *residual = after;
            *one = moved;
            return true;
        }
        false
    }

    /// Coordinate descent on the continuous surface: each contact refined
    /// in turn with the other held, until the pair's residual stops
    /// falling.
    pub(super) fn polish(&self, a: &mut Placed, b: &mut Placed) {
        if !self.settings.patches {
            return;
        }
        let mut residual = self.residual(a, b);
        for _ in 0..POLISH_ROUNDS {
            let before = residual;
            self.step(a, b, &mut residual);
            self.step(b, a, &mut residual);
            if before - residual < POLISH_CHI2 {
                break;
            }
        }
    }

    /// From one contact's place: the other given it, it given the other,
    /// and so on ([`PAIR_ROUNDS`] searches); `None` where a search finds
    /// no place away from the other contact.
    fn alternate(&self, start: Placed) -> Result<Option<[Placed; 2]>, EstimateError> {
        let mut a = start;
        let mut b: Option<Placed> = None;
        for round in 0..PAIR_ROUNDS {
            let (given, moving) = if round % 2 == 0 {
                (&a, b.as_ref())
            } else if let Some(other) = &b {
                (other, Some(&a))
            } else {
                break;
            };
            let Some(found) = self.conditional(given)? else {
                return Ok(None);
            };
            let settled = round >= 2 && moving.is_some_and(|m| settled(m, &found.placed));
            if round % 2 == 0 {
                b = Some(found.placed);
            } else {
                a = found.placed;
            }
            if settled {
                break;
            }
        }
        Ok(b.map(|b| [a, b]))
    }

    /// The pair of the largest evidence from `starts_given`, taken in
    /// order up to the first that explains the torques within the noise
    /// (see [`estimate_pair`]); a pair given whose pushes lie within the
    /// separation is passed over.
    fn best_of(&self, starts_given: &[PairStart], single: &Posterior) -> Result<Option<Best>, EstimateError> {
        let (posed, tau) = (self.posed, self.tau);
        let first = single.map_point;
        let mut best: Option<Best> = None;
        'starts: for start in starts_given {
            let seeds: Vec<Seed> = match start {
                PairStart::Both(both) => vec![Seed::Pair((**both).clone())],
                PairStart::One { point, force_newtons } => vec![Seed::From(self.at_sample(*point, *force_newtons))],
                PairStart::Unknown => {
                    let coarse = coarse_pair(posed, tau, &self.weights, self.force_range());
                    let mut seeds: Vec<Seed> = coarse
                        .into_iter()
                        .flat_map(|(i, fi, j, fj)| [(i, fi), (j, fj)])
                        .map(|(k, f)| Seed::From(self.at_sample(k, f)))
                        .collect();
                    if seeds.is_empty() {
                        let f = single.force_newtons.get(first).copied().unwrap_or(0.0);
                        seeds.push(Seed::From(self.at_sample(first, f)));
                    }
                    seeds
                }
            };
            for seed in seeds {
                let places = match seed {
                    Seed::Pair([a, b]) if self.too_near(a.link, a.point_in_link, &b) => None,
                    Seed::Pair(places) => Some(places),
                    Seed::From(one) => self.alternate(one)?,
                };
                if let Some(places) = places
                    && let Some((z, residual, pair)) = self.evaluate(places)?
                    && best.as_ref().is_none_or(|(top, ..)| z > *top)
                {
                    best = Some((z, residual, pair));
                }
                if best
                    .as_ref()
                    .is_some_and(|(_, residual, _)| *residual <= tau.len() as f64)
                {
                    break 'starts;
                }
            }
        }
        Ok(best)
    }

    /// Both places polished, then each contact's posterior and evidence
    /// given the other, and `Z₂` (see the module docs):
    /// `2 Z₁(τ − t_B̂) Z₁(τ − t_Â) / L(Â, B̂)`.
    fn evaluate(&self, [mut a, mut b]: [Placed; 2]) -> Result<Option<(f64, f64, [Conditional; 2])>, EstimateError> {
        self.polish(&mut a, &mut b);
        let (Some(a_given_b), Some(b_given_a)) = (self.conditional(&b)?, self.conditional(&a)?) else {
            return Ok(None);
        };
        // The polished places are the pair's: the searches above are for
        // the evidence and each contact's posterior given the other.
        let residual = self.residual(&a, &b);
        let log_evidence_two = if self.settings.patches {
            // Each contact's Occam factor from its samples, the peak from
            // the pair's places on the continuous surface (with friction,
            // what both tangential forces explain, `pair_friction_gain`).
            let friction = self.pair_friction_gain(&a, &b);
            std::f64::consts::LN_2 + a_given_b.log_occam + b_given_a.log_occam - 0.5 * residual + friction
        } else {
            std::f64::consts::LN_2 + a_given_b.log_evidence + b_given_a.log_evidence + 0.5 * residual
        };
        Ok(Some((
            log_evidence_two,
            residual,
            [
                Conditional { placed: a, ..a_given_b },
                Conditional { placed: b, ..b_given_a },
            ],
        )))
    }
}

/// The frame's two-contact account, from its one-contact posterior
/// `single` of the torques `tau`, the search started from each of
/// `starts_given`, the one with the larger evidence kept (`None` when no
/// start finds a place away from the first contact).
///
/// # Errors
/// As [`estimate`], for a remainder's posterior.
#[allow(clippy::too_many_arguments)]
pub fn estimate_pair(
    posed: &PosedSurface<'_>,
    pose: &RobotPose,
    tau: &[f64],
    settings: &EstimatorSettings,
    hierarchy: Option<&PhaseHierarchy>,
    single: &Posterior,
    pair: &PairSettings,
    starts_given: &[PairStart],
) -> Result<Option<PairEstimate>, EstimateError> {
    let search = Search::new(posed, pose, tau, settings, hierarchy, pair);
    let log_evidence_one = search.log_evidence_one(single);
    // From the places given, or from where one contact is believed to be,
    // or from each contact of the best pair of a coarse grid of samples,
    // searched whole (a two-contact frame's single contact can lie on
    // neither push, and a search started there stays near it); the pair
    // with the larger evidence is kept.
    // The starts are taken in the order given (the coarse pair's contacts
    // one after the other), and the search stops at the first whose pair
    // explains the torques within the noise (a residual χ² no larger
    // than the joints': what the noise alone gives on average): a pair
    // followed from the last frame usually does.
    let mut best = search.best_of(starts_given, single)?;
    // A pair whose pushes lie within the separation across a joint is
    // one push split in two, as on one link (two pushes a finger apart
    // about the wrist explain the `../shared` two-contact example as well
    // as its two probes 14 cm apart): searched again with the separation
    // counted across links, from the same starts and the coarse grid's
    // pair, and replaced by the pair found there unless that is less
    // probable by more than `SPLIT_EVIDENCE_NATS`. Only a split pair the
    // rules above would call: one they do not is a push with friction,
    // and a pair apart from it is a false one (generated link 6 slide,
    // seed 2: 25 of 635 one-press frames called two). Nor does the first
    // search count the separation across links: the `../shared` link 6
    // slide, dragging beyond its friction model, was then called a pair
    // with link 5 in 25 of its 274 frames.
    let apart = Search {
        across_links: true,
        ..search.clone()
    };
    let split = best.as_ref().is_some_and(|(_, _, [a, b])| {
        let (a, b) = (&a.placed, &b.placed);
        apart.too_near(a.link, a.point_in_link, b)
            && search
                .unidentifiable(sensing(posed.torque_model, a.link, b.link), a, b)
                .is_none()
    });
    if split {
        let mut starts = starts_given.to_vec();
        if !starts.contains(&PairStart::Unknown) {
            starts.push(PairStart::Unknown);
        }
        if let (Some((top, ..)), Some(found)) = (&best, apart.best_of(&starts, single)?)
            && found.0 >= *top - SPLIT_EVIDENCE_NATS
        {
            best = Some(found);
        }
    }
    Ok(best.map(|best| search.account(single, log_evidence_one, best)))
}

impl Search<'_> {
    /// The search of one frame's pair, the separation on one link only.
    pub(super) fn new<'a>(
        posed: &'a PosedSurface<'a>,
        pose: &'a RobotPose,
        tau: &'a [f64],
        settings: &'a EstimatorSettings,
        hierarchy: Option<&'a PhaseHierarchy>,
        pair: &'a PairSettings,
    ) -> Search<'a> {
        let surface = posed.surface;
        let ln_prior_norm = if settings.patches {
            surface.area_m2.iter().sum::<f64>().ln()
        } else {
            (surface.len().max(1) as f64).ln()
        };
        Search {
            posed,
            tau,
            settings,
            hierarchy,
            pair,
            weights: settings.weights(),
            ln_prior_norm,
            pose,
            across_links: false,
        }
    }

    /// The frame's account of the pair `best` against its single contact
    /// `single` (of ln evidence `log_evidence_one`).
    pub(super) fn account(
        &self,
        single: &Posterior,
        log_evidence_one: f64,
        (log_evidence_two, residual_chi2, [a, b]): Best,
    ) -> PairEstimate {
        let (posed, pose, pair) = (self.posed, self.pose, self.pair);
        let surface = posed.surface;
        let first = single.map_point;
        let odds = (pair.prior_two / (1.0 - pair.prior_two)).ln() + log_evidence_two - log_evidence_one;
        let sensing_joints = sensing(posed.torque_model, a.placed.link, b.placed.link);
        let unidentifiable = self.unidentifiable(sensing_joints, &a.placed, &b.placed);
        let world = |k: usize| -> DVec3 {
            match (surface.link.get(k), surface.point_in_link.get(k)) {
                (Some(&link), Some(&p)) => pose.point_to_world(link, p),
                _ => DVec3::ZERO,
            }
        };
        let contact = |c: Conditional| PairContact {
            point_world: pose.point_to_world(c.placed.link, c.placed.point_in_link),
            force_world: c.placed.force_newtons
                * pose
                    .world_from_link
                    .get(c.placed.link)
                    .map_or(DVec3::ZERO, |w| w.transform_vector3(c.placed.inward_normal_in_link)),
            credible90: credible_set(&c.posterior, world, 0.9),
            probability: c.posterior.probability,
            placed: c.placed,
        };
        // The contact nearer the single contact's place first.
        let first_world = world(first);
        let mut contacts = [contact(a), contact(b)];
        if contacts[1].point_world.distance(first_world) < contacts[0].point_world.distance(first_world) {
            contacts.swap(0, 1);
        }
        PairEstimate {
            contacts,
            log_evidence_one,
            log_evidence_two,
            probability_two: logistic(odds),
            residual_chi2,
            sensing_joints,
            unidentifiable,
        }
    }
}

/// ln of a posterior's marginal likelihood over the surface prior: its
/// most probable point's log-likelihood over that point's probability,
/// over the prior's normaliser.
#[must_use]
pub fn log_evidence(posterior: &Posterior, ln_prior_norm: f64) -> f64 {
    let k = posterior.map_point;
    match (posterior.log_likelihood.get(k), posterior.probability.get(k)) {
        (Some(&l), Some(&p)) if p > 0.0 => l - p.ln() - ln_prior_norm,
        _ => f64::NEG_INFINITY,
    }
}

#[cfg(test)]
#[path = "pair_tests.rs"]
mod tests;
