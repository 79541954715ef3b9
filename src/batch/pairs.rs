//! A session's second contacts, after its single-contact estimates: each
//! poorly explained frame's two-contact search in order (each starts where the
//! frames before left the contacts), then the chain of two states over
//! the frames' evidence, smoothed over the whole session (each run of
//! frames called two then carried into the frames beside it that one
//! contact explains, the arriving push's place held; each contact whose
//! single contact leaves a place and comes back to it, or begins on one
//! link and ends on another, searched from those places) or filtered
//! ([`crate::core::over_time::pairs`]); live, a frame at a time with the
//! chain filtered ([`LivePairs`]); frames alone, each searched on its own
//! ([`PairsOver`]).

use std::collections::BTreeMap;
use std::time::Instant;

use glam::DVec3;

use crate::core::estimate::estimator::{Estimator, Update, elapsed_ms};
use crate::core::estimate::pair::{HeldPush, PairEstimate, PairSettings, Unidentifiable};
use crate::core::estimate::pair_identifiable::{
    FREE_PUSH_MARGIN_CHI2, NEAR_FREE_PUSH_MARGIN_CHI2, NEAR_FREE_PUSH_RADIUS_M, pushes_unidentifiable,
};
use crate::core::estimate::settings::EstimateError;
use crate::core::estimate::summary::Verdict;
use crate::core::eval::metrics::percentile;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::over_time::pairs::{
    ChainFilter, NO_PAIR_LOG_RATIO, PairSketch, PairTracker, SecondContactChain, bridged,
};
use crate::core::over_time::sequence::Temporal;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{LinkId, Robot};
use crate::io::session::{ContactTruth, Frame};

mod bracket;
mod carry;
mod handover;
use bracket::bracket_pairs;
use carry::carry_pairs;
use handover::handover_pairs;

/// What the pair pass needs of a frame's single-contact estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SingleSeen {
    /// The single contact's sample.
    pub point: usize,
    /// Its magnitude, N.
    pub force_newtons: f64,
    /// Whether the single contact explains the torques (its verdict is
    /// "contact", not "poorly explained").
    pub explained: bool,
    /// The single contact as a push its link holds (`None` where the
    /// pose has no such link).
    pub push: Option<HeldPush>,
}

impl SingleSeen {
    /// A frame's single contact, `None` where it calls no contact.
    #[must_use]
    pub fn of(update: &Update) -> Option<Self> {
        let s = &update.summary;
        let push = update.pose.world_from_link.get(s.map.link).map(|world_from_link| {
            let link_from_world = world_from_link.inverse();
            HeldPush {
                link: s.map.link,
                point_in_link: link_from_world.transform_point3(s.map.point_world),
                force_in_link: link_from_world.transform_vector3(s.map.force_world),
            }
        });
        (s.verdict != Verdict::NoContact).then_some(Self {
            point: s.map.point,
            force_newtons: s.map.force_newtons,
            explained: s.verdict == Verdict::Contact,
            push,
        })
    }
}

/// A frame's two-contact account over the session.
#[derive(Debug, Clone, PartialEq)]
pub struct FramePair {
    /// Its own search's answer.
    pub pair: PairEstimate,
    /// Probability of two contacts given the whole session.
    pub probability_two: f64,
    /// Whether the frames beside it identify the pair that a rule read
    /// from this frame's torques alone does not
    /// ([`crate::core::over_time::pairs::bridged`]; smoothed sessions
    /// only: a filter has not seen the frame after).
    pub bridged: bool,
    /// Whether the pair is the one of the run of frames called two next
    /// to this frame, carried into it where one contact explains the
    /// frame, the arriving or leaving push's place held near where the
    /// frame beside has it (`carry_pairs`), or the pair searched from
    /// where one contact stood beside a run it left and came back to
    /// (`bracket_pairs`) or from where it stood as a contact began and
    /// ended on two links (`handover_pairs`); smoothed sessions only.
    pub carried: bool,
}

