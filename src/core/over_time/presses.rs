//! Presses over time: a smoothed press fitted as a whole (one tangential
//! force fixed on the link while the arm moves under it), checked
//! against its frames' own contacts, and a filtered press's friction
//! gated on the press so far.

use std::time::Instant;

use rayon::prelude::*;

use glam::DVec3;

use crate::core::estimate::estimator::{Estimator, Update, elapsed_ms, is_pressed};
use crate::core::estimate::explain::{PressAnswer, explain_press};
use crate::core::estimate::friction::friction_evidence;
use crate::core::estimate::measurement::Measurement;
use crate::core::estimate::press::{FRICTION_GAIN, PressFrame, PressSettings, locate, press_spreads};
use crate::core::estimate::summary::{ContactEstimate, PlacedContact, Summary};
use crate::core::geometry::shell::MeshPoint;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::over_time::starts::{Between, Start, in_link_frame, other_starts};
use crate::core::robot::model::{LinkId, Robot};
use crate::core::robot::torque::TorqueModel;

impl Estimator {
    /// Fits the frames of `press` (consecutive, one link, in order) as
    /// one press with a tangential force fixed in the link's frame (with
    /// a friction setting); where the friction model explains it far
    /// better than none, each frame's reported contact, fit test and
    /// verdict become the fit's. Then checks the press against its
    /// frames' own contacts (`alone`, one per frame; see
    /// [`PRESS_MISFIT_PER_FRAME`], and [`SLIDE_MISFIT_PER_FRAME`] where
    /// kinetic friction explains it), hands the frames to `each`, each with
    /// its share of the time, and empties `press` and `alone`. Returns the
    /// fit (`None` where the press keeps its estimates).
    pub(super) fn settle_press(
        &self,
        robot: &Robot,
        frames: &[SequenceFrame],
        slide_m_per_sqrt_s: f64,
        press: &mut Vec<(usize, Update, f64)>,
        alone: &mut Vec<Option<Summary>>,
        each: &mut impl FnMut(usize, Update, f64),
    ) -> Option<Fitted> {
        if press.is_empty() {
            alone.clear();
            return None;
        }
        let t0 = Instant::now();
        let fit = if self.fits_presses() {
            self.fit_press_of(robot, frames, slide_m_per_sqrt_s, press, alone)
        } else {
            None
        };
        let slides = fit.is_some_and(|(kinetic, _, _)| kinetic);
        let limit_per_frame = if slides {
            SLIDE_MISFIT_PER_FRAME
        } else {
            PRESS_MISFIT_PER_FRAME
        };
        check_press(press, alone, limit_per_frame);
        let share_ms = elapsed_ms(t0) / press.len() as f64;
        for (i, update, cost_ms) in press.drain(..) {
            each(i, update, cost_ms + share_ms);
        }
        fit.map(|(slides, cost, link)| Fitted { cost, link, slides })
    }

