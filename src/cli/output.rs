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
