//! Errors of estimates against the truth over a session: the thesis'
//! weighted errors (eq. 3.7–3.9) and plain medians and 90th percentiles.

use glam::DVec3;

/// One frame's estimate beside its truth.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameOutcome {
    /// Sensed joints that move the touched link.
    pub sensing_joints: usize,
    /// Probability of the most probable point (`P_max^i`).
    pub p_max: f64,
    /// Estimated contact point, m.
    pub estimated_point: DVec3,
    /// Estimated force, N.
    pub estimated_force: DVec3,
    /// True contact point, m.
    pub true_point: DVec3,
    /// True force, N.
    pub true_force: DVec3,
    /// The estimate is on the true link.
    pub link_correct: bool,
    /// Whether the 90 % credible set holds the true contact's sample
    /// (`None` where that was not told).
    pub in_credible90: Option<bool>,
}

/// Errors over a set of frames.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Metrics {
    /// Frames counted.
    pub frames: usize,
    /// `ε_F` (eq. 3.7): weighted RMS of the force-norm error, N.
    pub eps_f_newtons: f64,
    /// `ε_r` (eq. 3.8): weighted RMS of the position error, m.
    pub eps_r_m: f64,
    /// `σ_r` (eq. 3.9): weighted dispersion of the estimated points, m.
    pub sigma_r_m: f64,
    /// Median position error, m.
    pub position_median_m: f64,
    /// 90th percentile of the position error, m.
    pub position_p90_m: f64,
    /// Median force error (vector difference), N.
    pub force_median_newtons: f64,
    /// 90th percentile of the force error, N.
    pub force_p90_newtons: f64,
    /// Share of frames whose estimate is on the true link.
    pub link_accuracy: f64,
    /// Share of the frames that told it whose 90 % credible set held the
    /// true contact (`None` where none told it).
    pub credible90_held: Option<f64>,
}

/// Nearest-rank percentile of unsorted values (`fraction` in [0, 1]).
#[must_use]
pub fn percentile(values: &[f64], fraction: f64) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let rank = ((fraction * sorted.len() as f64).ceil() as usize).clamp(1, sorted.len());
    sorted[rank - 1]
}

/// Metrics over `outcomes` (all zeros for none).
#[must_use]
pub fn metrics(outcomes: &[FrameOutcome]) -> Metrics {
    if outcomes.is_empty() {
        return Metrics::default();
    }
    let n = outcomes.len() as f64;
    let weights: f64 = outcomes.iter().map(|o| o.p_max).sum();
    // With all weights zero the weighted forms fall back to plain means.
    let w = |o: &FrameOutcome| if weights > 0.0 { o.p_max / weights } else { 1.0 / n };
    let eps_f = outcomes
        .iter()
        .map(|o| w(o) * (o.true_force.length() - o.estimated_force.length()).powi(2))
        .sum::<f64>()
        .sqrt();
    let eps_r = outcomes
        .iter()
        .map(|o| w(o) * o.true_point.distance_squared(o.estimated_point))
        .sum::<f64>()
        .sqrt();
    let mean = outcomes.iter().map(|o| o.estimated_point).sum::<DVec3>() / n;
    let sigma_r = outcomes
        .iter()
        .map(|o| w(o) * o.estimated_point.distance_squared(mean))
        .sum::<f64>()
        .sqrt();
    let position: Vec<f64> = outcomes
        .iter()
        .map(|o| o.true_point.distance(o.estimated_point))
        .collect();
    let force: Vec<f64> = outcomes
        .iter()
        .map(|o| o.true_force.distance(o.estimated_force))
        .collect();
    Metrics {
        frames: outcomes.len(),
        eps_f_newtons: eps_f,
        eps_r_m: eps_r,
        sigma_r_m: sigma_r,
        position_median_m: percentile(&position, 0.5),
        position_p90_m: percentile(&position, 0.9),
        force_median_newtons: percentile(&force, 0.5),
        force_p90_newtons: percentile(&force, 0.9),
        link_accuracy: outcomes.iter().filter(|o| o.link_correct).count() as f64 / n,
        credible90_held: share_held(outcomes),
    }
}

/// The share of `outcomes` telling whether their credible set held the
/// truth that say it did (`None` where none tells).
fn share_held(outcomes: &[FrameOutcome]) -> Option<f64> {
    let told: Vec<bool> = outcomes.iter().filter_map(|o| o.in_credible90).collect();
    (!told.is_empty()).then(|| told.iter().filter(|&&h| h).count() as f64 / told.len() as f64)
}

/// Metrics per number of sensing joints, in increasing order.
#[must_use]
pub fn metrics_by_sensing_joints(outcomes: &[FrameOutcome]) -> Vec<(usize, Metrics)> {
    let mut counts: Vec<usize> = outcomes.iter().map(|o| o.sensing_joints).collect();
    counts.sort_unstable();
    counts.dedup();
    counts
        .into_iter()
        .map(|k| {
            let group: Vec<FrameOutcome> = outcomes.iter().copied().filter(|o| o.sensing_joints == k).collect();
            (k, metrics(&group))
        })
        .collect()
}

/// How well contacts were detected over a sequence of frames.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Detection {
    /// Frames with a true contact.
    pub contact_frames: usize,
    /// Of these, frames called a contact.
    pub detected: usize,
    /// Frames known to have no contact.
    pub quiet_frames: usize,
    /// Of these, frames called a contact.
    pub false_alarms: usize,
    /// Per true onset (a contact frame after a known quiet one, or the
    /// first frame), frames until the first frame called a contact
    /// (`None` if none was while the contact lasted).
    pub onset_delays: Vec<Option<usize>>,
}

