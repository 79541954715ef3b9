//! Contacts over time. A recorded contact lasts (a press is 0.1–2 s, tens
//! to hundreds of frames), keeps its place on its link or slides slowly,
//! and comes and goes; estimating each frame alone throws that away.
//!
//! The hidden state of a frame is *no contact* or *a contact at surface
//! sample k* (its magnitude is free in every frame: presses ramp up and
//! down within a few frames). Between frames `dt` apart:
//!
//! - a contact begins with probability `1 - e^{-λ_on dt}`, at a place drawn
//!   from the surface prior (area-weighted);
//! - a contact ends with probability `1 - e^{-λ_off dt}`;
//! - a contact that stays slides: a random walk over neighbouring samples
//!   of its link (a graph Laplacian scaled so that the RMS distance along
//!   each surface direction grows as `ℓ √t`), and with probability
//!   `1 - e^{-λ_jump dt}` it jumps to a place drawn from the prior (a
//!   release and a new press between two frames; it also keeps a wrong
//!   early lock from lasting).
//!
//! A contact that lasts keeps its place *within* its sample's patch too:
//! per sample the model carries a Gaussian over the contact's offset along
//! the sample's tangents (see [`PatchInformation`](crate::core::over_time::offsets::PatchInformation)), so that over a press
//! the patch is integrated once, over the product of the frames'
//! likelihoods, and the answer does not depend on where the samples fell.
//! The push magnitude is profiled per frame with one Occam charge shared
//! by every sample (a per-sample charge, multiplied over a hundred frames,
//! would favour the places with the weakest levers).
//!
//! The forward filter (what a live robot can know) and the smoother (a
//! recording: every frame uses all of it) are exact over the samples up to
//! the offsets' moment matching, in scaled probabilities,
//! `O(samples × neighbours)` per frame.

//!
//! This file holds the settings, the model and its step; the surface's
//! walk is [`crate::core::over_time::graph`], the offsets within a patch
//! [`crate::core::over_time::offsets`], the filter and the smoother
//! [`crate::core::over_time::smoother`].

use crate::core::numerics::fastmath;
use crate::core::numerics::lanes;
use crate::core::numerics::simd::{Kernel, widest};
use crate::core::over_time::combine::CombineKernel;
use crate::core::over_time::graph::SurfaceGraph;
use crate::core::over_time::offsets::{FrameLikelihood, GainsKernel, Offset};
use crate::core::surface::sampling::Surface;

/// How far below the best sample, in nats, [`TemporalModel::combine`]
/// still adds the offsets' share of a sample's weight.
const COMBINE_MARGIN: f64 = 100.0;

/// Largest smoother store of a whole recording ([`crate::core::over_time::smoother::Smoother`]: the scaled
/// likelihoods and filtered beliefs of every frame, 4 bytes per value):
/// 2 GiB.
pub const MAX_SMOOTHER_BYTES: usize = 1 << 31;

/// The store of a recording smoothed in stretches when the caller has not
/// said ([`TemporalModel::with_store_limit`]): 1 GiB.
pub const DEFAULT_STORE_BYTES: usize = 1 << 30;

/// Rates and length scale of the temporal model (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TemporalSettings {
    /// Contacts begin at this rate while there is none, 1/s.
    pub onset_per_s: f64,
    /// A contact ends at this rate, 1/s (its mean duration is the inverse).
    pub release_per_s: f64,
    /// RMS slide along each surface direction after one second, m (it
    /// grows as the square root of time).
    pub slide_m_per_sqrt_s: f64,
    /// A contact jumps to an unrelated place at this rate, 1/s.
    pub jump_per_s: f64,
    /// The smoother's time step, s: consecutive frames closer together
    /// than this share one state (their evidence multiplied), so that a
    /// recording at a robot's rate costs what one at `1/step_secs` would.
    /// 0: a step per frame.
    pub step_secs: f64,
}