impl FramePair {
    /// Whether the frame is called two contacts: more probable than one
    /// over the session, and identifiable (by its own rules, bridged by
    /// the frames beside it, or carried from them).
    #[must_use]
    pub fn has_two(&self) -> bool {
        calls_two(&self.pair, self.probability_two, self.bridged || self.carried)
    }
}

/// Whether a frame's `pair` is called two: more probable than one over
/// the frames taken together (`probability_two`), and identifiable by its
/// own rules or `vouched` for by the frames beside it.
fn calls_two(pair: &PairEstimate, probability_two: f64, vouched: bool) -> bool {
    (pair.identifiable() || vouched) && probability_two > 0.5
}

/// `pair` as a session keeps it: its summary, not its contacts'
/// posteriors over the surface (memory stays flat in the frames
/// searched).
fn summary_only(pair: &mut PairEstimate) {
    for contact in &mut pair.contacts {
        contact.probability = Vec::new();
    }
}

/// A session's pair searches in order, each started where the frames
/// before left the contacts ([`PairTracker`]): the part of the pass that
/// a recording and a live stream share.
#[derive(Debug, Clone, Default)]
pub struct PairFollower {
    tracker: PairTracker,
    /// The last single contact that explained its frame, while contact
    /// lasts.
    held: Option<HeldPush>,
    /// Whether each frame is called from the frames before it only
    /// (filtered, live).
    causal: bool,
}

impl PairFollower {
    /// A follower that has seen no frame.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// A follower whose frames are called from the frames before them
    /// only (filtered, live).
    #[must_use]
    pub fn causal() -> Self {
        Self {
            causal: true,
            ..Self::default()
        }
    }

