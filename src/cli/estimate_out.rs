//! Where `estimate --out` goes: JSON lines (one a frame), or an MCAP with
//! the input's topics, the estimates and what Foxglove shows of them.

use std::io::Write as _;

use anyhow::{Context as _, Result};
use proprioscope::batch::credible_set_holds_truth;
use proprioscope::core::estimate::estimator::{Estimator, Update};
use proprioscope::core::estimate::summary::Verdict;
use proprioscope::core::eval::metrics::FrameOutcome;
use proprioscope::core::robot::model::Robot;
use proprioscope::io::foxglove::{ArmScene, FoxglovePainter};
use proprioscope::io::mcap_out::{EstimateMessage, EstimateWriter};
use proprioscope::io::recording::{is_recording, read_bytes};
use proprioscope::io::session::{Frame, Session};

use super::output::{SlideVelocity, frame_json};

/// Where `--out` goes: JSON lines, or an MCAP file with the input's
/// topics and the estimates.
pub(super) enum Out {
    /// One JSON line a frame.
    Json(std::io::BufWriter<std::fs::File>, SlideVelocity),
    /// MCAP, with what Foxglove is sent once the estimator is set
    /// ([`Out::draw_for_foxglove`]).
    Mcap(Box<EstimateWriter>, Option<FoxglovePainter>),
}

impl Out {
    /// `.mcap` gets the input (a recording's messages, or a session's
    /// frames as joint states and truth), then an estimate a frame.
    pub(super) fn create(
        out_path: &std::path::Path,
        input: &std::path::Path,
        session: &Session,
        robot: &Robot,
        origin_ns: Option<i64>,
    ) -> Result<Self> {
        let is_mcap = out_path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("mcap"));
        if !is_mcap {
            let file = std::fs::File::create(out_path).with_context(|| format!("creating {}", out_path.display()))?;
            return Ok(Self::Json(std::io::BufWriter::new(file), SlideVelocity::default()));
        }
        let world = robot.links.get(robot.root).map_or("world", |l| l.name.as_str());
        let mut w = EstimateWriter::create(out_path, world)?;
        if is_recording(input) {
            w.copy_recording(input, &read_bytes(input)?)?;
        } else {
            let joints = session
                .joints
                .clone()
                .unwrap_or_else(|| robot.sensed_names().into_iter().map(str::to_owned).collect());
            w.write_frames(&joints, &session.frames, origin_ns.unwrap_or(0))?;
        }
        Ok(Self::Mcap(Box::new(w), None))
    }

    /// For an MCAP: from now on each estimate is also drawn for Foxglove
    /// on the arm (its meshes and URDF written at `stamp_ns`);
    /// `over_time`: the estimates come from the frames together;
    /// `transforms_hz`: the most transforms a second (0: every frame).
    pub(super) fn draw_for_foxglove(
        &mut self,
        robot: &Robot,
        estimator: &Estimator,
        (over_time, transforms_hz): (bool, f64),
        stamp_ns: i64,
    ) -> Result<()> {
        if let Self::Mcap(w, painter) = self {
            w.add_foxglove(ArmScene::new(robot), stamp_ns)?;
            *painter = Some(FoxglovePainter::new(robot, estimator, over_time, transforms_hz));
        }
        Ok(())
    }

    /// A frame's MCAP message (with what Foxglove is sent of it), for
    /// frames written later ([`Out::write_made`]).
    pub(super) fn message(
        &mut self,
        estimator: &Estimator,
        robot: &Robot,
        (frame, joint_positions): (&Frame, &[f64]),
        update: &Update,
        origin_ns: i64,
    ) -> EstimateMessage {
        let mut message = estimate_message(estimator, robot, update, origin_ns, frame.t);
        if let Self::Mcap(_, Some(painter)) = self {
            let drawn = painter.frame(estimator, update, frame, joint_positions, message.stamp_ns);
            // The credible set is drawn with the arrows, at their rate.
            if drawn.arrows.is_none() {
                message.region = None;
            }
            message.foxglove = Some(drawn);
        }
        message
    }

    /// One frame's estimate (`frame`: its number in the file, it, and its
    /// joint positions in the robot's order).
    #[allow(clippy::too_many_arguments)] // what a line holds, each from its own place
    pub(super) fn write(
        &mut self,
        estimator: &Estimator,
        robot: &Robot,
        (number, frame, joint_positions): (usize, &Frame, &[f64]),
        update: &Update,
        ms: f64,
        outcome: Option<&FrameOutcome>,
        origin_ns: Option<i64>,
    ) -> Result<()> {
        match self {
            Self::Json(w, slide) => {
                let mut line = json_line(estimator, robot, (number, frame), update, ms, outcome);
                slide.mark(&mut line);
                writeln!(w, "{line}").context("writing --out")
            }
            Self::Mcap(..) => {
                let message = self.message(
                    estimator,
                    robot,
                    (frame, joint_positions),
                    update,
                    origin_ns.unwrap_or(0),
                );
                if let Self::Mcap(w, _) = self {
                    w.write_estimate(&message).context("writing --out")?;
                }
                Ok(())
            }
        }
    }

    /// Frames made elsewhere: their JSON lines, or their MCAP estimates.
    pub(super) fn write_made(&mut self, lines: &mut [serde_json::Value], messages: &[EstimateMessage]) -> Result<()> {
        match self {
            Self::Json(w, slide) => {
                for line in lines {
                    slide.mark(line);
                    writeln!(w, "{line}").context("writing --out")?;
                }
            }
            Self::Mcap(w, _) => {
                for message in messages {
                    w.write_estimate(message).context("writing --out")?;
                }
            }
        }
        Ok(())
    }

    /// Whether the estimates go to an MCAP.
    pub(super) fn is_mcap(&self) -> bool {
        matches!(self, Self::Mcap(..))
    }

    /// Flushes JSON lines, or closes the MCAP with its summary.
    pub(super) fn finish(self) -> Result<()> {
        match self {
            Self::Json(mut w, _) => w.flush().context("writing --out"),
            Self::Mcap(w, _) => Ok(w.finish()?),
        }
    }
}

