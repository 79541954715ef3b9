//! `estimate --press-gaps`: each true press fitted again from the
//! estimate's places and from the true ones, to tell a press that the
//! search lost (the truth's fit far cheaper) from one the model itself
//! places wrong ([`proprioscope::core::eval::press_gap`]).

use std::io::Write;

use anyhow::Result;
use glam::DVec3;
use proprioscope::core::estimate::estimator::Estimator;
use proprioscope::core::estimate::press::FRICTION_GAIN;
use proprioscope::core::eval::press_gap::{GapFrame, PressFit, PressGap, press_gap};
use proprioscope::core::over_time::frame::SequenceFrame;
use proprioscope::core::robot::model::Robot;

/// A frame's true contact (its link, and its place in that link's frame)
/// and the estimate's place in that frame where it is called a contact
/// on that link.
pub type FramePlaces = (Option<(usize, DVec3)>, Option<DVec3>);

/// The presses of `frames` (runs of frames in a row with a true contact
/// on one link; `places` one per frame), each fitted from the estimate's
/// places and from the true ones as `estimator` fits a smoothed press.
#[must_use]
pub fn session_gaps(
    estimator: &Estimator,
    robot: &Robot,
    frames: &[SequenceFrame],
    places: &[FramePlaces],
    slide_m_per_sqrt_s: f64,
) -> Vec<PressGap> {
    let mut gaps = Vec::new();
    let mut press: Vec<GapFrame> = Vec::new();
    let mut link = None;
    let mut settle = |press: &mut Vec<GapFrame>, link: Option<usize>| {
        if let Some(link) = link
            && let Some(gap) = press_gap(estimator, robot, link, press, slide_m_per_sqrt_s)
        {
            gaps.push(gap);
        }
        press.clear();
    };
    for (frame, &(truth, estimated)) in frames.iter().zip(places) {
        let here = truth.map(|(l, _)| l);
        if here != link {
            settle(&mut press, link);
            link = here;
        }
        if let Some((_, true_in_link)) = truth {
            press.push(GapFrame {
                t_secs: frame.t_secs,
                joint_positions: frame.joint_positions,
                tau: frame.tau,
                true_in_link,
                estimated_in_link: estimated,
            });
        }
    }
    settle(&mut press, link);
    gaps
}

/// The presses' table and how many of them the search lost.
///
/// # Errors
/// Writing to stdout.
pub fn report_gaps(robot: &Robot, gaps: &[PressGap], friction: f64) -> Result<()> {
    if gaps.is_empty() {
        return Ok(());
    }
    let mut out = std::io::stdout().lock();
    writeln!(
        out,
        "\npresses, each fitted again (μ = {friction}) from the estimate's places and from the true ones: \
         the search lost a press where the fit from the truth costs more than {FRICTION_GAIN} less (−2 ln L)\n"
    )?;
    writeln!(
        out,
        "| start [s] | frames | link | from the estimate: −2 ln L | its median error [mm] | from the truth: −2 ln L | its median error [mm] | lost |"
    )?;
    writeln!(out, "|---:|---:|---|---:|---:|---:|---:|---|")?;
    let fit = |f: Option<PressFit>| match f {
        Some(PressFit {
            cost,
            median_error_m,
            kinetic_friction,
        }) => {
            let kinetic = kinetic_friction.map_or(String::new(), |mu| format!(" (μ_k {mu:.2})"));
            (format!("{cost:.1}{kinetic}"), format!("{:.1}", median_error_m * 1e3))
        }
        None => ("–".to_owned(), "–".to_owned()),
    };
    let (mut lost, mut lost_frames, mut frames) = (0, 0, 0);
    for gap in gaps {
        let name = robot.links.get(gap.link).map_or("?", |l| l.name.as_str());
        let (estimate_cost, estimate_error) = fit(gap.from_estimate);
        let (truth_cost, truth_error) = fit(gap.from_truth);
        let is_lost = gap.gap().is_some_and(|g| g > FRICTION_GAIN);
        frames += gap.frames;
        if is_lost {
            lost += 1;
            lost_frames += gap.frames;
        }
        writeln!(
            out,
            "| {:.3} | {} | {name} | {estimate_cost} | {estimate_error} | {truth_cost} | {truth_error} | {} |",
            gap.t_secs,
            gap.frames,
            if is_lost { "yes" } else { "" }
        )?;
    }
    writeln!(
        out,
        "\nthe search lost {lost} of {} presses ({lost_frames} of {frames} frames)",
        gaps.len()
    )?;
    Ok(())
}
