//! The parts of the calibration's fit that read a fit whole: each
//! joint's Coulomb shape, and how well the fit predicts each frame.

use super::{
    COULOMB_LEADS_SECS, COULOMB_SPEEDS_RAD_S, CalibrationError, Design, Fit, SHAPE_GAIN, STICTION_SPEED_RAD_S,
    coulomb_shape,
};
use rayon::prelude::*;

use crate::core::numerics::linalg::solve_spd;
use crate::core::over_time::observer::{Lag, frame_steps};

/// Per frame and joint, the variance of the fit's prediction of the
/// model error (`aᵀ Σ a` over the joint's lagged columns `a`), N·m²: where
/// the free frames leave a direction of the coefficients open (a joint
/// that turns round only while pressed leaves its Coulomb term and its
/// offset apart only by the prior), frames that depend on it are not
/// known to be busy just because the fit cannot yet predict them.
pub(super) fn prediction_spread(design: &Design, times_secs: &[f64], fit: &Fit) -> Vec<Vec<f64>> {
    let (p, n) = (design.columns, design.joints);
    let frames = design.lagged_frames(times_secs);
    // The spread follows the motion, slowly next to the frame rate: on a
    // long recording every few frames' value serves the ones after it.
    let stride = frames.div_ceil(20_000).max(1);
    let mut sampled: Vec<Vec<f64>> = Vec::with_capacity(frames.div_ceil(stride));
    design.for_each_lagged(times_secs, fit.gain, |k, row| {
        if k % stride != 0 {
            return;
        }
        sampled.push(
            (0..n)
                .map(|j| {
                    let a = &row[j * p..(j + 1) * p];
                    let used: Vec<usize> = (0..p).filter(|&c| a[c] != 0.0).collect();
                    let mut v = 0.0;
                    for &c1 in &used {
                        let inner: f64 = used.iter().map(|&c2| fit.covariance[c1 * p + c2] * a[c2]).sum();
                        v += a[c1] * inner;
                    }
                    v.max(0.0)
                })
                .collect(),
        );
    });
    (0..frames)
        .map(|k| sampled.get(k / stride).cloned().unwrap_or_else(|| vec![0.0; n]))
        .collect()
}

/// Inputs the Coulomb shape search reads besides the design.
pub(super) struct ShapeSearch<'a> {
    pub(super) times_secs: &'a [f64],
    pub(super) velocities: &'a [Vec<f64>],
    pub(super) accelerations: &'a [Vec<f64>],
    pub(super) free: &'a [bool],
    pub(super) weights: &'a [f64],
}

/// Each joint's Coulomb shape ([`COULOMB_LEADS_SECS`] ×
/// [`COULOMB_SPEEDS_RAD_S`]) that best fits what `fit` leaves of it: the
/// joint's own friction and offset are refitted for every shape, the
/// rest held. The joints' friction columns are their own, so one joint
/// at a time finds the same shapes as all together.
pub(super) fn best_coulomb_shapes(
    design: &Design,
    fit: &Fit,
    search: &ShapeSearch,
) -> Result<Vec<(f64, f64)>, CalibrationError> {
    let steps = frame_steps(search.times_secs);
    // Each joint's search reads only its own columns: the joints run on
    // every core.
    (0..design.joints)
        .into_par_iter()
        .map(|j| {
            let current = design.shapes.get(j).copied().unwrap_or((0.0, STICTION_SPEED_RAD_S));
            best_shape_of(j, current, design, fit, search, &steps)
        })
        .collect()
}

/// [`best_coulomb_shapes`] of joint `j`, whose shape is `current` until
/// another earns its place.
fn best_shape_of(
    j: usize,
    current: (f64, f64),
    design: &Design,
    fit: &Fit,
    search: &ShapeSearch,
    steps: &[(f64, bool)],
) -> Result<(f64, f64), CalibrationError> {
    let stride = fit.residuals.len().div_ceil(20_000).max(1);
    let width = design.joints * design.columns;
    // Frame by frame, `count` values per frame in one flat vector.
    let lag_series = |raw: &mut dyn FnMut(usize, &mut [f64]), count: usize| -> Vec<f64> {
        let mut lag = Lag::new(fit.gain, count);
        let mut input = vec![0.0; count];
        let mut out = Vec::with_capacity(steps.len() * count);
        for (k, (dt, restart)) in steps.iter().enumerate() {
            if *restart {
                lag.reset();
            }
            raw(k, &mut input);
            out.extend_from_slice(lag.step(*dt, &input));
        }
        out
    };
    let first = design.base.len() + 3 * j;
    let own = lag_series(
        &mut |k, out| {
            let row = &design.rows[k * width + j * design.columns..];
            for (o, r) in out.iter_mut().zip(&row[first..first + 3]) {
                *o = f64::from(*r);
            }
        },
        3,
    );
    let coef = &fit.coefficients[first..first + 3];
    let target: Vec<f64> = fit
        .residuals
        .iter()
        .zip(own.chunks_exact(3))
        .map(|(e, c)| e[j] + c.iter().zip(coef).map(|(x, b)| x * b).sum::<f64>())
        .collect();
    let prior = &design.prior_sd[first..first + 3];
    let mut best: Option<(f64, (f64, f64))> = None;
    let mut plain = None;
    for &lead in &COULOMB_LEADS_SECS {
        for &switch in &COULOMB_SPEEDS_RAD_S {
            let coulomb = lag_series(
                &mut |k, out| {
                    out[0] = coulomb_shape(search.velocities[k][j], search.accelerations[k][j], lead, switch);
                },
                1,
            );
            let column = |k: usize| [coulomb[k], own[3 * k + 1], own[3 * k + 2]];
            let mut normal = [0.0; 9];
            let mut rhs = [0.0; 3];
            for k in (0..target.len()).step_by(stride).filter(|k| search.free[*k]) {
                let (x, w) = (column(k), search.weights[k]);
                for a in 0..3 {
                    rhs[a] += w * x[a] * target[k];
                    for b in 0..3 {
                        normal[a * 3 + b] += w * x[a] * x[b];
                    }
                }
            }
            let scale = normal[0].max(normal[4]).max(normal[8]).max(1e-300);
            for a in 0..3 {
                normal[a * 3 + a] += scale * 1e-9 / (prior[a] * prior[a]);
            }
            let c = solve_spd(&normal, &rhs)?;
            let sse: f64 = (0..target.len())
                .step_by(stride)
                .filter(|k| search.free[*k])
                .map(|k| {
                    let x = column(k);
                    let e = target[k] - x[0] * c[0] - x[1] * c[1] - x[2] * c[2];
                    search.weights[k] * e * e
                })
                .sum();
            if (lead, switch) == (0.0, STICTION_SPEED_RAD_S) {
                plain = Some(sse);
            }
            if best.is_none_or(|(b, _)| sse < b * (1.0 - 1e-9)) {
                best = Some((sse, (lead, switch)));
            }
        }
    }
    // Another shape must earn its place: where the free frames hold no
    // reversal, every shape fits them alike (the Coulomb term is an
    // offset there) and the plain one stays.
    Ok(match (best, plain) {
        (Some((sse, found)), Some(plain)) if sse < (1.0 - SHAPE_GAIN) * plain => found,
        (Some(_), Some(_)) => (0.0, STICTION_SPEED_RAD_S),
        _ => current,
    })
}