/// A frame's estimate as the MCAP output holds it.
fn estimate_message(estimator: &Estimator, robot: &Robot, update: &Update, origin_ns: i64, t: f64) -> EstimateMessage {
    let s = &update.summary;
    let contact = s.verdict != Verdict::NoContact;
    let region = if contact {
        s.credible90
            .points
            .iter()
            .filter_map(|&i| {
                let p = estimator.surface.point_world(&update.pose, i)?;
                Some((
                    p.to_array(),
                    update.posterior.probability.get(i).copied().unwrap_or(0.0),
                ))
            })
            .collect()
    } else {
        Vec::new()
    };
    EstimateMessage {
        stamp_ns: origin_ns.saturating_add((t * 1e9).round() as i64),
        contact_probability: s.contact_probability,
        contact: contact.then(|| {
            (
                robot.links.get(s.map.link).map_or_else(String::new, |l| l.name.clone()),
                s.map.point_world.to_array(),
                s.map.force_world.to_array(),
            )
        }),
        second_contact: None,
        region: Some(region),
        foxglove: None,
    }
}

/// One frame's JSON line, its `contacts` the single contact's (or none).
pub(super) fn json_line(
    estimator: &Estimator,
    robot: &Robot,
    (number, frame): (usize, &Frame),
    update: &Update,
    ms: f64,
    outcome: Option<&FrameOutcome>,
) -> serde_json::Value {
    let held = credible_set_holds_truth(robot, &estimator.surface, update, &frame.truth);
    let mut line = frame_json(robot, (number, frame.t), update, ms, &frame.truth, (outcome, held));
    line["contacts"] = single_contact_json(robot, update);
    line
}

/// A frame's `contacts` with one contact or none: the summary's.
fn single_contact_json(robot: &Robot, update: &Update) -> serde_json::Value {
    let s = &update.summary;
    if s.verdict == Verdict::NoContact {
        return serde_json::json!([]);
    }
    serde_json::json!([{
        "link": robot.links.get(s.map.link).map(|l| l.name.clone()),
        "point": s.map.point_world.to_array(),
        "force": s.map.force_world.to_array(),
        "probability": s.contact_probability.unwrap_or(1.0),
        "credible90_radius_m": s.credible90.radius_m,
    }])
}
