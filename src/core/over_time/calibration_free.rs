//! Which frames of a recording are free of contact, and σ over them:
//! the quietest share that starts the search, the gate's σ and its
//! windows around busy frames, and, where no model error is found, the
//! free frames the readings themselves give.

use super::MIN_FREE_FRAMES;
use crate::core::numerics::special::{chi_square_survival, erf};
use crate::core::over_time::observer::correlation_samples;

/// How much wider a Gaussian's σ is than the RMS of the samples whose χ²
/// over `dof` joints lies below its `share` point: `√(dof / E[χ² | χ² < q])`,
/// by the χ²'s own recursion `E[χ²; χ² < q] = dof · P(χ²_{dof+2} < q)`.
pub(super) fn truncation_widening(dof: usize, share: f64) -> f64 {
    let q = chi_square_quantile(1.0 - share, dof);
    let below = 1.0 - chi_square_survival(q, dof + 2);
    // E[χ² | χ² < q] = dof · P(χ²_{dof+2} < q) / share.
    (share / below.max(1e-9)).sqrt()
}

/// The share of a recording's quietest frames that start the search for
/// free frames, set the gate's σ and always count as free: a recording
/// must be free of contact for this share of its frames, or for
/// [`CROWDED_SHARE`] (see [`quiet_share`]).
pub(super) const QUIET_SHARE: f64 = 0.3;

/// The share for a recording whose quietest [`QUIET_SHARE`] hold
/// contacts. At 30 % alone, a generated session pressed three quarters of
/// the time (presses of 1.5–3 s) took presses into σ, the gate then let
/// most frames in, and σ came out at up to 57 N·m where the noise is 0.05;
/// at 10 % for every recording, the `../shared` motor-side observer
/// example, whose joint friction leaves a heavy-tailed residual, kept 524
/// free frames instead of 804 and called contact on 19 % of its free
/// frames instead of 0.3 % (`docs/decisions.md`, *A recording pressed
/// most of the time*).
pub(super) const CROWDED_SHARE: f64 = 0.1;

/// How much wider than from the quietest [`CROWDED_SHARE`] the torques'
/// RMS may come out from the quietest [`QUIET_SHARE`] (each widened for
/// its truncation) before the wider share is taken to hold contacts.
/// Model error and joint friction widen it a little (1.66 and 1.68 on the
/// `../shared` observer examples, 1.12–1.35 on generated sessions pressed
/// about half the time); contacts in the wider share, up to 24 on
/// generated sessions pressed three quarters of the time, over 3 in 13 of
/// 21 (the other 8, 1.2–2.6, are missed: `docs/decisions.md`, *A
/// recording pressed most of the time*).
pub(super) const CROWDED_RATIO: f64 = 3.0;

/// The value below which the quietest `share` of `sorted` lie (the
/// share in whole percent, so that the index is exact).
pub(super) fn quiet_point(sorted: &[f64], share: f64) -> f64 {
    let percent = (share * 100.0).round() as usize;
    let at = (sorted.len() * percent / 100).min(sorted.len().saturating_sub(1));
    sorted.get(at).copied().unwrap_or(0.0)
}

/// Each joint's σ from the residuals of the quietest `share` of frames
/// (their χ² under `sigma`), widened for the truncation.
pub(super) fn gate_sigma(residuals: &[Vec<f64>], sigma: &[f64], share: f64) -> Vec<f64> {
    let chi2: Vec<f64> = residuals
        .iter()
        .map(|e| e.iter().zip(sigma).map(|(x, s)| (x / s).powi(2)).sum())
        .collect();
    let mut ranked = chi2.clone();
    ranked.sort_by(f64::total_cmp);
    let quietest = quiet_point(&ranked, share);
    let widen = truncation_widening(sigma.len(), share);
    (0..sigma.len())
        .map(|j| {
            let (sum, count) = residuals
                .iter()
                .zip(&chi2)
                .filter(|(_, z)| **z <= quietest)
                .fold((0.0, 0usize), |(s, c), (e, _)| {
                    (s + e.get(j).map_or(0.0, |x| x * x), c + 1)
                });
            ((sum / count.max(1) as f64).sqrt() * widen).max(1e-6)
        })
        .collect()
}

/// How far from the median a free frame's residual may lie on one
/// joint, in that joint's σ from the median absolute residual, and still
/// set the gate's σ ([`trimmed_sigma`]).
pub(super) const TRIM_SIGMAS: f64 = 3.0;

