//! The estimator of one frame: the surface and the phase hierarchy are
//! built once (they live in link frames), then each measurement is an
//! update at its own configuration, refined on the continuous surface
//! and summarised. A session's frames over time go through
//! [`crate::core::over_time::sequence`], which adds the temporal
//! model's belief to the same steps.

use std::time::Instant;

use glam::DVec3;

use crate::core::estimate::contact::{PatchForms, PosedSurface};
use crate::core::estimate::measurement::Measurement;
use crate::core::estimate::pair::{HeldPush, PairEstimate, PairSettings, PairStart, Placed, estimate_pair};
use crate::core::estimate::pair_held::{HeldPair, estimate_pair_held};
use crate::core::estimate::phases::{PhaseHierarchy, link_ranges};
use crate::core::estimate::place_spread::PlaceSpread;
use crate::core::estimate::posterior::{Posterior, estimate_keeping_forms};
use crate::core::estimate::press::{PressFrame, PressSettings, locate, press_spreads};
use crate::core::estimate::refine::{contact_at_offsets, refine};
use crate::core::estimate::settings::{EstimateError, EstimatorSettings, Mode};
use crate::core::estimate::summary::{
    NO_CONTACT_P, POOR_FIT_P, PlacedContact, Refinement, Summary, Verdict, summarize_refined,
};
use crate::core::geometry::shell::MeshPoint;
use crate::core::numerics::special::chi_square_survival;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{LinkId, Robot};
use crate::core::robot::torque::{TorqueModel, weighted_dot};
use crate::core::surface::sampling::{LinkShape, Surface, SurfaceError, SurfaceRequest};

/// Everything fixed across updates.
#[derive(Debug, Clone)]
pub struct Estimator {
    /// Candidate surface points.
    pub surface: Surface,
    /// Candidate links.
    pub links: Vec<LinkId>,
    /// Phases A/B/C, when used.
    pub hierarchy: Option<PhaseHierarchy>,
    /// Noise model, force range, mode.
    pub settings: EstimatorSettings,
}

/// A measurement's posterior awaiting a temporal model's belief (see
/// [`Estimator::update_for_sequence`], [`Estimator::with_belief`]).
#[derive(Debug, Clone)]
pub struct PendingUpdate {
    /// The robot at the measurement's configuration.
    pub pose: RobotPose,
    /// The frame's own posterior over the surface points.
    pub posterior: Posterior,
}

/// One measurement's result.
#[derive(Debug, Clone)]
pub struct Update {
    /// The robot at the measurement's configuration.
    pub pose: RobotPose,
    /// The posterior over the surface points.
    pub posterior: Posterior,
    /// What it says.
    pub summary: Summary,
    /// Where the time of a frame estimated alone ([`Estimator::update`])
    /// went; `None` for frames combined over time, whose stages
    /// interleave with the temporal model's.
    pub stages: Option<StageTimes>,
}

/// The wall time of one frame's stages, ms: disjoint parts of
/// [`Estimator::update`], so they add up to at most its time. What
/// `bench` reports to show where a frame's 99th percentile comes from.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct StageTimes {
    /// The posterior over the samples (the pose, the torque model, the
    /// likelihood of every sample and the posterior's masses).
    pub posterior_ms: f64,
    /// The search for the contact on the continuous surface (0 where the
    /// frame is not refined: no contact, or grid mode).
    pub refine_ms: f64,
    /// The summary: fit test, verdict, shares, credible set, clusters.
    pub summary_ms: f64,
}

impl Estimator {
    /// Samples the surface and, with `phase_sizes`, builds the phase
    /// hierarchy (seeded by the surface seed).
    pub fn new(
        robot: &Robot,
        request: &SurfaceRequest,
        settings: EstimatorSettings,
        phase_sizes: Option<[usize; 2]>,
    ) -> Result<Self, SurfaceError> {
        let surface = Surface::sample(robot, request)?;
        // The evidence's erfc fit is built on first use: here, not in the
        // first update (a few milliseconds that would be that frame's).
        let _ = crate::core::numerics::fastmath::ErfTable::get();
        let hierarchy = phase_sizes.map(|sizes| PhaseHierarchy::new(&surface, sizes, request.seed));
        Ok(Self {
            surface,
            links: request.links.clone(),
            hierarchy,
            settings,
        })
    }

