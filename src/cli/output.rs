//! One frame's estimate as the JSON line `estimate` writes (files and
//! live alike).

use proprioscope::core::estimate::estimator::Update;
use proprioscope::core::estimate::summary::{Summary, Verdict};
use proprioscope::core::eval::metrics::FrameOutcome;
use proprioscope::core::robot::model::Robot;
use proprioscope::io::session::Truth;

/// A frame's JSON line: frame number and time, the estimate, its
/// update time, and the error against `truth` where there is one.
pub fn frame_json(
    robot: &Robot,
    (frame, t): (usize, f64),
    update: &Update,
    ms: f64,
    truth: &Truth,
    (outcome, held): (Option<&FrameOutcome>, Option<bool>),
) -> serde_json::Value {
    let s = &update.summary;
    let verdict = match s.verdict {
        Verdict::Contact => "contact",
        Verdict::NoContact => "no_contact",
        Verdict::PoorFit => "poor_fit",
    };
    let contact = s.verdict != Verdict::NoContact;
    let mut v = serde_json::json!({
        "frame": frame,
        "t": t,
        "verdict": verdict,
        "link": contact.then(|| robot.links[s.map.link].name.clone()),
        "point": contact.then(|| s.map.point_world.to_array()),
        "force": contact.then(|| s.map.force_world.to_array()),
        "point_in_link": contact
            .then(|| update.pose.world_from_link.get(s.map.link))
            .flatten()
            .map(|w| w.inverse().transform_point3(s.map.point_world).to_array()),
        "force_tangential": contact.then(|| s.map.tangential_world().to_array()),
        "probability": s.map.probability,
        "contact_probability": s.contact_probability,
        "refined": s.refined,
        "grid": contact.then(|| serde_json::json!({
            "link": robot.links[s.grid_map.link].name.clone(),
            "point": s.grid_map.point_world.to_array(),
            "force": s.grid_map.force_world.to_array(),
        })),
        "credible90_points": s.credible90.points.len(),
        "credible90_radius_m": s.credible90.radius_m,
        "clusters": s.clusters.len(),
        "links": contact.then(|| link_shares_json(robot, s)),
        "fit_p": s.fit.p_value,
        "no_contact_p": s.fit.no_contact_p,
        "evaluated": update.posterior.phases.iter().map(|p| [p.points, p.particles]).collect::<Vec<_>>(),
        "update_ms": ms,
        "update_parts_ms": update.stages.map(|p| serde_json::json!({
            "posterior": p.posterior_ms,
            "refinement": p.refine_ms,
            "summary": p.summary_ms,
        })),
    });
    if let (Some(o), Truth::Contact { link, .. }) = (outcome, truth) {
        v["truth"] = serde_json::json!({
            "link": link,
            "position_error_m": o.true_point.distance(o.estimated_point),
            "force_error_n": o.true_force.distance(o.estimated_force),
            "link_correct": o.link_correct,
            "in_credible90": held,
        });
    } else if *truth == Truth::NoContact {
        v["truth"] = serde_json::Value::Null;
    }
    v
}

/// Links that hold at least [`LINK_SHARE_SHOWN`] of the posterior given a
/// contact, most probable first: where one frame (or a recording) cannot
/// tell the links apart, the shares say so.
const LINK_SHARE_SHOWN: f64 = 0.01;

/// The `links` field of a frame's JSON line: `[{"link", "probability"}]`,
/// most probable first (equal shares by name).
fn link_shares_json(robot: &Robot, s: &Summary) -> serde_json::Value {
    let mut shares: Vec<(String, f64)> = s
        .per_link
        .iter()
        .filter(|share| share.summed >= LINK_SHARE_SHOWN)
        .filter_map(|share| Some((robot.links.get(share.link)?.name.clone(), share.summed)))
        .collect();
    shares.sort_by(|x, y| y.1.total_cmp(&x.1).then_with(|| x.0.cmp(&y.0)));
    shares
        .into_iter()
        .map(|(link, probability)| serde_json::json!({ "link": link, "probability": probability }))
        .collect()
}

