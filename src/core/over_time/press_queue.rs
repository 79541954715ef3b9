//! A smoothed session's presses on their way to their fit: the frames of
//! one press held until it ends, and a press fitted whole or in pieces
//! (at a hop to another link, a jump of its own places, or its length).

use std::time::Instant;

use rayon::prelude::*;

use glam::DVec3;

use crate::core::estimate::estimator::{Estimator, Update, elapsed_ms, is_pressed};
use crate::core::estimate::explain::MIN_SLIDE_M;
use crate::core::estimate::press::FRICTION_GAIN;
use crate::core::estimate::summary::Summary;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::over_time::jumps::jumps;
use crate::core::over_time::presses::{Fitted, PRESS_MISFIT_MARGIN};
use crate::core::over_time::starts::in_link_frame;
use crate::core::robot::model::{LinkId, Robot};

/// While smoothing with contacts placed on the continuous surface, a
/// press's frames wait for its end: the press is fitted as a whole (with
/// friction) and checked against its frames' own contacts (see
/// [`Estimator::settle_press`]).
pub(crate) struct PressQueue<'a> {
    context: PressContext<'a>,
    /// The press so far: frame number, update, milliseconds it cost.
    held: Vec<(usize, Update, f64)>,
    /// Each held frame's summary from its own posterior alone.
    alone: Vec<Option<Summary>>,
    /// Frames pressed on another link right after the press held, while
    /// they may be a hop the press bridges ([`PRESS_BRIDGE_SECS`]).
    bridge: Vec<Bridged>,
    /// The longest hop each link allows on either side of it, s
    /// ([`bridge_secs`]), by [`LinkId`].
    bridge_secs: Vec<f64>,
}

/// A frame waiting to be bridged: frame number, its update and own
/// summary, milliseconds it cost.
type Bridged = (usize, (Update, Option<Summary>), f64);

/// A press's frame out of its fit: frame number, update, milliseconds.
type FrameOut = (usize, Update, f64);

