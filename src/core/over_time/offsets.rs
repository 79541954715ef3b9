//! What each frame says about a contact's place within its sample's
//! patch, and the Gaussian over that offset that the temporal model
//! carries per sample (see [`crate::core::over_time::temporal`]).

use crate::core::estimate::contact::PatchForms;
use crate::core::estimate::posterior::Posterior;
use crate::core::numerics::fastmath;
use crate::core::numerics::simd::{Kernel, lanes, widest};
use crate::core::surface::sampling::Surface;

/// How far from its sample (in patch widths ρ) a contact's offset may be
/// believed to lie: samples are two widths apart, so a patch reaches half
/// way past the middle to its neighbours.
pub const PATCH_REACH: f64 = 1.5;

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

/// [`TemporalModel::gains`]' loop: per sample, its likelihood with the
/// frame absorbed into its offset ([`Offset::absorb_within`] within
/// [`PATCH_REACH`] windows), and the offset after; a sample the frame did
/// not score keeps its likelihood and offset.
pub(crate) struct GainsKernel<'a> {
    pub(crate) points: &'a [f64],
    pub(crate) patch: &'a [PatchInformation],
    pub(crate) offsets: &'a [Offset],
    pub(crate) window_m: &'a [f64],
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
    pub(crate) fn det(&self) -> f64 {
        let [l11, l12, l22] = self.precision;
        l11 * l22 - l12 * l12
    }

    /// `nᵀ Λ⁻¹ n` (0 when Λ is singular).
    #[cfg(test)]
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
    pub(crate) fn absorb_within(&self, frame: &PatchInformation, reach_m: f64) -> (f64, Self) {
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
    pub(crate) fn mixed_with_window(&self, own: f64, rho_m: f64) -> Self {
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
/// belief's offsets of the same sample (0 when not defined). The smoother
/// runs it lane by lane (`combine`); this is the reference it is tested
/// against.
#[cfg(test)]
pub(crate) fn overlap(forward: &Offset, backward: &Offset, rho_m: f64) -> f64 {
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
    0.5 * (both.explained() - forward.explained() - backward.explained())
        + 0.5 * crate::core::numerics::fastmath::ln_or_minus_infinity(df * db / (d * d0))
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
    pub(crate) fn top(&self) -> f64 {
        self.points
            .iter()
            .copied()
            .filter(|l| !l.is_nan())
            .fold(self.no_contact, f64::max)
    }
}
