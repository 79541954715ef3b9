//! The temporal model run over frames: the forward filter (what a live
//! robot can know, frame by frame) and the smoother (a recording: every
//! frame with all of it, forward and backward).

use crate::core::over_time::offsets::{FrameLikelihood, Offset, PatchInformation};
use crate::core::over_time::temporal::{
    Belief, MAX_SMOOTHER_BYTES, TemporalError, TemporalModel, interval, smoother_bytes,
};

/// The forward filter: each frame's belief from that frame and the ones
/// before (what a live robot can know).
#[derive(Debug, Clone)]
pub struct Filter<'a> {
    model: &'a TemporalModel,
    state: FilterState,
}

/// What a forward filter carries from frame to frame, apart from its
/// model (for a caller that owns the model beside it, e.g. a live stream).
#[derive(Debug, Clone, Default)]
pub struct FilterState {
    belief: Option<Belief>,
    last_t_secs: Option<f64>,
    frames: usize,
}

impl FilterState {
    /// Takes the frame at `t_secs` through `model` and returns the belief
    /// after it.
    ///
    /// # Errors
    /// [`TemporalError::WrongLength`], [`TemporalError::BadTime`].
    pub fn step(
        &mut self,
        model: &TemporalModel,
        t_secs: f64,
        likelihood: &FrameLikelihood,
    ) -> Result<&Belief, TemporalError> {
        model.check(self.frames, likelihood)?;
        let dt = interval(self.frames, self.last_t_secs, t_secs)?;
        let predicted = match &self.belief {
            Some(b) => model.predict(b, dt),
            None => model.initial(),
        };
        self.frames += 1;
        self.last_t_secs = Some(t_secs);
        Ok(self.belief.insert(model.correct(&predicted, likelihood)))
    }
}

impl<'a> Filter<'a> {
    /// A filter that has seen nothing yet.
    #[must_use]
    pub fn new(model: &'a TemporalModel) -> Self {
        Self {
            model,
            state: FilterState::default(),
        }
    }

    /// Takes the frame at `t_secs` and returns the belief after it.
    ///
    /// # Errors
    /// [`TemporalError::WrongLength`], [`TemporalError::BadTime`].
    pub fn step(&mut self, t_secs: f64, likelihood: &FrameLikelihood) -> Result<&Belief, TemporalError> {
        self.state.step(self.model, t_secs, likelihood)
    }
}

/// The smoother: frames are pushed in order (the forward pass runs as
/// they come), then [`Smoother::finish`] gives every frame's belief given
/// the whole recording. Without offsets it passes messages backwards
/// (exact); with offsets it runs a second filter backwards in time and
/// combines the two (exact for a reversible model; ours is up to the
/// prior's area weights and the moment-matched offsets). It holds each
/// frame's likelihoods and filtered belief in f32 (8 bytes per sample and
/// frame, 52 with offsets; at most [`MAX_SMOOTHER_BYTES`]).
#[derive(Debug, Clone)]
pub struct Smoother<'a> {
    filter: Filter<'a>,
    times: Vec<f64>,
    frames: Vec<StoredFrame>,
    filtered: Vec<StoredBelief>,
    /// Frames in each stored step.
    counts: Vec<usize>,
    open: StepJoiner,
}

/// Frames that share one step of the model
/// ([`TemporalSettings::step_secs`](crate::core::over_time::temporal::TemporalSettings::step_secs)):
/// the state is the step's for each of them, so their log-likelihoods add,
/// and so do their patches' Gaussian terms (each frame's `ln L(s)` is a
/// quadratic in the offset); the step takes its first frame's time.
#[derive(Debug, Clone)]
pub(crate) struct OpenStep {
    pub(crate) t_secs: f64,
    last_t_secs: f64,
    pub(crate) likelihood: FrameLikelihood,
    pub(crate) frames: usize,
}

impl OpenStep {
    /// Whether `likelihood` can join the step: the same samples, with or
    /// without their patches as the step's.
    fn joins(&self, likelihood: &FrameLikelihood) -> bool {
        self.likelihood.points.len() == likelihood.points.len() && self.likelihood.patch.len() == likelihood.patch.len()
    }

