//! Contacts over time. A recorded contact lasts (a press is 0.1–2 s, tens
//! to hundreds of frames), keeps its place on its link or slides slowly,
//! and comes and goes; estimating each frame alone throws that away.
//!
//! The hidden state of a frame is *no contact* or *a contact at surface
//! sample k* (its magnitude is integrated out per frame, as in the
//! per-frame posterior: it changes freely between frames, since presses
//! ramp up and down within a few frames). Between frames `dt` apart:
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
//! The forward filter (what a live robot can know) and the forward–backward
//! smoother (a recording: every frame uses all of it) are exact over the
//! samples, in scaled probabilities (each frame's likelihoods divided by
//! their largest), `O(samples × neighbours)` per frame.

use crate::core::estimator::Posterior;
use crate::core::surface::{Surface, WINDOW_FRACTION};

/// Neighbours are the samples of the same link within this many sample
/// spacings (about 6–10 each for evenly spread samples).
pub const NEIGHBOUR_SPACINGS: f64 = 1.8;

/// Most Euler sub-steps of the random walk per frame interval; a gap
/// longer than this many sub-steps spreads the contact less than the
/// model says (after such a gap it is spread over the link anyway).
pub const MAX_SUBSTEPS: usize = 10_000;

/// Largest smoother store (the scaled likelihoods and filtered beliefs of
/// every frame, 4 bytes per value): 2 GiB.
pub const MAX_SMOOTHER_BYTES: usize = 1 << 31;

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
        "smoothing {frames} frames of {points} points needs more than {limit_bytes} bytes: use the filter, fewer points or a shorter recording"
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

/// Which samples neighbour which (same link, within
/// [`NEIGHBOUR_SPACINGS`], facing the same side), with the random walk's
/// hop weight per unit `ℓ²`: `(1/m_k + 1/m_j) / d²` for samples with `m_k`
/// and `m_j` neighbours `d` apart. The weights are symmetric, so the walk
/// keeps every total and its transpose is itself; for `m` neighbours at
/// distance `d` the spread grows by `2ℓ²` per second, `ℓ²` along each
/// surface direction.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceGraph {
    /// Neighbours of sample k: `neighbour[start[k]..start[k + 1]]`.
    start: Vec<u32>,
    neighbour: Vec<u32>,
    weight: Vec<f64>,
    /// Largest `Σ_j weight` of a sample: the fastest hop rate per `ℓ²`.
    max_rate: f64,
}

impl SurfaceGraph {
    /// The graph of `surface`'s samples.
    #[must_use]
    pub fn new(surface: &Surface) -> Self {
        let n = surface.len();
        // Members of each cell (cells are three spacings wide, so
        // neighbours lie in the same or a touching cell).
        let mut members: Vec<Vec<u32>> = vec![Vec::new(); surface.cells.len()];
        for (k, &c) in surface.cell.iter().enumerate() {
            if let Some(list) = members.get_mut(c as usize) {
                list.push(k as u32);
            }
        }
        let mut lists: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
        for (k, list) in lists.iter_mut().enumerate() {
            let (Some(&c), Some(&p), Some(&normal), Some(&window)) = (
                surface.cell.get(k),
                surface.point_in_link.get(k),
                surface.inward_normal_in_link.get(k),
                surface.window_m.get(k),
            ) else {
                continue;
            };
            let spacing = window / WINDOW_FRACTION;
            let radius = NEIGHBOUR_SPACINGS * spacing;
            let c = c as usize;
            let around = std::iter::once(c as u32).chain(surface.cells.neighbours_of(c).iter().copied());
            for cell in around {
                for &j in members.get(cell as usize).map_or(&[][..], Vec::as_slice) {
                    let j_index = j as usize;
                    if j_index == k {
                        continue;
                    }
                    let (Some(&q), Some(&other)) = (
                        surface.point_in_link.get(j_index),
                        surface.inward_normal_in_link.get(j_index),
                    ) else {
                        continue;
                    };
                    let d2 = p.distance_squared(q);
                    // Facing the same side: not through a thin wall.
                    if d2 > 0.0 && d2 <= radius * radius && normal.dot(other) > 0.0 {
                        list.push((j, d2));
                    }
                }
            }
            list.sort_unstable_by_key(|&(j, _)| j);
        }
        // Symmetric: keep a pair only when each lists the other (radii
        // differ between links' spacings only across links, which never
        // pair, but rounding may still break a tie one way).
        let counts: Vec<f64> = lists.iter().map(|l| l.len() as f64).collect();
        let mut graph = Self {
            start: Vec::with_capacity(n + 1),
            ..Self::default()
        };
        for (k, list) in lists.iter().enumerate() {
            graph.start.push(graph.neighbour.len() as u32);
            let mut rate = 0.0;
            for &(j, d2) in list {
                let mutual = lists
                    .get(j as usize)
                    .is_some_and(|other| other.binary_search_by_key(&(k as u32), |&(i, _)| i).is_ok());
                if !mutual {
                    continue;
                }
                let (Some(&mk), Some(&mj)) = (counts.get(k), counts.get(j as usize)) else {
                    continue;
                };
                let w = (1.0 / mk + 1.0 / mj) / d2;
                graph.neighbour.push(j);
                graph.weight.push(w);
                rate += w;
            }
            graph.max_rate = graph.max_rate.max(rate);
        }
        graph.start.push(graph.neighbour.len() as u32);
        graph
    }

