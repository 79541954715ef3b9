//! `bench --session` on a session with two true contacts at once
//! (`truth_all`): the two-contact search smoothed, as `estimate
//! --contacts 2 --temporal smooth` runs it, scored at every surface seed.
//! A pair search follows its contacts from frame to frame, so which pair
//! it settles on can change with the samples; one seed's figures do not
//! say how a session goes (`docs/validation.md`, *Two contacts*).

use std::fmt::Write as _;

use anyhow::{Result, anyhow};
use glam::DVec3;
use proprioscope::batch::pairs::{PairScore, PairsOver, SingleSeen, session_pairs};
use proprioscope::core::config::estimator::EstimatorConfig;
use proprioscope::core::estimate::estimator::{Estimator, Update};
use proprioscope::core::estimate::summary::Verdict;
use proprioscope::core::eval::metrics::percentile;
use proprioscope::core::over_time::frame::SequenceFrame;
use proprioscope::core::robot::model::Robot;
use proprioscope::io::session::Session;

use super::estimate::{each_contact_text, mm};

/// Whether any frame of `session` has two true contacts.
#[must_use]
pub fn has_two_contacts(session: &Session) -> bool {
    session.frames.iter().any(|f| f.truth_all.len() >= 2)
}

/// What the pair pass needs of a session's single contacts, frame by
/// frame.
#[derive(Debug, Default)]
pub struct Singles {
    seen: Vec<Option<SingleSeen>>,
    points_world: Vec<Option<DVec3>>,
}

impl Singles {
    /// Adds the next frame's single-contact update.
    pub fn push(&mut self, update: &Update) {
        self.seen.push(SingleSeen::of(update));
        self.points_world
            .push((update.summary.verdict != Verdict::NoContact).then_some(update.summary.map.point_world));
    }
}

/// The session's second contacts, smoothed over the session with the
/// default configuration's pair settings and chain, scored against its
/// true contacts.
///
/// # Errors
/// A frame whose pair search fails.
pub fn score_smoothed(
    estimator: &Estimator,
    robot: &Robot,
    session: &Session,
    sequence: &[SequenceFrame<'_>],
    singles: &Singles,
) -> Result<PairScore> {
    let config = EstimatorConfig::default();
    let over = PairsOver::Smoothed(config.second_contact_chain());
    let pairs = session_pairs(estimator, robot, sequence, &singles.seen, &config.pair, over)
        .map_err(|(frame, e)| anyhow!("frame {frame}: two-contact search: {e}"))?;
    let weights = estimator.settings.weights();
    let rules = (weights.as_slice(), estimator.settings.friction > 0.0);
    let mut score = PairScore::default();
    for (n, frame) in session.frames.iter().enumerate() {
        score.add_frame(
            robot,
            (frame, rules),
            pairs.get(n).and_then(Option::as_ref),
            singles.points_world.get(n).copied().flatten(),
        );
    }
    Ok(score)
}

/// The table of a session's two-contact scores, a row per surface seed
/// and one of the medians over them.
#[must_use]
pub fn pairs_text(scores: &[(u64, PairScore)]) -> String {
    if scores.is_empty() {
        return String::new();
    }
    let mut out = String::from(
        "\nTwo contacts, smoothed (`estimate --contacts 2 --temporal smooth`), at each surface seed: frames where both press called two, the median error of both contacts there, frames where one presses called two, each true contact's median error where both press and two are called / where it presses alone, and the frames where both press whose true pair the joints can tell apart (the rules for a pair applied to the truth) called two.\n\n",
    );
    out.push_str("| surface seed | both press: called two | median error [mm] | one presses: called two | each contact, with the other / alone [mm] | both press, the joints can tell apart: called two |\n");
    out.push_str("|---:|---:|---:|---:|---|---:|\n");
    let share = |k: usize, n: usize| if n > 0 { 100.0 * k as f64 / n as f64 } else { f64::NAN };
    for (seed, score) in scores {
        let _ = writeln!(
            out,
            "| {seed} | {} of {} ({:.1} %) | {} | {} of {} ({:.1} %) | {} | {} of {} ({:.1} %) |",
            score.both_called_two,
            score.both_frames,
            share(score.both_called_two, score.both_frames),
            mm(score.median_error_m()),
            score.one_called_two,
            score.one_frames,
            share(score.one_called_two, score.one_frames),
            each_contact_text(score, ""),
            score.both_separable_called_two,
            score.both_separable,
            share(score.both_separable_called_two, score.both_separable),
        );
    }
    let median = |values: Vec<f64>| {
        let finite: Vec<f64> = values.into_iter().filter(|v| v.is_finite()).collect();
        if finite.is_empty() {
            f64::NAN
        } else {
            percentile(&finite, 0.5)
        }
    };
    let called = median(
        scores
            .iter()
            .map(|(_, s)| share(s.both_called_two, s.both_frames))
            .collect(),
    );
    let error = median(scores.iter().map(|(_, s)| s.median_error_m()).collect());
    let false_two = median(
        scores
            .iter()
            .map(|(_, s)| share(s.one_called_two, s.one_frames))
            .collect(),
    );
    let separable = median(
        scores
            .iter()
            .map(|(_, s)| share(s.both_separable_called_two, s.both_separable))
            .collect(),
    );
    let _ = writeln!(
        out,
        "| median over seeds | {called:.1} % | {} | {false_two:.1} % | | {separable:.1} % |",
        mm(error)
    );
    out
}