/// Each joint's σ from its residuals on the `free` frames: the RMS of
/// those within [`TRIM_SIGMAS`] of the σ that their median absolute value
/// gives, widened for the trim (a Gaussian's RMS within ±c is
/// `√(1 − 2cφ(c)/(2Φ(c) − 1))` of its σ). `None` with fewer than
/// [`MIN_FREE_FRAMES`] free frames.
///
/// The frames a gate lets in hold a press's weak frames too: its ramps,
/// and stretches where the push barely loads a joint. Their readings are
/// a few tenths of a N·m where the noise is hundredths: in an RMS a few
/// dozen of them set a joint's σ, and the gate under that σ lets in
/// more of them. Half the free frames would have to be pressed to move
/// the median. Used only where no model error is found: the fit's own
/// gate keeps the RMS of its quietest frames ([`gate_sigma`]), since the
/// `../shared` motor-side observer example, whose joint friction leaves
/// a heavy-tailed residual, called contact on 8.0 % of its free frames
/// instead of 0.3 % with this σ in that gate.
pub(super) fn trimmed_sigma(residuals: &[Vec<f64>], free: &[bool], joints: usize) -> Option<Vec<f64>> {
    let count = free.iter().filter(|f| **f).count();
    if count < MIN_FREE_FRAMES {
        return None;
    }
    let c = TRIM_SIGMAS;
    let inside = erf(c / std::f64::consts::SQRT_2);
    let density = (-0.5 * c * c).exp() / (2.0 * std::f64::consts::PI).sqrt();
    let widen = (1.0 - 2.0 * c * density / inside).max(1e-9).sqrt().recip();
    (0..joints)
        .map(|j| {
            let values: Vec<f64> = residuals
                .iter()
                .zip(free)
                .filter(|(_, f)| **f)
                .filter_map(|(e, _)| e.get(j).copied())
                .collect();
            let mut magnitudes: Vec<f64> = values.iter().map(|x| x.abs()).collect();
            magnitudes.sort_by(f64::total_cmp);
            // 1.4826 × the median absolute value is a Gaussian's σ.
            let bound = c * 1.4826 * magnitudes.get(magnitudes.len() / 2).copied()?;
            let (sum, kept) = values
                .iter()
                .filter(|x| x.abs() <= bound)
                .fold((0.0, 0usize), |(s, k), x| (s + x * x, k + 1));
            (kept > 0).then(|| ((sum / kept as f64).sqrt() * widen).max(1e-6))
        })
        .collect()
}

/// Each of `n` joints' scale: the lower quartile of its readings'
/// magnitudes.
pub(super) fn reading_scale(torques: &[Vec<f64>], n: usize) -> Vec<f64> {
    (0..n)
        .map(|j| {
            let mut v: Vec<f64> = torques.iter().map(|t| t.get(j).map_or(0.0, |x| x.abs())).collect();
            v.sort_by(f64::total_cmp);
            v.get(v.len() / 4).copied().unwrap_or(0.0).max(1e-6)
        })
        .collect()
}

/// [`QUIET_SHARE`], or [`CROWDED_SHARE`] where the torques' RMS over the
/// quietest frames (each joint scaled by `scale`) comes out more than
/// [`CROWDED_RATIO`] times wider from the wider share than from the
/// narrower on some joint (each widened for its truncation): contacts,
/// not free motion, fill the wider share.
pub(super) fn quiet_share(torques: &[Vec<f64>], scale: &[f64]) -> f64 {
    let wide = gate_sigma(torques, scale, QUIET_SHARE);
    let narrow = gate_sigma(torques, scale, CROWDED_SHARE);
    let ratio = wide.iter().zip(&narrow).map(|(w, n)| w / n).fold(0.0, f64::max);
    log::debug!("calibration: the quietest frames' torques, widest ratio of shares {ratio:.2}");
    if ratio > CROWDED_RATIO {
        CROWDED_SHARE
    } else {
        QUIET_SHARE
    }
}