    /// Number of samples.
    #[must_use]
    pub fn len(&self) -> usize {
        self.start.len().saturating_sub(1)
    }

    /// True without samples.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The neighbours of sample k and their hop weights per `ℓ²`.
    #[must_use]
    pub fn neighbours(&self, k: usize) -> (&[u32], &[f64]) {
        let (Some(&a), Some(&b)) = (self.start.get(k), self.start.get(k + 1)) else {
            return (&[], &[]);
        };
        let range = a as usize..b as usize;
        (
            self.neighbour.get(range.clone()).unwrap_or(&[]),
            self.weight.get(range).unwrap_or(&[]),
        )
    }

    /// `values` after a random walk of `rate_scale · dt` (`rate_scale` = ℓ²):
    /// explicit Euler sub-steps short enough to keep every value ≥ 0.
    fn diffuse(&self, values: &mut Vec<f64>, rate_scale: f64, dt_secs: f64, scratch: &mut Vec<f64>) {
        let fastest = self.max_rate * rate_scale;
        if fastest <= 0.0 || dt_secs <= 0.0 || values.len() != self.len() {
            return;
        }
        let wanted = (fastest * dt_secs / 0.5).ceil();
        let steps = if wanted >= MAX_SUBSTEPS as f64 {
            MAX_SUBSTEPS
        } else {
            (wanted as usize).max(1)
        };
        let h = (dt_secs / steps as f64).min(0.5 / fastest) * rate_scale;
        for _ in 0..steps {
            scratch.clear();
            scratch.extend(values.iter().enumerate().map(|(k, &v)| {
                let (around, weights) = self.neighbours(k);
                let flow: f64 = around
                    .iter()
                    .zip(weights)
                    .map(|(&j, &w)| w * (values.get(j as usize).copied().unwrap_or(v) - v))
                    .sum();
                v + h * flow
            }));
            std::mem::swap(values, scratch);
        }
    }
}

/// One frame's evidence, up to a constant shared by every state:
/// `ln p(τ | no contact)` and `ln p(τ | contact at sample k)` (the push
/// magnitude integrated out; `-inf` where a sample was not evaluated).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameLikelihood {
    /// No contact: `-½ Σ τ²/σ²`.
    pub no_contact: f64,
    /// Per sample.
    pub points: Vec<f64>,
}

