//! Runs of frames called two, carried into the frames beside them: the
//! arriving or leaving push's place held where the run has it, weighed
//! against one contact where it stood ([`carry_pairs`]).

use std::collections::BTreeMap;
use std::time::Instant;

use glam::DVec3;

use super::{SingleSeen, summary_only};
use crate::core::estimate::estimator::{Estimator, elapsed_ms};
use crate::core::estimate::pair::{HeldPush, PairContact, PairEstimate, PairSettings, Placed, Unidentifiable};
use crate::core::estimate::pair_held::HeldPair;
use crate::core::estimate::settings::EstimateError;
use crate::core::numerics::special::logistic;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{LinkId, Robot};

/// Each run of frames called two (`called`: by their own searches, or,
/// once the other passes are done, by them or carried) carried into the frames
/// before and after it that one contact explains (which were not
/// searched), a frame at a time while the pair stays the better account
/// there ([`carry_step`]); the frames it reaches get that account in
/// `found`, and each search's time is added to its frame's in
/// `search_ms`. Which frames it reached.
///
/// A second push that arrives or leaves gradually is weak in the frames
/// at either end of its run: one contact, shifted a little, explains
/// them within the noise, and a frame alone prices the second push's
/// place over the whole surface. With its place held near where the
/// frame beside has it ([`crate::core::estimate::pair_held`]) the pair
/// is the more probable account in some of them (`../shared` two-contact
/// example: 60 → 65 of its 83 frames where both press at surface seed 0,
/// the link-7 probe's push from 7.5 N on instead of 8.9 N).
pub(super) fn carry_pairs(
    estimator: &Estimator,
    robot: &Robot,
    (frames, singles): (&[SequenceFrame<'_>], &[Option<SingleSeen>]),
    pair_settings: &PairSettings,
    (found, search_ms): (&mut [Option<PairEstimate>], &mut [f64]),
    called: &[bool],
) -> Result<Vec<bool>, (usize, EstimateError)> {
    let n = found.len();
    let mut carried = vec![false; n];
    let is_called = |k: usize| called.get(k).copied().unwrap_or(false);
    for k in (0..n).filter(|&k| is_called(k)) {
        let first = k == 0 || !is_called(k - 1);
        let last = !is_called(k + 1);
        let established = (first || last) && called_span_secs(frames, called, k) >= ESTABLISHED_PAIR_SECS;
        for (backward, edge) in [(true, first), (false, last)] {
            if !edge {
                continue;
            }
            let Some(mut held) = found
                .get(k)
                .and_then(|p| p.as_ref())
                .map(|p| p.contacts.clone().map(|c| c.placed))
            else {
                continue;
            };
            // Beside an established pair, the single contact the frames
            // beyond the edge hold says which contact stays (the one on
            // its link, nearer its place) and where one contact stood.
            let anchor = if established {
                anchor_push(frames, singles, k, backward)
            } else {
                None
            };
            // Else the run's edge puts the contact nearer its single
            // contact first: the other is the one that arrives or leaves.
            let mut new = anchor.map_or(1, |a| {
                let off = |p: &Placed| off_place(p, a.push.link, a.push.point_in_link);
                usize::from(off(&held[0]) <= off(&held[1]))
            });
            let mut j = k;
            while let Some(next) = if backward {
                j.checked_sub(1)
            } else {
                Some(j + 1).filter(|&x| x < n)
            } {
                if is_called(next) || carried.get(next).copied().unwrap_or(true) {
                    break;
                }
                let (Some(frame), Some(Some(single))) = (frames.get(next), singles.get(next)) else {
                    break;
                };
                let own_log_ratio = found
                    .get(next)
                    .and_then(|p| p.as_ref())
                    .map(PairEstimate::log_evidence_ratio);
                let t0 = Instant::now();
                let step = carry_step(
                    estimator,
                    robot,
                    frame,
                    (single, own_log_ratio),
                    pair_settings,
                    (&held, new),
                    if established {
                        Beside::Established {
                            anchor: anchor.as_ref(),
                        }
                    } else {
                        Beside::Short
                    },
                )
                .map_err(|e| (next, e))?;
                if let Some(ms) = search_ms.get_mut(next) {
                    *ms += elapsed_ms(t0);
                }
                let Some((mut account, now_new)) = step else {
                    break;
                };
                held = account.contacts.clone().map(|c| c.placed);
                new = now_new;
                summary_only(&mut account);
                if let (Some(slot), Some(c)) = (found.get_mut(next), carried.get_mut(next)) {
                    *slot = Some(account);
                    *c = true;
                }
                j = next;
            }
        }
    }
    Ok(carried)
}

/// The pair `held` (`held[new]` the contact that arrives or leaves)
/// carried into `frame`, whose single contact is `single` and whose own
/// search's `ln Z₂/Z₁` is `own_log_ratio` (`None`: not searched): its
/// account there and which of its contacts is the new one, or `None`
/// where it is not kept. Kept where one contact explains the frame (a
/// frame searched has its own pair and rules: a slide that drags beyond
/// the friction cone is a pair there, 30–120 nats above one contact
/// within the cone, that the push held before explains), or, beside an
/// established pair, where the frame's own search found two more
/// probable than one; where its contacts are `held`'s, each
/// within the separation, and the pair is the better account of the
/// frame: as [`held_pair_log_ratio`] weighs it beside a pair the frames
/// have established ([`Beside`]), else
/// - the pair is more probable than one contact, and identifiable but
///   for one of its pushes alone explaining the torques within the noise
///   (a χ² threshold, as [`bridged`] reads it);
/// - it explains the torques better than the session's own single
///   contact here, its push as smoothed (kinetic friction and all), by
///   more than the new contact's Occam factor and the prior odds of two
///   (a frame alone weighs the pair against one contact within a static
///   friction cone: on a generated link 7 slide drawn with
///   `--avoid-covered`, seed 2, 21 frames beside a false pair were
///   carried before this, 5 after).
fn carry_step(
    estimator: &Estimator,
    robot: &Robot,
    frame: &SequenceFrame<'_>,
    (single, own_log_ratio): (&SingleSeen, Option<f64>),
    pair_settings: &PairSettings,
    (held, new): (&[Placed; 2], usize),
    beside: Beside<'_>,
) -> Result<Option<(PairEstimate, usize)>, EstimateError> {
    // A frame searched on its own is carried into only beside an
    // established pair, and only where its own pair is already more
    // probable than one contact anywhere (it fails an identifiability
    // rule that the run beside has settled).
    let searched_and_two = matches!(beside, Beside::Established { .. }) && own_log_ratio.is_some_and(|r| r > 0.0);
    if !single.explained && !searched_and_two {
        return Ok(None);
    }
    let Some(HeldPair {
        mut account,
        new_log_occam,
    }) = estimator.pair_held_at(robot, frame.joint_positions, frame.tau, pair_settings, held, new)?
    else {
        return Ok(None);
    };
    // The new contact is the one nearer where it was.
    let now_new = held.get(new).map_or(1, |before| {
        let off = |p: &Placed| off_place(p, before.link, before.point_in_link);
        let [a, b] = account.contacts.each_ref().map(|c| &c.placed);
        usize::from(off(b) < off(a))
    });
    let prior_log_odds = pair_settings.prior_two.ln() - (-pair_settings.prior_two).ln_1p();
    let kept = if let Beside::Established { anchor } = beside {
        // The frame's own single contact is one contact where it stood
        // if it stands as near the anchor as the frames beyond did.
        let own_single = single.push.filter(|p| {
            single.explained
                && anchor.is_some_and(|a| {
                    a.push.link == p.link && a.push.point_in_link.distance(p.point_in_link) <= a.radius_m
                })
        });
        let anchors = [anchor.map(|a| &a.push), own_single.as_ref()];
        let Some(log_ratio) = held_pair_log_ratio(estimator, robot, frame, &account, new_log_occam, anchors) else {
            return Ok(None);
        };
        // The account says so (the chain over the frames weighs this
        // frame by the same ratio).
        account.log_evidence_one = account.log_evidence_two - log_ratio;
        account.probability_two = logistic(log_ratio + prior_log_odds);
        log_ratio + prior_log_odds > 0.0
            && matches!(
                account.unidentifiable,
                None | Some(Unidentifiable::OneExplains | Unidentifiable::Unconfirmed)
            )
    } else {
        let beats_push = single
            .push
            .and_then(|h| estimator.held_push_chi2(robot, frame.joint_positions, frame.tau, &h))
            .is_none_or(|chi2_push| 0.5 * (chi2_push - account.residual_chi2) + new_log_occam + prior_log_odds > 0.0);
        account.probability_two > 0.5
            && beats_push
            && matches!(account.unidentifiable, None | Some(Unidentifiable::OneExplains))
    };
    Ok((kept && same_places(&account, held, pair_settings.separation_m)).then_some((account, now_new)))
}

/// What a run of frames called two is, for the frames beside it.
#[derive(Debug, Clone, Copy)]
enum Beside<'a> {
    /// Shorter than [`ESTABLISHED_PAIR_SECS`].
    Short,
    /// As long or longer, with the single contact that the frames beyond
    /// its edge hold ([`anchor_push`]), where any.
    Established { anchor: Option<&'a Anchor> },
}

/// `ln Z₂/Z₁` of a frame beside a pair the frames have established, the
/// new contact paying its Occam factor near where it was
/// (`new_log_occam`), with one contact meaning the better of: either of
/// the pair's contacts alone, held where the pair has it and pushing
/// the way it pushes there (its magnitude fitted: the pair with the
/// other push taken away); and each of `anchors`, single contacts where
/// one contact stood (the frames beyond the run's edge, [`anchor_push`],
/// and the frame's own where it stands as near), pushing the way they
/// pushed there. `None` where no such push can be fitted.
///
/// A frame alone weighs the pair against one contact anywhere, and a
/// single contact free to move takes up a second push of a few newtons
/// by drifting along its link: on the `../shared` two-contact example
/// the link-5 probe's place drifts 7 → 21 mm while the link-7 probe's
/// push rises to 7 N, and no frame of the rise was called two. But the
/// frames before and after say where the first contact is, and it does
/// not move by centimetres in the 50 ms a rise takes. The anchor keeps
/// a pair whose staying contact the search moved off its place from
/// winning by that shift alone: on a generated two-hand session
/// (`synth --contacts 2 --avoid-covered --seed 1`) the pair's link-5
/// contact sat 7–24 mm off a held press that the single contact placed
/// within 1 mm, and its extra 1–2 N on link 7 was carried into 35 of the
/// 195 frames where one hand presses; with the anchors, none.
pub(super) fn held_pair_log_ratio(
    estimator: &Estimator,
    robot: &Robot,
    frame: &SequenceFrame<'_>,
    account: &PairEstimate,
    new_log_occam: f64,
    anchors: [Option<&HeldPush>; 2],
) -> Option<f64> {
    let pose = RobotPose::new(robot, frame.joint_positions);
    let chi2 = |held: &HeldPush| estimator.held_push_chi2(robot, frame.joint_positions, frame.tau, held);
    let alone = |contact: &PairContact| {
        let link_from_world = pose.world_from_link.get(contact.placed.link)?.inverse();
        chi2(&HeldPush {
            link: contact.placed.link,
            point_in_link: contact.placed.point_in_link,
            force_in_link: link_from_world.transform_vector3(contact.force_world),
        })
    };
    let [a, b] = account.contacts.each_ref().map(alone);
    let chi2_one = a
        .into_iter()
        .chain(b)
        .chain(anchors.into_iter().flatten().filter_map(chi2))
        .reduce(f64::min)?;
    Some(0.5 * (chi2_one - account.residual_chi2) + new_log_occam)
}

/// Where one contact stood beyond the edge of a run of frames called two.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Anchor {
    /// The single contact there ([`anchor_push`]).
    pub(super) push: HeldPush,
    /// Its sample and magnitude, N.
    pub(super) seen: (usize, f64),
    /// How far the single contacts there stood from it, m: four in five
    /// within this.
    pub(super) radius_m: f64,
}

/// How far beyond a run's edge, s, the frames that say where its staying
/// contact stood alone are read ([`anchor_push`]).
const ANCHOR_SECS: f64 = 0.5;

/// The single contact that the frames beyond the edge `k` of a run of
/// frames called two (before it where `backward`) hold where one contact
/// explains them, within [`ANCHOR_SECS`] of the edge and up to the first
/// frame without contact: of the pushes on the link most of them are
/// on, the one whose place is nearest the others' (their medoid: a
/// contact that drifts while a second push rises, or stands off for a
/// frame, is outvoted by the frames where it stood), and how far four in
/// five of them stand from it; `None` where no such frame is.
pub(super) fn anchor_push(
    frames: &[SequenceFrame<'_>],
    singles: &[Option<SingleSeen>],
    k: usize,
    backward: bool,
) -> Option<Anchor> {
    let t_edge = frames.get(k)?.t_secs;
    let mut pushes = Vec::new();
    let mut j = k;
    while let Some(next) = if backward {
        j.checked_sub(1)
    } else {
        Some(j + 1).filter(|&x| x < frames.len())
    } {
        let (Some(frame), Some(Some(single))) = (frames.get(next), singles.get(next)) else {
            break;
        };
        if (frame.t_secs - t_edge).abs() > ANCHOR_SECS {
            break;
        }
        if single.explained
            && let Some(push) = single.push
        {
            pushes.push((push, (single.point, single.force_newtons)));
        }
        j = next;
    }
    let mut counts: BTreeMap<LinkId, usize> = BTreeMap::new();
    for (push, _) in &pushes {
        *counts.entry(push.link).or_default() += 1;
    }
    let link = counts.iter().max_by_key(|&(_, n)| *n).map(|(&link, _)| link)?;
    pushes.retain(|(p, _)| p.link == link);
    pushes
        .iter()
        .map(|(p, seen)| {
            let spread: f64 = pushes
                .iter()
                .map(|(q, _)| q.point_in_link.distance(p.point_in_link))
                .sum();
            (spread, p, seen)
        })
        .min_by(|a, b| a.0.total_cmp(&b.0))
        .map(|(_, p, &seen)| {
            let mut off: Vec<f64> = pushes
                .iter()
                .map(|(q, _)| q.point_in_link.distance(p.point_in_link))
                .collect();
            off.sort_by(f64::total_cmp);
            let at = (off.len().saturating_sub(1) * 4 + 2) / 5;
            Anchor {
                push: *p,
                seen,
                radius_m: off.get(at).copied().unwrap_or(0.0),
            }
        })
}

/// Frames called two this close together, s, are one run for
/// [`ESTABLISHED_PAIR_SECS`]: a run's own search leaves a frame or a few
/// uncalled now and then (the `../shared` two-contact example's first run
/// is five frames, then two carried, then 55 called). With 15 ms, surface
/// seeds 3, 6, 7 and 9 of that example gain nothing (61, 65, 61 and 62 of
/// its 83 frames where both press, against 75, 70, 63 and 72), and with
/// 20 ms seed 4 (61, against 72: its first run ends 25 ms before the
/// next begins).
const PAIR_RUN_GAP_SECS: f64 = 0.025;

/// A run of frames called two that spans this long or longer, s, has
/// established its pair: in the frames beside it the pair is weighed
/// against its other contact held where it is
/// ([`held_pair_log_ratio`]). The false pairs of one-contact sessions
/// come in runs of up to 60 ms (a generated link 7 slide drawn with
/// `--avoid-covered`, seed 2: runs of 5–60 ms); carried so beside them,
/// they went from 37 to 73 of its 528 one-press frames.
const ESTABLISHED_PAIR_SECS: f64 = 0.1;

/// Stamps' rounding, s.
const RUN_TOLERANCE_SECS: f64 = 1e-9;

/// The span, s, of the run of frames called two that holds frame `k`,
/// gaps of up to [`PAIR_RUN_GAP_SECS`] between its called frames
/// included.
fn called_span_secs(frames: &[SequenceFrame<'_>], called: &[bool], k: usize) -> f64 {
    let time = |i: usize| frames.get(i).map(|f| f.t_secs);
    let is_called = |i: usize| called.get(i).copied().unwrap_or(false);
    let Some(t_k) = time(k) else {
        return 0.0;
    };
    let reach = PAIR_RUN_GAP_SECS + RUN_TOLERANCE_SECS;
    let (mut first, mut i) = (t_k, k);
    while let Some(t) = i.checked_sub(1).and_then(time) {
        if first - t > reach {
            break;
        }
        i -= 1;
        if is_called(i) {
            first = t;
        }
    }
    let (mut last, mut i) = (t_k, k);
    while let Some(t) = time(i + 1) {
        if t - last > reach {
            break;
        }
        i += 1;
        if is_called(i) {
            last = t;
        }
    }
    last - first
}

/// How far `placed` is from `point_in_link` on `link`, m (infinite on
/// another link).
pub(super) fn off_place(placed: &Placed, link: LinkId, point_in_link: DVec3) -> f64 {
    if placed.link == link {
        placed.point_in_link.distance(point_in_link)
    } else {
        f64::INFINITY
    }
}

/// Whether `account`'s contacts are `held`'s: each on the same link as
/// one of them, within `separation_m`.
fn same_places(account: &PairEstimate, held: &[Placed; 2], separation_m: f64) -> bool {
    let near = |a: &Placed, b: &Placed| a.link == b.link && a.point_in_link.distance(b.point_in_link) < separation_m;
    let [a, b] = account.contacts.each_ref().map(|c| &c.placed);
    let [c, d] = held;
    (near(a, c) && near(b, d)) || (near(a, d) && near(b, c))
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;

    /// Frames at 200 Hz from 0 s, called two where `called` says.
    fn span_at(called: &[bool], k: usize) -> f64 {
        let frames: Vec<SequenceFrame<'_>> = (0..called.len())
            .map(|i| SequenceFrame {
                t_secs: 0.005 * i as f64,
                joint_positions: &[],
                tau: &[],
            })
            .collect();
        called_span_secs(&frames, called, k)
    }

    #[test]
    fn a_run_spans_gaps_of_up_to_twenty_five_milliseconds() {
        // Called at 0–4, 9–20 (9 is 25 ms after 4), 27 (35 ms after 20).
        let called: Vec<bool> = (0..30).map(|i| i <= 4 || (9..=20).contains(&i) || i == 27).collect();
        for k in [0, 4, 9, 20] {
            assert!((span_at(&called, k) - 0.1).abs() < 1e-9, "{k}: {}", span_at(&called, k));
        }
        assert!(span_at(&called, 27).abs() < 1e-12);
        // A lone called frame spans nothing; one out of range, nothing.
        assert!(span_at(&[false, true, false], 1).abs() < 1e-12);
        assert!(span_at(&[true], 5).abs() < 1e-12);
    }

    #[test]
    fn only_a_run_of_a_tenth_of_a_second_is_established() {
        let run = |frames: usize| -> Vec<bool> { (0..40).map(|i| (5..5 + frames).contains(&i)).collect() };
        // 21 frames at 200 Hz span 0.1 s; 20 span 0.095 s.
        assert!(span_at(&run(21), 5) >= ESTABLISHED_PAIR_SECS);
        assert!(span_at(&run(20), 5) < ESTABLISHED_PAIR_SECS);
    }

    /// Frames at 200 Hz from 0 s.
    pub(in crate::batch::pairs) fn frames_at_200_hz(n: usize) -> Vec<SequenceFrame<'static>> {
        (0..n)
            .map(|i| SequenceFrame {
                t_secs: 0.005 * i as f64,
                joint_positions: &[],
                tau: &[],
            })
            .collect()
    }

    /// A single contact on `link` at `x` m along its x axis, explained.
    pub(in crate::batch::pairs) fn seen_at(link: LinkId, x: f64) -> SingleSeen {
        SingleSeen {
            point: 0,
            force_newtons: 10.0,
            explained: true,
            push: Some(HeldPush {
                link,
                point_in_link: DVec3::new(x, 0.0, 0.0),
                force_in_link: DVec3::new(0.0, 0.0, -10.0),
            }),
        }
    }

    #[test]
    fn where_one_contact_stood_is_read_from_most_frames_beyond_the_edge() {
        let frames = frames_at_200_hz(200);
        // A press on link 5 at 0.02 m from frame 10, drifting from frame
        // 60 while a second push rises; the run called two begins at 80,
        // and its frames' singles are on link 7.
        let singles: Vec<Option<SingleSeen>> = (0..200)
            .map(|i| match i {
                0..10 => None,
                10..60 => Some(seen_at(5, 0.02)),
                60..80 => Some(seen_at(5, 0.02 + 0.001 * f64::from(i - 59))),
                _ => Some(seen_at(7, 0.0)),
            })
            .collect();
        let anchor = anchor_push(&frames, &singles, 80, true).unwrap();
        assert_eq!(anchor.push.link, 5);
        assert!((anchor.push.point_in_link.x - 0.02).abs() < 1e-12, "{anchor:?}");
        // Of the 70 frames within half a second before frame 80 (10–79),
        // 50 stand at 0.02 m and 20 drift 1–20 mm: four in five within
        // 6 mm (of the 70 distances sorted, the one at 69 × 4/5 = 55.2,
        // rounded: 55, 0-based).
        assert!((anchor.radius_m - 0.006).abs() < 1e-12, "{anchor:?}");
        // After the run's edge at 120: link 7, the frames beyond.
        assert_eq!(anchor_push(&frames, &singles, 120, false).unwrap().push.link, 7);
    }

    #[test]
    fn where_one_contact_stood_stops_at_a_frame_without_contact_and_half_a_second_out() {
        let frames = frames_at_200_hz(300);
        // No contact at 50: nothing before it is read from the edge at 60.
        let mut singles: Vec<Option<SingleSeen>> = (0..300).map(|_| Some(seen_at(5, 0.03))).collect();
        singles[50] = None;
        for single in singles.iter_mut().take(50) {
            *single = Some(seen_at(6, 0.0));
        }
        assert_eq!(anchor_push(&frames, &singles, 60, true).unwrap().push.link, 5);
        // Frames not explained by their single contact are not read.
        for single in singles.iter_mut().skip(51).take(9).flatten() {
            single.explained = false;
        }
        assert!(anchor_push(&frames, &singles, 60, true).is_none());
        // Beyond half a second (100 frames) from the edge, frames are not
        // read: link 6 at 120–199 outnumbers link 5 within it from the
        // edge at 230 (70 to 30), not from the edge at 299 (1 to 99).
        for single in singles.iter_mut().skip(120).take(80) {
            *single = Some(seen_at(6, 0.0));
        }
        assert_eq!(anchor_push(&frames, &singles, 299, true).unwrap().push.link, 5);
        assert_eq!(anchor_push(&frames, &singles, 230, true).unwrap().push.link, 6);
    }
}