impl Default for TemporalSettings {
    /// Presses of about half a second (0.1–2 s), a couple of seconds apart,
    /// sliding a few centimetres per second at most.
    fn default() -> Self {
        Self {
            onset_per_s: 0.5,
            release_per_s: 2.0,
            slide_m_per_sqrt_s: 0.01,
            jump_per_s: 0.2,
            step_secs: 0.002,
        }
    }
}

/// Why a temporal estimate could not be made.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TemporalError {
    /// A setting is negative or not finite.
    #[error("temporal setting {name} = {value}: must be a finite number ≥ 0")]
    BadSetting {
        /// The setting.
        name: &'static str,
        /// Its value.
        value: f64,
    },
    /// A frame's likelihoods do not match the surface.
    #[error("frame {frame}: {points} point likelihoods for a surface of {expected} points")]
    WrongLength {
        /// Frame number (0-based, in the order given).
        frame: usize,
        /// Likelihoods given.
        points: usize,
        /// Surface points.
        expected: usize,
    },
    /// Time goes backwards or is not finite.
    #[error("frame {frame}: time {t_secs} s is before the previous frame's {previous_secs} s or not finite")]
    BadTime {
        /// Frame number (0-based, in the order given).
        frame: usize,
        /// Its time, s.
        t_secs: f64,
        /// The previous frame's, s.
        previous_secs: f64,
    },
    /// The smoother would hold too much.
    #[error(
        "smoothing holds {frames} frames of {points} points at once, more than {limit_bytes} bytes: allow more memory, or use fewer points or the filter"
    )]
    TooLarge {
        /// Frames so far.
        frames: usize,
        /// Surface points.
        points: usize,
        /// The limit.
        limit_bytes: usize,
    },
}

impl TemporalSettings {
    /// Every setting finite and ≥ 0.
    ///
    /// # Errors
    /// [`TemporalError::BadSetting`] naming the first that is not.
    pub fn validate(&self) -> Result<(), TemporalError> {
        for (name, value) in [
            ("onset rate", self.onset_per_s),
            ("release rate", self.release_per_s),
            ("slide", self.slide_m_per_sqrt_s),
            ("jump rate", self.jump_per_s),
            ("time step", self.step_secs),
        ] {
            if !value.is_finite() || value < 0.0 {
                return Err(TemporalError::BadSetting { name, value });
            }
        }
        Ok(())
    }

    /// The share of time with a contact when nothing is measured.
    #[must_use]
    pub fn stationary_contact(&self) -> f64 {
        let total = self.onset_per_s + self.release_per_s;
        if total > 0.0 { self.onset_per_s / total } else { 0.5 }
    }
}

/// Each `predicted · e^(gain - top)` (0 where `gain - top` is NaN or below
/// -700): the correct step's weights in one vectorised loop (one at a
/// time, the library's `exp` was a tenth of a filtered frame).
struct WeighKernel<'a>(&'a [f64], &'a [f64], f64);

impl Kernel for WeighKernel<'_> {
    type Output = Vec<f64>;
    #[inline(always)]
    fn run(self) -> Vec<f64> {
        let (predicted, gains, top) = (self.0, self.1, self.2);
        let n = predicted.len().min(gains.len());
        let (predicted, gains) = (&predicted[..n], &gains[..n]);
        let mut out = vec![0.0; n];
        for k in 0..n {
            let d = gains[k] - top;
            let e = fastmath::exp(d);
            out[k] = if d > -700.0 { predicted[k] * e } else { 0.0 };
        }
        out
    }
}

/// `e^(-rate · slide)` per sample: the chance that a contact stays on it
/// while sliding `slide` (m², the slide length squared times the time),
/// as a [`Kernel`].
struct DecayKernel<'a>(&'a [f64], f64);

