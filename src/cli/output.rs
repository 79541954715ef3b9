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
/// its contact moved over the link since the line before, where both have
/// one on the same link (null otherwise; the arm's own motion is not in
/// it). Lines are marked in time order.
#[derive(Debug, Default)]
pub struct SlideVelocity {
    /// The last line's time, link and point, where it had a contact.
    last: Option<(f64, serde_json::Value, [f64; 3])>,
}

impl SlideVelocity {
    /// Sets `line["slide_velocity_in_link"]` from the line before, and
    /// keeps this line's contact for the next.
    pub fn mark(&mut self, line: &mut serde_json::Value) {
        let t = line["t"].as_f64();
        let link = line["link"].clone();
        let point: Option<[f64; 3]> = line["point_in_link"].as_array().and_then(|a| {
            let v: Vec<f64> = a.iter().filter_map(serde_json::Value::as_f64).collect();
            <[f64; 3]>::try_from(v).ok()
        });
        let velocity = match (t, point, &self.last) {
            (Some(t), Some(p), Some((t0, l0, p0))) if *l0 == link && t > *t0 => {
                Some(std::array::from_fn::<f64, 3, _>(|k| (p[k] - p0[k]) / (t - t0)))
            }
            _ => None,
        };
        line["slide_velocity_in_link"] = serde_json::json!(velocity);
        self.last = match (t, point) {
            (Some(t), Some(p)) if !link.is_null() => Some((t, link, p)),
            _ => None,
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A contact that moves 1 mm in 10 ms on one link slides at 0.1 m/s;
    /// a change of link or a frame without contact gives none.
    #[test]
    fn slide_velocity_is_the_step_over_the_time_on_one_link() {
        let line = |t: f64, link: Option<&str>, x: f64| serde_json::json!({"t": t, "link": link, "point_in_link": link.map(|_| [x, 0.0, 0.0])});
        let mut slide = SlideVelocity::default();
        let mut lines = [
            line(0.0, Some("a"), 0.0),
            line(0.01, Some("a"), 0.001),
            line(0.02, Some("b"), 0.002),
            line(0.03, None, 0.0),
            line(0.04, Some("b"), 0.0),
        ];
        for l in &mut lines {
            slide.mark(l);
        }
        let v = |k: usize| lines[k]["slide_velocity_in_link"].clone();
        assert!(v(0).is_null() && v(2).is_null() && v(3).is_null() && v(4).is_null());
        let x = v(1)[0].as_f64().unwrap_or(f64::NAN);
        assert!((x - 0.1).abs() < 1e-12, "{x}");
    }
}
