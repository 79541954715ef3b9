//! Where a press's frames alone put its contact somewhere else at once:
//! a jump faster than any slide, where a second push joins or leaves.

use glam::DVec3;

use crate::core::estimate::estimator::Update;
use crate::core::estimate::summary::Summary;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::over_time::starts::{ALTERNATIVE_MIN_FRAMES, in_link_frame};
use crate::core::robot::model::LinkId;

/// The frames (by number within `press`, increasing) where the press's
/// own places jump: the median of its frames' own places on `link` (the
/// link's frame) over [`JUMP_WINDOW_SECS`] before a frame and over as
/// long from it lie [`JUMP_M`] apart or more, and [`JUMP_SPREADS`] times
/// the two windows' spreads, each window full and with
/// [`ALTERNATIVE_MIN_FRAMES`] such places. Of jumps within a window of
/// each other, the widest, cut where the places nearby split best
/// between its two medians.
///
/// A press that one push holds moves at a slide's speed (a few cm/s),
/// and its places alone stay within a centimetre or two of each other
/// over a few hundredths of a second. Where a second push arrives, the
/// single contact that the frames alone fit has to explain both, and its
/// place leaves the first push's within a few frames (`synth --contacts
/// 2 --seed 2`, the link 4 hand: 5 → 130 mm in 0.04 s). Fitted as one
/// press, the two places are bridged by a slide that drags the first
/// push's own frames off too; `PressJob::fit` in [`super::presses`]
/// weighs the cut.
pub(super) fn jumps(
    press: &[(usize, Update, f64)],
    alone: &[Option<Summary>],
    frames: &[SequenceFrame<'_>],
    link: LinkId,
) -> Vec<usize> {
    // Each frame's time and its own place on the link, if any.
    let own: Vec<(Option<f64>, Option<DVec3>)> = press
        .iter()
        .enumerate()
        .map(|(k, (i, update, _))| {
            let place = alone
                .get(k)
                .and_then(Option::as_ref)
                .filter(|s| s.refined && s.map.link == link)
                .and_then(|s| in_link_frame(update, link, s.map.point_world));
            (frames.get(*i).map(|f| f.t_secs), place)
        })
        .collect();
    // Each frame's jump: the medians' distance, where it clears the
    // threshold and the two sides' spreads.
    let widths: Vec<Option<(f64, DVec3, DVec3)>> = own
        .iter()
        .enumerate()
        .map(|(k, (t, _))| {
            let t = (*t)?;
            let (before, before_spread) = median_of(own.get(..k)?.iter().rev(), |s| t - s < JUMP_WINDOW_SECS)?;
            let (after, after_spread) = median_of(own.get(k..)?.iter(), |s| s - t < JUMP_WINDOW_SECS)?;
            let width = before.distance(after);
            (width >= JUMP_M && width >= JUMP_SPREADS * (before_spread + after_spread))
                .then_some((width, before, after))
        })
        .collect();
    // The widest jumps first; a jump within a window of one kept is the
    // same jump.
    let mut order: Vec<(usize, (f64, DVec3, DVec3))> = widths
        .iter()
        .enumerate()
        .filter_map(|(k, w)| Some((k, (*w)?)))
        .collect();
    order.sort_by(|a, b| b.1.0.total_cmp(&a.1.0).then(a.0.cmp(&b.0)));
    let time = |k: usize| own.get(k).and_then(|(t, _)| *t);
    let near = |j: usize, k: usize| match (time(j), time(k)) {
        (Some(a), Some(b)) => (a - b).abs() < JUMP_WINDOW_SECS,
        _ => true,
    };
    let mut found: Vec<usize> = Vec::new();
    for (k, (_, before, after)) in order {
        if found.iter().any(|&j| near(j, k)) {
            continue;
        }
        // The windows' medians are as far apart for every frame near the
        // step: the cut goes where the places nearby split best between
        // the two medians.
        let nearby: Vec<usize> = (0..own.len()).filter(|&j| near(j, k)).collect();
        let cost = |m: usize| -> f64 {
            nearby
                .iter()
                .filter_map(|&j| {
                    let place = own.get(j)?.1?;
                    Some(place.distance(if j < m { before } else { after }))
                })
                .sum()
        };
        let best = nearby
            .iter()
            .copied()
            .min_by(|&a, &b| cost(a).total_cmp(&cost(b)).then(a.abs_diff(k).cmp(&b.abs_diff(k))))
            .unwrap_or(k);
        found.push(best);
    }
    found.sort_unstable();
    found.dedup();
    found
}

/// The coordinate-wise median of the places of the frames `window` (each
/// frame's time and own place) taken in order: at least
/// [`ALTERNATIVE_MIN_FRAMES`] frames, then while their times pass
/// `within`; `None` where fewer than [`ALTERNATIVE_MIN_FRAMES`] of them
/// have a place, or the press ends within the window. A press's first
/// and last frames alone often stray while its push rises or falls (the
/// `../shared` two-contact example's link 5 probe: 5 cm in its first
/// three frames), and a piece that short is not a push of its own.
fn median_of<'a>(
    window: impl Iterator<Item = &'a (Option<f64>, Option<DVec3>)>,
    within: impl Fn(f64) -> bool,
) -> Option<(DVec3, f64)> {
    let mut points = Vec::new();
    let mut full = false;
    for (seen, (t, place)) in window.enumerate() {
        if seen >= ALTERNATIVE_MIN_FRAMES && !t.is_some_and(&within) {
            full = true;
            break;
        }
        points.extend(*place);
    }
    if !full || points.len() < ALTERNATIVE_MIN_FRAMES {
        return None;
    }
    let median = |values: &mut Vec<f64>| {
        values.sort_by(f64::total_cmp);
        values.get(values.len() / 2).copied()
    };
    let axis = |pick: fn(&DVec3) -> f64| median(&mut points.iter().map(pick).collect());
    let center = DVec3::new(axis(|p| p.x)?, axis(|p| p.y)?, axis(|p| p.z)?);
    let spread = median(&mut points.iter().map(|p| p.distance(center)).collect())?;
    Some((center, spread))
}

/// How many times the two sides' spreads (each the median distance of
/// its places from their median) a jump must be wide: along a link that
/// few joints pin, the frames alone scatter by centimetres from frame to
/// frame (`synth --contacts 2 --seed 4`, a link 5 press: 13–23 cm along
/// the link within 0.1 s), and a median of five of them moves as much.
pub const JUMP_SPREADS: f64 = 3.0;

/// How far a press's own places must jump (m) for [`jumps`] to cut it:
/// a slide of 0.1 m/s moves 5 mm in [`JUMP_WINDOW_SECS`], and a frame
/// alone strays by up to a few centimetres, which the medians ignore.
pub const JUMP_M: f64 = 0.05;

/// The window on either side of a jump (s) over which [`jumps`] takes the
/// places' median: five frames at 100 Hz (at lower rates,
/// [`ALTERNATIVE_MIN_FRAMES`] frames).
pub const JUMP_WINDOW_SECS: f64 = 0.05;

#[cfg(test)]
#[path = "jumps_tests.rs"]
mod tests;