impl Kernel for DecayKernel<'_> {
    type Output = Vec<f64>;
    #[inline(always)]
    fn run(self) -> Vec<f64> {
        let (rates, slide) = (self.0, self.1);
        let mut out = vec![0.0; rates.len()];
        for (o, &rate) in out.iter_mut().zip(rates) {
            *o = fastmath::exp(-rate * slide);
        }
        out
    }
}

/// What the model believes at one frame: probabilities of no contact and
/// of a contact at each sample (they sum to 1).
#[derive(Debug, Clone, PartialEq)]
pub struct Belief {
    /// Probability of no contact.
    pub no_contact: f64,
    /// Probability of a contact at each sample.
    pub points: Vec<f64>,
    /// Given a contact at a sample, where within its patch (empty when the
    /// samples are points).
    pub offsets: Vec<Offset>,
}

impl Belief {
    /// Probability that there is a contact.
    #[must_use]
    pub fn contact_probability(&self) -> f64 {
        lanes::sum(&self.points).clamp(0.0, 1.0)
    }

    /// Where the contact is, if there is one: the samples' probabilities
    /// divided by their sum (`None` when they are all 0).
    #[must_use]
    pub fn where_given_contact(&self) -> Option<Vec<f64>> {
        let total = lanes::sum(&self.points);
        (total > 0.0 && total.is_finite()).then(|| self.points.iter().map(|p| p / total).collect())
    }

    /// Divides by the total; `false` (and unchanged) when it is 0 or not finite.
    pub(crate) fn normalize(&mut self) -> bool {
        let total = self.no_contact + lanes::sum(&self.points);
        if !(total > 0.0 && total.is_finite()) {
            return false;
        }
        self.no_contact /= total;
        for p in &mut self.points {
            *p /= total;
        }
        true
    }
}

/// The temporal model of one surface.
#[derive(Debug, Clone)]
pub struct TemporalModel {
    settings: TemporalSettings,
    graph: SurfaceGraph,
    /// Where a new contact lands: by area with patches, else uniform.
    prior: Vec<f64>,
    /// Each sample's patch width, m (empty when the samples are points:
    /// then no offsets are tracked).
    window_m: Vec<f64>,
    /// Each sample's hop rate per `ℓ²` (the sum of its graph weights).
    hop_rate: Vec<f64>,
    /// `ln` of the prior (-∞ where it is 0).
    ln_prior: Vec<f64>,
    /// Most bytes a recording's smoother holds at once.
    store_limit_bytes: usize,
}

/// Transition probabilities over `dt`.
#[derive(Debug, Clone, Copy)]
struct Step {
    onset: f64,
    release: f64,
    jump: f64,
}

impl TemporalModel {
    /// The model of `surface`'s samples (`patches`: the per-frame
    /// posteriors weigh samples by area, and so does the prior here).
    ///
    /// # Errors
    /// [`TemporalError::BadSetting`].
    pub fn new(surface: &Surface, settings: TemporalSettings, patches: bool) -> Result<Self, TemporalError> {
        settings.validate()?;
        let n = surface.len();
        let prior = if patches {
            let total: f64 = surface.area_m2.iter().sum();
            if total > 0.0 && total.is_finite() {
                surface.area_m2.iter().map(|a| a / total).collect()
            } else {
                vec![1.0 / n.max(1) as f64; n]
            }
        } else {
            vec![1.0 / n.max(1) as f64; n]
        };
        let graph = SurfaceGraph::new(surface);
        let hop_rate = (0..n).map(|k| graph.neighbours(k).1.iter().sum()).collect();
        let window_m =
            if patches && surface.window_m.len() == n && surface.window_m.iter().all(|&w| w > 0.0 && w.is_finite()) {
                surface.window_m.clone()
            } else {
                Vec::new()
            };
        Ok(Self {
            settings,
            graph,
            window_m,
            hop_rate,
            ln_prior: prior.iter().map(|&p| fastmath::ln_or_minus_infinity(p)).collect(),
            prior,
            store_limit_bytes: DEFAULT_STORE_BYTES,
        })
    }