impl<'a> PressQueue<'a> {
    /// An empty queue for `frames`, with the temporal model's slide length.
    pub(crate) fn new(
        estimator: &'a Estimator,
        robot: &'a Robot,
        frames: &'a [SequenceFrame<'a>],
        slide_m_per_sqrt_s: f64,
    ) -> Self {
        Self {
            context: PressContext {
                estimator,
                robot,
                frames,
                slide_m_per_sqrt_s,
            },
            held: Vec::new(),
            alone: Vec::new(),
            bridge: Vec::new(),
            bridge_secs: (0..robot.links.len()).map(|link| bridge_secs(robot, link)).collect(),
        }
    }

    /// Frame `i`'s `update`: handed on to `each` at once, or held while it
    /// continues a press (one link, consecutive frames, a hop to another
    /// link bridged where it is shorter than [`bridge_secs`] says of every
    /// link on either side); a press that ends is handed on as a
    /// [`PressJob`] to fit.
    pub(crate) fn offer(
        &mut self,
        i: usize,
        (update, alone): (Update, Option<Summary>),
        cost_ms: f64,
        each: &mut impl FnMut(Offered<'a>),
    ) {
        if !self.context.estimator.uses_patches() {
            each(Offered::Frame(i, update, cost_ms));
            return;
        }
        let in_press = is_pressed(&update);
        let last = self
            .bridge
            .last()
            .map(|(j, _, _)| *j)
            .or(self.held.last().map(|(j, _, _)| *j));
        let held_link = self.held.first().map(|(_, u, _)| u.summary.map.link);
        if in_press && last.is_some_and(|j| j + 1 == i) && self.held.len() + self.bridge.len() < MAX_PRESS_FRAMES {
            if held_link == Some(update.summary.map.link) {
                // Back on the press's link: the hop between joins the press.
                for (j, (hop, hop_alone), ms) in self.bridge.drain(..) {
                    self.held.push((j, hop, ms));
                    self.alone.push(hop_alone);
                }
                self.held.push((i, update, cost_ms));
                self.alone.push(alone);
                return;
            }
            let t = |k: usize| self.context.frames.get(k).map(|f| f.t_secs);
            let first = self.bridge.first().map_or(i, |(j, _, _)| *j);
            // Every link on either side of the hop must allow its length.
            let longest_secs = std::iter::once(update.summary.map.link)
                .chain(held_link)
                .chain(self.bridge.iter().map(|(_, (u, _), _)| u.summary.map.link))
                .map(|link| self.bridge_secs.get(link).copied().unwrap_or(PRESS_BRIDGE_SECS))
                .fold(LONG_BRIDGE_SECS, f64::min);
            if let (Some(from), Some(to)) = (t(first), t(i))
                && to - from < longest_secs
            {
                self.bridge.push((i, (update, alone), cost_ms));
                return;
            }
        }
        // The press ends; a hop that did not return is offered afresh,
        // then this frame.
        self.settle_held(each);
        if self.offer_hop_again(each) {
            self.offer(i, (update, alone), cost_ms, each);
        } else if in_press {
            self.held.push((i, update, cost_ms));
            self.alone.push(alone);
        } else {
            each(Offered::Frame(i, update, cost_ms));
        }
    }

    /// Hands on the press held and any hop after it, if any.
    pub(crate) fn settle(&mut self, each: &mut impl FnMut(Offered<'a>)) {
        // A hop offered again may leave a shorter hop of its own.
        loop {
            self.settle_held(each);
            if !self.offer_hop_again(each) {
                return;
            }
        }
    }

    /// Offers the frames of a hop the press did not come back from
    /// afresh (each may start a press); whether there were any.
    fn offer_hop_again(&mut self, each: &mut impl FnMut(Offered<'a>)) -> bool {
        let hop = std::mem::take(&mut self.bridge);
        let any = !hop.is_empty();
        for (j, frame, ms) in hop {
            self.offer(j, frame, ms, each);
        }
        any
    }

    /// Hands on the press held, if any, as a [`PressJob`].
    fn settle_held(&mut self, each: &mut impl FnMut(Offered<'a>)) {
        if self.held.is_empty() {
            self.alone.clear();
            return;
        }
        each(Offered::Press(PressJob {
            context: self.context,
            held: std::mem::take(&mut self.held),
            alone: std::mem::take(&mut self.alone),
        }));
    }
}

/// What a [`PressQueue`] hands on, in frame order: a frame settled now,
/// or a press to fit (on any thread), whose frames come out of its fit.
// Handed straight to a closure and taken apart there, never stored: a
// frame's update moves as it is, without a box of its own.
#[allow(clippy::large_enum_variant)]
pub(crate) enum Offered<'a> {
    /// Frame number, its update, milliseconds it cost.
    Frame(usize, Update, f64),
    /// A press's frames, to fit as a whole.
    Press(PressJob<'a>),
}

/// A press's frames waiting for their fit ([`Estimator::settle_press`]):
/// it depends on nothing but its own frames, so it runs beside the rest.
pub(crate) struct PressJob<'a> {
    context: PressContext<'a>,
    held: Vec<(usize, Update, f64)>,
    alone: Vec<Option<Summary>>,
}

/// What a press's fit reads besides its frames.
#[derive(Clone, Copy)]
struct PressContext<'a> {
    estimator: &'a Estimator,
    robot: &'a Robot,
    frames: &'a [SequenceFrame<'a>],
    /// The temporal model's slide length, m/√s.
    slide_m_per_sqrt_s: f64,
}