    /// The posterior for torques `tau` measured at `joint_positions`
    /// (every joint's, see [`Robot::joint_positions`]).
    pub fn update(&self, robot: &Robot, joint_positions: &[f64], tau: &[f64]) -> Result<Update, EstimateError> {
        let started = Instant::now();
        let (pose, torque_model, posterior) = self.posterior_at(robot, joint_positions, tau, None)?;
        let posterior_ms = elapsed_ms(started);
        let concluding = Instant::now();
        let (summary, refine_ms) = self.conclude_alone(&torque_model, &pose, &posterior, tau);
        let mut update = Update {
            pose,
            posterior,
            summary,
            stages: None,
        };
        self.widen_alone(&mut update, &torque_model, tau);
        let summary_ms = (elapsed_ms(concluding) - refine_ms).max(0.0);
        update.stages = Some(StageTimes {
            posterior_ms,
            refine_ms,
            summary_ms,
        });
        finite(update)
    }

    /// A frame alone with friction: `update`'s credible set widened as a
    /// smoothed press's is ([`Estimator::widen_credible`]), by the spread
    /// that the frame's own torques leave its place once a tangential
    /// force under its prior (spread μ per newton of push) is let in
    /// ([`Estimator::spread_alone`]). The posterior over samples is the
    /// frictionless one, and it is sure of a place that a drag has shifted
    /// (measured: 34 % of a session's 30 % drags in the set).
    fn widen_alone(&self, update: &mut Update, torque_model: &TorqueModel, tau: &[f64]) {
        if !self.fits_presses() || !is_pressed(update) {
            return;
        }
        let Some((link, shape, at)) = self.located_contact(update) else {
            return;
        };
        let frame = PressFrame {
            t_secs: 0.0,
            torque_model,
            tau,
            start: at,
        };
        if let Some(spread) = self.spread_alone(shape, link, frame) {
            self.widen_credible(update, link, &spread);
        }
    }

    /// The spread that one frame's torques leave its place (`frame.start`
    /// on `link`), γ free under its prior: a press of one frame.
    pub(crate) fn spread_alone(&self, shape: &LinkShape, link: LinkId, frame: PressFrame) -> Option<PlaceSpread> {
        let weights = self.settings.weights();
        // One frame has no slide between frames: any positive length will do.
        let settings = self.press_settings(&weights, 1.0);
        press_spreads(shape, link, &[frame], &settings)?.first().copied()
    }

    pub(crate) fn posterior_at(
        &self,
        robot: &Robot,
        joint_positions: &[f64],
        tau: &[f64],
        forms: Option<&mut PatchForms>,
    ) -> Result<(RobotPose, TorqueModel, Posterior), EstimateError> {
        let pose = RobotPose::new(robot, joint_positions);
        let torque_model = TorqueModel::new(robot, &pose, &self.links);
        let posed = PosedSurface {
            torque_model: &torque_model,
            surface: &self.surface,
        };
        let posterior = estimate_keeping_forms(&posed, tau, &self.settings, self.hierarchy.as_ref(), forms)?;
        Ok((pose, torque_model, posterior))
    }

    /// The two-contact account of torques `tau` measured at
    /// `joint_positions` ([`crate::core::estimate::pair`]), its search
    /// started from each of `starts`; `None` when the surface has no place
    /// for a second contact.
    ///
    /// # Errors
    /// As [`Estimator::update`].
    pub fn pair_at(
        &self,
        robot: &Robot,
        joint_positions: &[f64],
        tau: &[f64],
        pair: &PairSettings,
        starts: &[PairStart],
    ) -> Result<Option<PairEstimate>, EstimateError> {
        self.with_single(robot, joint_positions, tau, |posed, pose, posterior| {
            estimate_pair(
                posed,
                pose,
                tau,
                &self.settings,
                self.hierarchy.as_ref(),
                posterior,
                pair,
                starts,
            )
        })
    }