impl FrameLikelihood {
    /// From a per-frame posterior of `surface`: its log-likelihoods carry
    /// each sample's `ln area` when patches were used (the surface prior
    /// the temporal model applies itself), which is taken out here.
    #[must_use]
    pub fn from_posterior(posterior: &Posterior, surface: &Surface, patches: bool) -> Self {
        let points = posterior
            .log_likelihood
            .iter()
            .zip(&surface.area_m2)
            .map(|(&l, &area)| {
                if patches {
                    l - area.max(f64::MIN_POSITIVE).ln()
                } else {
                    l
                }
            })
            .collect();
        Self {
            no_contact: -0.5 * posterior.no_contact_chi2,
            points,
        }
    }

    /// The largest value, and each value's `e^(value - largest)` (0 for
    /// `-inf` and NaN).
    fn scaled(&self) -> (f64, Vec<f64>) {
        let top = self
            .points
            .iter()
            .copied()
            .filter(|l| !l.is_nan())
            .fold(self.no_contact, f64::max);
        let scale = |l: f64| {
            let d = l - top;
            // NaN, -inf and anything below e^-700 of the best: 0.
            if d > -700.0 { d.exp() } else { 0.0 }
        };
        let mut out = Vec::with_capacity(self.points.len() + 1);
        out.push(scale(self.no_contact));
        out.extend(self.points.iter().map(|&l| scale(l)));
        (top, out)
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
}

impl Belief {
    /// Probability that there is a contact.
    #[must_use]
    pub fn contact_probability(&self) -> f64 {
        self.points.iter().sum::<f64>().clamp(0.0, 1.0)
    }

    /// Where the contact is, if there is one: the samples' probabilities
    /// divided by their sum (`None` when they are all 0).
    #[must_use]
    pub fn where_given_contact(&self) -> Option<Vec<f64>> {
        let total: f64 = self.points.iter().sum();
        (total > 0.0 && total.is_finite()).then(|| self.points.iter().map(|p| p / total).collect())
    }

    /// Divides by the total; `false` (and unchanged) when it is 0 or not finite.
    fn normalize(&mut self) -> bool {
        let total = self.no_contact + self.points.iter().sum::<f64>();
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
        Ok(Self {
            settings,
            graph: SurfaceGraph::new(surface),
            prior,
        })
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
        }
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
        let contact: f64 = belief.points.iter().sum();
        let mut moved = belief.points.clone();
        let mut scratch = Vec::new();
        self.graph.diffuse(&mut moved, self.slide_rate(), dt_secs, &mut scratch);
        let stay = (1.0 - s.release) * (1.0 - s.jump);
        let fresh = belief.no_contact * s.onset + (1.0 - s.release) * s.jump * contact;
        Belief {
            no_contact: belief.no_contact * (1.0 - s.onset) + contact * s.release,
            points: moved
                .iter()
                .zip(&self.prior)
                .map(|(m, prior)| stay * m + fresh * prior)
                .collect(),
        }
    }

    /// The backward message one frame earlier: for each state, the chance
    /// of what follows given it (up to a factor), from `later` = the next
    /// frame's scaled likelihoods times its backward message.
    fn backward(&self, later: &Belief, dt_secs: f64) -> Belief {
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
        }
    }

    /// `predicted` after measuring `scaled` (the frame's likelihoods over
    /// their largest, no contact first); if nothing predicted is
    /// consistent with the measurement (all products 0), the measurement
    /// alone under the prior.
    fn correct(&self, predicted: &Belief, scaled: &[f64]) -> Belief {
        let (none, points) = scaled.split_first().unwrap_or((&0.0, &[]));
        let mut out = Belief {
            no_contact: predicted.no_contact * none,
            points: predicted.points.iter().zip(points).map(|(p, l)| p * l).collect(),
        };
        if out.normalize() {
            return out;
        }
        let mut fresh = self.initial();
        fresh.no_contact *= none;
        for (p, l) in fresh.points.iter_mut().zip(points) {
            *p *= l;
        }
        if fresh.normalize() { fresh } else { self.initial() }
    }

    fn check(&self, frame: usize, likelihood: &FrameLikelihood) -> Result<(), TemporalError> {
        if likelihood.points.len() == self.prior.len() {
            Ok(())
        } else {
            Err(TemporalError::WrongLength {
                frame,
                points: likelihood.points.len(),
                expected: self.prior.len(),
            })
        }
    }
}

