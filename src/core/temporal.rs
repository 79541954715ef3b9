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
//! the sample's tangents (see [`PatchInformation`]), so that over a press
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

use crate::core::contact::PatchForms;
use crate::core::estimator::Posterior;
use crate::core::fastmath;
use crate::core::lanes;
use crate::core::simd::{Kernel, widest};
use crate::core::surface::{Surface, WINDOW_FRACTION};

/// Neighbours are the samples of the same link within this many sample
/// spacings (about 6–10 each for evenly spread samples).
pub const NEIGHBOUR_SPACINGS: f64 = 1.8;

/// How far from its sample (in patch widths ρ) a contact's offset may be
/// believed to lie: samples are two widths apart, so a patch reaches half
/// way past the middle to its neighbours.
pub const PATCH_REACH: f64 = 1.5;

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
    /// Per sample (integrated over its patch when `patch` is given).
    pub points: Vec<f64>,
    /// Per sample, what the frame says about the place of the contact
    /// within the sample's patch; empty when the samples are points.
    pub patch: Vec<PatchInformation>,
}

/// What one frame says about the offset `s` (m, along the sample's two
/// tangents) of a contact within a sample's patch:
/// `ln L(s) ≈ ln L(0) + shiftᵀ s - ½ sᵀ information s`.
///
/// A contact that lasts keeps its offset: over a press the patch must be
/// integrated once, over the product of the frames' likelihoods, not once
/// per frame (the product of per-frame patch integrals lets a sample
/// explain every frame with a different offset, and charges a contact
/// that lies between samples its distance once per frame: over a
/// hundred-frame press that makes the answer a property of the grid).
/// With these terms the temporal model carries, per sample, a Gaussian
/// over the offset and integrates it exactly.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct PatchInformation {
    /// `ln L(0)`: the sample's own log-likelihood (the magnitude
    /// profiled, with the frame's one Occam charge; no patch, no area), on
    /// the same scale as [`FrameLikelihood::no_contact`].
    pub point: f64,
    /// `[m11, m12, m22]`, 1/m².
    pub information: [f64; 3],
    /// `[n1, n2]`, 1/m.
    pub shift: [f64; 2],
}

impl PatchInformation {
    /// Each sample's terms from a frame's [`PatchForms`], with push
    /// magnitudes in `(f_min, f_max)` N: the magnitude is profiled out
    /// (the offset's information is what is left of the tangents' once
    /// the push direction's is taken away) and the offset scaled by the
    /// sample's best magnitude `f₀`, as the per-frame patch integral does.
    #[must_use]
    pub fn from_forms(forms: &PatchForms, c: f64, (f_min, f_max): (f64, f64)) -> Vec<Self> {
        let f = forms;
        let f_max = f_max.max(f_min);
        // The magnitude's Occam factor, `√(2π/a) / (f_max - f_min)`, taken
        // at the frame's median `a` (of every 8th sample: the charge need
        // only be the same for all): one charge for every sample (see the
        // struct's docs).
        let mut sensitive: Vec<f64> =
            f.a.iter()
                .step_by(8)
                .copied()
                .filter(|&a| a > 0.0 && a.is_finite())
                .collect();
        let a_typical = if sensitive.is_empty() {
            1.0
        } else {
            let mid = sensitive.len() / 2;
            *sensitive.select_nth_unstable_by(mid, f64::total_cmp).1
        };
        let occam = 0.5 * (std::f64::consts::TAU / a_typical).ln() - (f_max - f_min).max(f64::MIN_POSITIVE).ln();
        let mut out = widest(InformationKernel {
            forms: f,
            c,
            occam,
            force_range: (f_min, f_max),
        });
        out.resize(
            f.a.len(),
            Self {
                point: f64::NEG_INFINITY,
                ..Self::default()
            },
        );
        out
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

/// [`TemporalModel::gains`]' loop: per sample, its likelihood with the
/// frame absorbed into its offset ([`Offset::absorb_within`] within
/// [`PATCH_REACH`] windows), and the offset after; a sample the frame did
/// not score keeps its likelihood and offset.
struct GainsKernel<'a> {
    points: &'a [f64],
    patch: &'a [PatchInformation],
    offsets: &'a [Offset],
    window_m: &'a [f64],
}

/// Samples [`GainsKernel`] takes at once (one AVX2 register).
const GAIN_LANES: usize = 4;

impl Kernel for GainsKernel<'_> {
    type Output = (Vec<f64>, Vec<Offset>);
    #[inline(always)]
    fn run(self) -> (Vec<f64>, Vec<Offset>) {
        let n = [
            self.points.len(),
            self.patch.len(),
            self.offsets.len(),
            self.window_m.len(),
        ]
        .into_iter()
        .min()
        .unwrap_or(0);
        let mut gains = vec![0.0; n];
        let mut after = vec![Offset::window(1.0); n];
        let mut k = 0;
        while k + GAIN_LANES <= n {
            gains_at::<GAIN_LANES>(&self, k, &mut gains, &mut after);
            k += GAIN_LANES;
        }
        while k < n {
            gains_at::<1>(&self, k, &mut gains, &mut after);
            k += 1;
        }
        (gains, after)
    }
}

/// `[f64; L]` from a function of the lane: written out as a loop, not
/// `array::from_fn` (a closure is not inlined into the wide copy).
macro_rules! lanes {
    ($l:ident, $L:expr, $e:expr) => {{
        let mut out = [0.0; $L];
        for $l in 0..$L {
            out[$l] = $e;
        }
        out
    }};
}