    /// The next frame's two-contact account, given its single contact
    /// (`None`: no contact); `None` where it is not searched.
    ///
    /// # Errors
    /// The frame's search failing.
    pub fn search(
        &mut self,
        estimator: &Estimator,
        robot: &Robot,
        frame: &SequenceFrame<'_>,
        single: Option<SingleSeen>,
        pair_settings: &PairSettings,
    ) -> Result<Option<PairEstimate>, EstimateError> {
        let Some(single) = single else {
            self.tracker.observe(None, None);
            self.held = None;
            return Ok(None);
        };
        // One contact that explains the torques (the fit test) is not
        // searched for a second: on one-contact recordings with friction
        // and model error, the pair's two spare unknowns otherwise take
        // up the misfit (`docs/decisions.md`, *Two contacts*).
        if single.explained {
            self.tracker.observe(Some((single.point, single.force_newtons)), None);
            self.held = single.push;
            return Ok(None);
        }
        let mut pair = estimator.pair_at(
            robot,
            frame.joint_positions,
            frame.tau,
            pair_settings,
            &self.tracker.starts(),
        )?;
        // A pair with no contact on the link of the last push to explain
        // its frame alone is not identifiable where that push still
        // explains this frame, its force's direction kept: a slide whose
        // kinetic friction drags beyond the friction cone a frame is
        // fitted with, which a pair flanking its link explains better
        // than any single contact of that cone (the `../shared` link 6
        // slide, 1.285–1.315 s). A pair that keeps a contact on that link
        // is the held contact and a new one (a second hand arriving), and
        // the held push alone explains such frames as often (at the same
        // χ², 33–38 on seven joints). The search itself runs as before:
        // the frames after it start where it left the pair.
        if let Some(pair) = pair.as_mut()
            && pair.unidentifiable.is_none()
            && let Some(held) = self.held
            && pair.contacts.iter().all(|c| c.placed.link != held.link)
            && estimator.held_push_explains(robot, frame.joint_positions, frame.tau, &held)
        {
            pair.unidentifiable = Some(Unidentifiable::HeldExplains);
        }
        // A pair that does not beat the frame's single contact pushing
        // any way at its place, by more than three spare unknowns fit
        // by chance, is that contact's friction: a slide's kinetic
        // friction drags at up to 0.6 of its push, beyond the cone a
        // frame is fitted with, and a pair with a few newtons on
        // another link takes up the rest (`docs/decisions.md`, session
        // 82).
        if let Some(pair) = pair.as_mut()
            && pair.unidentifiable.is_none()
            && let Some(push) = single.push
            && estimator
                .free_push_chi2(robot, frame.joint_positions, frame.tau, push.link, push.point_in_link)
                .is_some_and(|chi2| chi2 - pair.residual_chi2 <= FREE_PUSH_MARGIN_CHI2)
        {
            pair.unidentifiable = Some(Unidentifiable::FreeExplains);
        }
        // Frames called from the frames before them only: the single
        // contact of a slide lags it by 15–24 mm or sits across the joint,
        // so its own place's free push misses what a free push a little
        // ahead explains. A pair must beat one contact pushing any way
        // within `NEAR_FREE_PUSH_RADIUS_M` of the single contact, and of
        // the last single contact that explained its frame where the pair
        // has left that contact's link, by more than one spare unknown fit
        // by chance. Smoothed sessions settle such frames from both sides
        // instead (`docs/decisions.md`, session 83).
        if self.causal
            && let Some(pair) = pair.as_mut()
            && pair.unidentifiable.is_none()
        {
            let single_place = single.push.map(|push| (push.link, push.point_in_link));
            let held_place = self
                .held
                .filter(|held| pair.contacts.iter().all(|c| c.placed.link != held.link))
                .map(|held| (held.link, held.point_in_link));
            let places: Vec<(LinkId, DVec3)> = single_place.into_iter().chain(held_place).collect();
            if !places.is_empty()
                && estimator
                    .free_push_chi2_near(
                        robot,
                        (frame.joint_positions, frame.tau),
                        &places,
                        NEAR_FREE_PUSH_RADIUS_M,
                    )
                    .is_some_and(|chi2| chi2 - pair.residual_chi2 <= NEAR_FREE_PUSH_MARGIN_CHI2)
            {
                pair.unidentifiable = Some(Unidentifiable::FreeExplains);
            }
        }
        if let Some(pair) = pair.as_mut() {
            summary_only(pair);
        }
        self.tracker.observe(None, pair.as_ref());
        Ok(pair)
    }
}

/// A frame's evidence ratio for the chain (a frame without a pair
/// account: "no second contact").
fn log_ratio(pair: Option<&PairEstimate>) -> f64 {
    pair.map_or(NO_PAIR_LOG_RATIO, PairEstimate::log_evidence_ratio)
}

/// How a session's frames are taken together for their second contacts.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PairsOver {
    /// Each frame alone: searched from the coarse grid (as the app's
    /// frame on screen is), its probability of two its own.
    Alone,
    /// Each frame from the frames before: the searches in order, the
    /// chain filtered (as [`LivePairs`]).
    Filtered(SecondContactChain),
    /// The whole session: the searches in order, the chain smoothed.
    Smoothed(SecondContactChain),
}

impl PairsOver {
    /// As the single contacts are taken over time (`temporal`), with
    /// `chain` where frames are taken together.
    #[must_use]
    pub fn of(temporal: Temporal, chain: SecondContactChain) -> Self {
        match temporal {
            Temporal::None => Self::Alone,
            Temporal::Filter => Self::Filtered(chain),
            Temporal::Smooth => Self::Smoothed(chain),
        }
    }
}