/// Checks that `t_secs` follows `previous` and gives the interval.
fn interval(frame: usize, previous: Option<f64>, t_secs: f64) -> Result<f64, TemporalError> {
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

/// The forward filter: each frame's belief from that frame and the ones
/// before (what a live robot can know).
#[derive(Debug, Clone)]
pub struct Filter<'a> {
    model: &'a TemporalModel,
    belief: Option<Belief>,
    last_t_secs: Option<f64>,
    frames: usize,
}

impl<'a> Filter<'a> {
    /// A filter that has seen nothing yet.
    #[must_use]
    pub fn new(model: &'a TemporalModel) -> Self {
        Self {
            model,
            belief: None,
            last_t_secs: None,
            frames: 0,
        }
    }

    /// Takes the frame at `t_secs` and returns the belief after it.
    ///
    /// # Errors
    /// [`TemporalError::WrongLength`], [`TemporalError::BadTime`].
    pub fn step(&mut self, t_secs: f64, likelihood: &FrameLikelihood) -> Result<&Belief, TemporalError> {
        self.model.check(self.frames, likelihood)?;
        let dt = interval(self.frames, self.last_t_secs, t_secs)?;
        let predicted = match &self.belief {
            Some(b) => self.model.predict(b, dt),
            None => self.model.initial(),
        };
        let (_, scaled) = likelihood.scaled();
        self.frames += 1;
        self.last_t_secs = Some(t_secs);
        Ok(self.belief.insert(self.model.correct(&predicted, &scaled)))
    }
}

/// The forward–backward smoother: frames are pushed in order (the forward
/// pass runs as they come), then [`Smoother::finish`] gives every frame's
/// belief given the whole recording. It holds each frame's scaled
/// likelihoods and filtered belief in f32 (8 bytes per sample and frame,
/// at most [`MAX_SMOOTHER_BYTES`]).
#[derive(Debug, Clone)]
pub struct Smoother<'a> {
    filter: Filter<'a>,
    times: Vec<f64>,
    scaled: Vec<Vec<f32>>,
    filtered: Vec<Vec<f32>>,
}

impl<'a> Smoother<'a> {
    /// A smoother that has seen nothing yet.
    #[must_use]
    pub fn new(model: &'a TemporalModel) -> Self {
        Self {
            filter: Filter::new(model),
            times: Vec::new(),
            scaled: Vec::new(),
            filtered: Vec::new(),
        }
    }

    /// Takes the next frame; returns its filtered belief.
    ///
    /// # Errors
    /// As [`Filter::step`], and [`TemporalError::TooLarge`] past the store's limit.
    pub fn push(&mut self, t_secs: f64, likelihood: &FrameLikelihood) -> Result<&Belief, TemporalError> {
        let points = likelihood.points.len();
        let bytes = (self.times.len() + 1).saturating_mul(points + 1).saturating_mul(8);
        if bytes > MAX_SMOOTHER_BYTES {
            return Err(TemporalError::TooLarge {
                frames: self.times.len() + 1,
                points,
                limit_bytes: MAX_SMOOTHER_BYTES,
            });
        }
        let belief = self.filter.step(t_secs, likelihood)?;
        let (_, scaled) = likelihood.scaled();
        self.times.push(t_secs);
        self.scaled.push(scaled.iter().map(|&v| v as f32).collect());
        let mut stored = Vec::with_capacity(points + 1);
        stored.push(belief.no_contact as f32);
        stored.extend(belief.points.iter().map(|&p| p as f32));
        self.filtered.push(stored);
        Ok(belief)
    }

    /// Frames pushed so far.
    #[must_use]
    pub fn len(&self) -> usize {
        self.times.len()
    }

