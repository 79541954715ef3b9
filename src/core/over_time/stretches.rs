//! The smoother of a recording of any length, in bounded memory: the
//! forward filter runs over the whole of it, and the backward pass runs
//! over stretches of it, cut where the filter is sure there is no contact.
//!
//! Where the filter has called "no contact" with near certainty for
//! [`QUIET_SECS`] and more, what comes later says next to nothing about
//! what came before: the chain forgets there. A stretch then ends
//! [`QUIET_SECS`] before the last frame, and its backward pass starts at
//! that last frame, so that the backward message reaching the stretch's
//! end has passed through [`QUIET_SECS`] of frames that say "free"
//! (those frames start the next stretch). A contact that never lets go (an
//! arm leaning on a table for minutes) is cut where the store would pass
//! its limit, with half of the store passed back over as a warm-up
//! for the backward message.
//!
//! The smoothed beliefs come out per stretch, as soon as it is cut, in the
//! store the stretch's filtered beliefs held: the peak memory is the
//! store's limit, whatever the length of the recording.
//!
//! The store holds the model's steps: frames closer together than
//! [`TemporalSettings::step_secs`](crate::core::over_time::temporal::TemporalSettings::step_secs)
//! share one ([`crate::core::over_time::smoother`]), and a stretch gives
//! each of its frames its step's belief. The lengths below count steps.

use crate::core::over_time::offsets::FrameLikelihood;
use crate::core::over_time::smoother::{
    FilterState, OpenStep, StepJoiner, StoredBelief, StoredFrame, backward_pass, packed_offset, unpacked_offset,
};
use crate::core::over_time::temporal::{Belief, TemporalError, TemporalModel};

/// How long the filter must have been sure of "no contact" for a stretch
/// to end there, s; also how much of that quiet the backward pass
/// crosses before it reaches the stretch's last frame.
pub const QUIET_SECS: f64 = 0.05;

/// The filter is "sure" of no contact where it gives a contact less than
/// this probability.
pub const QUIET_CONTACT: f64 = 1e-3;

/// A quiet cut is made only once the store holds this many frames (each
/// cut passes back over [`QUIET_SECS`] of frames twice).
pub const MIN_STRETCH_FRAMES: usize = 512;

/// Fewest frames the store's limit must hold.
const MIN_STORE_FRAMES: usize = 16;

/// One frame's smoothed belief, stored: the contact probability in f64,
/// and where the contact is given one in f32 (so that a frame the
/// recording calls free still says where a contact would most likely be).
#[derive(Debug, Clone)]
struct SmoothedBelief {
    contact: f64,
    given_contact: Vec<f32>,
    offsets: Vec<[f32; 5]>,
}

impl SmoothedBelief {
    fn of(belief: &Belief) -> Self {
        let contact = belief.points.iter().sum::<f64>();
        // A division per sample, not a product with 1/contact: a contact
        // of a subnormal size has an infinite reciprocal (0 · ∞ = NaN).
        let usable = contact > 0.0 && contact.is_finite();
        Self {
            contact: if usable { contact.min(1.0) } else { 0.0 },
            given_contact: belief
                .points
                .iter()
                .map(|&p| if usable { (p / contact) as f32 } else { 0.0 })
                .collect(),
            offsets: belief.offsets.iter().map(packed_offset).collect(),
        }
    }

    fn belief(&self) -> Belief {
        Belief {
            no_contact: 1.0 - self.contact,
            points: self
                .given_contact
                .iter()
                .map(|&p| f64::from(p) * self.contact)
                .collect(),
            offsets: self.offsets.iter().map(unpacked_offset).collect(),
        }
    }
}

/// Consecutive frames' beliefs given the whole recording, from a
/// [`StretchSmoother`].
#[derive(Debug, Clone)]
pub struct Stretch {
    /// Number (in the order pushed, from 0) of its first frame.
    pub first: usize,
    /// One per step of the model.
    beliefs: Vec<SmoothedBelief>,
    /// Frames up to the end of each step (from the stretch's first).
    ends: Vec<usize>,
}

