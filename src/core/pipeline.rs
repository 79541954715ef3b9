//! The estimator as a pipeline: the surface and the phase hierarchy are
//! built once (they live in link frames), then each measurement is an
//! update at its own configuration.

use std::time::Instant;

use glam::DVec3;

use crate::core::contact::{PatchForms, PosedSurface};
use crate::core::estimator::{EstimateError, EstimatorSettings, Mode, Posterior, estimate_keeping_forms};
use crate::core::friction::friction_evidence;
use crate::core::kinematics::RobotPose;
use crate::core::lanes;
use crate::core::phases::{PhaseHierarchy, link_ranges};
use crate::core::press::{
    FRICTION_GAIN, PlaceSpread, PressAnswer, PressFrame, PressSettings, explain_press, locate, press_spreads,
};
use crate::core::refine::{Measurement, contact_at_offsets, refine};
use crate::core::robot::{LinkId, Robot};
use crate::core::smooth::MeshPoint;
use crate::core::special::chi_square_survival;
use crate::core::summary::{
    ContactEstimate, NO_CONTACT_P, PlacedContact, Refinement, Summary, Verdict, summarize_refined,
};
use crate::core::surface::{LinkShape, Surface, SurfaceError, SurfaceRequest};
use crate::core::temporal::{
    Belief, FilterState, FrameLikelihood, MAX_SMOOTHER_BYTES, Offset, PatchInformation, Smoother, TemporalError,
    TemporalModel, TemporalSettings, is_continuous_recording, smoother_bytes,
};
use crate::core::torque::TorqueModel;

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
        let _ = crate::core::fastmath::ErfTable::get();
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
    fn spread_alone(&self, shape: &LinkShape, link: LinkId, frame: PressFrame) -> Option<PlaceSpread> {
        let weights = self.settings.weights();
        // One frame has no slide between frames: any positive length will do.
        let settings = self.press_settings(&weights, 1.0);
        press_spreads(shape, link, &[frame], &settings)?.first().copied()
    }

    /// The posterior of an update and what a temporal model needs of it
    /// (its likelihoods, and with patches what the frame says about the
    /// place within each patch), not yet summarised: the temporal model's
    /// belief places the contact ([`Estimator::with_belief`]).
    ///
    /// # Errors
    /// As [`Estimator::update`].
    pub fn update_for_sequence(
        &self,
        robot: &Robot,
        joint_positions: &[f64],
        tau: &[f64],
    ) -> Result<(PendingUpdate, FrameLikelihood), EstimateError> {
        let mut forms = PatchForms::default();
        let (pose, _, posterior) = self.posterior_at(robot, joint_positions, tau, Some(&mut forms))?;
        let likelihood = self.likelihood_of(&posterior, &forms);
        Ok((PendingUpdate { pose, posterior }, likelihood))
    }

    /// The posterior of an update, not yet summarised (a sequence's second
    /// pass: its likelihoods are in the smoother already).
    fn pending_update(
        &self,
        robot: &Robot,
        joint_positions: &[f64],
        tau: &[f64],
    ) -> Result<PendingUpdate, EstimateError> {
        let (pose, _, posterior) = self.posterior_at(robot, joint_positions, tau, None)?;
        Ok(PendingUpdate { pose, posterior })
    }

    fn posterior_at(
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

    /// [`Estimator::conclude_alone`] of a pending update where the
    /// recording (`belief`) calls its frame a contact and contacts are
    /// placed on the continuous surface: what its press is checked
    /// against ([`PRESS_MISFIT_PER_FRAME`]).
    fn summary_alone(&self, robot: &Robot, update: &PendingUpdate, tau: &[f64], belief: &Belief) -> Option<Summary> {
        (belief.contact_probability() >= 0.5 && self.uses_patches()).then(|| {
            let torque_model = TorqueModel::new(robot, &update.pose, &self.links);
            self.conclude_alone(&torque_model, &update.pose, &update.posterior, tau)
                .0
        })
    }

    /// A frame's summary from its own posterior: the contact refined
    /// unless the torques are within noise of zero (there is no contact
    /// to place; the summary reports the most probable sample); and the
    /// refinement's time, ms.
    fn conclude_alone(
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
    fn conclude(
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
                b.offsets,
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
                    Some((offsets, windows_m)) => {
                        // Confined to its patch (beyond it the linear
                        // model does not hold): the mean there.
                        let offset_m = |k: usize| {
                            let (offset, &rho) = (offsets.get(k)?, windows_m.get(k)?);
                            Some(offset.confined(rho).1.mean_m())
                        };
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

    /// What the temporal model needs of a frame's posterior: its
    /// likelihoods and, with patches, what the frame says about the place
    /// of the contact within each patch (from the frame's `forms`).
    fn likelihood_of(&self, posterior: &Posterior, forms: &PatchForms) -> FrameLikelihood {
        let mut likelihood = FrameLikelihood::from_posterior(posterior, &self.surface, self.uses_patches());
        if self.uses_patches() && forms.a.len() == self.surface.len() {
            let range = (self.settings.force_min_newtons, self.settings.force_max_newtons);
            likelihood.patch = PatchInformation::from_forms(forms, -2.0 * likelihood.no_contact, range);
        }
        likelihood
    }

    /// Whether smoothed presses are fitted as a whole with friction
    /// ([`crate::core::press`]): with a friction setting, exact mode and
    /// patches (the contacts are then placed on the continuous surface).
    #[must_use]
    pub fn fits_presses(&self) -> bool {
        self.settings.friction > 0.0 && self.uses_patches()
    }

    /// Fits the frames of `press` (consecutive, one link, in order) as
    /// one press with a tangential force fixed in the link's frame (with
    /// a friction setting); where the friction model explains it far
    /// better than none, each frame's reported contact, fit test and
    /// verdict become the fit's. Then checks the press against its
    /// frames' own contacts (`alone`, one per frame; see
    /// [`PRESS_MISFIT_PER_FRAME`]), hands the frames to `each`, each with
    /// its share of the time, and empties `press` and `alone`.
    fn settle_press(
        &self,
        robot: &Robot,
        frames: &[SequenceFrame],
        slide_m_per_sqrt_s: f64,
        press: &mut Vec<(usize, Update, f64)>,
        alone: &mut Vec<Option<Summary>>,
        each: &mut impl FnMut(usize, Update, f64),
    ) {
        if press.is_empty() {
            alone.clear();
            return;
        }
        let t0 = Instant::now();
        if self.fits_presses() {
            self.fit_press_of(robot, frames, slide_m_per_sqrt_s, press, alone);
        }
        check_press(press, alone);
        let share_ms = elapsed_ms(t0) / press.len() as f64;
        for (i, update, cost_ms) in press.drain(..) {
            each(i, update, cost_ms + share_ms);
        }
    }

    /// [`Estimator::settle_press`]'s fit; `None` (nothing changed) where
    /// the press keeps its estimates.
    ///
    /// The press is fitted from the recording's places and, where a few
    /// of its frames alone (`alone`; [`ALTERNATIVE_MIN_FRAMES`]) place the
    /// contact elsewhere together (on another link, or on this one
    /// farther than [`ALTERNATIVE_MIN_M`]), also from theirs; an
    /// alternative replaces the recording's places only where it explains
    /// the press by [`FRICTION_GAIN`] better (on another link, by
    /// [`LINK_SWITCH_GAIN`] unless [`LINK_SWITCH_SHARE`] agree). The
    /// smoother's model has no friction: where a press drags, it may
    /// settle on a place (or a link) that the frames alone, placed with
    /// friction in mind by the fit, contradict.
    fn fit_press_of(
        &self,
        robot: &Robot,
        frames: &[SequenceFrame],
        slide_m_per_sqrt_s: f64,
        press: &mut [(usize, Update, f64)],
        alone: &[Option<Summary>],
    ) -> Option<()> {
        let link = press.first()?.1.summary.map.link;
        let models: Vec<TorqueModel> = press
            .iter()
            .map(|(_, update, _)| TorqueModel::new(robot, &update.pose, &self.links))
            .collect();
        let weights = self.settings.weights();
        let settings = self.press_settings(&weights, slide_m_per_sqrt_s);
        let recording: Vec<Option<&ContactEstimate>> = press.iter().map(|(_, u, _)| Some(&u.summary.map)).collect();
        let here = self.explain_on(link, press, &recording, frames, &models, &settings)?;
        let (mut best_link, mut best) = (link, here);
        let mut alternative = false;
        // The frames' own places, in groups (one link, within
        // `ALTERNATIVE_GROUP_M` of the group's first place in the link's
        // frame): a group is one coherent place for the whole press.
        let own: Vec<Option<&ContactEstimate>> = (0..press.len())
            .map(|k| alone.get(k)?.as_ref().filter(|s| s.refined).map(|s| &s.map))
            .collect();
        let mut groups: Vec<Group> = Vec::new();
        for (k, ((_, update, _), map)) in press.iter().zip(&own).enumerate() {
            let Some(map) = map else { continue };
            let Some(point) = update
                .pose
                .world_from_link
                .get(map.link)
                .map(|world_from_link| world_from_link.inverse().transform_point3(map.point_world))
            else {
                continue;
            };
            let apart = map.link != update.summary.map.link
                || map.point_world.distance(update.summary.map.point_world) > ALTERNATIVE_MIN_M;
            match groups
                .iter_mut()
                .find(|g| g.link == map.link && g.center_in_link.distance(point) <= ALTERNATIVE_GROUP_M)
            {
                Some(g) => {
                    g.members.push(k);
                    g.apart += usize::from(apart);
                }
                None => groups.push(Group {
                    link: map.link,
                    center_in_link: point,
                    members: vec![k],
                    apart: usize::from(apart),
                }),
            }
        }
        groups.sort_by(|a, b| b.members.len().cmp(&a.members.len()).then(a.members.cmp(&b.members)));
        // A group on another link places every member elsewhere: its size says how many agree.
        let many = press.len().div_ceil(LINK_SWITCH_SHARE).max(ALTERNATIVE_MIN_FRAMES);
        for group in groups
            .iter()
            .filter(|g| g.members.len() >= ALTERNATIVE_MIN_FRAMES && g.apart >= ALTERNATIVE_MIN_FRAMES)
            .take(MAX_ALTERNATIVES)
        {
            let mut starts: Vec<Option<&ContactEstimate>> = vec![None; press.len()];
            for &k in &group.members {
                if let (Some(start), Some(map)) = (starts.get_mut(k), own.get(k)) {
                    *start = *map;
                }
            }
            let gain = if group.link == link || group.members.len() >= many {
                FRICTION_GAIN
            } else {
                LINK_SWITCH_GAIN
            };
            if let Some(answer) = self.explain_on(group.link, press, &starts, frames, &models, &settings)
                && answer.1.cost < best.1.cost - gain
            {
                (best_link, best) = (group.link, answer);
                alternative = true;
            }
        }
        let (link, (fallback, answer)) = (best_link, best);
        // The recording's own places, frictionless: nothing to move.
        let moved = answer.friction || alternative;
        for ((((_, update, _), contact), model), &fallback_sample) in
            press.iter_mut().zip(&answer.contacts).zip(&models).zip(&fallback)
        {
            if !moved {
                if let Some(spread) = &contact.spread {
                    self.widen_credible(update, link, spread);
                }
                continue;
            }
            let placed = PlacedContact {
                link,
                point_in_link: contact.point_in_link,
                inward_normal_in_link: contact.inward_normal_in_link,
                force_newtons: contact.force_newtons,
                tangential_in_link: contact.tangential_in_link,
                fallback_sample,
                residual_chi2: contact.residual_chi2,
            };
            self.place(update, &placed, model);
            if let Some(spread) = &contact.spread {
                self.widen_credible(update, link, spread);
            }
        }
        Some(())
    }

    /// `update`'s reported contact on its link's continuous surface: the
    /// link, its shape and the place there (walked to from the contact's
    /// sample). `None` where the link has no shape here.
    fn located_contact(&self, update: &Update) -> Option<(LinkId, &LinkShape, MeshPoint)> {
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
    fn widen_credible(&self, update: &mut Update, link: LinkId, spread: &PlaceSpread) {
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

    /// The press's frames fitted on `link` (see [`explain_press`]), each
    /// started at its place in `starts` when that is on `link`, else at
    /// the place of the nearest frame's that is (a place persists in its
    /// link's frame); with each frame's sample to fall back on. `None`
    /// where no start is on `link`.
    fn explain_on(
        &self,
        link: LinkId,
        press: &[(usize, Update, f64)],
        starts: &[Option<&ContactEstimate>],
        frames: &[SequenceFrame],
        models: &[TorqueModel],
        settings: &PressSettings,
    ) -> Option<(Vec<usize>, PressAnswer)> {
        let shape = self.surface.shape(link)?;
        let have: Vec<usize> = (0..press.len())
            .filter(|&k| starts.get(k).copied().flatten().is_some_and(|m| m.link == link))
            .collect();
        let mut press_frames = Vec::with_capacity(press.len());
        let mut fallback = Vec::with_capacity(press.len());
        for (k, ((i, _, _), torque_model)) in press.iter().zip(models).enumerate() {
            // The nearest frame with a start (`have` is sorted).
            let after = have.partition_point(|&j| j < k);
            let nearest = match (after.checked_sub(1).and_then(|b| have.get(b)), have.get(after)) {
                (Some(&before), Some(&next)) => {
                    if k - before <= next - k {
                        before
                    } else {
                        next
                    }
                }
                (Some(&j), None) | (None, Some(&j)) => j,
                (None, None) => return None,
            };
            let map = starts.get(nearest).copied().flatten()?;
            let (_, update, _) = press.get(nearest)?;
            let point_in_link = update
                .pose
                .world_from_link
                .get(link)?
                .inverse()
                .transform_point3(map.point_world);
            let sample = *self.surface.location.get(map.point)?;
            let frame = frames.get(*i)?;
            press_frames.push(PressFrame {
                t_secs: frame.t_secs,
                torque_model,
                tau: frame.tau,
                start: locate(shape, sample, point_in_link),
            });
            fallback.push(map.point);
        }
        let answer = explain_press(shape, link, &press_frames, settings)?;
        Some((fallback, answer))
    }

    /// Reports `placed` as `update`'s contact (see
    /// [`Summary::place_contact`]), `model` being the frame's torques.
    fn place(&self, update: &mut Update, placed: &PlacedContact, model: &TorqueModel) {
        update.summary.place_contact(
            placed,
            model.twists(placed.link).len(),
            (&update.posterior, &self.surface, &update.pose),
            model.sensed_count(),
        );
    }

    /// Filtering with friction: a frame's force at the recording's place
    /// is the friction model's only once the press so far says so, its
    /// frames' evidence for friction there (the drop in `-2 ln L` from a
    /// frictionless push) adding up to more than
    /// [`crate::core::press::FRICTION_GAIN`]; before, the frictionless
    /// force. What the filter can know of a press (its frames up to now)
    /// decides, as the whole press decides when smoothing.
    ///
    /// `i` numbers the frames in order, `tau` is this frame's torques and
    /// `gate` what the frames before left (start from its default).
    pub fn gate_friction(
        &self,
        robot: &Robot,
        update: &mut Update,
        (i, t_secs, tau): (usize, f64, &[f64]),
        slide_m_per_sqrt_s: f64,
        gate: &mut FrictionGate,
    ) {
        if !self.fits_presses() || !is_pressed(update) {
            *gate = FrictionGate::default();
            return;
        }
        let link = update.summary.map.link;
        if gate.last != Some((i.wrapping_sub(1), link)) {
            gate.gain = 0.0;
            gate.window.clear();
        }
        gate.last = Some((i, link));
        let Some(from_world) = update.pose.world_from_link.get(link).map(glam::DAffine3::inverse) else {
            return;
        };
        let model = TorqueModel::new(robot, &update.pose, &self.links);
        self.widen_by_press_so_far(update, (t_secs, tau), &model, slide_m_per_sqrt_s, gate);
        let map = &update.summary.map;
        let place = (
            from_world.transform_point3(map.point_world),
            from_world.transform_vector3(map.inward_normal_world),
        );
        let weights = self.settings.weights();
        let measurement = Measurement {
            tau,
            weights: &weights,
            force_range_newtons: (self.settings.force_min_newtons, self.settings.force_max_newtons),
            friction: self.settings.friction,
        };
        let Some((frictionless, gain)) = friction_evidence(&model, link, place, &measurement, self.settings.friction)
        else {
            return;
        };
        gate.gain += gain;
        if gate.gain > FRICTION_GAIN {
            return;
        }
        let placed = PlacedContact {
            link,
            point_in_link: place.0,
            inward_normal_in_link: place.1.normalize_or_zero(),
            force_newtons: frictionless.normal_newtons,
            tangential_in_link: DVec3::ZERO,
            fallback_sample: map.point,
            residual_chi2: frictionless.residual_chi2,
        };
        self.place(update, &placed, &model);
    }

    /// Filtering with friction: `update`'s credible set widened as a
    /// smoothed press's is ([`Estimator::widen_credible`]), by the spread
    /// that the press's latest frames (at most [`PRESS_WINDOW`], this one
    /// last, at the places the filter chose) leave this frame's place.
    /// The frame joins `gate`'s window.
    fn widen_by_press_so_far(
        &self,
        update: &mut Update,
        (t_secs, tau): (f64, &[f64]),
        model: &TorqueModel,
        slide_m_per_sqrt_s: f64,
        gate: &mut FrictionGate,
    ) {
        let Some((link, shape, at)) = self.located_contact(update) else {
            return;
        };
        if gate.window.len() >= PRESS_WINDOW {
            gate.window.pop_front();
        }
        gate.window.push_back(WindowFrame {
            t_secs,
            torque_model: model.clone(),
            tau: tau.to_vec(),
            at,
        });
        let weights = self.settings.weights();
        let settings = self.press_settings(&weights, slide_m_per_sqrt_s);
        let frames: Vec<PressFrame> = gate
            .window
            .iter()
            .map(|w| PressFrame {
                t_secs: w.t_secs,
                torque_model: &w.torque_model,
                tau: &w.tau,
                start: w.at,
            })
            .collect();
        if let Some(spread) = press_spreads(shape, link, &frames, &settings).and_then(|s| s.last().copied()) {
            self.widen_credible(update, link, &spread);
        }
        // The window holds γ fixed around places that the frictionless
        // filter chose, which a drag shifts, and a drag that grows within
        // the window (the `../shared` link 4 press: 1 to 17 % of the push)
        // is not one γ: the frame's own spread, γ free, is added.
        if let Some(spread) = frames.last().and_then(|&last| self.spread_alone(shape, link, last)) {
            self.widen_credible(update, link, &spread);
        }
    }

    /// How presses are fitted under these settings: the noise `weights`
    /// (`1/σ²`, [`EstimatorSettings::weights`]) and a fraction
    /// ([`PRESS_SLIDE_FRACTION`]) of the temporal model's slide length.
    fn press_settings<'w>(&self, weights: &'w [f64], slide_m_per_sqrt_s: f64) -> PressSettings<'w> {
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

    /// `update` (of the torques `tau`) seen through a temporal model's
    /// `belief` at its frame: the posterior over samples becomes the
    /// belief's (given a contact), the verdict follows its contact
    /// probability, and the contact is refined at this frame's torques.
    /// The frame's own likelihoods and magnitudes are kept.
    #[must_use]
    pub fn with_belief(&self, robot: &Robot, update: PendingUpdate, tau: &[f64], belief: &Belief) -> Update {
        self.with_belief_as(robot, update, tau, belief, true)
    }

    /// [`Estimator::with_belief`]; with `friction_at_place` false the
    /// force at the believed place is the frictionless one (a smoothed
    /// press brings friction in as a whole, [`Estimator::settle_press`]).
    fn with_belief_as(
        &self,
        robot: &Robot,
        update: PendingUpdate,
        tau: &[f64],
        belief: &Belief,
        friction_at_place: bool,
    ) -> Update {
        let torque_model = TorqueModel::new(robot, &update.pose, &self.links);
        let probability = belief
            .where_given_contact()
            .filter(|p| p.len() == update.posterior.probability.len());
        let Some(probability) = probability else {
            let (summary, _) = self.conclude_alone(&torque_model, &update.pose, &update.posterior, tau);
            return Update {
                pose: update.pose,
                posterior: update.posterior,
                summary,
                stages: None,
            };
        };
        let contact_probability = belief.contact_probability();
        let probability_len = probability.len();
        let mut posterior = update.posterior;
        let top = lanes::max_or(&probability, 0.0);
        posterior.support = lanes::positions_where(&probability, |p| p > 0.0 && p >= 1e-26 * top);
        // The most probable sample (the first of equals); where nothing is
        // positive, the frame's own.
        if top > 0.0
            && let Some(k) = probability.iter().position(|p| p.total_cmp(&top).is_eq())
        {
            posterior.map_point = k;
        }
        posterior.display.clone_from(&probability);
        posterior.probability = probability;
        // With offsets the place is the whole recording's: each frame's
        // own refinement would wander along that frame's valley.
        let offsets = (belief.offsets.len() == probability_len && self.surface.window_m.len() == probability_len)
            .then_some((belief.offsets.as_slice(), self.surface.window_m.as_slice()));
        let (summary, _) = self.conclude(
            &torque_model,
            &update.pose,
            &posterior,
            tau,
            contact_probability >= 0.5,
            Some(BeliefAtFrame {
                contact_probability,
                offsets,
                friction_at_place,
            }),
        );
        Update {
            pose: update.pose,
            posterior,
            summary,
            stages: None,
        }
    }
}

/// `update`, or the error that names its first number that is not
/// finite: an estimate is reported finite or not at all.
fn finite(update: Update) -> Result<Update, EstimateError> {
    match update.summary.non_finite_field() {
        None => Ok(update),
        Some(field) => Err(EstimateError::NonFiniteEstimate { field }),
    }
}

/// Milliseconds since `since`.
fn elapsed_ms(since: Instant) -> f64 {
    since.elapsed().as_secs_f64() * 1e3
}

/// What a temporal model believes at a frame, as a summary needs it.
#[derive(Debug, Clone, Copy)]
struct BeliefAtFrame<'a> {
    /// Probability of a contact.
    contact_probability: f64,
    /// Each sample's believed offset within its patch (the samples are
    /// points when `None`), with the samples' patch widths, m.
    offsets: Option<(&'a [Offset], &'a [f64])>,
    /// Whether the force at the believed place follows the friction
    /// setting (else it is frictionless).
    friction_at_place: bool,
}

/// How a sequence of frames is estimated.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Temporal {
    /// Each frame alone.
    #[default]
    None,
    /// Each frame with the ones before (causal, as live).
    Filter,
    /// Each frame with the whole sequence.
    Smooth,
}

/// The friction μ that frames combined over time are estimated with when
/// the user has not said (`estimate --friction auto`, `bench`, the app's
/// *auto* friction). Over time friction enters only where a press, or the
/// press so far, explains its torques far better with it than without
/// ([`crate::core::press`], [`Estimator::gate_friction`]), so frictionless
/// presses keep their estimate; on synthetic presses dragging by up to
/// 15 % and 30 % of the push, smoothing at μ = 0.2 places them better
/// than at 0.1 (30 %, `synth` seed 1: 10.8 → 4.2 mm at the median) and
/// 0.3 lost a `../shared` press at one surface seed (README, *Friction*).
pub const OVER_TIME_FRICTION: f64 = 0.2;

impl Temporal {
    /// μ when the user has not said: [`OVER_TIME_FRICTION`] over time,
    /// 0 for frames alone (a frame alone cannot pin the two extra unknowns
    /// of a tangential force, and its place suffers: frictionless
    /// synthetic presses 3.7 → 7.7 mm at μ = 0.2).
    #[must_use]
    pub const fn default_friction(self) -> f64 {
        match self {
            Self::None => 0.0,
            Self::Filter | Self::Smooth => OVER_TIME_FRICTION,
        }
    }
}

/// How a session is best estimated over time when the user has not said
/// (`estimate --temporal auto`, the app): a recording (frames closer than
/// a contact lasts, see [`is_continuous_recording`]) smoothed, or filtered
/// when the smoother would hold more than [`MAX_SMOOTHER_BYTES`]; a set of
/// unrelated frames each alone. With why, in words.
#[must_use]
pub fn automatic_temporal(
    times_secs: &[f64],
    settings: &TemporalSettings,
    points: usize,
    offsets: bool,
) -> (Temporal, &'static str) {
    if !is_continuous_recording(times_secs, settings) {
        (Temporal::None, "frames further apart than a contact lasts: each alone")
    } else if smoother_bytes(times_secs.len(), points, offsets) > MAX_SMOOTHER_BYTES {
        (Temporal::Filter, "a recording too long to smooth in memory: filtered")
    } else {
        (Temporal::Smooth, "a recording: smoothed")
    }
}

/// One frame of a sequence.
#[derive(Debug, Clone, Copy)]
pub struct SequenceFrame<'a> {
    /// Time, s.
    pub t_secs: f64,
    /// Every joint's position (see [`Robot::joint_positions`]).
    pub joint_positions: &'a [f64],
    /// Measured torques, sensed order, N·m.
    pub tau: &'a [f64],
}

/// Why a sequence could not be estimated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SequenceError {
    /// A frame's estimate failed.
    #[error("frame {frame}: {source}")]
    Frame {
        /// Frame number in the sequence (0-based).
        frame: usize,
        /// Why.
        source: EstimateError,
    },
    /// The temporal model refused a frame.
    #[error(transparent)]
    Temporal(#[from] TemporalError),
}

/// A stream filtered as it arrives ([`Temporal::Filter`]: each frame
/// with the frames before it) by a caller that keeps the temporal model
/// beside it, e.g. a live source: what is carried from frame to frame (the
/// belief, and what the press so far says for friction).
#[derive(Debug, Clone, Default)]
pub struct StreamFilter {
    state: FilterState,
    gate: FrictionGate,
}

impl StreamFilter {
    /// Frame `number` of the stream, at `t_secs`, given the frames before
    /// it: the frame's own likelihoods through `model`'s filter, the
    /// contact at the believed place, friction where the press so far
    /// asks for it. The frames after it see it only if this succeeds.
    ///
    /// # Errors
    /// [`SequenceError::Frame`] when the frame's own estimate fails (the
    /// stream can go on without it), [`SequenceError::Temporal`] when the
    /// model refuses it (e.g. a time before the last frame's).
    pub fn update(
        &mut self,
        estimator: &Estimator,
        model: &TemporalModel,
        robot: &Robot,
        (number, t_secs): (usize, f64),
        joint_positions: &[f64],
        tau: &[f64],
    ) -> Result<Update, SequenceError> {
        let (pending, likelihood) = estimator
            .update_for_sequence(robot, joint_positions, tau)
            .map_err(|source| SequenceError::Frame { frame: number, source })?;
        let belief = self.state.step(model, t_secs, &likelihood)?;
        let mut update = estimator.with_belief(robot, pending, tau, belief);
        let slide = model.settings().slide_m_per_sqrt_s;
        estimator.gate_friction(robot, &mut update, (number, t_secs, tau), slide, &mut self.gate);
        finite(update).map_err(|source| SequenceError::Frame { frame: number, source })
    }
}

/// Estimates `frames` in order, each alone or through `model`, and hands
/// each frame's update, in order, with the milliseconds it cost, to
/// `each`. Smoothing runs the per-frame estimate twice (once for the
/// likelihoods, once for the summaries, so that nothing per frame is held
/// but the smoother's store); its cost per frame is both passes and its
/// share of the backward pass.
///
/// # Errors
/// [`SequenceError`] for the first frame that fails.
pub fn estimate_sequence(
    estimator: &Estimator,
    robot: &Robot,
    model: Option<&TemporalModel>,
    temporal: Temporal,
    frames: &[SequenceFrame],
    each: impl FnMut(usize, Update, f64),
) -> Result<(), SequenceError> {
    estimate_sequence_while(estimator, robot, (model, temporal), frames, || true, each, |_, _| false).map(|_| ())
}

/// [`estimate_sequence`], asking `keep_going` before each frame's work
/// (both passes when smoothing), and handing each frame whose estimate
/// fails to `failed`: if it returns true the frame is left out (no
/// update for it; the temporal model goes on from the frames around it),
/// else the sequence stops with the error. `Ok(false)` when `keep_going`
/// said no (a newer request in an app), `Ok(true)` when done.
///
/// # Errors
/// [`SequenceError`] for a frame `failed` does not skip, or one the
/// temporal model refuses.
pub fn estimate_sequence_while(
    estimator: &Estimator,
    robot: &Robot,
    (model, temporal): (Option<&TemporalModel>, Temporal),
    frames: &[SequenceFrame],
    mut keep_going: impl FnMut() -> bool,
    mut each: impl FnMut(usize, Update, f64),
    mut failed: impl FnMut(usize, &EstimateError) -> bool,
) -> Result<bool, SequenceError> {
    // `Ok(None)`: failed and skipped.
    fn checked<T>(
        i: usize,
        result: Result<T, EstimateError>,
        failed: &mut impl FnMut(usize, &EstimateError) -> bool,
    ) -> Result<Option<T>, SequenceError> {
        match result {
            Ok(value) => Ok(Some(value)),
            Err(source) if failed(i, &source) => Ok(None),
            Err(source) => Err(SequenceError::Frame { frame: i, source }),
        }
    }
    let ms = elapsed_ms;
    match (model, temporal) {
        (None, _) | (_, Temporal::None) => {
            for (i, f) in frames.iter().enumerate() {
                if !keep_going() {
                    return Ok(false);
                }
                let t0 = Instant::now();
                if let Some(update) = checked(i, estimator.update(robot, f.joint_positions, f.tau), &mut failed)? {
                    each(i, update, ms(t0));
                }
            }
        }
        (Some(model), Temporal::Filter) => {
            let mut stream = StreamFilter::default();
            for (i, f) in frames.iter().enumerate() {
                if !keep_going() {
                    return Ok(false);
                }
                let t0 = Instant::now();
                match stream.update(estimator, model, robot, (i, f.t_secs), f.joint_positions, f.tau) {
                    Ok(update) => each(i, update, ms(t0)),
                    Err(SequenceError::Frame { frame, source }) if failed(frame, &source) => {}
                    Err(e) => return Err(e),
                }
            }
        }
        (Some(model), Temporal::Smooth) => {
            // A smoothed frame whose estimate is not finite is left out
            // and handed to `failed` once the presses are settled; the
            // first it does not skip is the sequence's error.
            let mut refused: Vec<(usize, EstimateError)> = Vec::new();
            let mut each = |i: usize, update: Update, ms: f64| match finite(update) {
                Ok(update) => each(i, update, ms),
                Err(source) => refused.push((i, source)),
            };
            let mut smoother = Smoother::new(model);
            // The frames pushed, and what each cost.
            let mut pushed: Vec<(usize, f64)> = Vec::with_capacity(frames.len());
            for (i, f) in frames.iter().enumerate() {
                if !keep_going() {
                    return Ok(false);
                }
                let t0 = Instant::now();
                let Some((_, likelihood)) = checked(
                    i,
                    estimator.update_for_sequence(robot, f.joint_positions, f.tau),
                    &mut failed,
                )?
                else {
                    continue;
                };
                smoother.push(f.t_secs, &likelihood)?;
                pushed.push((i, ms(t0)));
            }
            let t0 = Instant::now();
            let beliefs = smoother.finish();
            let backward_ms = ms(t0) / pushed.len().max(1) as f64;
            let mut presses = PressQueue {
                estimator,
                robot,
                frames,
                slide_m_per_sqrt_s: model.settings().slide_m_per_sqrt_s,
                held: Vec::new(),
                alone: Vec::new(),
            };
            for (&(i, first_ms), belief) in pushed.iter().zip(&beliefs) {
                if !keep_going() {
                    return Ok(false);
                }
                let Some(f) = frames.get(i) else {
                    continue;
                };
                let t0 = Instant::now();
                // It succeeded in the first pass; the same inputs again.
                let Some(update) = checked(
                    i,
                    estimator.pending_update(robot, f.joint_positions, f.tau),
                    &mut failed,
                )?
                else {
                    continue;
                };
                let alone = estimator.summary_alone(robot, &update, f.tau, belief);
                let update = estimator.with_belief_as(robot, update, f.tau, belief, !estimator.fits_presses());
                presses.offer(i, (update, alone), ms(t0) + backward_ms + first_ms, &mut each);
            }
            presses.settle(&mut each);
            if let Some((frame, source)) = refused.into_iter().find(|(i, e)| !failed(*i, e)) {
                return Err(SequenceError::Frame { frame, source });
            }
        }
    }
    Ok(true)
}

/// What filtering with friction knows of the press so far
/// ([`Estimator::gate_friction`]).
#[derive(Debug, Clone, Default)]
pub struct FrictionGate {
    /// The last frame and its link, while a press goes on.
    last: Option<(usize, LinkId)>,
    /// Its frames' evidence for friction, summed.
    gain: f64,
    /// Its latest frames, oldest first: what the place's spread is
    /// measured over.
    window: std::collections::VecDeque<WindowFrame>,
}

/// A frame of a filtered press, as [`PressFrame`] needs it.
#[derive(Debug, Clone)]
struct WindowFrame {
    t_secs: f64,
    torque_model: TorqueModel,
    tau: Vec<f64>,
    /// The filter's place.
    at: MeshPoint,
}

/// Frames of a filtered press whose places measure the spread of the
/// latest's ([`FrictionGate`]): the press so far, up to about the shortest
/// press the temporal model expects (0.1 s at 200 Hz, 0.4 s at 50 Hz),
/// so that a frame costs a bounded amount.
pub const PRESS_WINDOW: usize = 20;

/// While smoothing with contacts placed on the continuous surface, a
/// press's frames wait for its end: the press is fitted as a whole (with
/// friction) and checked against its frames' own contacts (see
/// [`Estimator::settle_press`]).
struct PressQueue<'a> {
    estimator: &'a Estimator,
    robot: &'a Robot,
    frames: &'a [SequenceFrame<'a>],
    /// The temporal model's slide length, m/√s.
    slide_m_per_sqrt_s: f64,
    /// The press so far: frame number, update, milliseconds it cost.
    held: Vec<(usize, Update, f64)>,
    /// Each held frame's summary from its own posterior alone.
    alone: Vec<Option<Summary>>,
}