impl PressJob<'_> {
    /// Bytes its frames' posteriors hold while it is fitted: twice over
    /// for a press in pieces, one that bridged a hop or is longer than
    /// [`PRESS_PIECE_FRAMES`] (its whole fit works on a copy),
    /// and twice that again for a press that jumps (fitted whole and side
    /// by side).
    pub(crate) fn bytes(&self) -> usize {
        let once: usize = self
            .held
            .iter()
            .map(|(_, update, _)| size_of::<Update>() + update.posterior.bytes())
            .sum();
        let bridged = if self.pieces().len() > 1 { 2 } else { 1 };
        let jumped = if self.cuts().is_empty() { 1 } else { 2 };
        bridged * jumped * once
    }

    /// Where the press's frames' own places jump ([`jumps`]), on the
    /// press's link.
    fn cuts(&self) -> Vec<usize> {
        self.held
            .first()
            .map(|(_, first, _)| jumps(&self.held, &self.alone, self.context.frames, first.summary.map.link))
            .unwrap_or_default()
    }

    /// Fits the press: its frames in order, each with its update and
    /// milliseconds (its share of the fit included). Where its frames'
    /// own places jump ([`jumps`]), the press is also fitted side by side
    /// (each side a press of its own), and the sides are kept where the
    /// whole's fit misses some side's frames by more than
    /// [`JUMP_MISFIT_PER_FRAME`] a frame (plus [`PRESS_MISFIT_MARGIN`])
    /// beyond that side's own fit. Where a second push joins or leaves,
    /// one fit across the jump bridges the two places by a slide that
    /// drags the frames on either side off (`synth --contacts 2 --seed 2`,
    /// the link 4 hand alone 26–80 mm off whole, 0 mm cut). Not the
    /// sides' summed cost against the whole's, as a hop's pieces are
    /// weighed: where the second push joins, the frames after the jump
    /// explain neither one place nor a slide, and their cost says nothing
    /// of the cut (`synth --contacts 2 --seed 4`: a 4-frame side at
    /// 64,000). Nor the cut at every jump: a slip's frames alone jump too
    /// (the drag outside their friction cone), and its whole fit is the
    /// better one (generated link 5 slides, seed 1: 2.1 → 10.4 mm cut).
    pub(crate) fn fit(self) -> Vec<(usize, Update, f64)> {
        let cuts = self.cuts();
        if cuts.is_empty() {
            return self.fit_side();
        }
        let whole = self.clone_job();
        let sides = self.split_at(&cuts);
        let ((whole, whole_ms), (sides, sides_ms)) = timed_join(
            || whole.fit_side(),
            || sides.into_par_iter().map(PressJob::fit_side).collect::<Vec<_>>(),
        );
        // The cut is kept where the whole's fit misses one side's frames
        // by far more than that side's own fit does.
        let chi2 =
            |frames: &[FrameOut]| -> f64 { frames.iter().map(|(_, u, _)| u.summary.fit.best_residual_chi2).sum() };
        let mut start = 0;
        let mut cut = false;
        for side in &sides {
            let n = side.len();
            let excess = whole.get(start..start + n).map_or(0.0, chi2) - chi2(side);
            cut |= excess > JUMP_MISFIT_PER_FRAME * n as f64 + PRESS_MISFIT_MARGIN;
            start += n;
        }
        if cut {
            with_share(sides.into_iter().flatten().collect(), whole_ms)
        } else {
            with_share(whole, sides_ms)
        }
    }

    /// [`PressJob::fit`] for a press without a jump. A press that bridged
    /// a hop to another link ([`PRESS_BRIDGE_SECS`]) is also fitted piece
    /// by piece (each run of frames on one link on its own, as without
    /// the bridge), and kept whole where its fit stays on the press's link
    /// and costs no more than the pieces' sum plus [`FRICTION_GAIN`] a
    /// piece beyond the first (each piece brings a force and a friction
    /// of its own). A whole fit that leaves the link says the hop was not
    /// one: on the `../shared` link 6 slide the smoother's hops back to
    /// link 6 are the truth, and the whole press they bridge on link 7
    /// moves to link 5, 130 mm off (`docs/decisions.md`, *A press across
    /// a hop*). A press longer than [`PRESS_PIECE_FRAMES`] is also cut
    /// into pieces of that length, and kept whole only where kinetic
    /// friction explains it whole as well.
    fn fit_side(self) -> Vec<(usize, Update, f64)> {
        let pieces = self.pieces();
        if pieces.len() < 2 {
            return self.fit_whole().0;
        }
        let press_link = self.held.first().map(|(_, u, _)| u.summary.map.link);
        let long = self.held.len() > PRESS_PIECE_FRAMES;
        // A long press whose places stay within the shortest slide cannot
        // be kept whole: its pieces alone.
        if long && !self.places_spread() {
            return self.fit_apart(&pieces).0;
        }
        let whole = self.clone_job();
        // The two fits do not depend on each other.
        let ((whole, whole_ms), (apart, apart_ms)) = timed_join(|| whole.fit_whole(), || self.fit_apart(&pieces));
        let extra = (pieces.len() - 1) as f64 * FRICTION_GAIN;
        let keep_whole = match (whole.1, apart.1) {
            (Some(fitted), _) if Some(fitted.link) != press_link || (long && !fitted.slides) => false,
            (Some(fitted), Some(apart_cost)) => fitted.cost <= apart_cost + extra,
            (whole_fit, _) => whole_fit.is_some(),
        };
        log::debug!(
            "press of {} frames from frame {}: whole {:?}, {} pieces {:?}: {}",
            whole.0.len(),
            whole.0.first().map_or(0, |(i, _, _)| *i),
            whole.1.map(|f| (f.cost.round(), f.slides)),
            pieces.len(),
            apart.1.map(f64::round),
            if keep_whole { "whole" } else { "pieces" }
        );
        if keep_whole {
            with_share(whole.0, apart_ms)
        } else {
            with_share(apart.0, whole_ms)
        }
    }

    /// The press fitted piece by piece (`pieces` as [`PressJob::pieces`]
    /// gives them): every frame in order, and the pieces' summed cost
    /// (`None` where a piece keeps its estimates).
    fn fit_apart(self, pieces: &[usize]) -> (Vec<FrameOut>, Option<f64>) {
        let fits: Vec<_> = self
            .split_at(pieces.get(1..).unwrap_or_default())
            .into_iter()
            .map(PressJob::fit_whole)
            .collect();
        let cost: Option<f64> = fits.iter().map(|(_, fitted)| fitted.map(|f| f.cost)).sum();
        let frames: Vec<FrameOut> = fits.into_iter().flat_map(|(frames, _)| frames).collect();
        (frames, cost)
    }

    /// Whether the recording's places on the press's link spread over the
    /// shortest slide kinetic friction may explain or more (their farthest
    /// from the first, in the link's frame).
    fn places_spread(&self) -> bool {
        let Some(link) = self.held.first().map(|(_, u, _)| u.summary.map.link) else {
            return false;
        };
        let places: Vec<DVec3> = self
            .held
            .iter()
            .filter(|(_, u, _)| u.summary.map.link == link)
            .filter_map(|(_, u, _)| in_link_frame(u, link, u.summary.map.point_world))
            .collect();
        places
            .first()
            .is_some_and(|&first| places.iter().any(|p| p.distance(first) >= MIN_SLIDE_M))
    }

    /// A copy of the press, to fit beside itself.
    fn clone_job(&self) -> Self {
        PressJob {
            context: self.context,
            held: self.held.clone(),
            alone: self.alone.clone(),
        }
    }

    /// The press cut before each frame of `starts` (increasing, each past
    /// the first frame): its pieces in order.
    fn split_at(mut self, starts: &[usize]) -> Vec<Self> {
        let mut jobs = Vec::with_capacity(starts.len() + 1);
        for &start in starts.iter().rev() {
            jobs.push(PressJob {
                context: self.context,
                held: self.held.split_off(start),
                alone: self.alone.split_off(start.min(self.alone.len())),
            });
        }
        jobs.push(self);
        jobs.reverse();
        jobs
    }

    /// Where each piece of the press starts (the first at 0): each run of
    /// frames on one link, cut again every [`PRESS_PIECE_FRAMES`] frames.
    fn pieces(&self) -> Vec<usize> {
        let mut starts = Vec::new();
        let mut last = None;
        let mut run_start = 0;
        for (k, (_, update, _)) in self.held.iter().enumerate() {
            let link = update.summary.map.link;
            if last != Some(link) {
                run_start = k;
                last = Some(link);
            }
            if (k - run_start) % PRESS_PIECE_FRAMES == 0 {
                starts.push(k);
            }
        }
        starts
    }

    /// The press fitted whole: its frames in order, the fit's cost and
    /// link (`None` where it keeps its estimates).
    fn fit_whole(mut self) -> (Vec<FrameOut>, Option<Fitted>) {
        let mut out = Vec::with_capacity(self.held.len());
        let c = self.context;
        let cost = c.estimator.settle_press(
            c.robot,
            c.frames,
            c.slide_m_per_sqrt_s,
            &mut self.held,
            &mut self.alone,
            &mut |i, update, ms| out.push((i, update, ms)),
        );
        (out, cost)
    }
}