    /// The model with a recording's smoother holding at most `bytes` at
    /// once (see [`crate::core::over_time::stretches`]).
    #[must_use]
    pub fn with_store_limit(mut self, bytes: usize) -> Self {
        self.store_limit_bytes = bytes;
        self
    }

    /// Most bytes a recording's smoother holds at once.
    #[must_use]
    pub fn store_limit_bytes(&self) -> usize {
        self.store_limit_bytes
    }

    /// The settings.
    #[must_use]
    pub fn settings(&self) -> &TemporalSettings {
        &self.settings
    }

    /// The neighbour graph.
    #[must_use]
    pub fn graph(&self) -> &SurfaceGraph {
        &self.graph
    }

    /// The belief before any frame: the long-run share of contact, spread
    /// by the prior.
    #[must_use]
    pub fn initial(&self) -> Belief {
        let contact = self.settings.stationary_contact();
        Belief {
            no_contact: 1.0 - contact,
            points: self.prior.iter().map(|p| p * contact).collect(),
            offsets: self.window_m.iter().map(|&w| Offset::window(w)).collect(),
        }
    }

    /// Whether offsets within the patches are tracked.
    pub(crate) fn tracks_offsets(&self) -> bool {
        !self.window_m.is_empty()
    }

    fn step(&self, dt_secs: f64) -> Step {
        let p = |rate: f64| -(-rate * dt_secs).exp_m1();
        Step {
            onset: p(self.settings.onset_per_s),
            release: p(self.settings.release_per_s),
            jump: p(self.settings.jump_per_s),
        }
    }

    fn slide_rate(&self) -> f64 {
        self.settings.slide_m_per_sqrt_s * self.settings.slide_m_per_sqrt_s
    }

    /// The belief `dt` later, before that frame's measurement.
    #[must_use]
    pub fn predict(&self, belief: &Belief, dt_secs: f64) -> Belief {
        let s = self.step(dt_secs);
        let contact = lanes::sum(&belief.points);
        let mut moved = belief.points.clone();
        let mut scratch = Vec::new();
        self.graph.diffuse(&mut moved, self.slide_rate(), dt_secs, &mut scratch);
        let stay = (1.0 - s.release) * (1.0 - s.jump);
        let fresh = belief.no_contact * s.onset + (1.0 - s.release) * s.jump * contact;
        let points: Vec<f64> = moved
            .iter()
            .zip(&self.prior)
            .map(|(m, prior)| stay * m + fresh * prior)
            .collect();
        // A contact that stayed on its sample keeps its offset; one that
        // arrived (a hop, a new press) is anywhere in the patch.
        let offsets = if self.tracks_offsets() && belief.offsets.len() == points.len() {
            let slide = self.slide_rate() * dt_secs;
            // What stays on each sample over `dt`, in one vectorised pass
            // (the loop below is scalar: one at a time, `exp` there cost
            // more than the rest of it).
            let stays = widest(DecayKernel(&self.hop_rate, slide));
            points
                .iter()
                .enumerate()
                .map(|(k, &predicted)| {
                    let (Some(&before), Some(offset), Some(&decay), Some(&rho)) = (
                        belief.points.get(k),
                        belief.offsets.get(k),
                        stays.get(k),
                        self.window_m.get(k),
                    ) else {
                        return Offset::window(1.0);
                    };
                    let kept = stay * before * decay;
                    let own = if predicted > 0.0 { kept / predicted } else { 0.0 };
                    // Nearly all its own or nearly all arrived: no mixing.
                    if own > 1.0 - 1e-9 {
                        *offset
                    } else if own < 1e-9 {
                        Offset::window(rho)
                    } else {
                        offset.mixed_with_window(own, rho)
                    }
                })
                .collect()
        } else {
            self.initial().offsets
        };
        Belief {
            no_contact: belief.no_contact * (1.0 - s.onset) + contact * s.release,
            points,
            offsets,
        }
    }