/// The `1 − p` point of a χ² with `dof` degrees of freedom (bisection).
pub(super) fn chi_square_quantile(p: f64, dof: usize) -> f64 {
    let (mut lo, mut hi) = (0.0, 1e4);
    for _ in 0..200 {
        let mid = 0.5 * (lo + hi);
        if chi_square_survival(mid, dof) > p {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    0.5 * (lo + hi)
}

/// Free frames: χ² below the gate, away from any frame that is not.
pub(super) fn free_frames(times_secs: &[f64], chi2: &[f64], threshold: f64, gain: Option<f64>) -> Vec<bool> {
    let (before, after) = gain.map_or((0.01, 0.05), |k| (1.0 / k, 5.0 / k));
    let busy: Vec<f64> = chi2
        .iter()
        .enumerate()
        .filter(|(_, z)| **z > threshold)
        .map(|(k, _)| times_secs[k])
        .collect();
    // Two sweeps over the busy times (sorted as the frames are).
    let mut free: Vec<bool> = chi2.iter().map(|z| *z <= threshold).collect();
    let mut next = 0;
    for (k, t) in times_secs.iter().enumerate() {
        while next < busy.len() && busy[next] < *t - after {
            next += 1;
        }
        if next < busy.len() && busy[next] <= *t + before {
            free[k] = false;
        }
    }
    free
}

/// The RMS of `values` (by frame) over the runs of `free` frames, and how
/// many frames its correlation spans there.
pub(super) fn free_runs(free: &[bool], values: &dyn Fn(usize) -> f64) -> (f64, f64) {
    let mut all_runs: Vec<Vec<f64>> = Vec::new();
    let mut current = Vec::new();
    for (k, f) in free.iter().enumerate() {
        if *f {
            current.push(values(k));
        } else if !current.is_empty() {
            all_runs.push(std::mem::take(&mut current));
        }
    }
    if !current.is_empty() {
        all_runs.push(current);
    }
    let refs: Vec<&[f64]> = all_runs.iter().map(Vec::as_slice).collect();
    let count: usize = refs.iter().map(|r| r.len()).sum();
    let rms = (refs.iter().flat_map(|r| r.iter()).map(|x| x * x).sum::<f64>() / count.max(1) as f64).sqrt();
    (rms, correlation_samples(&refs))
}

/// How much wider the readings' RMS may be, on some joint, over the free
/// frames of a calibration that finds no model error than over the
/// frames the readings themselves call free ([`free_readings`]) before
/// the latter replace them. Where both are free of contact they agree
/// within a fifth (1.01–1.21 on 21 generated sessions pressed about half
/// the time); where presses crowd the gate's free frames, they read
/// 1.9–25 times wider on generated sessions pressed three quarters of
/// the time (`docs/decisions.md`, *Free frames from the readings*).
pub(super) const CROWDED_FREE_RATIO: f64 = 1.5;

/// Rounds of [`free_readings`]' gate.
pub(super) const READING_ROUNDS: usize = 4;

/// The frames free of contact by the `torques` as read, starting from
/// the `free` frames given (the quietest readings): [`READING_ROUNDS`]
/// rounds of each joint's σ over the free frames ([`trimmed_sigma`]) and
/// the gate at `threshold` (χ²) under it, the quietest `share` always
/// free. `None` where fewer than [`MIN_FREE_FRAMES`] would stay.
///
/// Where the fit finds no model error, its residuals still hold what its
/// columns took from the frames it was fitted on, and a press's weak
/// frames pass its gate: on a generated session pressed four fifths of
/// the time, 586 frames were called free where 453 are, and joint 1's
/// σ came out at 0.31 N·m (noise 0.05), its correlation at 958 ms, and
/// 4.3 N·m once widened for it.
pub(super) fn free_readings(
    times_secs: &[f64],
    torques: &[Vec<f64>],
    mut free: Vec<bool>,
    (threshold, gain, share): (f64, Option<f64>, f64),
) -> Option<Vec<bool>> {
    let joints = torques.first().map_or(0, Vec::len);
    for _ in 0..READING_ROUNDS {
        let sigma = trimmed_sigma(torques, &free, joints)?;
        let chi2: Vec<f64> = torques
            .iter()
            .map(|t| t.iter().zip(&sigma).map(|(x, s)| (x / s).powi(2)).sum())
            .collect();
        let mut ranked = chi2.clone();
        ranked.sort_by(f64::total_cmp);
        let floor = quiet_point(&ranked, share);
        let next: Vec<bool> = free_frames(times_secs, &chi2, threshold, gain)
            .iter()
            .zip(&chi2)
            .map(|(f, z)| *f || *z <= floor)
            .collect();
        if next.iter().filter(|f| **f).count() < MIN_FREE_FRAMES {
            return None;
        }
        free = next;
    }
    Some(free)
}