    /// True before the first frame.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.times.is_empty()
    }

    /// Every frame's belief given all frames, in order.
    #[must_use]
    pub fn finish(self) -> Vec<Belief> {
        let model = self.filter.model;
        let to_belief = |v: &[f32]| {
            let (none, points) = v.split_first().unwrap_or((&0.0, &[]));
            Belief {
                no_contact: f64::from(*none),
                points: points.iter().map(|&p| f64::from(p)).collect(),
            }
        };
        let n = self.times.len();
        let mut out: Vec<Belief> = Vec::with_capacity(n);
        // β of the last frame is 1 everywhere.
        let points = self.filtered.first().map_or(0, |f| f.len().saturating_sub(1));
        let mut beta = Belief {
            no_contact: 1.0,
            points: vec![1.0; points],
        };
        for t in (0..n).rev() {
            let (Some(alpha), Some(scaled)) = (self.filtered.get(t), self.scaled.get(t)) else {
                continue;
            };
            let mut smoothed = to_belief(alpha);
            smoothed.no_contact *= beta.no_contact;
            for (s, b) in smoothed.points.iter_mut().zip(&beta.points) {
                *s *= b;
            }
            if !smoothed.normalize() {
                smoothed = to_belief(alpha);
            }
            out.push(smoothed);
            if t > 0 {
                // The message for frame t-1: this frame's likelihood times β.
                let mut later = to_belief(scaled);
                later.no_contact *= beta.no_contact;
                for (l, b) in later.points.iter_mut().zip(&beta.points) {
                    *l *= b;
                }
                let dt = match (self.times.get(t), self.times.get(t - 1)) {
                    (Some(a), Some(b)) => (a - b).max(0.0),
                    _ => 0.0,
                };
                let mut next = model.backward(&later, dt);
                if !next.normalize() {
                    next = Belief {
                        no_contact: 1.0,
                        points: vec![1.0; points],
                    };
                }
                beta = next;
            }
        }
        out.reverse();
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A chain of `n` samples 1 cm apart, each hop weight `(1/m_k + 1/m_j)/d²`.
    fn chain(n: usize) -> SurfaceGraph {
        let d2 = 1e-4;
        let count = |k: usize| if k == 0 || k + 1 == n { 1.0 } else { 2.0 };
        let mut g = SurfaceGraph::default();
        for k in 0..n {
            g.start.push(g.neighbour.len() as u32);
            let mut rate = 0.0;
            for j in [k.wrapping_sub(1), k + 1] {
                if j < n {
                    let w = (1.0 / count(k) + 1.0 / count(j)) / d2;
                    g.neighbour.push(j as u32);
                    g.weight.push(w);
                    rate += w;
                }
            }
            g.max_rate = g.max_rate.max(rate);
        }
        g.start.push(g.neighbour.len() as u32);
        g
    }

    fn model(n: usize, settings: TemporalSettings) -> TemporalModel {
        TemporalModel {
            settings,
            graph: chain(n),
            prior: (0..n)
                .map(|k| (k + 1) as f64)
                .map(|w| w / (n * (n + 1) / 2) as f64)
                .collect(),
        }
    }

    /// The transition matrix over states (no contact first) written out
    /// densely from the model's definition: the walk as repeated dense
    /// Euler steps.
    fn dense_transitions(m: &TemporalModel, dt: f64) -> Vec<Vec<f64>> {
        let n = m.prior.len();
        let s = m.settings;
        let p = |rate: f64| 1.0 - (-rate * dt).exp();
        let (on, off, jump) = (p(s.onset_per_s), p(s.release_per_s), p(s.jump_per_s));
        let scale = s.slide_m_per_sqrt_s * s.slide_m_per_sqrt_s;
        let fastest = m.graph.max_rate * scale;
        let steps = ((fastest * dt / 0.5).ceil() as usize).max(1);
        let h = (dt / steps as f64).min(0.5 / fastest) * scale;
        let mut walk: Vec<Vec<f64>> = (0..n)
            .map(|i| (0..n).map(|j| f64::from(u8::from(i == j))).collect())
            .collect();
        for _ in 0..steps {
            let mut next = walk.clone();
            for i in 0..n {
                for j in 0..n {
                    let (around, weights) = m.graph.neighbours(j);
                    let flow: f64 = around
                        .iter()
                        .zip(weights)
                        .map(|(&l, &w)| w * (walk[i][l as usize] - walk[i][j]))
                        .sum();
                    next[i][j] = walk[i][j] + h * flow;
                }
            }
            walk = next;
        }
        let mut t = vec![vec![0.0; n + 1]; n + 1];
        t[0][0] = 1.0 - on;
        for j in 0..n {
            t[0][j + 1] = on * m.prior[j];
            t[j + 1][0] = off;
            for k in 0..n {
                t[j + 1][k + 1] = (1.0 - off) * ((1.0 - jump) * walk[j][k] + jump * m.prior[k]);
            }
        }
        t
    }

    /// Smoothing by summing over every path of states (independent of the
    /// message passing): P(state at t | all frames).
    fn brute_force(m: &TemporalModel, times: &[f64], frames: &[FrameLikelihood]) -> Vec<Vec<f64>> {
        let n = m.prior.len() + 1;
        let init = m.initial();
        let start: Vec<f64> = std::iter::once(init.no_contact)
            .chain(init.points.iter().copied())
            .collect();
        let lik = |t: usize, s: usize| -> f64 {
            if s == 0 {
                frames[t].no_contact.exp()
            } else {
                frames[t].points[s - 1].exp()
            }
        };
        let steps: Vec<Vec<Vec<f64>>> = (1..times.len())
            .map(|t| dense_transitions(m, times[t] - times[t - 1]))
            .collect();
        let len = times.len();
        let mut marginal = vec![vec![0.0; n]; len];
        let mut path = vec![0usize; len];
        loop {
            let mut w = start[path[0]] * lik(0, path[0]);
            for t in 1..len {
                w *= steps[t - 1][path[t - 1]][path[t]] * lik(t, path[t]);
            }
            for t in 0..len {
                marginal[t][path[t]] += w;
            }
            // Next path (odometer).
            let mut i = 0;
            loop {
                if i == len {
                    for row in &mut marginal {
                        let total: f64 = row.iter().sum();
                        for v in row.iter_mut() {
                            *v /= total;
                        }
                    }
                    return marginal;
                }
                path[i] += 1;
                if path[i] < n {
                    break;
                }
                path[i] = 0;
                i += 1;
            }
        }
    }

    fn frames() -> (Vec<f64>, Vec<FrameLikelihood>) {
        let times = vec![0.0, 0.005, 0.012, 0.5, 0.505];
        let frames = vec![
            FrameLikelihood {
                no_contact: -1.0,
                points: vec![-3.0, -0.5, -2.0, -4.0],
            },
            FrameLikelihood {
                no_contact: -6.0,
                points: vec![-1.0, -0.2, -5.0, -9.0],
            },
            FrameLikelihood {
                no_contact: -2.0,
                points: vec![-2.5, -1.5, -0.3, f64::NEG_INFINITY],
            },
            FrameLikelihood {
                no_contact: -0.1,
                points: vec![-3.0, -3.0, -1.0, -2.0],
            },
            FrameLikelihood {
                no_contact: -4.0,
                points: vec![-0.4, -2.0, -2.0, -0.1],
            },
        ];
        (times, frames)
    }

    #[test]
    fn the_smoother_matches_summing_over_every_path() {
        let settings = TemporalSettings {
            onset_per_s: 3.0,
            release_per_s: 5.0,
            slide_m_per_sqrt_s: 0.03,
            jump_per_s: 2.0,
        };
        let m = model(4, settings);
        let (times, frames) = frames();
        let exact = brute_force(&m, &times, &frames);
        let mut smoother = Smoother::new(&m);
        for (t, f) in times.iter().zip(&frames) {
            smoother.push(*t, f).unwrap();
        }
        let smoothed = smoother.finish();
        for (t, (b, e)) in smoothed.iter().zip(&exact).enumerate() {
            let got: Vec<f64> = std::iter::once(b.no_contact).chain(b.points.iter().copied()).collect();
            for (g, x) in got.iter().zip(e) {
                assert!((g - x).abs() < 1e-6, "frame {t}: {got:?} vs {e:?}");
            }
        }
        // The filter's last belief is the smoother's last.
        let mut filter = Filter::new(&m);
        let mut last = None;
        for (t, f) in times.iter().zip(&frames) {
            last = Some(filter.step(*t, f).unwrap().clone());
        }
        let last = last.unwrap();
        let end = exact.last().unwrap();
        assert!((last.no_contact - end[0]).abs() < 1e-6);
    }

    #[test]
    fn the_walk_keeps_the_total_and_spreads_as_the_length_scale_says() {
        let n = 201;
        let g = chain(n);
        let mut v = vec![0.0; n];
        v[100] = 1.0;
        let mut scratch = Vec::new();
        let (l, t) = (0.02, 0.5);
        g.diffuse(&mut v, l * l, t, &mut scratch);
        let total: f64 = v.iter().sum();
        assert!((total - 1.0).abs() < 1e-12, "{total}");
        assert!(v.iter().all(|&x| x >= 0.0));
        // On a line of spacing d with weights 1/d² per neighbour the
        // variance grows by 2ℓ² per second (a chain is one surface
        // direction with twice the per-direction rate).
        let var: f64 = v
            .iter()
            .enumerate()
            .map(|(k, p)| p * ((k as f64 - 100.0) * 0.01).powi(2))
            .sum();
        assert!((var / (2.0 * l * l * t) - 1.0).abs() < 0.05, "variance {var}");
    }

    #[test]
    fn a_persistent_contact_is_believed_and_its_end_is_noticed() {
        let m = model(4, TemporalSettings::default());
        let mut filter = Filter::new(&m);
        let favour = |k: usize, strength: f64| FrameLikelihood {
            no_contact: -strength,
            points: (0..4).map(|j| if j == k { 0.0 } else { -strength }).collect(),
        };
        for i in 0..40 {
            let b = filter.step(f64::from(i) * 0.005, &favour(2, 3.0)).unwrap();
            if i >= 3 {
                assert!(b.contact_probability() > 0.9, "frame {i}: {}", b.contact_probability());
                assert!(b.points[2] > 0.8);
            }
        }
        let quiet = FrameLikelihood {
            no_contact: 0.0,
            points: vec![-3.0; 4],
        };
        let mut p = 1.0;
        for i in 40..50 {
            p = filter.step(f64::from(i) * 0.005, &quiet).unwrap().contact_probability();
        }
        assert!(p < 0.1, "{p}");
    }

    #[test]
    fn bad_settings_frames_and_times_are_errors() {
        let bad = TemporalSettings {
            slide_m_per_sqrt_s: f64::NAN,
            ..TemporalSettings::default()
        };
        assert!(matches!(
            bad.validate(),
            Err(TemporalError::BadSetting { name: "slide", .. })
        ));
        let m = model(3, TemporalSettings::default());
        let mut filter = Filter::new(&m);
        let short = FrameLikelihood {
            no_contact: 0.0,
            points: vec![0.0; 2],
        };
        assert!(matches!(
            filter.step(0.0, &short),
            Err(TemporalError::WrongLength { .. })
        ));
        let ok = FrameLikelihood {
            no_contact: 0.0,
            points: vec![0.0; 3],
        };
        filter.step(1.0, &ok).unwrap();
        assert!(matches!(filter.step(0.5, &ok), Err(TemporalError::BadTime { .. })));
        assert!(matches!(filter.step(f64::NAN, &ok), Err(TemporalError::BadTime { .. })));
        // Every likelihood -inf but no contact's: no contact, no NaN.
        let none = FrameLikelihood {
            no_contact: -1e9,
            points: vec![f64::NEG_INFINITY; 3],
        };
        let b = filter.step(2.0, &none).unwrap();
        assert!(b.no_contact.is_finite() && (b.no_contact - 1.0).abs() < 1e-12);
    }
}