/// [`GainsKernel`] for the `L` samples from `k`: [`Offset::absorb_within`]
/// written lane by lane without branches (both sides computed, one kept),
/// each operation a loop over the lanes, so that it is one vector
/// instruction.
#[inline(always)]
#[allow(clippy::too_many_lines)] // one formula, written out lane by lane
fn gains_at<const L: usize>(kernel: &GainsKernel, k: usize, gains: &mut [f64], after: &mut [Offset]) {
    let range = k..k + L;
    let (Some(points), Some(patch), Some(offsets), Some(window_m), Some(gains), Some(after)) = (
        kernel.points.get(range.clone()),
        kernel.patch.get(range.clone()),
        kernel.offsets.get(range.clone()),
        kernel.window_m.get(range.clone()),
        gains.get_mut(range.clone()),
        after.get_mut(range),
    ) else {
        return;
    };
    let (Ok(points), Ok(patch), Ok(offsets), Ok(window_m), Ok(gains), Ok(after)) = (
        <&[f64; L]>::try_from(points),
        <&[PatchInformation; L]>::try_from(patch),
        <&[Offset; L]>::try_from(offsets),
        <&[f64; L]>::try_from(window_m),
        <&mut [f64; L]>::try_from(gains),
        <&mut [Offset; L]>::try_from(after),
    ) else {
        return;
    };
    let l11 = lanes!(i, L, offsets[i].precision[0]);
    let l12 = lanes!(i, L, offsets[i].precision[1]);
    let l22 = lanes!(i, L, offsets[i].precision[2]);
    let n1 = lanes!(i, L, offsets[i].shift[0]);
    let n2 = lanes!(i, L, offsets[i].shift[1]);
    let a11 = lanes!(i, L, l11[i] + patch[i].information[0]);
    let a12 = lanes!(i, L, l12[i] + patch[i].information[1]);
    let a22 = lanes!(i, L, l22[i] + patch[i].information[2]);
    let p1 = lanes!(i, L, n1[i] + patch[i].shift[0]);
    let p2 = lanes!(i, L, n2[i] + patch[i].shift[1]);
    let point = lanes!(i, L, patch[i].point);
    let d0 = lanes!(i, L, l11[i] * l22[i] - l12[i] * l12[i]);
    let d1 = lanes!(i, L, a11[i] * a22[i] - a12[i] * a12[i]);
    let i0 = lanes!(i, L, 1.0 / d0[i]);
    let i1 = lanes!(i, L, 1.0 / d1[i]);
    let u1 = lanes!(i, L, (l22[i] * n1[i] - l12[i] * n2[i]) * i0[i]);
    let u2 = lanes!(i, L, (l11[i] * n2[i] - l12[i] * n1[i]) * i0[i]);
    let v1 = lanes!(i, L, (a22[i] * p1[i] - a12[i] * p2[i]) * i1[i]);
    let v2 = lanes!(i, L, (a11[i] * p2[i] - a12[i] * p1[i]) * i1[i]);
    let reach = lanes!(i, L, PATCH_REACH * window_m[i]);
    let charged = lanes!(
        i,
        L,
        charge_beyond(v1[i], v2[i], a11[i], a12[i], a22[i], reach[i])
            - charge_beyond(u1[i], u2[i], l11[i], l12[i], l22[i], reach[i])
    );
    // Scored: the frame and the sample have finite likelihoods. Defined:
    // scored, and both precisions positive definite; elsewhere the `ln`
    // gets 1 and its result is not kept.
    let scored = lanes!(
        i,
        L,
        if points[i].abs() < f64::INFINITY && point[i].abs() < f64::INFINITY {
            1.0
        } else {
            0.0
        }
    );
    let defined = lanes!(
        i,
        L,
        if scored[i] > 0.0 && d0[i] > 0.0 && d1[i] > 0.0 && d1[i] < f64::INFINITY {
            1.0
        } else {
            0.0
        }
    );
    let ratio = lanes!(i, L, if defined[i] > 0.0 { d1[i] * i0[i] } else { 1.0 });
    let ln_ratio = lanes!(i, L, fastmath::ln(ratio[i]));
    let gain = lanes!(
        i,
        L,
        0.5 * (p1[i] * v1[i] + p2[i] * v2[i] - n1[i] * u1[i] - n2[i] * u2[i]) - 0.5 * ln_ratio[i] - charged[i]
    );
    for i in 0..L {
        gains[i] = if scored[i] > 0.0 {
            point[i] + if defined[i] > 0.0 { gain[i] } else { 0.0 }
        } else {
            points[i]
        };
    }
    for i in 0..L {
        after[i] = if defined[i] > 0.0 {
            Offset {
                precision: [a11[i], a12[i], a22[i]],
                shift: [p1[i], p2[i]],
            }
        } else {
            offsets[i]
        };
    }
}

/// `½ dᵀ C d` for the part `d` of the mean `x` beyond `reach_m` of the
/// patch's centre (0 within), branch free.
#[inline(always)]
fn charge_beyond(x1: f64, x2: f64, c11: f64, c12: f64, c22: f64, reach_m: f64) -> f64 {
    let r2 = x1 * x1 + x2 * x2;
    let k = 1.0 - reach_m / r2.sqrt();
    let (d1, d2) = (x1 * k, x2 * k);
    let value = 0.5 * (c11 * d1 * d1 + 2.0 * c12 * d1 * d2 + c22 * d2 * d2);
    if r2 > reach_m * reach_m { value } else { 0.0 }
}

/// The per-sample loop of [`PatchInformation::from_forms`] over the
/// samples that every form has, branch free so that it vectorises.
struct InformationKernel<'a> {
    forms: &'a PatchForms,
    c: f64,
    occam: f64,
    force_range: (f64, f64),
}