impl PressQueue<'_> {
    /// Frame `i`'s `update`: handed on to `each` at once, or held while it
    /// continues a press (one link, consecutive frames).
    fn offer(
        &mut self,
        i: usize,
        (update, alone): (Update, Option<Summary>),
        cost_ms: f64,
        each: &mut impl FnMut(usize, Update, f64),
    ) {
        if !self.estimator.uses_patches() {
            each(i, update, cost_ms);
            return;
        }
        let in_press = is_pressed(&update);
        let continues = in_press
            && self.held.len() < MAX_PRESS_FRAMES
            && self
                .held
                .last()
                .is_some_and(|(j, last, _)| *j + 1 == i && last.summary.map.link == update.summary.map.link);
        if !continues {
            self.settle(each);
        }
        if in_press {
            self.held.push((i, update, cost_ms));
            self.alone.push(alone);
        } else {
            each(i, update, cost_ms);
        }
    }

    /// Fits the press held and hands its frames on.
    fn settle(&mut self, each: &mut impl FnMut(usize, Update, f64)) {
        self.estimator.settle_press(
            self.robot,
            self.frames,
            self.slide_m_per_sqrt_s,
            &mut self.held,
            &mut self.alone,
            each,
        );
    }
}

/// Frames of a press whose own contacts lie on one link within
/// [`ALTERNATIVE_GROUP_M`] of the first's (link frame).
struct Group {
    link: LinkId,
    center_in_link: DVec3,
    /// The frames, by number within the press.
    members: Vec<usize>,
    /// How many of them place the contact elsewhere than the recording.
    apart: usize,
}

