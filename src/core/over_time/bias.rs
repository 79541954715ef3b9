//! Torque bias: a per-joint offset that real external-torque signals carry
//! (model error, joint friction: non-zero readings with nothing touching).
//!
//! Without contact a joint reads its bias plus noise, frame after frame:
//! the readings pile up in a peak σ wide. A contact spreads them (its
//! torque changes with the press and the pose), and a joint that the
//! touched link does not move reads its bias too. So the bias is the
//! densest place of each joint's readings: the mode of a Gaussian kernel
//! density as wide as the noise, found among the readings and polished by
//! mean shift. It needs no estimate of the contacts, and holds as long as
//! no single contact holds one joint at one torque for longer than the
//! recording spends without contact. A bias that drifts is followed by
//! the same estimate over windows of the recording
//! ([`estimate_drifting_bias`]).

/// Why a bias could not be estimated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BiasError {
    /// Fewer than two frames.
    #[error("estimating a torque bias needs at least 2 frames, got {frames}")]
    TooFewFrames {
        /// Frames given.
        frames: usize,
    },
    /// A frame has a different number of joints than σ.
    #[error("frame {frame}: {got} torques for {expected} joints")]
    WrongLength {
        /// Frame number (0-based).
        frame: usize,
        /// Torques in it.
        got: usize,
        /// Joints (σ's length).
        expected: usize,
    },
    /// The drift window is not a positive finite number.
    #[error("bias window {window_secs} s: must be a finite number > 0")]
    BadWindow {
        /// The value given, s.
        window_secs: f64,
    },
    /// A σ is not a positive finite number.
    #[error("joint {joint}: σ = {sigma} must be a finite number > 0")]
    BadSigma {
        /// Joint (0-based, sensed order).
        joint: usize,
        /// Its σ, N·m.
        sigma: f64,
    },
}

/// Mean-shift steps that polish the mode (each moves it to the kernel
/// mean of the readings around it; a few suffice at σ resolution).
const MEAN_SHIFT_STEPS: usize = 20;

/// Histogram bins per kernel width when looking for the densest place.
const BINS_PER_KERNEL: f64 = 8.0;

/// At most this many histogram bins (readings spread over more than
/// `MAX_BINS / BINS_PER_KERNEL` kernel widths get wider bins).
const MAX_BINS: usize = 1 << 20;

/// Readings further than this many kernel widths do not count.
const KERNEL_REACH: f64 = 4.0;

/// Each sensed joint's bias (N·m) from the torques of every frame
/// (`taus[frame][joint]`) and the joints' noise σ (N·m): the mode of the
/// joint's readings (see the module docs). Non-finite readings are left
/// out.
///
/// # Errors
/// [`BiasError`] for fewer than two frames, a frame of the wrong length
/// or a σ that is not positive.
pub fn estimate_bias(taus: &[&[f64]], sigma: &[f64]) -> Result<Vec<f64>, BiasError> {
    if taus.len() < 2 {
        return Err(BiasError::TooFewFrames { frames: taus.len() });
    }
    for (joint, &s) in sigma.iter().enumerate() {
        if !(s.is_finite() && s > 0.0) {
            return Err(BiasError::BadSigma { joint, sigma: s });
        }
    }
    if let Some((frame, tau)) = taus.iter().enumerate().find(|(_, t)| t.len() != sigma.len()) {
        return Err(BiasError::WrongLength {
            frame,
            got: tau.len(),
            expected: sigma.len(),
        });
    }
    Ok(sigma
        .iter()
        .enumerate()
        .map(|(joint, &h)| {
            let mut values: Vec<f64> = taus
                .iter()
                .filter_map(|t| t.get(joint).copied())
                .filter(|v| v.is_finite())
                .collect();
            values.sort_unstable_by(f64::total_cmp);
            mode(&values, h)
        })
        .collect())
}