impl Kernel for InformationKernel<'_> {
    type Output = Vec<PatchInformation>;
    #[inline(always)]
    fn run(self) -> Vec<PatchInformation> {
        let (f, c, occam) = (self.forms, self.c, self.occam);
        let (f_min, f_max) = self.force_range;
        let n = [f.a.len(), f.b.len(), f.h1.len(), f.h2.len(), f.e1.len()]
            .into_iter()
            .chain([f.e2.len(), f.g11.len(), f.g12.len(), f.g22.len()])
            .min()
            .unwrap_or(0);
        let (a_all, b_all, h1_all, h2_all) = (&f.a[..n], &f.b[..n], &f.h1[..n], &f.h2[..n]);
        let (e1_all, e2_all) = (&f.e1[..n], &f.e2[..n]);
        let (g11_all, g12_all, g22_all) = (&f.g11[..n], &f.g12[..n], &f.g22[..n]);
        // Torques that do not see the push: no contact's fit.
        let unseen = PatchInformation {
            point: -0.5 * c + occam,
            ..PatchInformation::default()
        };
        let mut out = vec![unseen; n];
        for k in 0..n {
            let (a, b) = (a_all[k], b_all[k]);
            let seen = a > 0.0 && a.is_finite();
            let inv_a = 1.0 / a;
            // `clamp` without its check (which stops the loop from
            // vectorising): the same value, `f_min ≤ f_max` holding.
            let q = b * inv_a;
            let f0 = if q < f_min {
                f_min
            } else if q > f_max {
                f_max
            } else {
                q
            };
            let chi2 = (c - 2.0 * b * f0 + a * f0 * f0).max(0.0);
            let (h1, h2) = (h1_all[k], h2_all[k]);
            let m11 = (g11_all[k] - h1 * h1 * inv_a).max(0.0);
            let m22 = (g22_all[k] - h2 * h2 * inv_a).max(0.0);
            // Rounding must not make the Schur complement indefinite.
            let limit = (m11 * m22).sqrt();
            let m12 = g12_all[k] - h1 * h2 * inv_a;
            let m12 = if m12 < -limit {
                -limit
            } else if m12 > limit {
                limit
            } else {
                m12
            };
            let f2 = f0 * f0;
            let fitted = PatchInformation {
                point: -0.5 * chi2 + occam,
                information: [f2 * m11, f2 * m12, f2 * m22],
                shift: [f0 * (e1_all[k] - h1 * b * inv_a), f0 * (e2_all[k] - h2 * b * inv_a)],
            };
            out[k] = if seen { fitted } else { unseen };
        }
        out
    }
}

/// A Gaussian over a contact's offset within its sample's patch, in
/// information form: precision `[l11, l12, l22]` (1/m²) and
/// precision × mean `[n1, n2]` (1/m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Offset {
    /// Precision.
    pub precision: [f64; 3],
    /// Precision × mean.
    pub shift: [f64; 2],
}

impl Offset {
    /// The patch window of width `rho_m`: mean 0, variance ρ² each way.
    #[must_use]
    pub fn window(rho_m: f64) -> Self {
        let q = 1.0 / (rho_m * rho_m);
        Self {
            precision: [q, 0.0, q],
            shift: [0.0, 0.0],
        }
    }

    /// `det` of the precision.
    fn det(&self) -> f64 {
        let [l11, l12, l22] = self.precision;
        l11 * l22 - l12 * l12
    }

    /// `nᵀ Λ⁻¹ n` (0 when Λ is singular).
    fn explained(&self) -> f64 {
        let [l11, l12, l22] = self.precision;
        let [n1, n2] = self.shift;
        let det = self.det();
        if det > 0.0 {
            (l22 * n1 * n1 - 2.0 * l12 * n1 * n2 + l11 * n2 * n2) / det
        } else {
            0.0
        }
    }

    /// The mean, m.
    #[must_use]
    pub fn mean_m(&self) -> [f64; 2] {
        let [l11, l12, l22] = self.precision;
        let [n1, n2] = self.shift;
        let det = self.det();
        let mean = [(l22 * n1 - l12 * n2) / det, (l11 * n2 - l12 * n1) / det];
        // A precision that is singular, or so large (a σ far below the
        // torques' own precision) that its products overflow, says nothing
        // usable about the offset: the sample's own place.
        if det > 0.0 && mean.iter().all(|m| m.is_finite()) {
            mean
        } else {
            [0.0, 0.0]
        }
    }

    /// A frame's information taken in: returns `ln ∫ N(s; self) L(s) ds -
    /// ln L(0)` less the change of [`Offset::confined`]'s charge (for a
    /// reach of `reach_m`), and the Gaussian after it (not confined: it
    /// keeps every frame's information). 0 and itself when a precision is
    /// not positive definite. One sample at a time: the reference that
    /// the filter's `GainsKernel`, which does this for four samples at
    /// once without branches, is tested against.
    #[cfg(test)]
    fn absorb_within(&self, frame: &PatchInformation, reach_m: f64) -> (f64, Self) {
        let [l11, l12, l22] = self.precision;
        let [n1, n2] = self.shift;
        let [m11, m12, m22] = frame.information;
        let (a11, a12, a22) = (l11 + m11, l12 + m12, l22 + m22);
        let (p1, p2) = (n1 + frame.shift[0], n2 + frame.shift[1]);
        let (d0, d1) = (l11 * l22 - l12 * l12, a11 * a22 - a12 * a12);
        if !(d0 > 0.0 && d1 > 0.0 && d1.is_finite()) {
            return (0.0, *self);
        }
        let (i0, i1) = (1.0 / d0, 1.0 / d1);
        // Means, and nᵀΛ⁻¹n = n·μ.
        let (u1, u2) = ((l22 * n1 - l12 * n2) * i0, (l11 * n2 - l12 * n1) * i0);
        let (v1, v2) = ((a22 * p1 - a12 * p2) * i1, (a11 * p2 - a12 * p1) * i1);
        let gain = 0.5 * (p1 * v1 + p2 * v2 - n1 * u1 - n2 * u2) - 0.5 * (d1 * i0).ln();
        let charge = |(x1, x2): (f64, f64), (c11, c12, c22): (f64, f64, f64)| {
            let r2 = x1 * x1 + x2 * x2;
            if r2 > reach_m * reach_m {
                let k = 1.0 - reach_m / r2.sqrt();
                let (d1, d2) = (x1 * k, x2 * k);
                0.5 * (c11 * d1 * d1 + 2.0 * c12 * d1 * d2 + c22 * d2 * d2)
            } else {
                0.0
            }
        };
        let charged = charge((v1, v2), (a11, a12, a22)) - charge((u1, u2), (l11, l12, l22));
        (
            gain - charged,
            Self {
                precision: [a11, a12, a22],
                shift: [p1, p2],
            },
        )
    }

