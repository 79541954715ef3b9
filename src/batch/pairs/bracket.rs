//! A single contact that leaves where it stood and comes back: the
//! frames between, where a second push may have come and gone while one
//! contact elsewhere explained them ([`bracket_pairs`]).
//!
//! Two pushes' torques are often those of one push at a third place:
//! seven joints, five unknowns for one contact with friction. A frame
//! alone then calls one contact, and the single contact's track leaves
//! the place where the first push stood for a third place,
//! and comes back to it when the second push lets go. One contact
//! cannot do that by chance: it would land again, after centimetres,
//! within millimetres of where it left. So where the frames before and
//! after a run hold one contact at the same place, and the run's own
//! single contact stands away from it, each frame of the run is weighed
//! as [`super::carry`] weighs a frame beside a pair: the pair searched
//! from the contact that stood against that contact alone, held where it
//! stood with any force (it may have turned within its friction or
//! beyond), and against either push of the pair alone.

use std::time::Instant;

use super::carry::{Anchor, anchor_push, held_pair_log_ratio, off_place};
use super::{SingleSeen, summary_only};
use crate::core::estimate::estimator::{Estimator, elapsed_ms};
use crate::core::estimate::pair::{HeldPush, PairEstimate, PairSettings, PairStart, Placed, Unidentifiable};
use crate::core::estimate::pair_held::HeldPair;
use crate::core::estimate::settings::EstimateError;
use crate::core::numerics::special::logistic;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::robot::model::Robot;

/// How near where it left, m, a single contact must come back for the
/// frames between to be bracketed: a push held still comes back within
/// millimetres (2.3 mm on a generated two-hand session, `synth
/// --contacts 2 --avoid-covered --seed 1`), a slide's contact that hops
/// to another place and back does not (7.8–47 mm on the generated slides
/// of `tests/slides.rs`' kind, links 4, 5 and 7: with a return within
/// 5 cm, 1–3 frames of three of them, where one contact presses, were
/// called two).
const RETURN_M: f64 = 0.005;

/// A run of contact frames whose single contact stands away from where
/// the frames on both sides of it hold one contact.
#[derive(Debug, Clone, Copy)]
struct Bracket {
    first: usize,
    last: usize,
    anchor: Anchor,
}

/// Whether frame `k`'s single contact stands away from `anchor`: on
/// another link, or farther than `separation_m` from it on its link.
fn away(singles: &[Option<SingleSeen>], k: usize, anchor: &Anchor, separation_m: f64) -> bool {
    singles.get(k).copied().flatten().is_some_and(|single| {
        single.push.is_none_or(|p| {
            p.link != anchor.push.link || p.point_in_link.distance(anchor.push.point_in_link) > separation_m
        })
    })
}