/// Each frame's two-contact account (`None` for frames without contact),
/// `singles[i]` frame `i`'s single contact, the frames taken together
/// as `over` says.
///
/// # Errors
/// A frame whose search fails, with its number.
pub fn session_pairs(
    estimator: &Estimator,
    robot: &Robot,
    frames: &[SequenceFrame<'_>],
    singles: &[Option<SingleSeen>],
    pair_settings: &PairSettings,
    over: PairsOver,
) -> Result<Vec<Option<FramePair>>, (usize, EstimateError)> {
    session_pairs_timed(estimator, robot, frames, singles, pair_settings, over, || true)
        .map(|found| found.map(|(pairs, _)| pairs).unwrap_or_default())
}

/// Each frame's two-contact account and its search time, ms.
pub type TimedPairs = (Vec<Option<FramePair>>, Vec<f64>);

/// [`session_pairs`], asking `keep_going` before each frame's search
/// (`None` once it says no: a newer job in the app), with each frame's
/// search time, ms (next to nothing for a frame not searched): what a
/// frame's update costs under the two-contact model beyond its single
/// contact's.
///
/// # Errors
/// A frame whose search fails, with its number.
pub fn session_pairs_timed(
    estimator: &Estimator,
    robot: &Robot,
    frames: &[SequenceFrame<'_>],
    singles: &[Option<SingleSeen>],
    pair_settings: &PairSettings,
    over: PairsOver,
    keep_going: impl Fn() -> bool,
) -> Result<Option<TimedPairs>, (usize, EstimateError)> {
    let mut follower = if matches!(over, PairsOver::Filtered(_)) {
        PairFollower::causal()
    } else {
        PairFollower::new()
    };
    let mut found = Vec::with_capacity(frames.len());
    let mut search_ms = Vec::with_capacity(frames.len());
    for (i, (frame, &single)) in frames.iter().zip(singles).enumerate() {
        if !keep_going() {
            return Ok(None);
        }
        if over == PairsOver::Alone {
            // Nothing carries over from the frame before.
            follower = PairFollower::new();
        }
        let t0 = Instant::now();
        found.push(
            follower
                .search(estimator, robot, frame, single, pair_settings)
                .map_err(|e| (i, e))?,
        );
        search_ms.push(elapsed_ms(t0));
    }
    let (mut probabilities, mut bridges) = chain_over(&found, frames, pair_settings, over);
    let mut carried = vec![false; found.len()];
    if matches!(over, PairsOver::Smoothed(_)) {
        let called: Vec<bool> = found
            .iter()
            .zip(&probabilities)
            .zip(&bridges)
            .map(|((pair, &p), &b)| pair.as_ref().is_some_and(|pair| calls_two(pair, p, b)))
            .collect();
        carried = carry_pairs(
            estimator,
            robot,
            (frames, singles),
            pair_settings,
            (&mut found, &mut search_ms),
            &called,
        )?;
        // A contact that leaves a place and comes back to it, then one
        // handed over from link to link: each pass searches the frames not
        // called or carried yet. Last, the runs that the frames called and
        // carried now make are carried again into the frames beside them:
        // a run the passes before joined can be long enough to be
        // established where its called frames alone were not, or can
        // begin at a frame carried by a pass after the first carry (the
        // `../shared` two-contact example at surface seeds 1 and 5: the
        // link 7 probe's rise, carried from the frames that a bracket
        // search found two in, 60 → 76 and 63 → 75 of the 76 frames whose
        // true pair the joints can tell apart).
        for pass in [bracket_pairs, handover_pairs, carry_pairs] {
            let taken: Vec<bool> = called.iter().zip(&carried).map(|(&a, &b)| a || b).collect();
            let marked = pass(
                estimator,
                robot,
                (frames, singles),
                pair_settings,
                (&mut found, &mut search_ms),
                &taken,
            )?;
            for (c, m) in carried.iter_mut().zip(marked) {
                *c |= m;
            }
        }
        if carried.contains(&true) {
            (probabilities, bridges) = chain_over(&found, frames, pair_settings, over);
        }
    }
    let pairs = found
        .into_iter()
        .zip(probabilities)
        .zip(bridges.into_iter().zip(carried))
        .map(|((pair, probability_two), (bridged, carried))| {
            pair.map(|pair| FramePair {
                pair,
                probability_two,
                bridged,
                carried,
            })
        })
        .collect();
    Ok(Some((pairs, search_ms)))
}

/// Each frame's probability of two contacts, and whether the frames
/// beside it bridge its pair, from the frames' accounts `found`.
fn chain_over(
    found: &[Option<PairEstimate>],
    frames: &[SequenceFrame<'_>],
    pair_settings: &PairSettings,
    over: PairsOver,
) -> (Vec<f64>, Vec<bool>) {
    let times: Vec<f64> = frames.iter().map(|f| f.t_secs).collect();
    let ratios: Vec<f64> = found.iter().map(|p| log_ratio(p.as_ref())).collect();
    let probabilities = match over {
        PairsOver::Alone => found
            .iter()
            .map(|p| p.as_ref().map_or(0.0, |p| p.probability_two))
            .collect(),
        PairsOver::Filtered(chain) => chain.filter(&times, &ratios, pair_settings.prior_two),
        PairsOver::Smoothed(chain) => chain.smooth(&times, &ratios, pair_settings.prior_two),
    };
    let bridges = match over {
        PairsOver::Smoothed(_) => {
            let sketches: Vec<Option<PairSketch>> = found
                .iter()
                .zip(&probabilities)
                .map(|(pair, &p)| pair.as_ref().map(|pair| PairSketch::of(pair, p)))
                .collect();
            bridged(&sketches, pair_settings.separation_m)
        }
        PairsOver::Alone | PairsOver::Filtered(_) => vec![false; found.len()],
    };
    (probabilities, bridges)
}

/// What the app's timeline keeps of a frame's two-contact account.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PairSeen {
    /// Probability of two contacts given the frames estimated together.
    pub probability_two: f64,
    /// Whether two are called ([`FramePair::has_two`]).
    pub called: bool,
    /// Each contact's link, point (world frame, m) and push on the robot
    /// (world frame, N), the one nearer the single contact first.
    pub contacts: [(LinkId, DVec3, DVec3); 2],
}

impl PairSeen {
    /// The compact form of a frame's account.
    #[must_use]
    pub fn of(pair: &FramePair) -> Self {
        Self {
            probability_two: pair.probability_two,
            called: pair.has_two(),
            contacts: pair
                .pair
                .contacts
                .each_ref()
                .map(|c| (c.placed.link, c.point_world, c.force_world)),
        }
    }
}

/// Second contacts of a live stream, a frame at a time: the searches as
/// a recording's, the chain filtered (each frame's probability of two
/// from it and the frames before).
#[derive(Debug, Clone)]
pub struct LivePairs {
    follower: PairFollower,
    filter: ChainFilter,
    settings: PairSettings,
}

impl LivePairs {
    /// Nothing seen yet; pairs searched with `settings`, followed over
    /// time with `chain`.
    #[must_use]
    pub fn new(settings: PairSettings, chain: SecondContactChain) -> Self {
        Self {
            follower: PairFollower::causal(),
            filter: ChainFilter::new(chain, settings.prior_two),
            settings,
        }
    }

    /// The next frame's two-contact account (`None` where it is not
    /// searched): the stream's `frame`, its joint positions in the
    /// robot's order, and its single-contact `update`.
    ///
    /// # Errors
    /// The frame's search failing; the stream goes on from the next frame
    /// as from a frame without a pair account.
    pub fn push(
        &mut self,
        estimator: &Estimator,
        robot: &Robot,
        (frame, joint_positions): (&Frame, &[f64]),
        update: &Update,
    ) -> Result<Option<FramePair>, EstimateError> {
        let frame = SequenceFrame {
            t_secs: frame.t,
            joint_positions,
            tau: &frame.tau,
        };
        let found = self
            .follower
            .search(estimator, robot, &frame, SingleSeen::of(update), &self.settings);
        let pair = found.as_ref().ok().and_then(Option::as_ref);
        let probability_two = self.filter.push(frame.t_secs, log_ratio(pair));
        Ok(found?.map(|pair| FramePair {
            pair,
            probability_two,
            bridged: false,
            carried: false,
        }))
    }

    /// Forgets every frame (a new sender, a new stream).
    pub fn reset(&mut self) {
        self.follower = PairFollower::causal();
        self.filter.reset();
    }
}

/// How the second contacts of a session with every true contact recorded
/// (`truth_all`) compare with the truth.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PairScore {
    /// Frames where two contacts press.
    pub both_frames: usize,
    /// Of these, frames called two.
    pub both_called_two: usize,
    /// Frames where two contacts press that six or more sensed joints
    /// feel (fewer leave a pair's six unknowns open: it cannot be called).
    pub both_identifiable: usize,
    /// Of these, frames called two.
    pub both_identifiable_called_two: usize,
    /// Frames where two contacts press whose true pair the joints can
    /// tell apart ([`pushes_unidentifiable`] finds no reason: each push
    /// read by the joints only it moves, and so on): where a pair can be
    /// called at all.
    pub both_separable: usize,
    /// Of these, frames called two.
    pub both_separable_called_two: usize,
    /// Frames where one contact presses.
    pub one_frames: usize,
    /// Of these, frames called two.
    pub one_called_two: usize,
    /// In frames where both press and two are called, each true contact's
    /// distance from the estimate matched to it, m (truths matched to
    /// estimates by the smaller total distance).
    pub both_errors_m: Vec<f64>,
    /// Each true contact's errors by its link's name: where both press
    /// and two are called, and where it presses alone.
    pub by_link: BTreeMap<String, LinkErrors>,
}

/// One link's true contacts' errors, m.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LinkErrors {
    /// Where another contact presses too and two are called: its
    /// distance from the estimate matched to it.
    pub with_other_m: Vec<f64>,
    /// Where it presses alone: its distance from the single contact.
    pub alone_m: Vec<f64>,
    /// Of [`LinkErrors::with_other_m`], those of the frames whose true
    /// pair the joints can tell apart ([`TruthFelt::separable`]).
    pub separable_m: Vec<f64>,
}

