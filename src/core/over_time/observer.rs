//! What a momentum observer does to a torque signal, and the signals a
//! calibration needs from joint positions alone.
//!
//! A real arm's external torque is the residual `r` of a momentum observer
//! (De Luca): `r = K (p − p(0) − ∫ (τ_m + Cᵀq̇ − g + r) dt)` with
//! `p = M q̇` from the controller's model. Its residual obeys
//! `ṙ = K (τ_ext + e − r)`: a first-order lag of gain `K` of the external
//! torque plus whatever the model gets wrong (`e`: inertial error, and on
//! arms that sense motor current, the joints' friction). Every correction
//! of `e` must pass through the same lag before it is taken off `r`.

use crate::core::over_time::temporal::median_interval_secs;

/// A first-order lag of gain `K`, one state per channel, stepped frame by
/// frame as a robot's controller steps its observer: forward Euler,
/// `y_k = y_{k−1} + K dt (x − y_{k−1})` (the pole `1 − K dt`, not
/// `e^{−K dt}`: at K = 50/s and 1 kHz the two differ by 2.6 % in the
/// gain, which leaves a tail of a few hundredths of a N·m after every
/// release). A step `K dt ≥ 1` follows the input at once; `K = ∞`
/// passes it through.
#[derive(Debug, Clone)]
pub struct Lag {
    gain_per_s: Option<f64>,
    state: Vec<f64>,
    started: bool,
}

impl Lag {
    /// A lag of `gain_per_s` (`None`: none) over `channels` values.
    #[must_use]
    pub fn new(gain_per_s: Option<f64>, channels: usize) -> Self {
        Self {
            gain_per_s,
            state: vec![0.0; channels],
            started: false,
        }
    }

    /// Starts again from rest (after a gap in the recording).
    pub fn reset(&mut self) {
        self.state.iter_mut().for_each(|s| *s = 0.0);
        self.started = false;
    }

    /// Steps `dt_secs` forward with input `input` and returns the output.
    /// The first step after a start holds the state at 0, as the
    /// observer's `r(0) = 0`.
    pub fn step(&mut self, dt_secs: f64, input: &[f64]) -> &[f64] {
        let blend = match self.gain_per_s {
            None => 1.0,
            Some(_) if !self.started => 0.0,
            Some(k) => euler_blend(k, dt_secs),
        };
        self.started = true;
        for (s, x) in self.state.iter_mut().zip(input) {
            *s += blend * (x - *s);
        }
        &self.state
    }
}

/// The share of the way to its input that a lag of gain `k` goes in a
/// step of `dt_secs`: `K dt`, at most 1.
fn euler_blend(k: f64, dt_secs: f64) -> f64 {
    (k * dt_secs.max(0.0)).clamp(0.0, 1.0)
}

/// The inverse of [`Lag`]: from a lagged signal, the input that made it
/// (`x_k = y_{k−1} + (y_k − y_{k−1}) / (K dt)`). It takes the
/// observer's lag off its residual: what is left is the torque at the
/// frame's own time, with the sensor's white noise instead of a noise
/// correlated over 1/K.
#[derive(Debug, Clone)]
pub struct Unlag {
    gain_per_s: Option<f64>,
    previous: Option<Vec<f64>>,
}

impl Unlag {
    /// The inverse of a lag of `gain_per_s` (`None`: passes through).
    #[must_use]
    pub fn new(gain_per_s: Option<f64>) -> Self {
        Self {
            gain_per_s,
            previous: None,
        }
    }

    /// Starts again (after a gap in the recording).
    pub fn reset(&mut self) {
        self.previous = None;
    }

    /// The input of the step to `lagged`, `dt_secs` after the previous one.
    pub fn step(&mut self, dt_secs: f64, lagged: &[f64]) -> Vec<f64> {
        let out = match (self.gain_per_s, &self.previous) {
            (Some(k), Some(previous)) if dt_secs > 0.0 => {
                let blend = euler_blend(k, dt_secs);
                lagged.iter().zip(previous).map(|(y, p)| p + (y - p) / blend).collect()
            }
            _ => lagged.to_vec(),
        };
        self.previous = Some(lagged.to_vec());
        out
    }
}

/// A gap longer than this many times the median frame step restarts a
/// lag (the observer's state across it is unknown).
pub const GAP_STEPS: f64 = 5.0;

/// The typical step between frames, s: the median interval, or 1 s where
/// there is none (fewer than two frames, or repeated times).
#[must_use]
pub fn typical_step_secs(times_secs: &[f64]) -> f64 {
    median_interval_secs(times_secs).filter(|d| *d > 0.0).unwrap_or(1.0)
}

/// Each frame's step from the one before, s (0 for the first), and
/// whether a lag starts again there (the first frame, or after a gap of
/// more than [`GAP_STEPS`] typical steps).
#[must_use]
pub fn frame_steps(times_secs: &[f64]) -> Vec<(f64, bool)> {
    let typical = typical_step_secs(times_secs);
    let mut previous: Option<f64> = None;
    times_secs
        .iter()
        .map(|&t| {
            let dt = previous.map_or(0.0, |p| t - p);
            previous = Some(t);
            (dt, dt > GAP_STEPS * typical)
        })
        .collect()
}

