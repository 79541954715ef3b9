//! A contact handed over: one push holds, a second arrives, the first
//! lets go, and the second holds on ([`handover_pairs`]).
//!
//! Where the second push arrives beside the first, the single contact
//! often explains the frames between by a push at a third place, or by
//! the first push shifted a few centimetres along its link: seven joints,
//! five unknowns for one contact with friction. But the frames before the
//! overlap hold one contact at one place and the frames after it hold
//! one at another place, on another link, and both places are known to
//! within millimetres there. So each frame of such a contact is weighed
//! as [`super::bracket`] weighs a frame between a contact's leaving and
//! coming back: the pair searched from both places, kept where it has a
//! contact near each, against one contact at either place, or where the
//! frame has it, with any force.

use super::SingleSeen;
use super::bracket::{Stood, search_run};
use super::carry::{Anchor, anchor_push};
use crate::core::estimate::estimator::Estimator;
use crate::core::estimate::pair::{PairEstimate, PairSettings};
use crate::core::estimate::settings::EstimateError;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::robot::model::Robot;

/// A contact (frames with contact throughout) whose first and last
/// frames hold one contact on different links.
#[derive(Debug, Clone, Copy)]
struct Handover {
    first: usize,
    last: usize,
    before: Anchor,
    after: Anchor,
}

/// The contact that starts at frame `first` (the frame before it has
/// none), where one contact stood on one link as it began and on another
/// as it ended ([`anchor_push`] over the frames at either end); `None`
/// where frame `first` does not start a contact, or both ends hold one
/// contact on the same link.
fn handover_at(frames: &[SequenceFrame<'_>], singles: &[Option<SingleSeen>], first: usize) -> Option<Handover> {
    let before_first = first.checked_sub(1)?;
    if singles.get(before_first).copied().flatten().is_some() {
        return None;
    }
    singles.get(first).copied().flatten()?;
    let mut last = first;
    while singles.get(last + 1).copied().flatten().is_some() {
        last += 1;
    }
    let before = anchor_push(frames, singles, before_first, false)?;
    let after = anchor_push(frames, singles, (last + 1).min(frames.len().saturating_sub(1)), true)?;
    (before.push.link != after.push.link).then_some(Handover {
        first,
        last,
        before,
        after,
    })
}

/// Each contact handed over from one link to another ([`handover_at`]),
/// its frames searched for a pair from the two places: the frames not
/// `taken` (called two or carried already) where the pair is kept
/// ([`search_run`], weighed against both places and the frame's own
/// single contact) get its account in `found`, and each search's time is
/// added to its frame's in `search_ms`. Which frames got one.
pub(super) fn handover_pairs(
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
        let Some(handover) = handover_at(frames, singles, first) else {
            first += 1;
            continue;
        };
        search_run(
            estimator,
            robot,
            frames,
            pair_settings,
            (found, search_ms, &mut marked),
            taken,
            (handover.first, handover.last),
            |k| Stood {
                before: &handover.before,
                after: Some(&handover.after),
                own: singles.get(k).copied().flatten().and_then(|s| s.push),
            },
        )?;
        first = handover.last + 1;
    }
    Ok(marked)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::batch::pairs::carry::tests::{frames_at_200_hz, seen_at};

    /// A contact over frames 10–119 at 200 Hz: on link 5 at 0.02 m up to
    /// frame 49, placed by `during` for frames 50–69, and by `after` from
    /// frame 70.
    fn pressed(
        during: impl Fn(usize) -> Option<SingleSeen>,
        after: impl Fn(usize) -> Option<SingleSeen>,
    ) -> Vec<Option<SingleSeen>> {
        (0..150)
            .map(|i| match i {
                0..10 | 120.. => None,
                10..50 => Some(seen_at(5, 0.02)),
                50..70 => during(i),
                _ => after(i),
            })
            .collect()
    }

    #[test]
    fn a_contact_that_begins_on_one_link_and_ends_on_another_is_handed_over() {
        let frames = frames_at_200_hz(150);
        let singles = pressed(|_| Some(seen_at(5, 0.06)), |_| Some(seen_at(6, 0.0)));
        let handover = handover_at(&frames, &singles, 10).unwrap();
        assert_eq!((handover.first, handover.last), (10, 119));
        assert_eq!((handover.before.push.link, handover.after.push.link), (5, 6));
        // Only from the frame where the contact begins.
        assert!(handover_at(&frames, &singles, 9).is_none());
        assert!(handover_at(&frames, &singles, 11).is_none());
    }

    #[test]
    fn a_contact_that_ends_on_its_link_or_breaks_is_not_handed_over() {
        let frames = frames_at_200_hz(150);
        // Back on link 5, 8 cm along: the bracket's, not a handover.
        let same = pressed(|_| Some(seen_at(6, 0.0)), |_| Some(seen_at(5, 0.10)));
        assert!(handover_at(&frames, &same, 10).is_none());
        // Released at 60 and pressed again on link 6 at 70: two contacts
        // one after the other, each on one link.
        let broken = pressed(|i| (i < 60).then(|| seen_at(5, 0.02)), |_| Some(seen_at(6, 0.0)));
        assert!(handover_at(&frames, &broken, 10).is_none());
        assert!(handover_at(&frames, &broken, 70).is_none());
    }
}