    /// The backward message one frame earlier: for each state, the chance
    /// of what follows given it (up to a factor), from `later` = the next
    /// frame's scaled likelihoods times its backward message.
    pub(crate) fn backward(&self, later: &Belief, dt_secs: f64) -> Belief {
        let s = self.step(dt_secs);
        let fresh: f64 = later.points.iter().zip(&self.prior).map(|(v, p)| v * p).sum();
        let mut moved = later.points.clone();
        let mut scratch = Vec::new();
        self.graph.diffuse(&mut moved, self.slide_rate(), dt_secs, &mut scratch);
        let stay = (1.0 - s.release) * (1.0 - s.jump);
        let jump = (1.0 - s.release) * s.jump * fresh;
        Belief {
            no_contact: (1.0 - s.onset) * later.no_contact + s.onset * fresh,
            points: moved
                .iter()
                .map(|m| s.release * later.no_contact + stay * m + jump)
                .collect(),
            offsets: Vec::new(),
        }
    }

    /// Each sample's log-likelihood given `predicted`'s offsets (the
    /// frame's own when offsets are not tracked) and the offsets after it.
    fn gains(&self, predicted: &Belief, likelihood: &FrameLikelihood) -> (Vec<f64>, Vec<Offset>) {
        let n = likelihood.points.len();
        let tracked = self.tracks_offsets()
            && likelihood.patch.len() == n
            && predicted.offsets.len() == n
            && self.window_m.len() == n;
        if !tracked {
            return (likelihood.points.clone(), predicted.offsets.clone());
        }
        // The sample's own likelihood and the patch integrated over the
        // contact's offset as believed so far ([`Offset::absorb_within`],
        // four samples at a time). Beyond the patch's reach the Gaussian
        // is charged, not moved: the charge so far is in the weight, and
        // the Gaussian keeps every frame's information, so that what is
        // charged over a press does not depend on the order the frames
        // came in (the smoother's two halves combine).
        widest(GainsKernel {
            points: &likelihood.points,
            patch: &likelihood.patch,
            offsets: &predicted.offsets,
            window_m: &self.window_m,
        })
    }

    /// `predicted` after measuring `likelihood`; if nothing predicted is
    /// consistent with the measurement (all products 0), the measurement
    /// alone under the prior.
    pub(crate) fn correct(&self, predicted: &Belief, likelihood: &FrameLikelihood) -> Belief {
        let weigh = |predicted: &Belief| {
            let (gains, offsets) = self.gains(predicted, likelihood);
            // NaN left out, as `f64::max` does.
            let top = lanes::max_or(&gains, likelihood.no_contact);
            let scale = |l: f64| {
                let d = l - top;
                // NaN, -inf and anything below e^-700 of the best: 0.
                if d > -700.0 { d.exp() } else { 0.0 }
            };
            let mut points = widest(WeighKernel(&predicted.points, &gains, top));
            points.resize(predicted.points.len(), 0.0);
            let mut out = Belief {
                no_contact: predicted.no_contact * scale(likelihood.no_contact),
                points,
                offsets,
            };
            let ok = out.normalize();
            (ok, out)
        };
        let (ok, out) = weigh(predicted);
        if ok {
            return out;
        }
        let (ok, fresh) = weigh(&self.initial());
        if ok { fresh } else { self.initial() }
    }