    /// The two-contact account of torques `tau` at `joint_positions` with
    /// both contacts where the frame beside left them, `both[new]` held
    /// near its place there ([`crate::core::estimate::pair_held`]).
    ///
    /// # Errors
    /// As [`Estimator::update`].
    pub fn pair_held_at(
        &self,
        robot: &Robot,
        joint_positions: &[f64],
        tau: &[f64],
        pair: &PairSettings,
        both: &[Placed; 2],
        new: usize,
    ) -> Result<Option<HeldPair>, EstimateError> {
        self.with_single(robot, joint_positions, tau, |posed, pose, posterior| {
            estimate_pair_held(
                posed,
                pose,
                tau,
                &self.settings,
                self.hierarchy.as_ref(),
                posterior,
                pair,
                both,
                new,
            )
        })
    }

    /// `then` of the surface posed at `joint_positions`, the pose, and the
    /// one-contact posterior of `tau` there: what a frame's pair search
    /// starts from.
    fn with_single<T>(
        &self,
        robot: &Robot,
        joint_positions: &[f64],
        tau: &[f64],
        then: impl FnOnce(&PosedSurface<'_>, &RobotPose, &Posterior) -> Result<T, EstimateError>,
    ) -> Result<T, EstimateError> {
        let (pose, torque_model, posterior) = self.posterior_at(robot, joint_positions, tau, None)?;
        let posed = PosedSurface {
            torque_model: &torque_model,
            surface: &self.surface,
        };
        then(&posed, &pose, &posterior)
    }

    /// Whether `held`, a push that explained an earlier frame, explains
    /// the torques `tau` at `joint_positions` as well: with its force's
    /// direction in its link's frame kept and its magnitude fitted (at
    /// least 0), the residual passes the fit test ([`POOR_FIT_P`]). A
    /// sliding contact's kinetic friction drags at up to half its push,
    /// beyond the friction cone a frame alone is fitted with: the press
    /// fit finds it, and the frames that follow keep it.
    #[must_use]
    pub fn held_push_explains(&self, robot: &Robot, joint_positions: &[f64], tau: &[f64], held: &HeldPush) -> bool {
        self.held_push_chi2(robot, joint_positions, tau, held)
            .is_some_and(|chi2| chi_square_survival(chi2, tau.len().saturating_sub(1)) >= POOR_FIT_P)
    }

    /// The residual χ² of `held` on the torques `tau` at
    /// `joint_positions`, its force's direction in its link's frame kept
    /// and its magnitude fitted (at least 0); `None` for a push of no
    /// direction or torques of the wrong length.
    #[must_use]
    pub fn held_push_chi2(&self, robot: &Robot, joint_positions: &[f64], tau: &[f64], held: &HeldPush) -> Option<f64> {
        let length = held.force_in_link.length();
        if !(length > 0.0 && length.is_finite()) {
            return None;
        }
        let pose = RobotPose::new(robot, joint_positions);
        let torque_model = TorqueModel::new(robot, &pose, &self.links);
        let per_newton = torque_model.torques(held.link, held.point_in_link, held.force_in_link / length);
        let weights = self.settings.weights();
        if per_newton.len() != tau.len() || weights.len() != tau.len() {
            return None;
        }
        let along = weighted_dot(&weights, tau, &per_newton);
        let norm = weighted_dot(&weights, &per_newton, &per_newton);
        if !(norm > 0.0 && norm.is_finite()) {
            return None;
        }
        let newtons = (along / norm).max(0.0);
        let left: Vec<f64> = tau.iter().zip(&per_newton).map(|(t, u)| t - newtons * u).collect();
        let chi2 = weighted_dot(&weights, &left, &left);
        chi2.is_finite().then_some(chi2)
    }

    /// The residual χ² of a push at `point_in_link` on `link` whose force
    /// is free (its three components fitted, any direction, friction or
    /// not) on the torques `tau` at `joint_positions`: one contact that
    /// stays where it stood, however its force turns. `None` where the
    /// place's torques do not fix the three components, or the torques
    /// are of the wrong length.
    #[must_use]
    pub fn free_push_chi2(
        &self,
        robot: &Robot,
        joint_positions: &[f64],
        tau: &[f64],
        link: LinkId,
        point_in_link: DVec3,
    ) -> Option<f64> {
        let pose = RobotPose::new(robot, joint_positions);
        let torque_model = TorqueModel::new(robot, &pose, &self.links);
        Self::free_push_chi2_with((&torque_model, &self.settings.weights()), tau, link, point_in_link)
    }

    /// The least [`Self::free_push_chi2`] over each of `places` (a link
    /// and a point in it) and the surface samples within `radius_m` of
    /// it, on any link: one contact that pushes any way near where it
    /// stood (a place that lags a slide by centimetres, or sits across
    /// the joint from it). `None` where no such place fixes its force.
    #[must_use]
    pub fn free_push_chi2_near(
        &self,
        robot: &Robot,
        (joint_positions, tau): (&[f64], &[f64]),
        places: &[(LinkId, DVec3)],
        radius_m: f64,
    ) -> Option<f64> {
        let pose = RobotPose::new(robot, joint_positions);
        let torque_model = TorqueModel::new(robot, &pose, &self.links);
        let weights = self.settings.weights();
        let radius_sq = radius_m * radius_m;
        let centres: Vec<DVec3> = places
            .iter()
            .filter_map(|&(link, point)| Some(pose.world_from_link.get(link)?.transform_point3(point)))
            .collect();
        let near = self
            .surface
            .link
            .iter()
            .zip(&self.surface.point_in_link)
            .filter(|&(&l, &p)| {
                pose.world_from_link.get(l).is_some_and(|w| {
                    let world = w.transform_point3(p);
                    centres.iter().any(|c| world.distance_squared(*c) <= radius_sq)
                })
            })
            .map(|(&l, &p)| (l, p));
        places
            .iter()
            .copied()
            .chain(near)
            .filter_map(|(l, p)| Self::free_push_chi2_with((&torque_model, &weights), tau, l, p))
            .reduce(f64::min)
    }

    /// [`Self::free_push_chi2`] with the pose's torque model built and
    /// the noise's weights (1/σ²) taken.
    fn free_push_chi2_with(
        (torque_model, weights): (&TorqueModel, &[f64]),
        tau: &[f64],
        link: LinkId,
        point_in_link: DVec3,
    ) -> Option<f64> {
        let columns = [DVec3::X, DVec3::Y, DVec3::Z].map(|axis| torque_model.torques(link, point_in_link, axis));
        if columns.iter().any(|c| c.len() != tau.len()) || weights.len() != tau.len() {
            return None;
        }
        // The normal equations of the weighted least squares, 3 × 3.
        let gram = glam::DMat3::from_cols_array_2d(
            &columns
                .each_ref()
                .map(|a| columns.each_ref().map(|b| weighted_dot(weights, a, b))),
        );
        let along = DVec3::from_array(columns.each_ref().map(|c| weighted_dot(weights, c, tau)));
        let scale = gram.x_axis.x + gram.y_axis.y + gram.z_axis.z;
        // A place whose three force directions make nearly the same
        // torques (a point on a joint's axis, say) leaves them unfixed.
        if !(scale > 0.0 && gram.determinant() > 1e-12 * scale * scale * scale) {
            return None;
        }
        let force = gram.inverse() * along;
        let left: Vec<f64> = tau
            .iter()
            .enumerate()
            .map(|(j, t)| {
                t - columns
                    .iter()
                    .zip(force.to_array())
                    .map(|(c, f)| f * c.get(j).copied().unwrap_or(0.0))
                    .sum::<f64>()
            })
            .collect();
        let chi2 = weighted_dot(weights, &left, &left);
        chi2.is_finite().then_some(chi2)
    }

    /// A frame's summary from its own posterior: the contact refined
    /// unless the torques are within noise of zero (there is no contact
    /// to place; the summary reports the most probable sample); and the
    /// refinement's time, ms.
    pub(crate) fn conclude_alone(
        &self,
        torque_model: &TorqueModel,
        pose: &RobotPose,
        posterior: &Posterior,
        tau: &[f64],
    ) -> (Summary, f64) {
        let no_contact = chi_square_survival(posterior.no_contact_chi2, torque_model.sensed_count()) > NO_CONTACT_P;
        self.conclude(torque_model, pose, posterior, tau, !no_contact, None)
    }

    /// Refines (when asked and the settings allow) and summarises a
    /// posterior of the torques `tau` at `pose`; also the refinement's
    /// time, ms.
    pub(crate) fn conclude(
        &self,
        torque_model: &TorqueModel,
        pose: &RobotPose,
        posterior: &Posterior,
        tau: &[f64],
        refine_contact: bool,
        belief: Option<BeliefAtFrame>,
    ) -> (Summary, f64) {
        let (contact_probability, offsets, friction) = match belief {
            Some(b) => (
                Some(b.contact_probability),
                b.offset_m,
                if b.friction_at_place {
                    self.settings.friction
                } else {
                    0.0
                },
            ),
            None => (None, None, self.settings.friction),
        };
        let refines = self.settings.patches && self.settings.mode == Mode::Exact && refine_contact;
        let refining = Instant::now();
        let refined = refines
            .then(|| {
                let weights = self.settings.weights();
                let measurement = Measurement {
                    tau,
                    weights: &weights,
                    force_range_newtons: (self.settings.force_min_newtons, self.settings.force_max_newtons),
                    friction,
                };
                // With friction (`Measurement::friction`) a frame's own
                // refinement places the contact by the friction model; both
                // report that model's force.
                match offsets {
                    Some(offset_m) => {
                        contact_at_offsets(torque_model, &self.surface, posterior, &measurement, offset_m)
                    }
                    None => refine(torque_model, &self.surface, posterior, &measurement),
                }
            })
            .flatten();
        let refine_ms = if refines { elapsed_ms(refining) } else { 0.0 };
        let summary = summarize_refined(
            posterior,
            &self.surface,
            pose,
            torque_model.sensed_count(),
            refined.as_ref().map(|contact| Refinement {
                contact,
                sensing_joints: torque_model.twists(contact.link).len(),
            }),
            contact_probability,
        );
        (summary, refine_ms)
    }

    /// Whether smoothed presses are fitted as a whole with friction
    /// ([`crate::core::estimate::press`]): with a friction setting, exact mode and
    /// patches (the contacts are then placed on the continuous surface).
    #[must_use]
    pub fn fits_presses(&self) -> bool {
        self.settings.friction > 0.0 && self.uses_patches()
    }

    /// `update`'s reported contact on its link's continuous surface: the
    /// link, its shape and the place there (walked to from the contact's
    /// sample). `None` where the link has no shape here.
    pub(crate) fn located_contact(&self, update: &Update) -> Option<(LinkId, &LinkShape, MeshPoint)> {
        let map = &update.summary.map;
        let shape = self.surface.shape(map.link)?;
        let &sample = self.surface.location.get(map.point)?;
        let world_from_link = update.pose.world_from_link.get(map.link)?;
        let point_in_link = world_from_link.inverse().transform_point3(map.point_world);
        Some((map.link, shape, locate(shape, sample, point_in_link)))
    }

    /// Adds to `update`'s 90 % credible set the samples of `link` (its
    /// reported contact's) that lie in the press's 90 % region around the
    /// reported place (`spread`, a patch's radius added; samples facing
    /// away from the place's normal left out): the smoother multiplies
    /// its frames' likelihoods as if each frame's misfit were fresh noise,
    /// and a press whose friction shifts every frame's place the same way
    /// ends up sure of a wrong place (measured: `../shared` link 4, the
    /// set a few millimetres wide and 68 mm from the push).
    pub(crate) fn widen_credible(&self, update: &mut Update, link: LinkId, spread: &PlaceSpread) {
        let map = &update.summary.map;
        let Some(link_from_world) = update.pose.world_from_link.get(link).map(glam::DAffine3::inverse) else {
            return;
        };
        if map.link != link {
            return;
        }
        let center = link_from_world.transform_point3(map.point_world);
        let normal = link_from_world.transform_vector3(map.inward_normal_world);
        let Some(region) = spread.region(0.5 * self.surface.spacing_m(), CHI2_2_AT_90) else {
            return;
        };
        let surface = &self.surface;
        // Only the link's own samples (the surface keeps each link's in one
        // run): a scan of every sample read more memory than the rest of
        // the widening cost.
        let Some(range) = link_ranges(&surface.link)
            .into_iter()
            .find_map(|(on, range)| (on == link).then_some(range))
        else {
            return;
        };
        let (Some(points), Some(normals)) = (
            surface.point_in_link.get(range.clone()),
            surface.inward_normal_in_link.get(range.clone()),
        ) else {
            return;
        };
        let more: Vec<usize> = range
            .zip(points.iter().zip(normals))
            .filter(|&(_, (&point, &inward))| inward.dot(normal) > 0.0 && region.contains(point - center))
            .map(|(k, _)| k)
            .collect();
        if more.is_empty() {
            return;
        }
        let pose = &update.pose;
        update.summary.credible90 = update
            .summary
            .credible90
            .with_points(&more, &update.posterior.probability, |k| {
                surface.point_world(pose, k).unwrap_or(DVec3::ZERO)
            });
    }

    /// Reports `placed` as `update`'s contact (see
    /// [`Summary::place_contact`]), `model` being the frame's torques.
    pub(crate) fn place(&self, update: &mut Update, placed: &PlacedContact, model: &TorqueModel) {
        update.summary.place_contact(
            placed,
            model.twists(placed.link).len(),
            (&update.posterior, &self.surface, &update.pose),
            model.sensed_count(),
        );
    }

    /// How presses are fitted under these settings: the noise `weights`
    /// (`1/σ²`, [`EstimatorSettings::weights`]) and a fraction
    /// ([`PRESS_SLIDE_FRACTION`]) of the temporal model's slide length.
    pub(crate) fn press_settings<'w>(&self, weights: &'w [f64], slide_m_per_sqrt_s: f64) -> PressSettings<'w> {
        PressSettings {
            weights,
            force_range_newtons: (self.settings.force_min_newtons, self.settings.force_max_newtons),
            friction: self.settings.friction,
            slide_m_per_sqrt_s: slide_m_per_sqrt_s * PRESS_SLIDE_FRACTION,
        }
    }

    /// Whether posteriors integrate each sample's patch (exact mode with
    /// patches): their samples are then weighed by area.
    #[must_use]
    pub fn uses_patches(&self) -> bool {
        self.settings.patches && self.settings.mode == Mode::Exact
    }
}