impl Stretch {
    /// Frames in the stretch.
    #[must_use]
    pub fn len(&self) -> usize {
        self.ends.last().copied().unwrap_or(0)
    }

    /// True when it holds no frame.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The belief of its `i`-th frame (frame `first + i`): its step's.
    #[must_use]
    pub fn belief(&self, i: usize) -> Option<Belief> {
        let step = self.ends.partition_point(|&end| end <= i);
        self.beliefs.get(step).map(SmoothedBelief::belief)
    }
}

/// A step of the model gathered from its frames and packed for the
/// store: the part of a step's work that does not depend on the filter's
/// state, so that it can be done beside the filter
/// ([`StepPreparer`]).
#[derive(Debug, Clone)]
pub struct PreparedStep {
    step: OpenStep,
    stored: StoredFrame,
}

impl PreparedStep {
    fn of(step: OpenStep) -> Self {
        let stored = StoredFrame::of(&step.likelihood);
        Self { step, stored }
    }
}

/// Gathers frames into the model's steps ahead of a
/// [`StretchSmoother`], on any thread: the filter, which runs in order
/// and bounds how fast a recording goes on many cores, is left with only
/// its own step ([`StretchSmoother::push_step`]).
#[derive(Debug, Clone)]
pub struct StepPreparer {
    step_secs: f64,
    open: StepJoiner,
}

impl StepPreparer {
    /// A preparer for `model`'s steps that has seen nothing yet.
    #[must_use]
    pub fn new(model: &TemporalModel) -> Self {
        Self {
            step_secs: model.settings().step_secs,
            open: StepJoiner::default(),
        }
    }

    /// Takes the next frame; hands back the step it closes.
    ///
    /// # Errors
    /// [`TemporalError::BadTime`]: the time is not finite or goes back.
    pub fn push(&mut self, t_secs: f64, likelihood: FrameLikelihood) -> Result<Option<PreparedStep>, TemporalError> {
        Ok(self
            .open
            .push(self.step_secs, t_secs, likelihood)?
            .map(PreparedStep::of))
    }

    /// The open step, closed (after the last frame).
    pub fn finish(&mut self) -> Option<PreparedStep> {
        self.open.finish().map(PreparedStep::of)
    }

    /// Frames in the open step.
    fn held(&self) -> usize {
        self.open.held()
    }
}

/// The smoother of a recording of any length: frames are pushed in order
/// (the forward filter runs as they come); now and then a push hands back
/// a [`Piece`] of frames to smooth into a [`Stretch`], and
/// [`StretchSmoother::finish`] the last. The store holds at most
/// `limit_bytes` (see the module docs); a piece holds its own frames.
#[derive(Debug, Clone)]
pub struct StretchSmoother<'a> {
    model: &'a TemporalModel,
    state: FilterState,
    limit_bytes: usize,
    /// Number of the store's first frame.
    first: usize,
    times: Vec<f64>,
    frames: Vec<StoredFrame>,
    filtered: Vec<StoredBelief>,
    bytes: usize,
    /// Frames in each stored step.
    counts: Vec<usize>,
    /// Index in the store where the filter last became sure of "no
    /// contact" (`None` while it is not).
    quiet_from: Option<usize>,
    /// The step that the latest frames share, not yet filtered (frames
    /// taken by [`StretchSmoother::push`]).
    open: StepPreparer,
}

impl<'a> StretchSmoother<'a> {
    /// A smoother that has seen nothing yet and holds at most `limit_bytes`.
    #[must_use]
    pub fn new(model: &'a TemporalModel, limit_bytes: usize) -> Self {
        Self {
            model,
            state: FilterState::default(),
            limit_bytes,
            first: 0,
            times: Vec::new(),
            frames: Vec::new(),
            filtered: Vec::new(),
            bytes: 0,
            counts: Vec::new(),
            quiet_from: None,
            open: StepPreparer::new(model),
        }
    }