/// Each frame's bias (`[frame][joint]`, N·m) for an offset that drifts
/// slowly: the mode (as [`estimate_bias`]) of the frames within
/// `window_secs` of knots half a window apart, linearly interpolated in
/// between (and continued before the first knot and after the last). A session
/// no longer than the window has one knot: a constant bias. `times_secs`
/// must be sorted.
///
/// # Errors
/// As [`estimate_bias`], and [`BiasError::BadWindow`] for a window that
/// is not a positive finite number.
pub fn estimate_drifting_bias(
    times_secs: &[f64],
    taus: &[&[f64]],
    sigma: &[f64],
    window_secs: f64,
) -> Result<Vec<Vec<f64>>, BiasError> {
    if !(window_secs.is_finite() && window_secs > 0.0) {
        return Err(BiasError::BadWindow { window_secs });
    }
    let overall = estimate_bias(taus, sigma)?;
    let (Some(&first), Some(&last)) = (times_secs.first(), times_secs.last()) else {
        return Ok(Vec::new());
    };
    let span = last - first;
    if !(span.is_finite() && span > window_secs) {
        return Ok(vec![overall; taus.len()]);
    }
    // Knots from the middle of the first window to that of the last.
    let step = 0.5 * window_secs;
    let knots_count = ((span - window_secs) / step).ceil() as usize + 1;
    let knots: Vec<(f64, Vec<f64>)> = (0..knots_count)
        .map(|k| {
            let at = (first + 0.5 * window_secs + k as f64 * step).min(last - 0.5 * window_secs);
            let lo = times_secs.partition_point(|&t| t < at - 0.5 * window_secs);
            let hi = times_secs.partition_point(|&t| t <= at + 0.5 * window_secs);
            let local = taus
                .get(lo..hi.min(taus.len()))
                .filter(|w| w.len() >= 2)
                .and_then(|w| estimate_bias(w, sigma).ok())
                .unwrap_or_else(|| overall.clone());
            (at, local)
        })
        .collect();
    Ok(times_secs
        .iter()
        .map(|&t| {
            // The segment around t: before the first knot and after the
            // last, the nearest segment continued (the drift goes on).
            let after = knots
                .partition_point(|(at, _)| *at <= t)
                .clamp(1, knots.len().max(2) - 1);
            match (knots.get(after - 1), knots.get(after)) {
                (Some((a, ba)), Some((b, bb))) if b > a => {
                    let w = (t - a) / (b - a);
                    ba.iter().zip(bb).map(|(x, y)| x + w * (y - x)).collect()
                }
                (Some((_, b)), _) | (None, Some((_, b))) => b.clone(),
                (None, None) => overall.clone(),
            }
        })
        .collect())
}

/// `taus` less each frame's own bias.
#[must_use]
pub fn without_drifting_bias(taus: &[&[f64]], bias: &[Vec<f64>]) -> Vec<Vec<f64>> {
    taus.iter()
        .zip(bias.iter().map(Vec::as_slice).chain(std::iter::repeat(&[][..])))
        .map(|(t, b)| {
            t.iter()
                .zip(b.iter().chain(std::iter::repeat(&0.0)))
                .map(|(v, b)| v - b)
                .collect()
        })
        .collect()
}

/// The mode of the kernel density (width `h`) of sorted `values` (0 when
/// empty).
fn mode(values: &[f64], h: f64) -> f64 {
    let reach = KERNEL_REACH * h;
    // The densest place, from a histogram a fraction of the kernel wide
    // smoothed by the kernel: linear in the readings (the density at every
    // reading cost their number squared: minutes on a long recording).
    // Mean shift below then finds the mode itself.
    let (Some(&lo), Some(&hi)) = (values.first(), values.last()) else {
        return 0.0;
    };
    let bin = (h / BINS_PER_KERNEL).max((hi - lo) / MAX_BINS as f64);
    let bins = (((hi - lo) / bin).floor() as usize).saturating_add(1).min(MAX_BINS + 1);
    let mut counts = vec![0.0f64; bins];
    for &v in values {
        let b = (((v - lo) / bin) as usize).min(bins - 1);
        counts[b] += 1.0;
    }
    let span = (reach / bin).ceil() as usize;
    let kernel: Vec<f64> = (0..=span)
        .map(|k| {
            let z = k as f64 * bin / h;
            (-0.5 * z * z).exp()
        })
        .collect();
    // The densest bin (the lowest among equals: deterministic).
    let mut best = (f64::NEG_INFINITY, 0usize);
    for b in 0..bins {
        let first = b.saturating_sub(span);
        let last = (b + span).min(bins - 1);
        let d: f64 = (first..=last).map(|c| counts[c] * kernel[c.abs_diff(b)]).sum();
        if d > best.0 {
            best = (d, b);
        }
    }
    let mut x = lo + (best.1 as f64 + 0.5) * bin;
    for _ in 0..MEAN_SHIFT_STEPS {
        let lo = values.partition_point(|&v| v < x - reach);
        let hi = values.partition_point(|&v| v <= x + reach);
        let (mut weight, mut sum) = (0.0, 0.0);
        for &v in values.get(lo..hi).unwrap_or(&[]) {
            let z = (v - x) / h;
            let w = (-0.5 * z * z).exp();
            weight += w;
            sum += w * v;
        }
        if weight <= 0.0 {
            break;
        }
        let next = sum / weight;
        if (next - x).abs() < 1e-6 * h {
            x = next;
            break;
        }
        x = next;
    }
    x
}