/// `update`, or the error that names its first number that is not
/// finite: an estimate is reported finite or not at all.
pub(crate) fn finite(update: Update) -> Result<Update, EstimateError> {
    match update.summary.non_finite_field() {
        None => Ok(update),
        Some(field) => Err(EstimateError::NonFiniteEstimate { field }),
    }
}

/// Milliseconds since `since`.
pub(crate) fn elapsed_ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// What a temporal model believes at a frame, as a summary needs it.
#[derive(Clone, Copy)]
pub(crate) struct BeliefAtFrame<'a> {
    /// Probability of a contact.
    pub contact_probability: f64,
    /// Where within its patch the contact is believed to be, per sample,
    /// m along the sample's tangents (confined to the patch: beyond it
    /// the linear model does not hold); the samples are points when
    /// `None`.
    pub offset_m: Option<&'a dyn Fn(usize) -> Option<[f64; 2]>>,
    /// Whether the force at the believed place follows the friction
    /// setting (else it is frictionless).
    pub friction_at_place: bool,
}

/// The 90 % point of χ² with two degrees of freedom: a 2-D Gaussian's
/// 90 % region is where the squared Mahalanobis distance is below it
/// (`-2 ln 0.1`).
pub const CHI2_2_AT_90: f64 = 4.605_170_185_988_091;

