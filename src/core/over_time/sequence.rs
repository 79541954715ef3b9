//! A session's frames in order: each alone, filtered (with the frames
//! before) or smoothed (with the whole recording), through the temporal
//! model's belief; and a stream filtered as it arrives.

use crate::core::estimate::contact::PatchForms;
use crate::core::estimate::estimator::{BeliefAtFrame, Estimator, PendingUpdate, Update, finite};
use crate::core::estimate::posterior::Posterior;
use crate::core::estimate::settings::EstimateError;
use crate::core::estimate::summary::Summary;
use crate::core::numerics::lanes;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::over_time::offsets::{FrameLikelihood, PatchInformation};
use crate::core::over_time::parallel::{self, Callbacks};
use crate::core::over_time::pipeline;
use crate::core::over_time::presses::FrictionGate;
use crate::core::over_time::smoother::FilterState;
use crate::core::over_time::temporal::{Belief, TemporalModel, TemporalSettings, is_continuous_recording};
use crate::core::robot::model::Robot;
use crate::core::robot::torque::TorqueModel;

impl Estimator {
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

    /// [`Estimator::conclude_alone`] of a pending update where the
    /// recording (`belief`) calls its frame a contact and contacts are
    /// placed on the continuous surface: what its press is checked
    /// against ([`PRESS_MISFIT_PER_FRAME`]).
    pub(crate) fn summary_alone(
        &self,
        robot: &Robot,
        update: &PendingUpdate,
        tau: &[f64],
        belief: &Belief,
    ) -> Option<Summary> {
        (belief.contact_probability() >= 0.5 && self.uses_patches()).then(|| {
            let torque_model = TorqueModel::new(robot, &update.pose, &self.links);
            self.conclude_alone(&torque_model, &update.pose, &update.posterior, tau)
                .0
        })
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
    pub(crate) fn with_belief_as(
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
        // Confined to its patch (beyond it the linear model does not
        // hold): the mean there.
        let (offsets, windows_m) = (belief.offsets.as_slice(), self.surface.window_m.as_slice());
        let offset_m = |k: usize| {
            let (offset, &rho) = (offsets.get(k)?, windows_m.get(k)?);
            Some(offset.confined(rho).1.mean_m())
        };
        let with_offsets = offsets.len() == probability_len && windows_m.len() == probability_len;
        let (summary, _) = self.conclude(
            &torque_model,
            &update.pose,
            &posterior,
            tau,
            contact_probability >= 0.5,
            Some(BeliefAtFrame {
                contact_probability,
                offset_m: with_offsets.then_some(&offset_m as &dyn Fn(usize) -> Option<[f64; 2]>),
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
/// ([`crate::core::estimate::press`], [`Estimator::gate_friction`]), so frictionless
/// presses keep their estimate; on synthetic presses dragging by up to
/// 15 % and 30 % of the push, smoothing at μ = 0.2 places them better
/// than at 0.1 (30 %, `synth` seed 1: 10.8 → 4.2 mm at the median) and
/// 0.3 lost a `../shared` press at one surface seed (`docs/validation.md`, *Friction*).
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
/// a contact lasts, see [`is_continuous_recording`]) smoothed, whatever
/// its length (in stretches of bounded memory,
/// [`crate::core::over_time::stretches`]); a set of unrelated frames each
/// alone. With why, in words.
#[must_use]
pub fn automatic_temporal(times_secs: &[f64], settings: &TemporalSettings) -> (Temporal, &'static str) {
    if is_continuous_recording(times_secs, settings) {
        (Temporal::Smooth, "a recording: smoothed")
    } else {
        (Temporal::None, "frames further apart than a contact lasts: each alone")
    }
}

pub use crate::core::over_time::parallel::SequenceError;

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
    keep_going: impl FnMut() -> bool,
    each: impl FnMut(usize, Update, f64),
    failed: impl FnMut(usize, &EstimateError) -> bool,
) -> Result<bool, SequenceError> {
    let calls = Callbacks {
        keep_going,
        each,
        failed,
    };
    match (model, temporal) {
        (None, _) | (_, Temporal::None) => parallel::alone(estimator, robot, frames, calls),
        (Some(model), Temporal::Filter) => parallel::filter(estimator, robot, model, frames, calls),
        (Some(model), Temporal::Smooth) => smooth(estimator, robot, model, frames, calls),
    }
}

/// Smooths `frames` on the path that suits the pool: threads of its own
/// for the parts in order from [`pipeline::MIN_THREADS`] up, else the
/// calling thread doing a worker's share. A smoothed frame whose estimate
/// is not finite is left out and handed to `failed` once the presses are
/// settled (they may still move it); the first it does not skip is the
/// sequence's error.
fn smooth(
    estimator: &Estimator,
    robot: &Robot,
    model: &TemporalModel,
    frames: &[SequenceFrame],
    calls: Callbacks<impl FnMut() -> bool, impl FnMut(usize, Update, f64), impl FnMut(usize, &EstimateError) -> bool>,
) -> Result<bool, SequenceError> {
    let Callbacks {
        keep_going,
        mut each,
        mut failed,
    } = calls;
    let mut refused: Vec<(usize, EstimateError)> = Vec::new();
    let calls = Callbacks {
        keep_going,
        each: |i: usize, update: Update, ms: f64| match finite(update) {
            Ok(update) => each(i, update, ms),
            Err(source) => refused.push((i, source)),
        },
        failed: &mut failed,
    };
    let settled = if rayon::current_num_threads() >= pipeline::MIN_THREADS {
        pipeline::smooth(estimator, robot, model, frames, calls)?
    } else {
        parallel::smooth(estimator, robot, model, frames, calls)?
    };
    if !settled {
        return Ok(false);
    }
    if let Some((frame, source)) = refused.into_iter().find(|(i, e)| !failed(*i, e)) {
        return Err(SequenceError::Frame { frame, source });
    }
    Ok(true)
}