/// The radius of a [`Group`], m.
pub const ALTERNATIVE_GROUP_M: f64 = 0.03;

/// A frame alone places its press's contact elsewhere when on another
/// link or farther than this from the recording's place, m (a few patch
/// widths: closer, both fits start in the same valley).
pub const ALTERNATIVE_MIN_M: f64 = 0.02;

/// A press is fitted from its frames' own places too when at least this
/// many of its frames place the contact elsewhere in one group. No share
/// of the press is asked for: an alternative is kept only where it
/// explains the whole press by [`FRICTION_GAIN`] better, and where the
/// smoother settled on a poor place its frames alone scatter (on a
/// synthetic link 4 press of 46 frames, the largest group near the truth
/// held 10 and the recording's place cost 3023 against 264 there).
pub const ALTERNATIVE_MIN_FRAMES: usize = 3;

/// The drop in the press's cost (`-2 ln L`, see [`crate::core::press`])
/// an alternative on another link than the recording's must bring to be
/// kept: moving a press to another link moves its answer by a link, and
/// with friction a rival link can explain a press's frames better by tens
/// (on synthetic sessions that drag by up to 30 %, link 7 presses moved to
/// link 6 for gains of 36 and 60 and landed 117 mm from the truth, while
/// the presses rightly moved gained 134 and 245), unless at least one in
/// [`LINK_SWITCH_SHARE`] of the press's frames place it there.
pub const LINK_SWITCH_GAIN: f64 = 100.0;