    /// Adds the evidence of a frame at `t_secs`.
    fn add(&mut self, t_secs: f64, likelihood: &FrameLikelihood) {
        let sum = &mut self.likelihood;
        sum.no_contact += likelihood.no_contact;
        for (a, b) in sum.points.iter_mut().zip(&likelihood.points) {
            *a += b;
        }
        for (a, b) in sum.patch.iter_mut().zip(&likelihood.patch) {
            a.point += b.point;
            for (x, y) in a.information.iter_mut().zip(b.information) {
                *x += y;
            }
            for (x, y) in a.shift.iter_mut().zip(b.shift) {
                *x += y;
            }
        }
        self.last_t_secs = t_secs;
        self.frames += 1;
    }
}

/// Frames this much short of a step's length after its first frame
/// still start the next step, s: a recording's stamps at a steady rate
/// carry rounding (1 ns, below any stamp's resolution).
const STEP_TOLERANCE_SECS: f64 = 1e-9;

/// Gathers frames into the model's steps: a frame joins the open step
/// while it is less than the step's length after the step's first frame.
#[derive(Debug, Clone, Default)]
pub(crate) struct StepJoiner {
    open: Option<OpenStep>,
    /// Frames taken so far.
    frames: usize,
}

impl StepJoiner {
    /// Takes the frame at `t_secs`; hands back the step it closes.
    ///
    /// # Errors
    /// [`TemporalError::BadTime`]: the time is not finite or goes back.
    pub(crate) fn push(
        &mut self,
        step_secs: f64,
        t_secs: f64,
        likelihood: FrameLikelihood,
    ) -> Result<Option<OpenStep>, TemporalError> {
        let previous = self.open.as_ref().map(|o| o.last_t_secs);
        interval(self.frames, previous, t_secs)?;
        self.frames += 1;
        if let Some(open) = &mut self.open
            && t_secs - open.t_secs < step_secs - STEP_TOLERANCE_SECS
            && open.joins(&likelihood)
        {
            open.add(t_secs, &likelihood);
            return Ok(None);
        }
        let step = OpenStep {
            t_secs,
            last_t_secs: t_secs,
            likelihood,
            frames: 1,
        };
        // Without a step's length no frame joins another: close it now.
        if step_secs <= STEP_TOLERANCE_SECS && self.open.is_none() {
            return Ok(Some(step));
        }
        Ok(self.open.replace(step))
    }

    /// The open step, closed.
    pub(crate) fn finish(&mut self) -> Option<OpenStep> {
        self.open.take()
    }

    /// Frames in the open step.
    pub(crate) fn held(&self) -> usize {
        self.open.as_ref().map_or(0, |o| o.frames)
    }
}

/// A frame's likelihoods in f32 (relative to `top`).
#[derive(Debug, Clone)]
pub(crate) struct StoredFrame {
    top: f64,
    no_contact: f32,
    points: Vec<f32>,
    patch: Vec<[f32; 6]>,
}

/// An offset's precision and shift in f32, as the stores hold it.
pub(crate) fn packed_offset(offset: &Offset) -> [f32; 5] {
    let [l11, l12, l22] = offset.precision;
    let [n1, n2] = offset.shift;
    [l11 as f32, l12 as f32, l22 as f32, n1 as f32, n2 as f32]
}

/// [`packed_offset`] undone (to f32's precision).
pub(crate) fn unpacked_offset(&[l11, l12, l22, n1, n2]: &[f32; 5]) -> Offset {
    Offset {
        precision: [l11, l12, l22].map(f64::from),
        shift: [n1, n2].map(f64::from),
    }
}

/// A belief in f32.
#[derive(Debug, Clone)]
pub(crate) struct StoredBelief {
    no_contact: f32,
    points: Vec<f32>,
    offsets: Vec<[f32; 5]>,
}

impl StoredFrame {
    pub(crate) fn of(likelihood: &FrameLikelihood) -> Self {
        let top = likelihood.top();
        // Relative log-likelihoods (f32 keeps 7 digits of a difference of
        // a few hundred: plenty), -inf as is.
        let rel = |l: f64| (l - top) as f32;
        Self {
            top,
            no_contact: rel(likelihood.no_contact),
            points: likelihood.points.iter().map(|&l| rel(l)).collect(),
            patch: likelihood
                .patch
                .iter()
                .map(|p| {
                    let [m11, m12, m22] = p.information;
                    let [n1, n2] = p.shift;
                    [rel(p.point), m11 as f32, m12 as f32, m22 as f32, n1 as f32, n2 as f32]
                })
                .collect(),
        }
    }