    /// [`Estimator::settle_press`]'s fit: whether kinetic friction along
    /// the slide explains the press, the fit's cost (`-2 ln` of its
    /// posterior) and its link; `None` (nothing changed) where the press keeps its
    /// estimates.
    ///
    /// The press is fitted from the recording's places and from the other
    /// starts of [`crate::core::over_time::starts`]: where a few of its
    /// frames alone (`alone`) place the contact elsewhere together, from
    /// theirs, and from its two rests; an alternative replaces the
    /// recording's places only where it explains the press by
    /// [`FRICTION_GAIN`] better (on another link, by more unless enough
    /// frames agree). The
    /// smoother's model has no friction: where a press drags, it may
    /// settle on a place (or a link) that the frames alone, placed with
    /// friction in mind by the fit, contradict. Where the fit kept so far
    /// has friction, each start is also followed at a faster slide and
    /// fitted again from there ([`FOLLOW_SLIDE_M_PER_SQRT_S`]), kept by
    /// the same rule.
    fn fit_press_of(
        &self,
        robot: &Robot,
        frames: &[SequenceFrame],
        slide_m_per_sqrt_s: f64,
        press: &mut [(usize, Update, f64)],
        alone: &[Option<Summary>],
    ) -> Option<(bool, f64, LinkId)> {
        let link = press.first()?.1.summary.map.link;
        let models: Vec<TorqueModel> = press
            .iter()
            .map(|(_, update, _)| TorqueModel::new(robot, &update.pose, &self.links))
            .collect();
        let weights = self.settings.weights();
        let settings = self.press_settings(&weights, slide_m_per_sqrt_s);
        let recording = Start {
            link,
            places: press.iter().map(|(_, u, _)| Some(&u.summary.map)).collect(),
            between: Between::Nearest,
            gain: FRICTION_GAIN,
        };
        let here = self.explain_on(&recording, press, frames, &models, &settings)?;
        let (mut best_link, mut best) = (link, here);
        let mut alternative = false;
        let own: Vec<Option<&ContactEstimate>> = (0..press.len())
            .map(|k| alone.get(k)?.as_ref().filter(|s| s.refined).map(|s| &s.map))
            .collect();
        let starts = other_starts(press, &own, link);
        // The starts' fits do not depend on one another: in parallel, then
        // judged in order.
        let answers: Vec<_> = starts
            .par_iter()
            .map(|start| self.explain_on(start, press, frames, &models, &settings))
            .collect();
        for (start, answer) in starts.iter().zip(answers) {
            if let Some(answer) = answer
                && answer.1.cost < best.1.cost - start.gain
            {
                (best_link, best) = (start.link, answer);
                alternative = true;
            }
        }
        // A press that drags is followed from each start at a faster
        // slide, then fitted again at the recording's; but from the rests,
        // whose line already crosses the slide: followed, it found cheaper
        // answers farther off (generated link 5 seed 2 slide, 2.4 → 5.9
        // mm) at a fifth more time.
        if best.1.friction && FOLLOW_SLIDE_M_PER_SQRT_S > slide_m_per_sqrt_s {
            let follow = self.press_settings(&weights, FOLLOW_SLIDE_M_PER_SQRT_S);
            let nearest = starts.into_iter().filter(|s| s.between == Between::Nearest);
            let starts = std::iter::once(recording).chain(nearest);
            let fit = (frames, models.as_slice(), &settings, &follow);
            if let Some(found) = self.followed(press, starts, fit, best.1.cost) {
                (best_link, best) = found;
                alternative = true;
            }
        }
        let (link, (fallback, answer)) = (best_link, best);
        // The recording's own places, frictionless: nothing to move, unless
        // the press check would hand every frame its own contact for them
        // and the fit explains the frames as a right recording does
        // (`FIT_AS_OWN_PER_FRAME`).
        let recording_misses = misses_alone(
            press.iter().map(|(_, u, _)| u.summary.fit.best_residual_chi2),
            alone,
            (PRESS_MISFIT_PER_FRAME, PRESS_MISFIT_MARGIN),
        );
        let moved = answer.friction
            || alternative
            || (recording_misses
                && !misses_alone(
                    answer.contacts.iter().map(|c| c.residual_chi2),
                    alone,
                    (FIT_AS_OWN_PER_FRAME, 0.0),
                ));
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
        Some((answer.kinetic_friction.is_some(), answer.cost, link))
    }

    /// The press's frames fitted on `start.link` (see [`explain_press`]),
    /// each started at its place in `start.places` when that is on the
    /// link, else as [`Between`] says (a place persists in its link's
    /// frame); with each frame's sample to fall back on. `None` where no
    /// start is on the link.
    fn explain_on(
        &self,
        start: &Start,
        press: &[(usize, Update, f64)],
        frames: &[SequenceFrame],
        models: &[TorqueModel],
        settings: &PressSettings,
    ) -> Option<(Vec<usize>, PressAnswer)> {
        let (link, starts) = (start.link, start.places.as_slice());
        let shape = self.surface.shape(link)?;
        let have: Vec<usize> = (0..press.len())
            .filter(|&k| starts.get(k).copied().flatten().is_some_and(|m| m.link == link))
            .collect();
        // A start's place in the link's frame, and its sample.
        let place = |j: usize| -> Option<(DVec3, usize)> {
            let map = starts.get(j).copied().flatten()?;
            let (_, update, _) = press.get(j)?;
            Some((in_link_frame(update, link, map.point_world)?, map.point))
        };
        let mut locations = Vec::with_capacity(press.len());
        let mut fallback = Vec::with_capacity(press.len());
        for k in 0..press.len() {
            // The frames with a start on either side (`have` is sorted).
            let after = have.partition_point(|&j| j < k);
            let before = after.checked_sub(1).and_then(|b| have.get(b)).copied();
            let next = have.get(after).copied();
            let (point_in_link, sample) = match (before, next) {
                (Some(b), Some(n)) if start.between == Between::Nearest => place(if k - b <= n - k { b } else { n })?,
                (Some(b), Some(n)) if n > b => {
                    let ((from, from_sample), (to, to_sample)) = (place(b)?, place(n)?);
                    let share = (k - b) as f64 / (n - b) as f64;
                    (from.lerp(to, share), if share <= 0.5 { from_sample } else { to_sample })
                }
                (Some(j), _) | (None, Some(j)) => place(j)?,
                (None, None) => return None,
            };
            let sample_location = *self.surface.location.get(sample)?;
            locations.push(locate(shape, sample_location, point_in_link));
            fallback.push(sample);
        }
        self.explain_from(link, press, (locations, fallback), frames, models, settings)
    }