/// Whether a frame's contact can join a press: a contact placed on the
/// continuous surface.
pub(crate) fn is_pressed(update: &Update) -> bool {
    update.summary.refined && update.summary.verdict != Verdict::NoContact
}

/// The press fit (see [`crate::core::estimate::press`]) slides the place by this
/// fraction of the temporal model's slide length. The smoother reports
/// one place per press (its heaviest sample moved by the offset every
/// frame believes), whereas a trajectory free to slide at the full
/// length follows each frame's noise: on synthetic sessions without
/// friction (`synth --seed 3`) a fit at the full length moved the median
/// error from 1.4 to 7 mm on a press of link 6, and on the link 4
/// `MuJoCo` presses it took a second press for friction at 27 mm instead of
/// 10 mm.
pub const PRESS_SLIDE_FRACTION: f64 = 0.3;

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::numerics::rng::Rng;
    use crate::core::robot::builtin;

    /// A push on link 6 dragging sideways at half its magnitude, as a
    /// slide's kinetic friction does, and the estimator of the LWR.
    fn sliding_push() -> (Robot, Estimator, Vec<f64>, HeldPush, DVec3) {
        let robot = builtin::lwr4plus_generated().unwrap();
        let request = SurfaceRequest {
            links: robot.default_candidate_links(),
            total_points: 500,
            seed: 0,
        };
        let settings = EstimatorSettings::exact(vec![0.05; 7]);
        let estimator = Estimator::new(&robot, &request, settings, None).unwrap();
        let link = robot.link_id("lwr_6_link").unwrap();
        let surface = &estimator.surface;
        let k = (0..surface.len()).find(|&k| surface.link[k] == link).unwrap();
        let normal = surface.inward_normal_in_link[k];
        let (tangent, _) = normal.any_orthonormal_pair();
        let held = HeldPush {
            link,
            point_in_link: surface.point_in_link[k],
            force_in_link: normal * 12.0 + tangent * 6.0,
        };
        (
            robot,
            estimator,
            vec![0.4, -0.3, 0.5, -1.2, 0.6, 0.8, -0.2],
            held,
            normal,
        )
    }

    /// Torques of `push` scaled by `scale` at `q`, with noise of σ 0.05.
    fn torques_of(robot: &Robot, estimator: &Estimator, q: &[f64], push: &HeldPush, scale: f64) -> Vec<f64> {
        let pose = RobotPose::new(robot, q);
        let model = TorqueModel::new(robot, &pose, &estimator.links);
        let mut rng = Rng::new(5);
        model
            .torques(push.link, push.point_in_link, push.force_in_link * scale)
            .iter()
            .map(|t| t + 0.05 * rng.normal())
            .collect()
    }

    #[test]
    fn a_held_push_explains_its_own_torques_at_any_magnitude_and_nothing_else() {
        let (robot, estimator, q, held, normal) = sliding_push();
        for scale in [0.5, 1.0, 1.6] {
            let tau = torques_of(&robot, &estimator, &q, &held, scale);
            assert!(estimator.held_push_explains(&robot, &q, &tau, &held), "×{scale}");
        }
        let tau = torques_of(&robot, &estimator, &q, &held, 1.0);
        // Without its drag, the same push along the normal does not: the
        // drag is what a frame alone, in the friction cone, leaves out.
        let normal_only = HeldPush {
            force_in_link: normal * 12.0,
            ..held
        };
        assert!(!estimator.held_push_explains(&robot, &q, &tau, &normal_only));
        let (tangent, _) = held.force_in_link.normalize().any_orthonormal_pair();
        let turned = HeldPush {
            force_in_link: held.force_in_link + tangent * 8.0,
            ..held
        };
        assert!(!estimator.held_push_explains(&robot, &q, &tau, &turned));
        // Five centimetres off its line of action, the same force does not.
        let across = held.force_in_link.cross(normal).normalize();
        let moved = HeldPush {
            point_in_link: held.point_in_link + across * 0.05,
            ..held
        };
        assert!(!estimator.held_push_explains(&robot, &q, &tau, &moved));
        // Nor does a push that pulls, or none.
        let tau_pull = torques_of(&robot, &estimator, &q, &held, -1.0);
        assert!(!estimator.held_push_explains(&robot, &q, &tau_pull, &held));
        let none = HeldPush {
            force_in_link: DVec3::ZERO,
            ..held
        };
        assert!(!estimator.held_push_explains(&robot, &q, &tau, &none));
        let nan = HeldPush {
            force_in_link: DVec3::NAN,
            ..held
        };
        assert!(!estimator.held_push_explains(&robot, &q, &tau, &nan));
    }

    #[test]
    fn a_free_push_fits_any_force_at_its_place_and_no_second_push() {
        let (robot, estimator, q, held, normal) = sliding_push();
        // Any direction at the place, pulling too: within the noise
        // (χ² with four degrees of freedom left; 30 is p < 10⁻⁵).
        let (tangent, other) = normal.any_orthonormal_pair();
        for force in [held.force_in_link, tangent * 9.0 - normal * 3.0, other * 15.0] {
            let push = HeldPush {
                force_in_link: force,
                ..held
            };
            let tau = torques_of(&robot, &estimator, &q, &push, 1.0);
            let chi2 = estimator
                .free_push_chi2(&robot, &q, &tau, held.link, held.point_in_link)
                .unwrap();
            assert!(chi2 < 30.0, "{force}: {chi2}");
            // Without noise, exactly.
            let pose = RobotPose::new(&robot, &q);
            let exact = TorqueModel::new(&robot, &pose, &estimator.links).torques(held.link, held.point_in_link, force);
            let chi2 = estimator
                .free_push_chi2(&robot, &q, &exact, held.link, held.point_in_link)
                .unwrap();
            assert!(chi2 < 1e-12, "{force}: {chi2}");
        }
        // A second push on link 4 beside it: not.
        let tau = torques_of(&robot, &estimator, &q, &held, 1.0);
        let link4 = robot.link_id("lwr_4_link").unwrap();
        let surface = &estimator.surface;
        let k = (0..surface.len()).find(|&k| surface.link[k] == link4).unwrap();
        let pose = RobotPose::new(&robot, &q);
        let second = TorqueModel::new(&robot, &pose, &estimator.links).torques(
            link4,
            surface.point_in_link[k],
            surface.inward_normal_in_link[k] * 15.0,
        );
        let both: Vec<f64> = tau.iter().zip(&second).map(|(a, b)| a + b).collect();
        let chi2 = estimator
            .free_push_chi2(&robot, &q, &both, held.link, held.point_in_link)
            .unwrap();
        // Measured 238.7: p far below 10⁻⁴⁰ with four degrees of freedom.
        assert!(chi2 > 100.0, "{chi2}");
        // Torques of the wrong length: none.
        assert!(
            estimator
                .free_push_chi2(&robot, &q, &tau[..6], held.link, held.point_in_link)
                .is_none()
        );
    }

    #[test]
    fn a_free_push_searched_near_a_place_finds_the_push_beside_it() {
        let (robot, estimator, q, held, _) = sliding_push();
        let pose = RobotPose::new(&robot, &q);
        let exact = TorqueModel::new(&robot, &pose, &estimator.links).torques(
            held.link,
            held.point_in_link,
            held.force_in_link,
        );
        // The nearest other sample on the link: its own free push misses
        // the torques; the search reaching just past the push's sample
        // finds it, exactly, and one reaching half as far does not.
        let surface = &estimator.surface;
        let beside = (0..surface.len())
            .filter(|&k| surface.link[k] == held.link)
            .map(|k| surface.point_in_link[k])
            .filter(|p| p.distance(held.point_in_link) > 1e-6)
            .min_by(|a, b| {
                a.distance(held.point_in_link)
                    .total_cmp(&b.distance(held.point_in_link))
            })
            .unwrap();
        let apart_m = beside.distance(held.point_in_link);
        let there = estimator.free_push_chi2(&robot, &q, &exact, held.link, beside).unwrap();
        assert!(there > 1.0, "{apart_m} m: {there}");
        let near = estimator
            .free_push_chi2_near(&robot, (&q, &exact), &[(held.link, beside)], apart_m * 1.01)
            .unwrap();
        assert!(near < 1e-12, "{near}");
        let close = estimator
            .free_push_chi2_near(&robot, (&q, &exact), &[(held.link, beside)], apart_m * 0.5)
            .unwrap();
        assert!(close > 1.0, "{close}");
        // Of several places, the one that reaches the push is enough.
        let either = estimator
            .free_push_chi2_near(
                &robot,
                (&q, &exact),
                &[(held.link, beside), (held.link, held.point_in_link)],
                apart_m * 0.5,
            )
            .unwrap();
        assert!(either < 1e-12, "{either}");
    }
}