    /// Takes the next frame (filtered at once); hands back the frames
    /// before it that are settled, to be smoothed, when a stretch ends here.
    ///
    /// # Errors
    /// As [`FilterState::step`] (a frame's time checked as it comes);
    /// [`TemporalError::TooLarge`] when the limit cannot hold
    /// `MIN_STORE_FRAMES` frames.
    pub fn push(&mut self, t_secs: f64, likelihood: FrameLikelihood) -> Result<Option<Piece>, TemporalError> {
        match self.open.push(t_secs, likelihood)? {
            Some(step) => self.push_step(step),
            None => Ok(None),
        }
    }

    /// Takes the next step, gathered by a [`StepPreparer`] instead of
    /// [`StretchSmoother::push`] (the two are not mixed): filters and
    /// stores it, and hands back a piece when a stretch ends there.
    ///
    /// # Errors
    /// As [`StretchSmoother::push`].
    pub fn push_step(&mut self, step: PreparedStep) -> Result<Option<Piece>, TemporalError> {
        let PreparedStep {
            step:
                OpenStep {
                    t_secs,
                    likelihood,
                    frames,
                    ..
                },
            stored: frame,
        } = step;
        let likelihood = &likelihood;
        let belief = StoredBelief::of(self.state.step(self.model, t_secs, likelihood)?);
        let frame_bytes = belief.bytes() + frame.bytes() + size_of::<f64>();
        if frame_bytes.saturating_mul(MIN_STORE_FRAMES) > self.limit_bytes {
            return Err(TemporalError::TooLarge {
                frames: MIN_STORE_FRAMES,
                points: likelihood.points.len(),
                limit_bytes: self.limit_bytes,
            });
        }
        let quiet = belief.contact_probability() < QUIET_CONTACT;
        self.bytes += frame_bytes;
        self.times.push(t_secs);
        self.frames.push(frame);
        self.filtered.push(belief);
        self.counts.push(frames);
        let last = self.times.len() - 1;
        self.quiet_from = if quiet { self.quiet_from.or(Some(last)) } else { None };
        // A quiet cut: the quiet has lasted twice QUIET_SECS, and the
        // stretch ends QUIET_SECS before this frame.
        if let Some(from) = self.quiet_from
            && self.times.len() >= MIN_STRETCH_FRAMES
            && let (Some(&start), Some(&now)) = (self.times.get(from), self.times.get(last))
            && now - start >= 2.0 * QUIET_SECS
        {
            let keep = self.times.partition_point(|&t| t <= now - QUIET_SECS);
            if keep > from {
                return Ok(Some(self.cut(keep)));
            }
        }
        // A forced cut: the store is full.
        if self.bytes.saturating_add(frame_bytes) > self.limit_bytes {
            let keep = (self.times.len() - self.times.len() / 2).max(1);
            return Ok(Some(self.cut(keep)));
        }
        Ok(None)
    }

    /// Frames pushed and not yet handed back.
    #[must_use]
    pub fn held(&self) -> usize {
        self.counts.iter().sum::<usize>() + self.open.held()
    }

    /// Bytes held.
    #[must_use]
    pub fn held_bytes(&self) -> usize {
        self.bytes
    }

    /// The last pieces: every frame not yet handed back (the last step
    /// filtered may end a stretch of its own before them).
    ///
    /// # Errors
    /// As [`StretchSmoother::push`].
    pub fn finish(mut self) -> Result<Vec<Piece>, TemporalError> {
        let mut pieces = Vec::new();
        if let Some(step) = self.open.finish() {
            pieces.extend(self.push_step(step)?);
        }
        let all = self.times.len();
        if all > 0 {
            pieces.push(self.cut(all));
        }
        Ok(pieces)
    }