    /// The press's frames fitted on `link`, each started at its place in
    /// `starts` (its location on the link's surface, and its sample to
    /// fall back on).
    fn explain_from(
        &self,
        link: LinkId,
        press: &[(usize, Update, f64)],
        (locations, fallback): (Vec<MeshPoint>, Vec<usize>),
        frames: &[SequenceFrame],
        models: &[TorqueModel],
        settings: &PressSettings,
    ) -> Option<(Vec<usize>, PressAnswer)> {
        let shape = self.surface.shape(link)?;
        let press_frames = press
            .iter()
            .zip(models)
            .zip(locations)
            .map(|(((i, _, _), torque_model), start)| {
                let frame = frames.get(*i)?;
                Some(PressFrame {
                    t_secs: frame.t_secs,
                    torque_model,
                    tau: frame.tau,
                    start,
                })
            })
            .collect::<Option<Vec<_>>>()?;
        let answer = explain_press(shape, link, &press_frames, settings)?;
        Some((fallback, answer))
    }

    /// The cheapest fit of `press` from `starts` (each with the drop in
    /// cost it must bring below `best_cost`) that the
    /// press settings `follow` fit first and `settings` again from there
    /// ([`FOLLOW_SLIDE_M_PER_SQRT_S`]); `None` where none brings its drop.
    fn followed<'s>(
        &self,
        press: &[(usize, Update, f64)],
        starts: impl Iterator<Item = Start<'s>>,
        (frames, models, settings, follow): (&[SequenceFrame], &[TorqueModel], &PressSettings, &PressSettings),
        best_cost: f64,
    ) -> Option<(LinkId, (Vec<usize>, PressAnswer))> {
        // The starts' fits do not depend on one another: in parallel, then
        // judged in order.
        let starts: Vec<_> = starts.collect();
        let fits: Vec<_> = starts
            .into_par_iter()
            .map(|start| {
                // Fitted again from where the followed fit left each frame.
                let answer = self
                    .explain_on(&start, press, frames, models, follow)
                    .and_then(|(fallback, followed)| {
                        let locations = followed.contacts.iter().map(|c| c.location).collect();
                        self.explain_from(start.link, press, (locations, fallback), frames, models, settings)
                    });
                (start.link, answer, start.gain)
            })
            .collect();
        let mut found: Option<(LinkId, (Vec<usize>, PressAnswer))> = None;
        for (link, answer, gain) in fits {
            let limit = found.as_ref().map_or(best_cost, |(_, (_, a))| a.cost) - gain;
            if let Some(answer) = answer
                && answer.1.cost < limit
            {
                found = Some((link, answer));
            }
        }
        found
    }

    /// Filtering with friction: a frame's force at the recording's place
    /// is the friction model's only once the press so far says so, its
    /// frames' evidence for friction there (the drop in `-2 ln L` from a
    /// frictionless push) adding up to more than
    /// [`crate::core::estimate::press::FRICTION_GAIN`]; before, the frictionless
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

/// A press's fit, where it changed the press's estimates.
#[derive(Debug, Clone, Copy)]
pub(super) struct Fitted {
    /// `-2 ln` of the fit's posterior.
    pub(super) cost: f64,
    /// The link it placed the press on.
    pub(super) link: LinkId,
    /// Whether kinetic friction along a slide explains it.
    pub(super) slides: bool,
}

/// A press that drags (its fit keeps friction) is also fitted from each
/// of its starts with a track free to slide this far (m/√s, times
/// [`crate::core::estimate::estimator::PRESS_SLIDE_FRACTION`]), then again
/// from there at the recording's slide length, and kept where that costs
/// less by the alternatives' rule. The fit at the recording's length
/// (1 cm/√s by default) cannot follow a slide of centimetres from a
/// start that holds one place (the smoother's) or a few frames' (a
/// group): it ends in the valley of the one place that explains the
/// whole slide least badly, centimetres from every true place (a
/// generated link 5 press, `-2 ln L` 7,011; followed, then fitted again,
/// 1,329 and 6 mm off). The faster track follows the slide, and the fit
/// at the recording's length, started on it, keeps it where the frames
/// ask for it. On short pieces of a press the same two steps leave a
/// poor valley (the `../shared` link 6 slide: a 25-frame piece 4,753 →
/// 212). Not a second smoothing at the faster walk: its places hop
/// between valleys from frame to frame, and a track through them costs
/// millions (`docs/decisions.md`, *Slides placed centimetres off*).
pub const FOLLOW_SLIDE_M_PER_SQRT_S: f64 = 0.1;