    /// Kept within the patch: a linear model of the torques holds within
    /// a patch, not beyond (extrapolated along the tangent plane it
    /// explains torques that no point of the surface can: such offsets
    /// belong to the neighbouring samples). A mean farther than
    /// [`PATCH_REACH`] windows is moved to that distance, and the evidence
    /// loses `½ (μ - s)ᵀ Λ (μ - s)`: the Laplace approximation of the
    /// Gaussian confined to the disc. Returns that loss and the moved
    /// Gaussian.
    #[must_use]
    pub fn confined(&self, rho_m: f64) -> (f64, Self) {
        let [m1, m2] = self.mean_m();
        let reach = PATCH_REACH * rho_m;
        let r2 = m1 * m1 + m2 * m2;
        if r2.is_nan() || r2 <= reach * reach {
            return (0.0, *self);
        }
        let k = reach / r2.sqrt();
        let (s1, s2) = (m1 * k, m2 * k);
        let (d1, d2) = (m1 - s1, m2 - s2);
        let [l11, l12, l22] = self.precision;
        let penalty = 0.5 * (l11 * d1 * d1 + 2.0 * l12 * d1 * d2 + l22 * d2 * d2);
        (
            penalty,
            Self {
                precision: self.precision,
                shift: [l11 * s1 + l12 * s2, l12 * s1 + l22 * s2],
            },
        )
    }

    /// This Gaussian with weight `own` mixed with the patch window with
    /// weight `1 - own`, matched by its first two moments.
    fn mixed_with_window(&self, own: f64, rho_m: f64) -> Self {
        if own >= 1.0 {
            return *self;
        }
        let det = self.det();
        if own <= 0.0 || det <= 0.0 {
            return Self::window(rho_m);
        }
        let [l11, l12, l22] = self.precision;
        let [n1, n2] = self.shift;
        // One division for the covariance and the mean (`mean_m`'s).
        let inverse_det = 1.0 / det;
        let (s11, s12, s22) = (l22 * inverse_det, -l12 * inverse_det, l11 * inverse_det);
        let (m1, m2) = (s11 * n1 + s12 * n2, s12 * n1 + s22 * n2);
        let r2 = rho_m * rho_m;
        let w = 1.0 - own;
        // Second moments about 0, then about the mixture's mean `own·m`.
        let (a11, a12, a22) = (
            own * (s11 + m1 * m1) + w * r2,
            own * (s12 + m1 * m2),
            own * (s22 + m2 * m2) + w * r2,
        );
        let (c1, c2) = (own * m1, own * m2);
        let (v11, v12, v22) = (a11 - c1 * c1, a12 - c1 * c2, a22 - c2 * c2);
        let vdet = v11 * v22 - v12 * v12;
        if !(vdet > 0.0 && vdet.is_finite()) {
            return Self::window(rho_m);
        }
        let inverse_vdet = 1.0 / vdet;
        let (p11, p12, p22) = (v22 * inverse_vdet, -v12 * inverse_vdet, v11 * inverse_vdet);
        Self {
            precision: [p11, p12, p22],
            shift: [p11 * c1 + p12 * c2, p12 * c1 + p22 * c2],
        }
    }
}