/// An alternative on another link that at least one in this many of the
/// press's frames alone agree on needs only [`FRICTION_GAIN`] (on
/// `synth --seconds 20 --rate 50 --friction 0.15 --seed 1`, surface seeds
/// 0 and 2, such a switch places a press 1.3 mm from the truth that
/// [`LINK_SWITCH_GAIN`] would have left 138 mm off).
pub const LINK_SWITCH_SHARE: usize = 4;

/// Groups a press is fitted from besides the recording's places, at most
/// (the largest; four changed nothing on the synthetic sessions).
pub const MAX_ALTERNATIVES: usize = 2;

/// Longest run of frames fitted as one press (2 s at 200 Hz): a longer
/// contact is fitted in pieces, so that what waits for a press's end
/// stays bounded (each frame's posterior is held until then).
pub const MAX_PRESS_FRAMES: usize = 400;

/// The press fit (see [`crate::core::press`]) slides the place by this
/// fraction of the temporal model's slide length. The smoother reports
/// one place per press (its heaviest sample moved by the offset every
/// frame believes), whereas a trajectory free to slide at the full
/// length follows each frame's noise: on synthetic sessions without
/// friction (`synth --seed 3`) a fit at the full length moved the median
/// error from 1.4 to 7 mm on a press of link 6, and on the link 4
/// `MuJoCo` presses it took a second press for friction at 27 mm instead of
/// 10 mm.
pub const PRESS_SLIDE_FRACTION: f64 = 0.3;

