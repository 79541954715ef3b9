//! A session's second contacts, after its single-contact estimates: each
//! poorly explained frame's two-contact search in order (each starts where the
//! frames before left the contacts), then the chain of two states over
//! the frames' evidence, smoothed over the whole session
//! ([`crate::core::over_time::pairs`]).

use glam::DVec3;

use crate::core::estimate::estimator::{Estimator, Update};
use crate::core::estimate::pair::{PairEstimate, PairSettings};
use crate::core::estimate::settings::EstimateError;
use crate::core::estimate::summary::Verdict;
use crate::core::eval::metrics::percentile;
use crate::core::over_time::frame::SequenceFrame;
use crate::core::over_time::pairs::{NO_PAIR_LOG_RATIO, PairTracker, SecondContactChain};
use crate::core::robot::model::Robot;
use crate::io::session::ContactTruth;

/// What the pair pass needs of a frame's single-contact estimate.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SingleSeen {
    /// The single contact's sample.
    pub point: usize,
    /// Its magnitude, N.
    pub force_newtons: f64,
    /// Whether the single contact explains the torques (its verdict is
    /// "contact", not "poorly explained").
    pub explained: bool,
}

impl SingleSeen {
    /// A frame's single contact, `None` where it calls no contact.
    #[must_use]
    pub fn of(update: &Update) -> Option<Self> {
        let s = &update.summary;
        (s.verdict != Verdict::NoContact).then_some(Self {
            point: s.map.point,
            force_newtons: s.map.force_newtons,
            explained: s.verdict == Verdict::Contact,
        })
    }
}

/// A frame's two-contact account over the session.
#[derive(Debug, Clone, PartialEq)]
pub struct FramePair {
    /// Its own search's answer.
    pub pair: PairEstimate,
    /// Probability of two contacts given the whole session.
    pub probability_two: f64,
}

impl FramePair {
    /// Whether the frame is called two contacts: more probable than one
    /// over the session, and identifiable.
    #[must_use]
    pub fn has_two(&self) -> bool {
        self.pair.identifiable && self.probability_two > 0.5
    }
}

/// Each frame's two-contact account (`None` for frames without contact),
/// the searches run in order, `singles[i]` frame `i`'s single contact.
///
/// # Errors
/// A frame whose search fails, with its number.
pub fn session_pairs(
    estimator: &Estimator,
    robot: &Robot,
    frames: &[SequenceFrame<'_>],
    singles: &[Option<SingleSeen>],
    pair_settings: &PairSettings,
    chain: SecondContactChain,
) -> Result<Vec<Option<FramePair>>, (usize, EstimateError)> {
    let mut tracker = PairTracker::new();
    let mut found: Vec<Option<PairEstimate>> = Vec::with_capacity(frames.len());
    for (i, (frame, single)) in frames.iter().zip(singles).enumerate() {
        let Some(single) = single else {
            tracker.observe(None, None);
            found.push(None);
            continue;
        };
        // One contact that explains the torques (the fit test) is not
        // searched for a second: on one-contact recordings with friction
        // and model error, the pair's two spare unknowns otherwise take
        // up the misfit (`docs/decisions.md`, *Two contacts*).
        if single.explained {
            tracker.observe(Some((single.point, single.force_newtons)), None);
            found.push(None);
            continue;
        }
        let mut pair = estimator
            .pair_at(
                robot,
                frame.joint_positions,
                frame.tau,
                pair_settings,
                &tracker.starts(),
            )
            .map_err(|e| (i, e))?;
        // A session keeps each pair's summary, not its posteriors over
        // the surface: memory stays flat in the frames searched.
        for contact in pair.iter_mut().flat_map(|p| p.contacts.iter_mut()) {
            contact.probability = Vec::new();
        }
        let alone = single.explained.then_some((single.point, single.force_newtons));
        tracker.observe(alone, pair.as_ref());
        found.push(pair);
    }
    let times: Vec<f64> = frames.iter().map(|f| f.t_secs).collect();
    let ratios: Vec<f64> = found
        .iter()
        .map(|p| p.as_ref().map_or(NO_PAIR_LOG_RATIO, PairEstimate::log_evidence_ratio))
        .collect();
    let smoothed = chain.smooth(&times, &ratios, pair_settings.prior_two);
    Ok(found
        .into_iter()
        .zip(smoothed)
        .map(|(pair, probability_two)| pair.map(|pair| FramePair { pair, probability_two }))
        .collect())
}

/// How the second contacts of a session with every true contact recorded
/// (`truth_all`) compare with the truth.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct PairScore {
    /// Frames where two contacts press.
    pub both_frames: usize,
    /// Of these, frames called two.
    pub both_called_two: usize,
    /// Frames where two contacts press that six or more sensed joints
    /// feel (fewer leave a pair's six unknowns open: it cannot be called).
    pub both_identifiable: usize,
    /// Of these, frames called two.
    pub both_identifiable_called_two: usize,
    /// Frames where one contact presses.
    pub one_frames: usize,
    /// Of these, frames called two.
    pub one_called_two: usize,
    /// In frames where both press and two are called, each true contact's
    /// distance from the estimate matched to it, m (truths matched to
    /// estimates by the smaller total distance).
    pub both_errors_m: Vec<f64>,
}

impl PairScore {
    /// Adds a frame: its true contacts (world points), how many sensed
    /// joints feel them, and the world points of its two estimates where
    /// it is called two.
    pub fn add(&mut self, truths: &[ContactTruth], sensing_joints: usize, two: Option<[DVec3; 2]>) {
        match truths {
            [one] => {
                let _ = one;
                self.one_frames += 1;
                self.one_called_two += usize::from(two.is_some());
            }
            [a, b] => {
                self.both_frames += 1;
                let identifiable = sensing_joints >= 6;
                self.both_identifiable += usize::from(identifiable);
                if let Some([e0, e1]) = two {
                    self.both_called_two += 1;
                    self.both_identifiable_called_two += usize::from(identifiable);
                    let (a, b) = (DVec3::from_array(a.point), DVec3::from_array(b.point));
                    let straight = [a.distance(e0), b.distance(e1)];
                    let crossed = [a.distance(e1), b.distance(e0)];
                    let pick = if straight[0] + straight[1] <= crossed[0] + crossed[1] {
                        straight
                    } else {
                        crossed
                    };
                    self.both_errors_m.extend(pick);
                }
            }
            _ => {}
        }
    }

    /// The median of [`PairScore::both_errors_m`], m (NaN without any).
    #[must_use]
    pub fn median_error_m(&self) -> f64 {
        if self.both_errors_m.is_empty() {
            f64::NAN
        } else {
            percentile(&self.both_errors_m, 0.5)
        }
    }
}