/// `a` and `b` run side by side, each with its milliseconds.
fn timed_join<A: Send, B: Send>(a: impl FnOnce() -> A + Send, b: impl FnOnce() -> B + Send) -> ((A, f64), (B, f64)) {
    rayon::join(
        || {
            let t0 = Instant::now();
            let out = a();
            (out, elapsed_ms(t0))
        },
        || {
            let t0 = Instant::now();
            let out = b();
            (out, elapsed_ms(t0))
        },
    )
}

/// `out`, the frames of the fit kept where two ran, each also carrying its
/// share of the other fit's `other_ms`.
fn with_share(mut out: Vec<FrameOut>, other_ms: f64) -> Vec<FrameOut> {
    let share_ms = other_ms / out.len().max(1) as f64;
    for (_, _, ms) in &mut out {
        *ms += share_ms;
    }
    out
}

/// Longest run of frames held as one press (6 s at 200 Hz, 1.2 s at
/// 1 kHz): a longer contact is fitted in parts, so that what waits for a
/// press's end stays bounded (each frame's posterior is held until then).
pub const MAX_PRESS_FRAMES: usize = 1200;

/// A press longer than this (frames; 2 s at 200 Hz) is fitted whole only
/// where kinetic friction explains it whole (a slide, whose rests before
/// and after belong in one fit), and otherwise in pieces of this length
/// (`PressJob::fit_side`). Cut into pieces, a generated link 5 slide
/// (`synth --seconds 12 --seed 1 --links lwr_5_link --slide 0.1
/// --slide-min 0.02 --kinetic-friction 0.3,0.6 --press-secs 1.5,3`, 483
/// frames) stood 81–110 mm off through its slip, and its 61 mm path
/// read as 452 mm; whole, 62 mm. A press without a slide keeps its
/// pieces: on the `../shared` observer examples (720-frame presses at
/// 1 kHz) a whole fit costs less than the pieces and lands farther off
/// (motor side 8.6 → 11.1 mm, `docs/decisions.md`, *A longer press
/// before the cut*).
pub const PRESS_PIECE_FRAMES: usize = 400;