impl Detection {
    /// Share of contact frames called a contact (1 without any).
    #[must_use]
    pub fn detection_rate(&self) -> f64 {
        if self.contact_frames == 0 {
            1.0
        } else {
            self.detected as f64 / self.contact_frames as f64
        }
    }

    /// Share of quiet frames called a contact (0 without any).
    #[must_use]
    pub fn false_alarm_rate(&self) -> f64 {
        if self.quiet_frames == 0 {
            0.0
        } else {
            self.false_alarms as f64 / self.quiet_frames as f64
        }
    }

    /// The longest onset delay, frames (`None` if an onset was missed;
    /// 0 without onsets).
    #[must_use]
    pub fn worst_onset_delay(&self) -> Option<usize> {
        self.onset_delays.iter().try_fold(0, |worst, d| d.map(|d| d.max(worst)))
    }
}

/// Detection over frames: `truth[i]` is `Some(true)` for a contact,
/// `Some(false)` for none, `None` when unknown; `called[i]` whether the
/// estimate said contact.
#[must_use]
pub fn detection(truth: &[Option<bool>], called: &[bool]) -> Detection {
    let mut d = Detection::default();
    for (i, (t, &c)) in truth.iter().zip(called).enumerate() {
        match t {
            Some(true) => {
                d.contact_frames += 1;
                d.detected += usize::from(c);
                let onset = i == 0 || truth.get(i - 1).is_some_and(|p| *p == Some(false));
                if onset {
                    let delay = truth
                        .iter()
                        .zip(called)
                        .skip(i)
                        .take_while(|(t, _)| **t == Some(true))
                        .position(|(_, c)| *c);
                    d.onset_delays.push(delay);
                }
            }
            Some(false) => {
                d.quiet_frames += 1;
                d.false_alarms += usize::from(c);
            }
            None => {}
        }
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    fn outcome(p: f64, dx: f64, df: f64, ok: bool) -> FrameOutcome {
        FrameOutcome {
            sensing_joints: 3,
            p_max: p,
            estimated_point: DVec3::new(dx, 0.0, 0.0),
            estimated_force: DVec3::new(0.0, 10.0 + df, 0.0),
            true_point: DVec3::ZERO,
            true_force: DVec3::new(0.0, 10.0, 0.0),
            link_correct: ok,
            in_credible90: None,
        }
    }

    /// The share counts only the frames that tell, and is `None` without any.
    #[test]
    fn credible_share_counts_the_frames_that_tell() {
        let mut o = [outcome(0.1, 0.0, 0.0, true); 4];
        assert_eq!(metrics(&o).credible90_held, None);
        o[0].in_credible90 = Some(true);
        o[1].in_credible90 = Some(false);
        o[2].in_credible90 = Some(true);
        let share = metrics(&o).credible90_held.unwrap();
        assert!((share - 2.0 / 3.0).abs() < 1e-15, "{share}");
    }

    #[test]
    fn weighted_and_plain_errors_by_hand() {
        let o = [outcome(0.1, 0.01, 1.0, true), outcome(0.3, 0.03, -2.0, false)];
        let m = metrics(&o);
        // ε_r = sqrt((0.1·0.01² + 0.3·0.03²) / 0.4)
        assert!((m.eps_r_m - ((0.1 * 1e-4 + 0.3 * 9e-4) / 0.4f64).sqrt()).abs() < 1e-15);
        assert!((m.eps_f_newtons - ((0.1 * 1.0 + 0.3 * 4.0) / 0.4f64).sqrt()).abs() < 1e-12);
        // Estimates at x = 0.01 and 0.03, mean 0.02.
        assert!((m.sigma_r_m - 0.01).abs() < 1e-15);
        assert!((m.position_median_m - 0.01).abs() < 1e-15);
        assert!((m.position_p90_m - 0.03).abs() < 1e-15);
        assert!((m.force_median_newtons - 1.0).abs() < 1e-12);
        assert!((m.link_accuracy - 0.5).abs() < 1e-15);
    }

    #[test]
    fn detection_counts_hits_false_alarms_and_onset_delays() {
        let (c, q) = (Some(true), Some(false));
        let truth = [q, q, c, c, c, q, c, c, q, None, c];
        let said = [false, true, false, false, true, false, false, false, false, true, true];
        let d = detection(&truth, &said);
        assert_eq!(
            (d.contact_frames, d.detected, d.quiet_frames, d.false_alarms),
            (6, 2, 4, 1)
        );
        // Onsets at 2 (found 2 frames late) and 6 (missed); 10 follows an
        // unknown frame, so it is no onset.
        assert_eq!(d.onset_delays, vec![Some(2), None]);
        assert_eq!(d.worst_onset_delay(), None);
        assert!((d.detection_rate() - 2.0 / 6.0).abs() < 1e-15);
        assert!((d.false_alarm_rate() - 0.25).abs() < 1e-15);
    }

    #[test]
    fn percentile_is_nearest_rank() {
        let v = [5.0, 1.0, 4.0, 2.0, 3.0, 6.0, 7.0, 8.0, 9.0, 10.0];
        assert!((percentile(&v, 0.5) - 5.0).abs() < 1e-15);
        assert!((percentile(&v, 0.9) - 9.0).abs() < 1e-15);
        assert!((percentile(&v, 1.0) - 10.0).abs() < 1e-15);
    }
}