    /// Hands back the store's first `keep` frames, with copies of the
    /// rest for the backward pass to start from.
    fn cut(&mut self, keep: usize) -> Piece {
        let keep = keep.min(self.times.len());
        // The kept frames move into the piece; the later ones are copied.
        let later = (self.frames.split_off(keep), self.filtered.split_off(keep));
        let mut frames = std::mem::replace(&mut self.frames, later.0);
        let mut filtered = std::mem::replace(&mut self.filtered, later.1);
        frames.extend(self.frames.iter().cloned());
        filtered.extend(self.filtered.iter().cloned());
        let counts: Vec<usize> = self.counts.drain(..keep).collect();
        let kept_frames = counts.iter().sum::<usize>();
        let piece = Piece {
            first: self.first,
            keep,
            counts,
            times: self.times.clone(),
            frames,
            filtered,
        };
        self.times.drain(..keep);
        self.bytes = self.frames.iter().map(StoredFrame::bytes).sum::<usize>()
            + self.filtered.iter().map(StoredBelief::bytes).sum::<usize>()
            + self.times.len() * size_of::<f64>();
        // A quiet run that began before the cut goes on from the store's
        // first frame.
        self.quiet_from = self.quiet_from.map(|q| q.saturating_sub(keep));
        self.first += kept_frames;
        piece
    }
}

/// Frames cut from a [`StretchSmoother`]'s store, filtered and not yet
/// smoothed: its frames and the later ones its backward pass starts from.
/// [`Piece::smooth`] runs on any thread.
#[derive(Debug, Clone)]
pub struct Piece {
    first: usize,
    /// Steps it settles.
    keep: usize,
    /// Frames in each step it settles.
    counts: Vec<usize>,
    times: Vec<f64>,
    frames: Vec<StoredFrame>,
    filtered: Vec<StoredBelief>,
}

impl Piece {
    /// Frames it settles.
    #[must_use]
    pub fn len(&self) -> usize {
        self.counts.iter().sum()
    }

    /// True when it settles no frame.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.keep == 0
    }

    /// Bytes held.
    #[must_use]
    pub fn bytes(&self) -> usize {
        self.frames.iter().map(StoredFrame::bytes).sum::<usize>()
            + self.filtered.iter().map(StoredBelief::bytes).sum::<usize>()
            + self.times.len() * size_of::<f64>()
    }

    /// The backward pass from its last frame: its frames' beliefs given
    /// the whole recording.
    #[must_use]
    pub fn smooth(self, model: &TemporalModel) -> Stretch {
        let keep = self.keep;
        let mut beliefs: Vec<Option<SmoothedBelief>> = vec![None; keep];
        backward_pass(model, (&self.times, &self.frames, &self.filtered), keep, |t, belief| {
            if let Some(slot) = beliefs.get_mut(t) {
                *slot = Some(SmoothedBelief::of(&belief));
            }
        });
        // The pass visits every kept frame; one it skipped would keep its
        // filtered belief.
        let beliefs = beliefs
            .into_iter()
            .zip(&self.filtered)
            .map(|(smoothed, filtered)| smoothed.unwrap_or_else(|| SmoothedBelief::of(&filtered.belief())))
            .collect();
        let ends = self
            .counts
            .iter()
            .scan(0, |end, &n| {
                *end += n;
                Some(*end)
            })
            .collect();
        Stretch {
            first: self.first,
            beliefs,
            ends,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Fuzz finding: a contact probability of a subnormal size (its
    /// reciprocal is infinite) gave NaN where the contact would be.
    #[test]
    fn a_subnormal_contact_stays_a_probability() {
        for contact in [5e-324, 1e-310, f64::MIN_POSITIVE, 0.0, f64::NAN, f64::INFINITY] {
            let belief = Belief {
                no_contact: 1.0,
                points: vec![contact, 0.0, 0.0],
                offsets: Vec::new(),
            };
            let back = SmoothedBelief::of(&belief).belief();
            let p = back.contact_probability();
            assert!((0.0..=1.0).contains(&p), "{contact}: {p}");
            assert!((0.0..=1.0).contains(&back.no_contact), "{contact}: {back:?}");
            assert!(
                back.points.iter().all(|q| (0.0..=1.0).contains(q)),
                "{contact}: {back:?}"
            );
        }
    }
}