    /// Bytes held (the vectors' contents).
    pub(crate) fn bytes(&self) -> usize {
        size_of::<Self>() + self.points.len() * size_of::<f32>() + self.patch.len() * size_of::<[f32; 6]>()
    }

    fn likelihood(&self) -> FrameLikelihood {
        FrameLikelihood {
            no_contact: f64::from(self.no_contact) + self.top,
            points: self.points.iter().map(|&l| f64::from(l) + self.top).collect(),
            patch: self
                .patch
                .iter()
                .map(|&[point, m11, m12, m22, n1, n2]| PatchInformation {
                    point: f64::from(point) + self.top,
                    information: [m11, m12, m22].map(f64::from),
                    shift: [n1, n2].map(f64::from),
                })
                .collect(),
        }
    }

    /// `e^(l - top)` per state, no contact first (the untracked smoother's
    /// messages).
    fn scaled(&self) -> Belief {
        let e = |l: f32| {
            let d = f64::from(l);
            if d > -700.0 { d.exp() } else { 0.0 }
        };
        Belief {
            no_contact: e(self.no_contact),
            points: self.points.iter().map(|&l| e(l)).collect(),
            offsets: Vec::new(),
        }
    }
}

impl StoredBelief {
    pub(crate) fn of(belief: &Belief) -> Self {
        Self {
            no_contact: belief.no_contact as f32,
            points: belief.points.iter().map(|&p| p as f32).collect(),
            offsets: belief.offsets.iter().map(packed_offset).collect(),
        }
    }

    /// Bytes held (the vectors' contents).
    pub(crate) fn bytes(&self) -> usize {
        size_of::<Self>() + self.points.len() * size_of::<f32>() + self.offsets.len() * size_of::<[f32; 5]>()
    }

    /// Probability of a contact.
    pub(crate) fn contact_probability(&self) -> f64 {
        1.0 - f64::from(self.no_contact)
    }

    pub(crate) fn belief(&self) -> Belief {
        Belief {
            no_contact: f64::from(self.no_contact),
            points: self.points.iter().map(|&p| f64::from(p)).collect(),
            offsets: self.offsets.iter().map(unpacked_offset).collect(),
        }
    }
}

impl<'a> Smoother<'a> {
    /// A smoother that has seen nothing yet.
    #[must_use]
    pub fn new(model: &'a TemporalModel) -> Self {
        Self {
            filter: Filter::new(model),
            times: Vec::new(),
            frames: Vec::new(),
            filtered: Vec::new(),
            counts: Vec::new(),
            open: StepJoiner::default(),
        }
    }

    /// Takes the next frame (filtered with the frames that share its
    /// step, once the step is closed).
    ///
    /// # Errors
    /// As [`Filter::step`], and [`TemporalError::TooLarge`] past the store's limit.
    pub fn push(&mut self, t_secs: f64, likelihood: &FrameLikelihood) -> Result<(), TemporalError> {
        let step_secs = self.filter.model.settings().step_secs;
        match self.open.push(step_secs, t_secs, likelihood.clone())? {
            Some(step) => self.store(&step),
            None => Ok(()),
        }
    }

    /// Filters a closed step and stores it.
    fn store(&mut self, step: &OpenStep) -> Result<(), TemporalError> {
        let likelihood = &step.likelihood;
        let points = likelihood.points.len();
        let bytes = smoother_bytes(self.times.len() + 1, points, !likelihood.patch.is_empty());
        if bytes > MAX_SMOOTHER_BYTES {
            return Err(TemporalError::TooLarge {
                frames: self.times.len() + 1,
                points,
                limit_bytes: MAX_SMOOTHER_BYTES,
            });
        }
        let belief = self.filter.step(step.t_secs, likelihood)?;
        self.filtered.push(StoredBelief::of(belief));
        self.times.push(step.t_secs);
        self.frames.push(StoredFrame::of(likelihood));
        self.counts.push(step.frames);
        Ok(())
    }