/// The run that starts at frame `first` where the single contact jumps
/// away from where the frames before it held one contact, and ends at
/// the frame before it stands there again, contact lasting throughout;
/// `None` where frame `first` does not jump, or the contact ends or
/// stays away.
fn bracket_at(
    frames: &[SequenceFrame<'_>],
    singles: &[Option<SingleSeen>],
    first: usize,
    separation_m: f64,
) -> Option<Bracket> {
    let before = first.checked_sub(1)?;
    singles.get(before).copied().flatten()?;
    let anchor = anchor_push(frames, singles, first, true)?;
    if away(singles, before, &anchor, separation_m) || !away(singles, first, &anchor, separation_m) {
        return None;
    }
    let mut last = first;
    while away(singles, last + 1, &anchor, separation_m) {
        last += 1;
    }
    // The frame after the run holds a contact, back where it stood, and
    // so do the frames after it.
    singles.get(last + 1).copied().flatten()?;
    let after = anchor_push(frames, singles, last, false)?;
    (after.push.link == anchor.push.link && after.push.point_in_link.distance(anchor.push.point_in_link) <= RETURN_M)
        .then_some(Bracket { first, last, anchor })
}

/// Each run of frames where the single contact leaves the place the
/// frames on both sides hold and comes back ([`bracket_at`]), searched
/// for a pair from that place: the frames not `taken` (called two or
/// carried already) where the pair is kept ([`bracket_step`]) get its
/// account in `found`, and each search's time is added to its frame's
/// in `search_ms`. Which frames got one.
pub(super) fn bracket_pairs(
    estimator: &Estimator,
    robot: &Robot,
    (frames, singles): (&[SequenceFrame<'_>], &[Option<SingleSeen>]),
    pair_settings: &PairSettings,
    (found, search_ms): (&mut [Option<PairEstimate>], &mut [f64]),
    taken: &[bool],
) -> Result<Vec<bool>, (usize, EstimateError)> {
    let n = found.len();
    let mut marked = vec![false; n];
    let mut first = 1;
    while first < n {
        let Some(bracket) = bracket_at(frames, singles, first, pair_settings.separation_m) else {
            first += 1;
            continue;
        };
        let stood = Stood {
            before: &bracket.anchor,
            after: None,
            own: None,
        };
        search_run(
            estimator,
            robot,
            frames,
            pair_settings,
            (found, search_ms, &mut marked),
            taken,
            (bracket.first, bracket.last),
            |_| stood,
        )?;
        first = bracket.last + 1;
    }
    Ok(marked)
}

/// The frames `first..=last` not `taken`, each searched for a pair as
/// `stood_at(k)` says ([`bracket_step`]): where the pair is kept, its
/// account goes in `found` and the frame is `marked`; each search's time
/// is added to its frame's in `search_ms`. Each frame's search also
/// starts where the nearest pair kept before it left the contacts; then,
/// for the frames still without one, where the nearest pair kept after
/// it did (the frames where the second push arrives come before any
/// pair is kept).
#[allow(clippy::too_many_arguments)]
pub(super) fn search_run<'a>(
    estimator: &Estimator,
    robot: &Robot,
    frames: &[SequenceFrame<'_>],
    pair_settings: &PairSettings,
    (found, search_ms, marked): (&mut [Option<PairEstimate>], &mut [f64], &mut [bool]),
    taken: &[bool],
    (first, last): (usize, usize),
    stood_at: impl Fn(usize) -> Stood<'a>,
) -> Result<(), (usize, EstimateError)> {
    let forward: Vec<usize> = (first..=last).collect();
    for order in [forward.clone(), forward.into_iter().rev().collect()] {
        let mut kept_last: Option<[Placed; 2]> = None;
        for k in order {
            if marked.get(k) == Some(&true) {
                kept_last = found
                    .get(k)
                    .and_then(Option::as_ref)
                    .map(|kept| kept.contacts.clone().map(|c| c.placed));
                continue;
            }
            if taken.get(k).copied().unwrap_or(true) {
                continue;
            }
            let Some(frame) = frames.get(k) else {
                continue;
            };
            let t0 = Instant::now();
            let step = bracket_step(estimator, robot, frame, pair_settings, stood_at(k), kept_last.as_ref())
                .map_err(|e| (k, e))?;
            if let Some(ms) = search_ms.get_mut(k) {
                *ms += elapsed_ms(t0);
            }
            if let (Some(mut account), Some(slot), Some(m)) = (step, found.get_mut(k), marked.get_mut(k)) {
                kept_last = Some(account.contacts.clone().map(|c| c.placed));
                summary_only(&mut account);
                *slot = Some(account);
                *m = true;
            }
        }
    }
    Ok(())
}

/// What a bracketed frame's pair is weighed against: where one contact
/// stood beside the run, and the frame's own single contact.
#[derive(Debug, Clone, Copy)]
pub(super) struct Stood<'a> {
    /// Where one contact stood before the run (and after it, where it
    /// came back).
    pub(super) before: &'a Anchor,
    /// Where the other contact stood alone after the run, where the first
    /// let go during it ([`super::handover`]): the pair must have a
    /// contact near each, and is weighed against either alone.
    pub(super) after: Option<&'a Anchor>,
    /// The frame's own single contact, weighed against with any force
    /// where the run's single contact may be one that moved.
    pub(super) own: Option<HeldPush>,
}

impl Stood<'_> {
    /// Whether a pair that a frame's torques alone leave `unidentifiable`
    /// is told apart here. Where both places are known from the frames
    /// on either side ([`Stood::after`]), the frame need not tell its six
    /// unknowns apart, only the pushes' forces: a pair felt by five
    /// joints, or whose push its own joints do not confirm, or one of
    /// whose pushes alone explains the torques, is weighed by its
    /// evidence against each place alone with any force. A push felt by
    /// fewer than three joints, two pushes of the same torques, and two
    /// on one link are not told apart by any evidence of one frame.
    fn tells_apart(&self, unidentifiable: Option<Unidentifiable>) -> bool {
        match unidentifiable {
            None => true,
            Some(Unidentifiable::FewJoints | Unidentifiable::Unconfirmed | Unidentifiable::OneExplains) => {
                self.after.is_some()
            }
            Some(_) => false,
        }
    }
}

/// The pair of `frame`, inside a run whose single contact left where
/// `stood.before` stood, searched from that place (and from where
/// `stood.after` stood): kept where one of its contacts is on that link
/// within the separation of it and the other is not (near
/// `stood.after`, where given), the torques tell its six unknowns apart
/// (identifiable), and it is more probable, with the prior odds of two,
/// than one contact where it stood: each anchor's push with any force,
/// the frame's own single contact with any force, or either push of the
/// pair alone ([`held_pair_log_ratio`], the new contact paying its Occam
/// factor near where the search found it).
pub(super) fn bracket_step(
    estimator: &Estimator,
    robot: &Robot,
    frame: &SequenceFrame<'_>,
    pair_settings: &PairSettings,
    stood: Stood<'_>,
    last: Option<&[Placed; 2]>,
) -> Result<Option<PairEstimate>, EstimateError> {
    let (q, tau) = (frame.joint_positions, frame.tau);
    let anchor = stood.before;
    // The last pair kept first: the search stops at the first start
    // whose pair explains the torques within the noise.
    let mut starts: Vec<PairStart> = last
        .map(|both| PairStart::Both(Box::new(both.clone())))
        .into_iter()
        .collect();
    for a in [Some(anchor), stood.after].into_iter().flatten() {
        let (point, force_newtons) = a.seen;
        starts.push(PairStart::One { point, force_newtons });
    }
    let Some(found) = estimator.pair_at(robot, q, tau, pair_settings, &starts)? else {
        return Ok(None);
    };
    if !stood.tells_apart(found.unidentifiable) {
        return Ok(None);
    }
    let separation = pair_settings.separation_m;
    let near = |placed: &Placed, a: &Anchor| off_place(placed, a.push.link, a.push.point_in_link) <= separation;
    let arrived = |placed: &Placed| stood.after.map_or(!near(placed, anchor), |after| near(placed, after));
    // The contact that stood, and the one that came.
    let [a, b] = found
        .contacts
        .each_ref()
        .map(|c| (near(&c.placed, anchor), arrived(&c.placed)));
    let new = match (a, b) {
        ((true, false), (false, true)) => 1,
        ((false, true), (true, false)) => 0,
        _ => return Ok(None),
    };
    let both = found.contacts.clone().map(|c| c.placed);
    let Some(HeldPair {
        mut account,
        new_log_occam,
    }) = estimator.pair_held_at(robot, q, tau, pair_settings, &both, new)?
    else {
        return Ok(None);
    };
    let kept = account.contacts.get(1 - new).is_some_and(|c| near(&c.placed, anchor))
        && account.contacts.get(new).is_some_and(|c| arrived(&c.placed));
    if !stood.tells_apart(account.unidentifiable) || !kept {
        return Ok(None);
    }
    let Some(pair_log_ratio) = held_pair_log_ratio(
        estimator,
        robot,
        frame,
        &account,
        new_log_occam,
        [Some(&anchor.push), stood.after.map(|a| &a.push)],
    ) else {
        return Ok(None);
    };
    // One contact where it stood, or where the frame has it, its force
    // free.
    let free_places = [Some(anchor.push), stood.after.map(|a| a.push), stood.own];
    let log_ratio = free_places
        .into_iter()
        .flatten()
        .filter_map(|p| estimator.free_push_chi2(robot, q, tau, p.link, p.point_in_link))
        .map(|chi2| 0.5 * (chi2 - account.residual_chi2) + new_log_occam)
        .fold(pair_log_ratio, f64::min);
    let prior_log_odds = pair_settings.prior_two.ln() - (-pair_settings.prior_two).ln_1p();
    account.log_evidence_one = account.log_evidence_two - log_ratio;
    account.probability_two = logistic(log_ratio + prior_log_odds);
    Ok((log_ratio + prior_log_odds > 0.0).then_some(account))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::batch::pairs::carry::tests::{frames_at_200_hz, seen_at};

    /// A press on link 5 at 0.02 m, frames 10–119 at 200 Hz; frames
    /// 50–69 placed by `during`.
    fn pressed(during: impl Fn(usize) -> Option<SingleSeen>) -> Vec<Option<SingleSeen>> {
        (0..150)
            .map(|i| match i {
                0..10 | 120.. => None,
                50..70 => during(i),
                _ => Some(seen_at(5, 0.02)),
            })
            .collect()
    }

    #[test]
    fn a_single_contact_that_leaves_and_comes_back_brackets_the_frames_between() {
        let frames = frames_at_200_hz(150);
        // On link 6 for frames 50–69, back on link 5 at 70.
        let singles = pressed(|_| Some(seen_at(6, 0.0)));
        let bracket = bracket_at(&frames, &singles, 50, 0.05).unwrap();
        assert_eq!((bracket.first, bracket.last, bracket.anchor.push.link), (50, 69, 5));
        // Not where the contact has not left, nor inside the run.
        assert!(bracket_at(&frames, &singles, 49, 0.05).is_none());
        assert!(bracket_at(&frames, &singles, 51, 0.05).is_none());
        // 8 cm along the same link is away; 4 cm is not.
        let far = pressed(|_| Some(seen_at(5, 0.10)));
        assert_eq!(bracket_at(&frames, &far, 50, 0.05).map(|b| b.last), Some(69));
        let near = pressed(|_| Some(seen_at(5, 0.06)));
        assert!(bracket_at(&frames, &near, 50, 0.05).is_none());
    }

    #[test]
    fn a_contact_that_ends_or_stays_away_brackets_nothing() {
        let frames = frames_at_200_hz(150);
        // Released at 60, before coming back.
        let released = pressed(|i| (i < 60).then(|| seen_at(6, 0.0)));
        assert!(bracket_at(&frames, &released, 50, 0.05).is_none());
        // Back on link 5, but 8 cm from where it left.
        let mut moved = pressed(|_| Some(seen_at(6, 0.0)));
        for single in moved.iter_mut().skip(70).take(50) {
            *single = Some(seen_at(5, 0.10));
        }
        assert!(bracket_at(&frames, &moved, 50, 0.05).is_none());
    }
}