/// `ln ∫ N(s; f) N(s; b) / N(s; window) ds` for a forward and a backward
/// belief's offsets of the same sample (0 when not defined).
fn overlap(forward: &Offset, backward: &Offset, rho_m: f64) -> f64 {
    let window = Offset::window(rho_m);
    let both = Offset {
        precision: [
            forward.precision[0] + backward.precision[0] - window.precision[0],
            forward.precision[1] + backward.precision[1],
            forward.precision[2] + backward.precision[2] - window.precision[2],
        ],
        shift: [
            forward.shift[0] + backward.shift[0],
            forward.shift[1] + backward.shift[1],
        ],
    };
    let (df, db, d, d0) = (forward.det(), backward.det(), both.det(), window.det());
    if !(df > 0.0 && db > 0.0 && d > 0.0 && both.precision[0] > 0.0 && d.is_finite()) {
        return 0.0;
    }
    0.5 * (both.explained() - forward.explained() - backward.explained()) + 0.5 * (df * db / (d * d0)).ln()
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
            .zip(&surface.ln_area)
            .map(|(&l, &ln_area)| if patches { l - ln_area } else { l })
            .collect();
        Self {
            no_contact: -0.5 * posterior.no_contact_chi2,
            points,
            patch: Vec::new(),
        }
    }

    /// The largest value (no contact's at least).
    fn top(&self) -> f64 {
        self.points
            .iter()
            .copied()
            .filter(|l| !l.is_nan())
            .fold(self.no_contact, f64::max)
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
    fn normalize(&mut self) -> bool {
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
            prior,
            window_m,
            hop_rate,
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
            offsets: self.window_m.iter().map(|&w| Offset::window(w)).collect(),
        }
    }

    /// Whether offsets within the patches are tracked.
    fn tracks_offsets(&self) -> bool {
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
    fn correct(&self, predicted: &Belief, likelihood: &FrameLikelihood) -> Belief {
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
    fn combine(&self, forward: &Belief, backward: &Belief) -> Belief {
        let contact = self.settings.stationary_contact().clamp(1e-300, 1.0 - 1e-16);
        let ln = |x: f64| if x > 0.0 { x.ln() } else { f64::NEG_INFINITY };
        let none = ln(forward.no_contact) + ln(backward.no_contact) - (1.0 - contact).ln();
        let n = forward.points.len();
        let tracked = forward.offsets.len() == n && backward.offsets.len() == n && self.window_m.len() == n;
        let mut offsets = Vec::with_capacity(if tracked { n } else { 0 });
        let logs: Vec<f64> = (0..n)
            .map(|k| {
                let (Some(&f), Some(&b), Some(&prior)) =
                    (forward.points.get(k), backward.points.get(k), self.prior.get(k))
                else {
                    return f64::NEG_INFINITY;
                };
                let mut l = ln(f) + ln(b) - ln(prior * contact);
                if tracked
                    && let (Some(fo), Some(bo), Some(&rho)) =
                        (forward.offsets.get(k), backward.offsets.get(k), self.window_m.get(k))
                {
                    let window = Offset::window(rho);
                    let both = Offset {
                        precision: [
                            fo.precision[0] + bo.precision[0] - window.precision[0],
                            fo.precision[1] + bo.precision[1],
                            fo.precision[2] + bo.precision[2] - window.precision[2],
                        ],
                        shift: [fo.shift[0] + bo.shift[0], fo.shift[1] + bo.shift[1]],
                    };
                    // Each half was charged for its own reach; the whole is
                    // charged for the whole's.
                    l += overlap(fo, bo, rho) + fo.confined(rho).0 + bo.confined(rho).0 - both.confined(rho).0;
                    offsets.push(both);
                }
                l
            })
            .collect();
        let top = logs.iter().copied().filter(|l| !l.is_nan()).fold(none, f64::max);
        let scale = |l: f64| {
            let d = l - top;
            if d > -700.0 { d.exp() } else { 0.0 }
        };
        let mut out = Belief {
            no_contact: scale(none),
            points: logs.iter().map(|&l| scale(l)).collect(),
            offsets,
        };
        if out.normalize() { out } else { forward.clone() }
    }

    fn check(&self, frame: usize, likelihood: &FrameLikelihood) -> Result<(), TemporalError> {
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

/// Bytes the [`Smoother`] holds for `frames` frames of `points` samples
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
    let mut intervals: Vec<f64> = times_secs
        .windows(2)
        .filter_map(|w| match w {
            [a, b] => Some(b - a),
            _ => None,
        })
        .filter(|dt| dt.is_finite())
        .collect();
    if intervals.is_empty() {
        return false;
    }
    let mid = intervals.len() / 2;
    let median = *intervals.select_nth_unstable_by(mid, f64::total_cmp).1;
    median * settings.release_per_s <= std::f64::consts::LN_2
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
}

/// A frame's likelihoods in f32 (relative to `top`).
#[derive(Debug, Clone)]
struct StoredFrame {
    top: f64,
    no_contact: f32,
    points: Vec<f32>,
    patch: Vec<[f32; 6]>,
}

/// A belief in f32.
#[derive(Debug, Clone)]
struct StoredBelief {
    no_contact: f32,
    points: Vec<f32>,
    offsets: Vec<[f32; 5]>,
}

impl StoredFrame {
    fn of(likelihood: &FrameLikelihood) -> Self {
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
    fn of(belief: &Belief) -> Self {
        Self {
            no_contact: belief.no_contact as f32,
            points: belief.points.iter().map(|&p| p as f32).collect(),
            offsets: belief
                .offsets
                .iter()
                .map(|o| {
                    let [l11, l12, l22] = o.precision;
                    let [n1, n2] = o.shift;
                    [l11 as f32, l12 as f32, l22 as f32, n1 as f32, n2 as f32]
                })
                .collect(),
        }
    }

    fn belief(&self) -> Belief {
        Belief {
            no_contact: f64::from(self.no_contact),
            points: self.points.iter().map(|&p| f64::from(p)).collect(),
            offsets: self
                .offsets
                .iter()
                .map(|&[l11, l12, l22, n1, n2]| Offset {
                    precision: [l11, l12, l22].map(f64::from),
                    shift: [n1, n2].map(f64::from),
                })
                .collect(),
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
        }
    }

    /// Takes the next frame; returns its filtered belief.
    ///
    /// # Errors
    /// As [`Filter::step`], and [`TemporalError::TooLarge`] past the store's limit.
    pub fn push(&mut self, t_secs: f64, likelihood: &FrameLikelihood) -> Result<&Belief, TemporalError> {
        let points = likelihood.points.len();
        let bytes = smoother_bytes(self.times.len() + 1, points, !likelihood.patch.is_empty());
        if bytes > MAX_SMOOTHER_BYTES {
            return Err(TemporalError::TooLarge {
                frames: self.times.len() + 1,
                points,
                limit_bytes: MAX_SMOOTHER_BYTES,
            });
        }
        let belief = self.filter.step(t_secs, likelihood)?;
        self.times.push(t_secs);
        self.frames.push(StoredFrame::of(likelihood));
        self.filtered.push(StoredBelief::of(belief));
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
        let tracked = self.filter.model.tracks_offsets() && self.frames.iter().all(|f| !f.patch.is_empty());
        if tracked { self.two_filters() } else { self.messages() }
    }

    fn dt(&self, t: usize) -> f64 {
        match (self.times.get(t + 1), self.times.get(t)) {
            (Some(a), Some(b)) => (a - b).max(0.0),
            _ => 0.0,
        }
    }

    /// Forward filter × a filter run backwards in time, over the prior.
    fn two_filters(self) -> Vec<Belief> {
        let model = self.filter.model;
        let n = self.times.len();
        let mut out: Vec<Belief> = Vec::with_capacity(n);
        let mut backward: Option<Belief> = None;
        for t in (0..n).rev() {
            let (Some(forward), Some(frame)) = (self.filtered.get(t), self.frames.get(t)) else {
                continue;
            };
            let predicted = match &backward {
                Some(b) => model.predict(b, self.dt(t)),
                None => model.initial(),
            };
            out.push(model.combine(&forward.belief(), &predicted));
            backward = Some(model.correct(&predicted, &frame.likelihood()));
        }
        out.reverse();
        out
    }

    /// Forward–backward messages (samples as points).
    fn messages(self) -> Vec<Belief> {
        let model = self.filter.model;
        let n = self.times.len();
        let mut out: Vec<Belief> = Vec::with_capacity(n);
        // β of the last frame is 1 everywhere.
        let points = self.filtered.first().map_or(0, |f| f.points.len());
        let ones = Belief {
            no_contact: 1.0,
            points: vec![1.0; points],
            offsets: Vec::new(),
        };
        let mut beta = ones.clone();
        for t in (0..n).rev() {
            let (Some(alpha), Some(frame)) = (self.filtered.get(t), self.frames.get(t)) else {
                continue;
            };
            let mut smoothed = alpha.belief();
            smoothed.no_contact *= beta.no_contact;
            for (s, b) in smoothed.points.iter_mut().zip(&beta.points) {
                *s *= b;
            }
            if !smoothed.normalize() {
                smoothed = alpha.belief();
            }
            out.push(smoothed);
            if t > 0 {
                // The message for frame t-1: this frame's likelihood times β.
                let mut later = frame.scaled();
                later.no_contact *= beta.no_contact;
                for (l, b) in later.points.iter_mut().zip(&beta.points) {
                    *l *= b;
                }
                let mut next = model.backward(&later, self.dt(t - 1));
                if !next.normalize() {
                    next = ones.clone();
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

    /// The branch-free loop of `PatchInformation::from_forms`, in the copy
    /// for the widest vector unit, against the plain formulas (with
    /// `f64::clamp`) sample by sample, bit for bit but for the shared
    /// Occam charge; samples whose torques do not see the push (a ≤ 0,
    /// NaN, ∞) get no contact's fit.
    /// The filter's gains, four samples at a time without branches,
    /// against [`Offset::absorb_within`] one sample at a time: random
    /// offsets and frames (means within and beyond the patch's reach),
    /// samples the frame did not score (-∞, NaN) and precisions that are
    /// not positive definite keep their likelihood and offset.
    #[test]
    fn gains_in_lanes_match_absorbing_one_sample_at_a_time() {
        use crate::core::rng::Rng;
        let n = 1003;
        let mut rng = Rng::new(17);
        let mut offsets = Vec::new();
        let mut patch = Vec::new();
        let mut points = Vec::new();
        let mut window_m = Vec::new();
        for _ in 0..n {
            let rho = rng.uniform_in(0.002, 0.02);
            let q = 1.0 / (rho * rho);
            let (s11, s22) = (q * rng.uniform_in(0.5, 3.0), q * rng.uniform_in(0.5, 3.0));
            let s12 = rng.uniform_in(-0.9, 0.9) * (s11 * s22).sqrt();
            // Shifts from means of about a window.
            let (x1, x2) = (rng.uniform_in(-1.0, 1.0) * rho, rng.uniform_in(-1.0, 1.0) * rho);
            offsets.push(Offset {
                precision: [s11, s12, s22],
                shift: [s11 * x1 + s12 * x2, s12 * x1 + s22 * x2],
            });
            let (m11, m22) = (q * rng.uniform_in(0.0, 50.0), q * rng.uniform_in(0.0, 50.0));
            let m12 = rng.uniform_in(-0.99, 0.99) * (m11 * m22).sqrt();
            let (y1, y2) = (rng.uniform_in(-2.0, 2.0) * rho, rng.uniform_in(-2.0, 2.0) * rho);
            patch.push(PatchInformation {
                point: rng.uniform_in(-200.0, 0.0),
                information: [m11, m12, m22],
                shift: [m11 * y1 + m12 * y2, m12 * y1 + m22 * y2],
            });
            points.push(rng.uniform_in(-200.0, 0.0));
            window_m.push(rho);
        }
        points[3] = f64::NEG_INFINITY;
        patch[4].point = f64::NAN;
        offsets[5].precision = [1.0, 2.0, 1.0];
        patch[6].information = [f64::INFINITY, 0.0, 1.0];
        let (gains, after) = widest(GainsKernel {
            points: &points,
            patch: &patch,
            offsets: &offsets,
            window_m: &window_m,
        });
        assert_eq!((gains.len(), after.len()), (n, n));
        let mut beyond = 0;
        for k in 0..n {
            let (l, frame, offset) = (points[k], patch[k], offsets[k]);
            let (want_gain, want_after) = if !l.is_finite() || !frame.point.is_finite() {
                (l, offset)
            } else {
                let (gain, absorbed) = offset.absorb_within(&frame, PATCH_REACH * window_m[k]);
                let (free, _) = offset.absorb_within(&frame, f64::INFINITY);
                if (free - gain).abs() > 1e-9 {
                    beyond += 1;
                }
                (frame.point + gain, absorbed)
            };
            let close =
                |x: f64, y: f64| x.to_bits() == y.to_bits() || (x - y).abs() <= 1e-12 * x.abs().max(y.abs()).max(1.0);
            assert!(
                close(gains[k], want_gain) || (gains[k].is_nan() && want_gain.is_nan()),
                "sample {k}: {} vs {want_gain}",
                gains[k]
            );
            assert_eq!(after[k], want_after, "sample {k}");
        }
        assert!(
            beyond > 50 && beyond < n - 50,
            "{beyond} samples charged beyond the reach"
        );
    }

    #[test]
    fn patch_information_matches_the_plain_formulas_bit_for_bit() {
        let n = 503;
        let mut forms = PatchForms::random(9, n, -10.0, 1e4);
        forms.a[7] = f64::NAN;
        forms.a[8] = 0.0;
        forms.a[9] = f64::INFINITY;
        let (c, range) = (300.0, (1.0, 30.0));
        let got = PatchInformation::from_forms(&forms, c, range);
        let occam = got
            .iter()
            .zip(&forms.a)
            .find(|(_, a)| !(**a > 0.0 && a.is_finite()))
            .map(|(p, _)| p.point + 0.5 * c)
            .unwrap();
        // The Occam charge is read back from an unseen sample (to rounding).
        let bits = |p: &PatchInformation| {
            [
                p.information[0],
                p.information[1],
                p.information[2],
                p.shift[0],
                p.shift[1],
            ]
            .map(f64::to_bits)
        };
        for (k, found) in got.iter().enumerate() {
            let (a, b) = (forms.a[k], forms.b[k]);
            let want = if a > 0.0 && a.is_finite() {
                let inv_a = 1.0 / a;
                let f0 = (b * inv_a).clamp(range.0, range.1);
                let chi2 = (c - 2.0 * b * f0 + a * f0 * f0).max(0.0);
                let (h1, h2) = (forms.h1[k], forms.h2[k]);
                let m11 = (forms.g11[k] - h1 * h1 * inv_a).max(0.0);
                let m22 = (forms.g22[k] - h2 * h2 * inv_a).max(0.0);
                let limit = (m11 * m22).sqrt();
                let m12 = (forms.g12[k] - h1 * h2 * inv_a).clamp(-limit, limit);
                let f2 = f0 * f0;
                PatchInformation {
                    point: -0.5 * chi2 + occam,
                    information: [f2 * m11, f2 * m12, f2 * m22],
                    shift: [f0 * (forms.e1[k] - h1 * b * inv_a), f0 * (forms.e2[k] - h2 * b * inv_a)],
                }
            } else {
                PatchInformation {
                    point: -0.5 * c + occam,
                    ..PatchInformation::default()
                }
            };
            assert_eq!(bits(found), bits(&want), "sample {k}");
            assert!(
                (found.point - want.point).abs() <= 1e-9 * want.point.abs().max(1.0),
                "sample {k}: {} against {}",
                found.point,
                want.point
            );
        }
    }

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
        let graph = chain(n);
        TemporalModel {
            settings,
            hop_rate: (0..n).map(|k| graph.neighbours(k).1.iter().sum()).collect(),
            window_m: Vec::new(),
            graph,
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
                patch: Vec::new(),
            },
            FrameLikelihood {
                no_contact: -6.0,
                points: vec![-1.0, -0.2, -5.0, -9.0],
                patch: Vec::new(),
            },
            FrameLikelihood {
                no_contact: -2.0,
                points: vec![-2.5, -1.5, -0.3, f64::NEG_INFINITY],
                patch: Vec::new(),
            },
            FrameLikelihood {
                no_contact: -0.1,
                points: vec![-3.0, -3.0, -1.0, -2.0],
                patch: Vec::new(),
            },
            FrameLikelihood {
                no_contact: -4.0,
                points: vec![-0.4, -2.0, -2.0, -0.1],
                patch: Vec::new(),
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
            patch: Vec::new(),
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
            patch: Vec::new(),
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
            patch: Vec::new(),
        };
        assert!(matches!(
            filter.step(0.0, &short),
            Err(TemporalError::WrongLength { .. })
        ));
        let ok = FrameLikelihood {
            no_contact: 0.0,
            points: vec![0.0; 3],
            patch: Vec::new(),
        };
        filter.step(1.0, &ok).unwrap();
        assert!(matches!(filter.step(0.5, &ok), Err(TemporalError::BadTime { .. })));
        assert!(matches!(filter.step(f64::NAN, &ok), Err(TemporalError::BadTime { .. })));
        // Every likelihood -inf but no contact's: no contact, no NaN.
        let none = FrameLikelihood {
            no_contact: -1e9,
            points: vec![f64::NEG_INFINITY; 3],
            patch: Vec::new(),
        };
        let b = filter.step(2.0, &none).unwrap();
        assert!(b.no_contact.is_finite() && (b.no_contact - 1.0).abs() < 1e-12);
    }

    type Integrand<'a> = &'a dyn Fn(f64, f64) -> f64;

    /// `∫ f(s) ds` over a square of half-width `half` (m) about 0.
    fn integrate_2d(half: f64, f: impl Fn(f64, f64) -> f64) -> f64 {
        let steps = 600;
        let h = 2.0 * half / f64::from(steps);
        let mut total = 0.0;
        for i in 0..steps {
            for j in 0..steps {
                let x = -half + (f64::from(i) + 0.5) * h;
                let y = -half + (f64::from(j) + 0.5) * h;
                total += f(x, y);
            }
        }
        total * h * h
    }

    fn density(o: &Offset, x: f64, y: f64) -> f64 {
        let [l11, l12, l22] = o.precision;
        let [m1, m2] = o.mean_m();
        let (dx, dy) = (x - m1, y - m2);
        (o.det().sqrt() / std::f64::consts::TAU) * (-0.5 * (l11 * dx * dx + 2.0 * l12 * dx * dy + l22 * dy * dy)).exp()
    }

    /// Offsets against brute-force integration over the plane: a frame
    /// absorbed, a forward and a backward belief combined, a mixture with
    /// the window matched by its moments.
    #[test]
    fn offsets_integrate_as_brute_force_does() {
        let rho = 0.004;
        let prior = Offset {
            precision: [9e4, 2e4, 5e4],
            shift: [120.0, -40.0],
        };
        let frame = PatchInformation {
            point: 0.0,
            information: [3e5, -1e5, 8e4],
            shift: [900.0, 150.0],
        };
        let (gain, after) = prior.absorb_within(&frame, f64::INFINITY);
        let brute = integrate_2d(0.03, |x, y| {
            let [m11, m12, m22] = frame.information;
            let l = frame.shift[0] * x + frame.shift[1] * y - 0.5 * (m11 * x * x + 2.0 * m12 * x * y + m22 * y * y);
            density(&prior, x, y) * l.exp()
        });
        assert!((gain - brute.ln()).abs() < 1e-4, "{gain} vs {}", brute.ln());
        let backward = Offset {
            precision: [2e5, -3e4, 1.5e5],
            shift: [-300.0, 500.0],
        };
        let window = Offset::window(rho);
        let brute = integrate_2d(0.03, |x, y| {
            density(&after, x, y) * density(&backward, x, y) / density(&window, x, y)
        });
        let got = overlap(&after, &backward, rho);
        assert!((got - brute.ln()).abs() < 1e-4, "{got} vs {}", brute.ln());
        let own = 0.7;
        let mixed = after.mixed_with_window(own, rho);
        let moments = |f: &dyn Fn(f64, f64) -> f64| {
            let of = |o: &Offset| integrate_2d(0.03, |x, y| density(o, x, y) * f(x, y));
            (of(&mixed), own * of(&after) + (1.0 - own) * of(&window))
        };
        let tests: [(&str, Integrand, f64); 5] = [
            ("x", &|x, _| x, 1e-6),
            ("y", &|_, y| y, 1e-6),
            ("xx", &|x, _| x * x, 1e-8),
            ("xy", &|x, y| x * y, 1e-8),
            ("yy", &|_, y| y * y, 1e-8),
        ];
        for (name, f, tol) in tests {
            let (got, want) = moments(f);
            assert!((got - want).abs() < tol, "{name}: {got} vs {want}");
        }
    }

    /// A mean beyond the patch's reach is brought back to it, at a cost.
    #[test]
    fn offsets_stay_within_the_patch() {
        let rho = 0.005;
        let far = Offset {
            precision: [1e6, 0.0, 1e6],
            shift: [1e6 * 0.03, 0.0],
        };
        let (penalty, kept) = far.confined(rho);
        let [m1, m2] = kept.mean_m();
        assert!((m1 - PATCH_REACH * rho).abs() < 1e-12 && m2.abs() < 1e-12, "{m1} {m2}");
        let d = 0.03 - PATCH_REACH * rho;
        assert!((penalty - 0.5 * 1e6 * d * d).abs() < 1e-9, "{penalty}");
        let near = Offset::window(rho);
        assert_eq!(near.confined(rho), (0.0, near));
        // Absorbing a frame that pulls the mean out of reach charges the
        // change of the confinement's cost, and keeps the Gaussian whole.
        let pull = PatchInformation {
            point: 0.0,
            information: [4e5, 0.0, 4e5],
            shift: [4e5 * 0.02, 0.0],
        };
        let start = Offset::window(rho);
        let (free, whole) = start.absorb_within(&pull, f64::INFINITY);
        let (kept, same) = start.absorb_within(&pull, PATCH_REACH * rho);
        assert_eq!(whole, same);
        let expected = free - (whole.confined(rho).0 - start.confined(rho).0);
        assert!(whole.confined(rho).0 > 1.0);
        assert!((kept - expected).abs() < 1e-9, "{kept} vs {expected}");
    }

    /// The magnitude is profiled per frame with one Occam charge for all
    /// samples: two samples that explain the torques equally well score
    /// the same whatever their lever arms (a per-sample charge would
    /// favour the weaker lever by `ln 2` per frame here, a hundred-frame
    /// press by 69 nats).
    #[test]
    fn equally_good_fits_score_the_same_whatever_the_lever() {
        // τ = (2, 0) with σ = 1: sample 0 has u = (1, 0), sample 1 u = (0.5, 0).
        let forms = PatchForms {
            a: vec![1.0, 0.25],
            b: vec![2.0, 1.0],
            h1: vec![0.0; 2],
            h2: vec![0.0; 2],
            e1: vec![0.0; 2],
            e2: vec![0.0; 2],
            g11: vec![1.0; 2],
            g12: vec![0.0; 2],
            g22: vec![1.0; 2],
            window_m: vec![0.01; 2],
            ln_area: vec![0.0; 2],
        };
        let info = PatchInformation::from_forms(&forms, 4.0, (0.5, 10.0));
        assert!((info[0].point - info[1].point).abs() < 1e-12, "{info:?}");
        // Both fit exactly (f = 2 and 4): χ² = 0, so only the charge is
        // left, at the upper median `a` (1).
        let charge = 0.5 * std::f64::consts::TAU.ln() - 9.5_f64.ln();
        assert!((info[0].point - charge).abs() < 1e-12, "{info:?}");
    }

    #[test]
    fn recordings_are_told_from_sets_of_unrelated_frames() {
        let d = TemporalSettings::default();
        let at = |dt: f64| (0..10).map(|i| f64::from(i) * dt).collect::<Vec<_>>();
        assert!(is_continuous_recording(&at(0.005), &d));
        assert!(is_continuous_recording(&at(0.3), &d));
        assert!(!is_continuous_recording(&at(0.4), &d));
        assert!(!is_continuous_recording(&at(1.0), &d));
        assert!(!is_continuous_recording(&[0.0], &d));
    }
}