/// Joint velocities and accelerations from positions by central
/// differences on the (possibly uneven) frame times; the ends repeat
/// their neighbours. `positions[k]` is frame `k`'s joint vector.
#[must_use]
pub fn differentiate(times_secs: &[f64], positions: &[Vec<f64>]) -> (Vec<Vec<f64>>, Vec<Vec<f64>>) {
    let count = positions.len().min(times_secs.len());
    let joints = positions.first().map_or(0, Vec::len);
    let mut velocities = vec![vec![0.0; joints]; count];
    let mut accelerations = vec![vec![0.0; joints]; count];
    if count < 3 {
        return (velocities, accelerations);
    }
    for k in 1..count - 1 {
        let (h1, h2) = (times_secs[k] - times_secs[k - 1], times_secs[k + 1] - times_secs[k]);
        if h1 <= 0.0 || h2 <= 0.0 {
            continue;
        }
        for j in 0..joints {
            let (before, here, after) = (positions[k - 1][j], positions[k][j], positions[k + 1][j]);
            let (slope1, slope2) = ((here - before) / h1, (after - here) / h2);
            velocities[k][j] = (slope1 * h2 + slope2 * h1) / (h1 + h2);
            accelerations[k][j] = 2.0 * (slope2 - slope1) / (h1 + h2);
        }
    }
    // The ends repeat their neighbours.
    for (end, neighbour) in [(0, 1), (count - 1, count - 2)] {
        let (v, a) = (velocities[neighbour].clone(), accelerations[neighbour].clone());
        velocities[end] = v;
        accelerations[end] = a;
    }
    (velocities, accelerations)
}

/// The integrated autocorrelation time of a signal, in samples:
/// `1 + 2 Σ ρ_k`, summed while the autocorrelation stays positive (the
/// initial positive sequence), at least 1. Over the `runs` of consecutive
/// samples given (free stretches), each centred on the mean of all.
#[must_use]
pub fn correlation_samples(runs: &[&[f64]]) -> f64 {
    let total: usize = runs.iter().map(|r| r.len()).sum();
    if total < 4 {
        return 1.0;
    }
    let mean = runs.iter().flat_map(|r| r.iter()).sum::<f64>() / total as f64;
    let variance = runs
        .iter()
        .flat_map(|r| r.iter())
        .map(|x| (x - mean).powi(2))
        .sum::<f64>()
        / total as f64;
    if variance <= 0.0 {
        return 1.0;
    }
    let longest = runs.iter().map(|r| r.len()).max().unwrap_or(0);
    let mut sum = 0.0;
    for lag in 1..longest.min(5000) {
        let (mut products, mut pairs) = (0.0, 0usize);
        for run in runs {
            if run.len() > lag {
                for k in lag..run.len() {
                    products += (run[k] - mean) * (run[k - lag] - mean);
                }
                pairs += run.len() - lag;
            }
        }
        if pairs < 10 {
            break;
        }
        let rho = products / pairs as f64 / variance;
        if rho <= 0.0 {
            break;
        }
        sum += rho;
    }
    (1.0 + 2.0 * sum).max(1.0)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::numerics::rng::Rng;

    #[test]
    fn the_lag_settles_on_its_input_at_its_gain() {
        let mut lag = Lag::new(Some(50.0), 1);
        let mut out = 0.0;
        for k in 0..=21 {
            out = lag.step(0.001, &[1.0])[0];
            if k == 20 {
                // After 20 Euler steps of K dt = 0.05 (the first holds at 0):
                // 1 − 0.95^20 of the step, close to 1 − e^{−1}.
                assert!((out - (1.0 - 0.95_f64.powi(20))).abs() < 1e-12, "{out}");
            }
        }
        assert!(out > 0.63);
        let mut through = Lag::new(None, 2);
        assert_eq!(through.step(0.001, &[3.0, -1.0]), &[3.0, -1.0]);
    }

    #[test]
    fn unlag_undoes_the_lag() {
        let mut lag = Lag::new(Some(50.0), 2);
        let mut unlag = Unlag::new(Some(50.0));
        for k in 0..200 {
            let x = [f64::from(k).sin(), if k > 50 { 3.0 } else { 0.0 }];
            let y = lag.step(0.001, &x).to_vec();
            let back = unlag.step(0.001, &y);
            if k > 0 {
                assert!(
                    (back[0] - x[0]).abs() < 1e-9 && (back[1] - x[1]).abs() < 1e-9,
                    "{k}: {back:?}"
                );
            }
        }
    }

    #[test]
    fn differences_of_a_polynomial_are_exact() {
        let times: Vec<f64> = (0..50)
            .map(|k| f64::from(k) * 0.01 + 0.002 * f64::from(k % 3))
            .collect();
        let positions: Vec<Vec<f64>> = times.iter().map(|t| vec![1.0 + 2.0 * t - 3.0 * t * t]).collect();
        let (v, a) = differentiate(&times, &positions);
        for k in 1..49 {
            assert!((v[k][0] - (2.0 - 6.0 * times[k])).abs() < 1e-9, "{k}: {}", v[k][0]);
            assert!((a[k][0] + 6.0).abs() < 1e-6, "{k}: {}", a[k][0]);
        }
    }

    /// White noise has a correlation time of one sample; noise through a
    /// lag of pole `a` has `(1 + a) / (1 − a)`.
    #[test]
    fn correlation_time_of_white_and_lagged_noise() {
        let mut rng = Rng::new(7);
        let white: Vec<f64> = (0..200_000).map(|_| rng.normal()).collect();
        let t_white = correlation_samples(&[&white]);
        assert!((t_white - 1.0).abs() < 0.1, "{t_white}");
        let mut lag = Lag::new(Some(50.0), 1);
        let lagged: Vec<f64> = white.iter().map(|&x| lag.step(0.001, &[x])[0]).collect();
        let a = 0.95;
        let expected = (1.0 + a) / (1.0 - a);
        let t_lagged = correlation_samples(&[&lagged]);
        assert!((t_lagged / expected - 1.0).abs() < 0.15, "{t_lagged} vs {expected}");
    }
}