impl LinkErrors {
    /// The medians of [`LinkErrors::with_other_m`] and
    /// [`LinkErrors::alone_m`], m (NaN without any).
    #[must_use]
    pub fn medians_m(&self) -> (f64, f64) {
        (median_or_nan(&self.with_other_m), median_or_nan(&self.alone_m))
    }

    /// The median of [`LinkErrors::separable_m`], m (NaN without any).
    #[must_use]
    pub fn separable_median_m(&self) -> f64 {
        median_or_nan(&self.separable_m)
    }
}

/// The median of `values` (NaN without any: none measured).
fn median_or_nan(values: &[f64]) -> f64 {
    if values.is_empty() {
        f64::NAN
    } else {
        percentile(values, 0.5)
    }
}

impl PairScore {
    /// Adds a frame: its true contacts (world points), what the joints
    /// make of them, and the world points of its two estimates where it
    /// is called two.
    pub fn add(&mut self, truths: &[ContactTruth], felt: TruthFelt, two: Option<[DVec3; 2]>) {
        match truths {
            [one] => {
                let _ = one;
                self.one_frames += 1;
                self.one_called_two += usize::from(two.is_some());
            }
            [a, b] => {
                let both_truths = [a, b];
                self.both_frames += 1;
                let identifiable = felt.joints >= 6;
                self.both_identifiable += usize::from(identifiable);
                self.both_separable += usize::from(felt.separable);
                if let Some([e0, e1]) = two {
                    self.both_called_two += 1;
                    self.both_identifiable_called_two += usize::from(identifiable);
                    self.both_separable_called_two += usize::from(felt.separable);
                    let (a, b) = (DVec3::from_array(a.point), DVec3::from_array(b.point));
                    let straight = [a.distance(e0), b.distance(e1)];
                    let crossed = [a.distance(e1), b.distance(e0)];
                    let pick = if straight[0] + straight[1] <= crossed[0] + crossed[1] {
                        straight
                    } else {
                        crossed
                    };
                    self.both_errors_m.extend(pick);
                    for (truth, error) in both_truths.into_iter().zip(pick) {
                        let errors = self.by_link.entry(truth.link.clone()).or_default();
                        errors.with_other_m.push(error);
                        if felt.separable {
                            errors.separable_m.push(error);
                        }
                    }
                }
            }
            _ => {}
        }
    }