/// A press continues across a hop to another link shorter than this (s;
/// five frames at 200 Hz), its frames fitted with the press. The
/// smoother's model has no friction, and where a slide starts or turns it
/// puts a frame or a few on another link: the press is cut into pieces,
/// each with its own force, and each piece's place free to jump from the
/// last (a generated link 5 slide, seed 3: 17.9 mm with pieces, 11.8
/// bridged; 10 ms gives the same, `docs/validation.md`, *A press across
/// a hop*).
pub const PRESS_BRIDGE_SECS: f64 = 0.025;

/// A press continues across a hop to another link shorter than this (s)
/// where [`LONG_BRIDGE_MIN_JOINTS`] or more sensed joints feel both the
/// press's link and the hop's. While a contact slips, its drag (`μ_k`
/// 0.3–0.6 of the push) lies outside the smoother's friction cone, and
/// the smoother explains the slipping frames by a push on a
/// neighbouring link for as long as the slip lasts: on the generated link
/// 6 seed 1 slide (`synth --seed 1 --links lwr_6_link --slide 0.1
/// --slide-min 0.02 --kinetic-friction 0.3,0.6`) the second press's whole
/// 0.55 s slip went to link 5, 51 mm off, and the link was right in 60 %
/// of the contact frames. Bridged,
/// the press is fitted whole with kinetic friction and kept whole only
/// where it stays on its link and costs no more than its pieces (see
/// `PressJob::fit`): 99 % (`docs/decisions.md`, *Slips that the smoother
/// puts on the next link*).
pub const LONG_BRIDGE_SECS: f64 = 0.6;

/// Sensed joints that must feel a press's link and its hop's for the
/// press to bridge a hop of up to [`LONG_BRIDGE_SECS`]. With fewer (link
/// 3 of the LWR and the links before it) a frame's place, push and drag
/// are more unknowns than its readings, and a whole press across a longer
/// hop is fitted cheaper but wrong: the `../shared` link 4 slide's force
/// 2.8 → 7.8 N at surface seed 0 (its hop to link 3 bridged at 0.1 s).
/// Between link 4 and the links after it the long bridge holds: on the
/// generated slides at surface seed 0, link 4 seed 2 11.8 → 2.5 mm (a
/// 0.3 s slip the smoother puts on link 6) and link 5 seed 1 9.0 → 5.7
/// mm (0.2 s on link 4) (`docs/validation.md`, *Long hops to and from
/// link 4*).
pub const LONG_BRIDGE_MIN_JOINTS: usize = 4;

/// The longest hop to another link that `link` allows on either side of
/// it, s: [`LONG_BRIDGE_SECS`] where [`LONG_BRIDGE_MIN_JOINTS`] or more
/// sensed joints move it, [`PRESS_BRIDGE_SECS`] elsewhere.
fn bridge_secs(robot: &Robot, link: LinkId) -> f64 {
    if robot.sensing_joints(link) >= LONG_BRIDGE_MIN_JOINTS {
        LONG_BRIDGE_SECS
    } else {
        PRESS_BRIDGE_SECS
    }
}

/// How much worse a press's whole fit must explain one side of a jump
/// than that side's own fit does, per frame of the side, for
/// `PressJob::fit` to cut the press there (χ², plus
/// [`PRESS_MISFIT_MARGIN`]). Measured per frame, at surface seed 0:
/// where a second push joins or leaves (`synth --contacts 2`, seeds 1–4,
/// links 4–7, `--avoid-covered`) the worse side 12–68; on generated
/// slides on links 4 and 5 (`--slide 0.1 --slide-min 0.02
/// --kinetic-friction 0.3,0.6`, seeds 1–3) at most 5.9.
pub const JUMP_MISFIT_PER_FRAME: f64 = 8.0;

#[cfg(test)]
#[path = "press_queue_tests.rs"]
mod tests;