/// Where a smoothed press's contacts explain its frames far worse than
/// each frame's own contact does (by more than `limit_per_frame` a frame,
/// plus [`PRESS_MISFIT_MARGIN`]), each frame
/// takes its own contact (the recording's contact probability, shares
/// and credible set stay). Empties `alone`.
fn check_press(press: &mut [(usize, Update, f64)], alone: &mut Vec<Option<Summary>>, limit_per_frame: f64) {
    let residuals = press.iter().map(|(_, u, _)| u.summary.fit.best_residual_chi2);
    if misses_alone(residuals, alone, (limit_per_frame, PRESS_MISFIT_MARGIN)) {
        for ((_, update, _), own) in press.iter_mut().zip(alone.iter()) {
            if let Some(own) = own {
                update.summary.take_contact_of(own);
            }
        }
    }
    alone.clear();
}

/// Whether contacts leaving a press's frames the residuals `residuals`
/// (χ², one a frame) explain them worse than each frame's own contact
/// (`alone`) by more than `limit_per_frame` a frame plus `margin`; false
/// unless every frame has its own refined contact to compare with.
fn misses_alone(
    residuals: impl ExactSizeIterator<Item = f64>,
    alone: &[Option<Summary>],
    (limit_per_frame, margin): (f64, f64),
) -> bool {
    let frames = residuals.len();
    let together: f64 = residuals.sum();
    let apart: Option<f64> = alone
        .iter()
        .map(|s| s.as_ref().filter(|s| s.refined).map(|s| s.fit.best_residual_chi2))
        .sum();
    alone.len() == frames && apart.is_some_and(|apart| together - apart > limit_per_frame * frames as f64 + margin)
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

/// [`PRESS_MISFIT_PER_FRAME`] for a press that kinetic friction along its
/// slide explains. That model follows a slide and can absorb misfit a
/// fixed place cannot: on the `../shared` two-contact example, the link 7
/// press (which link 6 explains frame by frame) misses its frames by 302
/// a frame with it and 327 without, and where such a press is kept as a
/// slide on link 7 it is poorly explained throughout, which calls a
/// second contact in its frames (22 of the 170 one-probe frames, with
/// the slide's direction over 300 ms). The presses the model does
/// explain miss by at most 33 a frame on the shared slide and observer
/// examples (surface seeds 0–2) and 20 on generated slides, but for one
/// link 4 press at 199, now each frame's own.
pub const SLIDE_MISFIT_PER_FRAME: f64 = 50.0;

/// How much worse than each frame's own contact a frictionless press fit
/// may explain the frames (χ² a frame, with no margin for a short press)
/// and still replace a recording that the press check rejects (by
/// [`PRESS_MISFIT_PER_FRAME`]), rather than each frame taking its own
/// contact: the excess where the recording is right is 1.2–4.3 a frame
/// (see [`PRESS_MISFIT_PER_FRAME`]). Where a slide stops and the contact
/// sticks on the LWR's flange (`synth --seed 3 --links lwr_7_link --slide
/// 0.1 --slide-min 0.02 --kinetic-friction 0.3,0.6`, surface seed 0, 2.54–
/// 2.80 s), the smoother's place lies on the edge between the flange's
/// side and its end face, 1.8 mm from the true one on the side, where a
/// frictionless push misses each frame at χ² about 11,000; the fit from
/// there lands on the true place at 2.5 a frame beyond the frames' own.
/// Taken one by one, their own contacts hop 1–10 mm from frame to frame
/// and onto link 5 in 8 of the 53 frames. Where model error rather than the place sets the
/// misfit (the `../shared` observer link-side example, surface seed 1: a
/// 318-frame press at 23 a frame beyond its own), each frame's own contact
/// is the nearer (3.4 mm at the median, 5.1 with the fit).
pub const FIT_AS_OWN_PER_FRAME: f64 = 5.0;

/// See [`PRESS_MISFIT_PER_FRAME`]: a short press must still miss by this
/// much in all.
pub const PRESS_MISFIT_MARGIN: f64 = 30.0;