    /// Adds a frame: its true contacts (from `frame`), its two-contact
    /// account (`None` where it was not searched) and its single
    /// contact's world point (`None` where no contact is called);
    /// `rules` are the noise's weights (1/σ²) and whether contacts have
    /// friction, with which the true pair is judged.
    pub fn add_frame(
        &mut self,
        robot: &Robot,
        (frame, rules): (&Frame, (&[f64], bool)),
        pair: Option<&FramePair>,
        single: Option<DVec3>,
    ) {
        let truths = frame.true_contacts();
        let two = pair.filter(|p| p.has_two());
        let felt = TruthFelt {
            joints: sensing_joints(robot, &truths),
            separable: true_pair_separable(robot, frame, &truths, rules),
        };
        self.add(
            &truths,
            felt,
            two.map(|p| p.pair.contacts.each_ref().map(|c| c.point_world)),
        );
        self.add_single(&truths, single);
    }

    /// Adds a frame's single contact (its world point, `None` where no
    /// contact is called) against its true contacts: scored where one
    /// presses alone.
    pub fn add_single(&mut self, truths: &[ContactTruth], single: Option<DVec3>) {
        if let ([truth], Some(point)) = (truths, single) {
            let error = DVec3::from_array(truth.point).distance(point);
            self.by_link.entry(truth.link.clone()).or_default().alone_m.push(error);
        }
    }