/// Each line's `slide_velocity_in_link` (m/s, the link's frame): how fast
/// its contact moves over the link, the slope of a line fitted through
/// its places over the last [`SLIDE_WINDOW_SECS`] (this line's and the
/// one before at least), where those lines have a contact on the same
/// link and no hop between two of them ([`is_hop`]) and span half the
/// window at least; null otherwise (the arm's own motion is not in it).
/// Lines are marked in time order, so live output reads the same as a
/// file's.
///
/// Not the step from the line before: a smoothed place strays by a
/// millimetre or so from frame to frame, which at 1 kHz reads as a metre
/// a second. Nor across a hop: that is the estimate moving to another
/// place (a press cut where its places jump, a place that flickers
/// between two valleys), not a slide. Step by step, the `../shared`
/// link-side observer example (1 kHz, probes that hold) read 0.58 m/s at
/// p99 of its frames and 9.9 m/s at most; generated two-hand sessions
/// 1.7 m/s at p90 and 17 m/s at most (`docs/validation.md`, *The slide
/// velocity in the JSON lines*).
#[derive(Debug, Default)]
pub struct SlideVelocity {
    /// The link of the places in `run`.
    link: serde_json::Value,
    /// The places (time, point in the link's frame) of the lines within
    /// the window, on one link with no hop between, oldest first.
    run: std::collections::VecDeque<(f64, glam::DVec3)>,
}

/// The window [`SlideVelocity`] fits a contact's slide over, s: five
/// frames at 100 Hz, fifty at 1 kHz; a slide of a few cm/s moves 1–5 mm
/// in it.
pub const SLIDE_WINDOW_SECS: f64 = 0.05;

/// A step of a contact's place between two lines longer than this, m,
/// and faster than [`FASTEST_SLIDE_M_PER_S`], is a hop, not a slide
/// (see [`is_hop`]).
pub const HOP_M: f64 = 0.01;

/// The fastest slide [`SlideVelocity`] reads, m/s: an object slides over
/// an arm that it pushes at centimetres a second (the slides drawn by
/// `synth` at 2–10 cm/s), a hand that strokes it at tenths of a metre.
pub const FASTEST_SLIDE_M_PER_S: f64 = 0.5;

/// Whether a step of `step_m` over `dt_secs` is a hop to another place:
/// longer than [`HOP_M`] and than [`FASTEST_SLIDE_M_PER_S`] goes in
/// `dt_secs` (1 cm at 100 Hz and faster, 5 cm at 10 Hz).
fn is_hop(step_m: f64, dt_secs: f64) -> bool {
    step_m > HOP_M.max(FASTEST_SLIDE_M_PER_S * dt_secs)
}

impl SlideVelocity {
    /// Sets `line["slide_velocity_in_link"]` from the lines before it
    /// and this one, and keeps this line's contact for the next.
    pub fn mark(&mut self, line: &mut serde_json::Value) {
        let t = line["t"].as_f64();
        let link = line["link"].clone();
        let point: Option<glam::DVec3> = line["point_in_link"].as_array().and_then(|a| {
            let v: Vec<f64> = a.iter().filter_map(serde_json::Value::as_f64).collect();
            <[f64; 3]>::try_from(v).ok().map(glam::DVec3::from)
        });
        let velocity = match (t, point) {
            (Some(t), Some(p)) if !link.is_null() && t.is_finite() && p.is_finite() => {
                let goes_on = self.link == link
                    && self
                        .run
                        .back()
                        .is_some_and(|&(t0, p0)| t > t0 && !is_hop(p.distance(p0), t - t0));
                if !goes_on {
                    self.run.clear();
                    self.link = link;
                }
                self.run.push_back((t, p));
                while self.run.len() > 2 && self.run.front().is_some_and(|&(t0, _)| t - t0 > SLIDE_WINDOW_SECS) {
                    self.run.pop_front();
                }
                // Two places a frame apart at a high rate read their
                // jitter: half a window of the track at least.
                let span = self.run.front().map_or(0.0, |&(t0, _)| t - t0);
                (span >= 0.5 * SLIDE_WINDOW_SECS)
                    .then(|| slope(&self.run))
                    .flatten()
                    .map(|v| v.to_array())
            }
            _ => {
                self.run.clear();
                None
            }
        };
        line["slide_velocity_in_link"] = serde_json::json!(velocity);
    }
}