    /// Frames pushed so far.
    #[must_use]
    pub fn len(&self) -> usize {
        self.counts.iter().sum::<usize>() + self.open.held()
    }

    /// True before the first frame.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every frame's belief given all frames, in order (the frames of a
    /// step share its belief).
    ///
    /// # Errors
    /// As [`Smoother::push`], for the last step.
    pub fn finish(mut self) -> Result<Vec<Belief>, TemporalError> {
        if let Some(step) = self.open.finish() {
            self.store(&step)?;
        }
        let n = self.times.len();
        let mut steps: Vec<Belief> = Vec::with_capacity(n);
        backward_pass(
            self.filter.model,
            (&self.times, &self.frames, &self.filtered),
            n,
            |_, belief| steps.push(belief),
        );
        steps.reverse();
        let mut out = Vec::with_capacity(self.counts.iter().sum());
        for (belief, &count) in steps.into_iter().zip(&self.counts) {
            out.extend(std::iter::repeat_n(belief, count));
        }
        Ok(out)
    }
}

/// The backward pass over stored frames (their times, likelihoods and
/// filtered beliefs), from the last: hands the smoothed belief of each
/// of the first `keep` frames to `out`, last first. The frames past
/// `keep` only carry the later evidence back (where a stretch of a long
/// recording ends, they stand in for the rest of it).
pub(crate) fn backward_pass(
    model: &TemporalModel,
    stored: (&[f64], &[StoredFrame], &[StoredBelief]),
    keep: usize,
    out: impl FnMut(usize, Belief),
) {
    let tracked = model.tracks_offsets() && stored.1.iter().all(|f| !f.patch.is_empty());
    if tracked {
        two_filters(model, stored, keep, out);
    } else {
        messages(model, stored, keep, out);
    }
}

/// The interval after frame `t`, s (0 after the last).
fn dt(times: &[f64], t: usize) -> f64 {
    match (times.get(t + 1), times.get(t)) {
        (Some(a), Some(b)) => (a - b).max(0.0),
        _ => 0.0,
    }
}

/// Forward filter × a filter run backwards in time, over the prior.
fn two_filters(
    model: &TemporalModel,
    (times, frames, filtered): (&[f64], &[StoredFrame], &[StoredBelief]),
    keep: usize,
    mut out: impl FnMut(usize, Belief),
) {
    let mut backward: Option<Belief> = None;
    for t in (0..times.len()).rev() {
        let (Some(forward), Some(frame)) = (filtered.get(t), frames.get(t)) else {
            continue;
        };
        let predicted = match &backward {
            Some(b) => model.predict(b, dt(times, t)),
            None => model.initial(),
        };
        if t < keep {
            out(t, model.combine(&forward.belief(), &predicted));
        }
        if t > 0 {
            backward = Some(model.correct(&predicted, &frame.likelihood()));
        }
    }
}

/// Forward–backward messages (samples as points).
fn messages(
    model: &TemporalModel,
    (times, frames, filtered): (&[f64], &[StoredFrame], &[StoredBelief]),
    keep: usize,
    mut out: impl FnMut(usize, Belief),
) {
    // β of the last frame is 1 everywhere.
    let points = filtered.first().map_or(0, |f| f.points.len());
    let ones = Belief {
        no_contact: 1.0,
        points: vec![1.0; points],
        offsets: Vec::new(),
    };
    let mut beta = ones.clone();
    for t in (0..times.len()).rev() {
        let (Some(alpha), Some(frame)) = (filtered.get(t), frames.get(t)) else {
            continue;
        };
        if t < keep {
            let mut smoothed = alpha.belief();
            smoothed.no_contact *= beta.no_contact;
            for (s, b) in smoothed.points.iter_mut().zip(&beta.points) {
                *s *= b;
            }
            if !smoothed.normalize() {
                smoothed = alpha.belief();
            }
            out(t, smoothed);
        }
        if t > 0 {
            // The message for frame t-1: this frame's likelihood times β.
            let mut later = frame.scaled();
            later.no_contact *= beta.no_contact;
            for (l, b) in later.points.iter_mut().zip(&beta.points) {
                *l *= b;
            }
            let mut next = model.backward(&later, dt(times, t - 1));
            if !next.normalize() {
                next = ones.clone();
            }
            beta = next;
        }
    }
}