    /// The belief given every frame, from the forward filter's belief at
    /// a frame and the backward filter's prediction for it (the frames
    /// after it run backwards through the same model): their product
    /// over the prior, offsets included.
    pub(crate) fn combine(&self, forward: &Belief, backward: &Belief) -> Belief {
        let contact = self.settings.stationary_contact().clamp(1e-300, 1.0 - 1e-16);
        let none = fastmath::ln_or_minus_infinity(forward.no_contact)
            + fastmath::ln_or_minus_infinity(backward.no_contact)
            - (1.0 - contact).ln();
        // Each sample's weight before the offsets' share, then that share
        // where it can matter: within COMBINE_MARGIN of the best (beyond,
        // the sample's weight is below e^-100 of the best's, which no
        // summary reads; the offsets' share is a few nats).
        let (logs, offsets) = widest(CombineKernel {
            forward_points: &forward.points,
            backward_points: &backward.points,
            ln_prior: &self.ln_prior,
            ln_contact: contact.ln(),
            none,
            margin: COMBINE_MARGIN,
            forward_offsets: &forward.offsets,
            backward_offsets: &backward.offsets,
            window_m: &self.window_m,
        });
        let top = logs.iter().copied().filter(|l| !l.is_nan()).fold(none, f64::max);
        let scale = |l: f64| {
            let d = l - top;
            if d > -700.0 { fastmath::exp(d) } else { 0.0 }
        };
        let mut out = Belief {
            no_contact: scale(none),
            points: logs.iter().map(|&l| scale(l)).collect(),
            offsets,
        };
        if out.normalize() { out } else { forward.clone() }
    }

    pub(crate) fn check(&self, frame: usize, likelihood: &FrameLikelihood) -> Result<(), TemporalError> {
        let n = self.prior.len();
        if likelihood.points.len() == n && (likelihood.patch.is_empty() || likelihood.patch.len() == n) {
            Ok(())
        } else {
            Err(TemporalError::WrongLength {
                frame,
                points: if likelihood.points.len() == n {
                    likelihood.patch.len()
                } else {
                    likelihood.points.len()
                },
                expected: n,
            })
        }
    }
}

/// Bytes the `Smoother` holds for `frames` frames of `points` samples
/// (with offsets tracked or not).
#[must_use]
pub fn smoother_bytes(frames: usize, points: usize, offsets: bool) -> usize {
    frames
        .saturating_mul(points.saturating_add(1))
        .saturating_mul(if offsets { 52 } else { 8 })
}

/// Whether frames at `times_secs` form a recording that the temporal
/// model connects: a contact outlives the median interval between frames
/// with probability at least ½ (`dt ≤ ln 2 / λ_off`: 0.35 s by default;
/// frames a second apart, as in a set of unrelated pushes, are not).
#[must_use]
pub fn is_continuous_recording(times_secs: &[f64], settings: &TemporalSettings) -> bool {
    median_interval_secs(times_secs).is_some_and(|median| median * settings.release_per_s <= std::f64::consts::LN_2)
}

/// The median of the finite intervals between consecutive frames, s;
/// `None` for fewer than two frames.
#[must_use]
pub fn median_interval_secs(times_secs: &[f64]) -> Option<f64> {
    let mut intervals: Vec<f64> = times_secs
        .windows(2)
        .filter_map(|w| match w {
            [a, b] => Some(b - a),
            _ => None,
        })
        .filter(|dt| dt.is_finite())
        .collect();
    if intervals.is_empty() {
        return None;
    }
    let mid = intervals.len() / 2;
    Some(*intervals.select_nth_unstable_by(mid, f64::total_cmp).1)
}

/// Checks that `t_secs` follows `previous` and gives the interval.
pub(crate) fn interval(frame: usize, previous: Option<f64>, t_secs: f64) -> Result<f64, TemporalError> {
    let bad = |previous_secs: f64| TemporalError::BadTime {
        frame,
        t_secs,
        previous_secs,
    };
    if !t_secs.is_finite() {
        return Err(bad(previous.unwrap_or(f64::NAN)));
    }
    match previous {
        None => Ok(0.0),
        Some(p) if t_secs >= p => Ok(t_secs - p),
        Some(p) => Err(bad(p)),
    }
}

#[cfg(test)]
#[path = "temporal_tests.rs"]
mod tests;