/// The least-squares slope of `points` (time, place) over time, m/s:
/// `None` with fewer than two or all at one time (no spread in time).
fn slope(points: &std::collections::VecDeque<(f64, glam::DVec3)>) -> Option<glam::DVec3> {
    let n = points.len() as f64;
    let t_mean = points.iter().map(|(t, _)| t).sum::<f64>() / n;
    let p_mean = points.iter().map(|(_, p)| *p).sum::<glam::DVec3>() / n;
    let spread: f64 = points.iter().map(|(t, _)| (t - t_mean).powi(2)).sum();
    let along: glam::DVec3 = points.iter().map(|(t, p)| (*p - p_mean) * (t - t_mean)).sum();
    (spread > 0.0).then(|| along / spread)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A contact that moves 1 mm every 10 ms on one link slides at 0.1
    /// m/s once 30 ms of its track are in, and 3 cm in 0.1 s at 0.3 m/s;
    /// a change of link, a frame without contact or a hop of 2 cm in 10
    /// ms gives none, nor less than half a window of track.
    #[test]
    fn slide_velocity_keeps_to_one_link_and_one_place() {
        let line = |t: f64, link: Option<&str>, x: f64| serde_json::json!({"t": t, "link": link, "point_in_link": link.map(|_| [x, 0.0, 0.0])});
        let mut slide = SlideVelocity::default();
        let mut lines = [
            line(0.0, Some("a"), 0.0),
            line(0.01, Some("a"), 0.001),
            line(0.02, Some("a"), 0.002),
            line(0.03, Some("a"), 0.003),
            line(0.04, Some("b"), 0.003),
            line(0.05, None, 0.0),
            line(0.06, Some("b"), 0.0),
            line(0.07, Some("b"), 0.02),
            line(0.08, Some("b"), 0.0199),
            line(0.09, Some("b"), 0.0198),
            line(0.10, Some("b"), 0.0197),
            line(1.0, Some("c"), 0.0),
            line(1.1, Some("c"), 0.03),
        ];
        for l in &mut lines {
            slide.mark(l);
        }
        let v = |k: usize| lines[k]["slide_velocity_in_link"].clone();
        let x = |k: usize| v(k)[0].as_f64().unwrap_or(f64::NAN);
        for k in [0, 1, 2, 4, 5, 6, 7, 8, 9, 11] {
            assert!(v(k).is_null(), "line {k}: {}", v(k));
        }
        assert!((x(3) - 0.1).abs() < 1e-9, "{}", x(3));
        assert!((x(10) + 0.01).abs() < 1e-9, "{}", x(10));
        assert!((x(12) - 0.3).abs() < 1e-9, "{}", x(12));
    }

    /// A slide of 0.1 m/s at 1 kHz whose places stray by ±1 mm from frame
    /// to frame (±2 m/s step by step) reads within 0.02 m/s of its speed
    /// once the window is full, and the window forgets what came before.
    #[test]
    fn slide_velocity_is_fitted_over_the_window() {
        let mut slide = SlideVelocity::default();
        let mut last = serde_json::Value::Null;
        for k in 0..200 {
            let t = f64::from(k) * 0.001;
            let speed = if k < 100 { 0.0 } else { 0.1 };
            let x = speed * (t - 0.1).max(0.0) + if k % 2 == 0 { 0.001 } else { -0.001 };
            let mut line = serde_json::json!({"t": t, "link": "a", "point_in_link": [x, 0.0, 0.0]});
            slide.mark(&mut line);
            if k == 99 {
                let still = line["slide_velocity_in_link"][0].as_f64().unwrap_or(f64::NAN);
                assert!(still.abs() < 0.02, "{still}");
            }
            last = line;
        }
        let x = last["slide_velocity_in_link"][0].as_f64().unwrap_or(f64::NAN);
        assert!((x - 0.1).abs() < 0.02, "{x}");
    }
}