    /// The median of [`PairScore::both_errors_m`], m (NaN without any).
    #[must_use]
    pub fn median_error_m(&self) -> f64 {
        median_or_nan(&self.both_errors_m)
    }
}

/// What the joints make of a frame's true contacts.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct TruthFelt {
    /// Sensed joints on the path of any of them ([`sensing_joints`]).
    pub joints: usize,
    /// Whether they are two that the joints can tell apart
    /// ([`pushes_unidentifiable`] finds no reason).
    pub separable: bool,
}

/// Whether `truths` are two pushes that the joints can tell apart at
/// `frame`'s joint positions, with `rules` (1/σ², friction); false for
/// any other count, an unknown link or joint positions the robot does
/// not take.
fn true_pair_separable(robot: &Robot, frame: &Frame, truths: &[ContactTruth], rules: (&[f64], bool)) -> bool {
    let push = |t: &ContactTruth| {
        robot
            .link_id(&t.link)
            .ok()
            .map(|link| (link, DVec3::from_array(t.point), DVec3::from_array(t.force)))
    };
    let ([a, b], Ok(joint_positions)) = (truths, robot.joint_positions(&frame.q, &[])) else {
        return false;
    };
    let (Some(a), Some(b)) = (push(a), push(b)) else {
        return false;
    };
    let pose = RobotPose::new(robot, &joint_positions);
    pushes_unidentifiable(robot, &pose, rules, [a, b]).is_none()
}

/// Sensed joints that feel any of `truths` (links unknown to the robot
/// feel none).
#[must_use]
pub fn sensing_joints(robot: &Robot, truths: &[ContactTruth]) -> usize {
    let mut joints: Vec<usize> = truths
        .iter()
        .filter_map(|t| robot.link_id(&t.link).ok())
        .flat_map(|link| robot.path_joints(link))
        .filter(|j| robot.sensed().contains(j))
        .collect();
    joints.sort_unstable();
    joints.dedup();
    joints.len()
}