/// Where a smoothed press's contacts explain its frames far worse than
/// each frame's own contact does ([`PRESS_MISFIT_PER_FRAME`]), each frame
/// takes its own contact (the recording's contact probability, shares
/// and credible set stay). Empties `alone`.
fn check_press(press: &mut [(usize, Update, f64)], alone: &mut Vec<Option<Summary>>) {
    let together: f64 = press.iter().map(|(_, u, _)| u.summary.fit.best_residual_chi2).sum();
    // Every frame must have its own refined contact to compare with.
    let apart: Option<f64> = alone
        .iter()
        .map(|s| s.as_ref().filter(|s| s.refined).map(|s| s.fit.best_residual_chi2))
        .sum();
    let frames = press.len() as f64;
    if alone.len() == press.len()
        && apart.is_some_and(|apart| together - apart > PRESS_MISFIT_PER_FRAME * frames + PRESS_MISFIT_MARGIN)
    {
        for ((_, update, _), own) in press.iter_mut().zip(alone.iter()) {
            if let Some(own) = own {
                update.summary.take_contact_of(own);
            }
        }
    }
    alone.clear();
}

/// A smoothed press whose contacts' residuals (χ², summed over its
/// frames) exceed those of each frame's own contact by more than this per
/// frame, plus [`PRESS_MISFIT_MARGIN`], reports each frame's own contact.
/// A frame's own place is free to fit its noise, two unknowns more than
/// the recording's, so the sum's excess is about 2 a frame where the
/// recording is right (measured 1.2–4.3 on presses without friction,
/// one press at 47). Where a press drags and the smoother, whose model
/// has no friction, settles on a place the frames contradict, the excess
/// is hundreds to thousands a frame (synthetic `--slide 0.03 --friction
/// 0.15 --seed 1`: a link 7 press at 8988, its force 25 N off), and each
/// frame alone is the better report. 300 (17σ a frame) leaves every
/// frictionless press measured alone.
pub const PRESS_MISFIT_PER_FRAME: f64 = 300.0;

/// See [`PRESS_MISFIT_PER_FRAME`]: a short press must still miss by this
/// much in all.
pub const PRESS_MISFIT_MARGIN: f64 = 30.0;

/// The 90 % point of χ² with two degrees of freedom: a 2-D Gaussian's
/// 90 % region is where the squared Mahalanobis distance is below it
/// (`-2 ln 0.1`).
pub const CHI2_2_AT_90: f64 = 4.605_170_185_988_091;

/// Whether a frame's contact can join a press: a contact placed on the
/// continuous surface.
fn is_pressed(update: &Update) -> bool {
    update.summary.refined && update.summary.verdict != Verdict::NoContact
}
