//! Where a press's fit starts besides the recording's places: groups of
//! its frames' own places that put it elsewhere, and its two rests.

use glam::DVec3;

use crate::core::estimate::estimator::Update;
use crate::core::estimate::press::FRICTION_GAIN;
use crate::core::estimate::summary::ContactEstimate;
use crate::core::robot::model::LinkId;

/// The starts of a press on `link` besides the recording's, from the
/// frames' own places `own`: the largest groups of them that place the
/// press elsewhere ([`MAX_ALTERNATIVES`]), and the press's two rests
/// ([`rests_at_ends`]).
pub(super) fn other_starts<'s>(
    press: &[(usize, Update, f64)],
    own: &[Option<&'s ContactEstimate>],
    link: LinkId,
) -> Vec<Start<'s>> {
    // The frames' own places, in groups (one link, within
    // `ALTERNATIVE_GROUP_M` of the group's first place in the link's
    // frame): a group is one coherent place for the whole press.
    let groups = groups_of(press, own);
    // A group on another link places every member elsewhere: its size says how many agree.
    let many = press.len().div_ceil(LINK_SWITCH_SHARE).max(ALTERNATIVE_MIN_FRAMES);
    let mut starts: Vec<Start> = Vec::new();
    for group in groups
        .iter()
        .filter(|g| g.members.len() >= ALTERNATIVE_MIN_FRAMES && g.apart >= ALTERNATIVE_MIN_FRAMES)
        .take(MAX_ALTERNATIVES)
    {
        let places = own_places(own, group.members.iter().copied());
        let gain = if group.link == link || group.members.len() >= many {
            FRICTION_GAIN
        } else {
            LINK_SWITCH_GAIN
        };
        starts.push(Start {
            link: group.link,
            places,
            between: Between::Nearest,
            gain,
        });
    }
    // The press's rests at its two ends, as its frames alone place
    // them, and a slide between: the slipping frames alone, whose drag
    // exceeds the friction cone, are placed centimetres off (see
    // [`rests_at_ends`]).
    let in_link: Vec<Option<DVec3>> = press
        .iter()
        .zip(own)
        .map(|((_, update, _), map)| in_link_frame(update, link, map.filter(|m| m.link == link)?.point_world))
        .collect();
    if let Some(pinned) = rests_at_ends(&in_link) {
        starts.push(Start {
            link,
            places: own_places(own, pinned.into_iter()),
            between: Between::Evenly,
            gain: FRICTION_GAIN,
        });
    }
    starts
}

/// Where a press's fit starts: on `link`, each frame at its place in
/// `places` where it has one on the link, the others as `between` says;
/// kept where it explains the press by `gain` better than the best so far.
pub(super) struct Start<'s> {
    pub(super) link: LinkId,
    pub(super) places: Vec<Option<&'s ContactEstimate>>,
    pub(super) between: Between,
    pub(super) gain: f64,
}

/// Where a frame without a place of its own starts ([`Start`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Between {
    /// At the place of the nearest frame with one.
    Nearest,
    /// Between two frames with one, moved evenly from the earlier's place
    /// to the later's (a slide between two rests); beyond them, at the
    /// nearest's.
    Evenly,
}

/// A start for a press that rests, slides and rests again: of the
/// frames' own places on the press's link (`in_link`, the link's frame,
/// in the press's order; `None` where a frame has none there), those
/// within [`END_REST_M`] of their medoid in the press's first and last
/// fifth, each to keep its own place (the fit moves the others evenly
/// from one rest to the next). `None` unless each end has
/// [`ALTERNATIVE_MIN_FRAMES`] such frames and the two rests lie
/// [`END_REST_M`] apart.
pub(super) fn rests_at_ends(in_link: &[Option<DVec3>]) -> Option<Vec<usize>> {
    let n = in_link.len();
    let width = (n / 5).max(ALTERNATIVE_MIN_FRAMES);
    if 2 * width > n {
        return None;
    }
    // The frames of `range` within END_REST_M of their medoid, and it.
    let rest = |range: std::ops::Range<usize>| -> Option<(Vec<usize>, DVec3)> {
        let points: Vec<(usize, DVec3)> = range.filter_map(|k| Some((k, (*in_link.get(k)?)?))).collect();
        let spread = |p: DVec3| points.iter().map(|(_, q)| p.distance(*q)).sum::<f64>();
        let medoid = points
            .iter()
            .map(|&(_, p)| p)
            .min_by(|a, b| spread(*a).total_cmp(&spread(*b)))?;
        let kept: Vec<usize> = points
            .iter()
            .filter(|(_, p)| p.distance(medoid) <= END_REST_M)
            .map(|&(k, _)| k)
            .collect();
        (kept.len() >= ALTERNATIVE_MIN_FRAMES).then_some((kept, medoid))
    };
    let (mut first, from) = rest(0..width)?;
    let (last, to) = rest(n - width..n)?;
    if from.distance(to) < END_REST_M {
        return None;
    }
    first.extend(last);
    Some(first)
}

/// The radius of a rest at a press's end (`rests_at_ends`), m: a few
/// millimetres of a frame alone's jitter.
pub const END_REST_M: f64 = 0.01;

/// The frames' own places `own` of `press`, in [`Group`]s, the largest
/// first.
fn groups_of(press: &[(usize, Update, f64)], own: &[Option<&ContactEstimate>]) -> Vec<Group> {
    let mut groups: Vec<Group> = Vec::new();
    for (k, ((_, update, _), map)) in press.iter().zip(own).enumerate() {
        let Some(map) = map else { continue };
        let Some(point) = in_link_frame(update, map.link, map.point_world) else {
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
    groups
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

/// The radius of a `Group`, m.
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

/// The drop in the press's cost (`-2 ln L`, see [`crate::core::estimate::press`])
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

/// The frames' own places `own` kept for the frames `members`, none for
/// the others.
fn own_places<'a>(
    own: &[Option<&'a ContactEstimate>],
    members: impl Iterator<Item = usize>,
) -> Vec<Option<&'a ContactEstimate>> {
    let mut places = vec![None; own.len()];
    for k in members {
        if let (Some(start), Some(map)) = (places.get_mut(k), own.get(k)) {
            *start = *map;
        }
    }
    places
}

/// `point_world` in `link`'s frame at `update`'s pose (a place persists
/// in its link's frame while the arm moves under it).
pub(super) fn in_link_frame(update: &Update, link: LinkId, point_world: DVec3) -> Option<DVec3> {
    let world_from_link = update.pose.world_from_link.get(link)?;
    Some(world_from_link.inverse().transform_point3(point_world))
}

#[cfg(test)]
#[path = "starts_tests.rs"]
mod tests;