/// `taus` with `bias` taken off every frame.
#[must_use]
pub fn without_bias(taus: &[&[f64]], bias: &[f64]) -> Vec<Vec<f64>> {
    taus.iter()
        .map(|t| {
            t.iter()
                .zip(bias.iter().chain(std::iter::repeat(&0.0)))
                .map(|(v, b)| v - b)
                .collect()
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::numerics::rng::Rng;

    /// Readings: 40 % of frames at the bias, the rest spread by contacts
    /// (one joint's contact torques held near a second value for 20 %).
    #[test]
    fn the_bias_is_the_densest_reading() {
        let mut rng = Rng::new(3);
        let bias = [0.3, -0.25, 0.0];
        let sigma = [0.05, 0.05, 0.1];
        let frames: Vec<Vec<f64>> = (0..1000)
            .map(|i| {
                bias.iter()
                    .zip(&sigma)
                    .enumerate()
                    .map(|(j, (&b, &s))| {
                        let contact = match i % 10 {
                            0..=3 => 0.0,
                            4 | 5 if j == 0 => 1.2,
                            _ => rng.uniform_in(-3.0, 3.0),
                        };
                        b + contact + s * rng.normal()
                    })
                    .collect()
            })
            .collect();
        let refs: Vec<&[f64]> = frames.iter().map(Vec::as_slice).collect();
        let got = estimate_bias(&refs, &sigma).unwrap();
        for ((g, b), s) in got.iter().zip(&bias).zip(&sigma) {
            // 400 frames of noise σ: the mode is good to a fraction of σ.
            assert!((g - b).abs() < 0.3 * s, "{got:?} vs {bias:?}");
        }
        let clean = without_bias(&refs, &got);
        assert!((clean[0][0] - (frames[0][0] - got[0])).abs() < 1e-15);
    }

    #[test]
    fn bad_inputs_are_errors() {
        let one = [0.0, 0.0];
        assert!(matches!(
            estimate_bias(&[&one], &[0.05, 0.05]),
            Err(BiasError::TooFewFrames { frames: 1 })
        ));
        assert!(matches!(
            estimate_bias(&[&one, &[0.0]], &[0.05, 0.05]),
            Err(BiasError::WrongLength { frame: 1, .. })
        ));
        assert!(matches!(
            estimate_bias(&[&one, &one], &[0.05, 0.0]),
            Err(BiasError::BadSigma { joint: 1, .. })
        ));
        // Non-finite readings are left out.
        let nan = [f64::NAN, 0.1];
        let got = estimate_bias(&[&one, &nan, &one], &[0.05, 0.05]).unwrap();
        assert!(got.iter().all(|b| b.is_finite()), "{got:?}");
    }

    /// An offset drifting from +0.3 to -0.3 N·m over 60 s, under presses
    /// on a third of the frames: windows of 10 s follow it within a
    /// fraction of σ (a constant fit is off by up to 0.3 at the ends).
    #[test]
    fn a_drifting_bias_is_followed() {
        let mut rng = Rng::new(9);
        let sigma = [0.05];
        let times: Vec<f64> = (0..6000).map(|i| f64::from(i) * 0.01).collect();
        let truth = |t: f64| 0.3 - 0.6 * t / 60.0;
        let frames: Vec<Vec<f64>> = times
            .iter()
            .enumerate()
            .map(|(i, &t)| {
                let contact = if (i / 100) % 3 == 0 {
                    rng.uniform_in(0.5, 3.0)
                } else {
                    0.0
                };
                vec![truth(t) + contact + sigma[0] * rng.normal()]
            })
            .collect();
        let refs: Vec<&[f64]> = frames.iter().map(Vec::as_slice).collect();
        let bias = estimate_drifting_bias(&times, &refs, &sigma, 10.0).unwrap();
        let worst = times
            .iter()
            .zip(&bias)
            .map(|(&t, b)| (b[0] - truth(t)).abs())
            .fold(0.0, f64::max);
        assert!(worst < 0.5 * sigma[0], "worst {worst}");
        let constant = estimate_bias(&refs, &sigma).unwrap();
        assert!((constant[0] - truth(0.0)).abs() > 0.2);
        // A session shorter than the window: the constant fit.
        let short = estimate_drifting_bias(&times[..500], &refs[..500], &sigma, 10.0).unwrap();
        assert_eq!(short[0], estimate_bias(&refs[..500], &sigma).unwrap());
        assert!(matches!(
            estimate_drifting_bias(&times, &refs, &sigma, 0.0),
            Err(BiasError::BadWindow { .. })
        ));
        let clean = without_drifting_bias(&refs, &bias);
        assert!((clean[10][0] - (frames[10][0] - bias[10][0])).abs() < 1e-15);
    }
}
