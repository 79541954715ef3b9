//! Whether a press's error is the search's or the model's: the press fit
//! ([`crate::core::estimate::explain::explain_press`]) run again from the
//! estimate's places and from the true ones. Where the fit from the truth
//! costs far less (`-2 ln L`), the model holds a better answer that the
//! search did not reach from where the estimate stood; where it costs as
//! much or more, the model itself prefers the estimate, and only a better
//! model moves it (`docs/validation.md`, *Sliding contacts*).

use glam::DVec3;

use crate::core::estimate::estimator::Estimator;
use crate::core::estimate::explain::explain_press;
use crate::core::estimate::press::{PressFrame, locate};
use crate::core::geometry::shell::MeshPoint;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{LinkId, Robot};
use crate::core::robot::torque::TorqueModel;

/// One press fitted from one set of places.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PressFit {
    /// `-2 ln` of the posterior at the fit.
    pub cost: f64,
    /// `μ_k` where kinetic friction explains the press.
    pub kinetic_friction: Option<f64>,
    /// Median distance of the fit's places from the true ones, m.
    pub median_error_m: f64,
}

/// A press (frames with a true contact on one link, in a row) fitted
/// from the estimate's places and from the true ones.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PressGap {
    /// The true contact's link.
    pub link: LinkId,
    /// Time of its first frame, s.
    pub t_secs: f64,
    /// Its frames.
    pub frames: usize,
    /// From the estimate's places (each frame called a contact on the
    /// true link at its own, every other at the nearest such frame's);
    /// `None` where no frame is placed on that link.
    pub from_estimate: Option<PressFit>,
    /// From the true places.
    pub from_truth: Option<PressFit>,
}

impl PressGap {
    /// How much more the fit from the estimate's places costs than the
    /// fit from the truth (positive: the search lost the truth's answer).
    #[must_use]
    pub fn gap(&self) -> Option<f64> {
        Some(self.from_estimate?.cost - self.from_truth?.cost)
    }
}

/// One frame of a press as [`press_gap`] reads it.
#[derive(Debug, Clone, Copy)]
pub struct GapFrame<'a> {
    /// Time, s.
    pub t_secs: f64,
    /// Every joint's position.
    pub joint_positions: &'a [f64],
    /// Measured torques, sensed order, N·m.
    pub tau: &'a [f64],
    /// The true place, link frame, m.
    pub true_in_link: DVec3,
    /// The estimate's place in the same frame where it is called a
    /// contact on the true link.
    pub estimated_in_link: Option<DVec3>,
}

/// The press `frames` on `link` fitted as `estimator` fits a smoothed
/// press (its noise, force range and friction; `slide_m_per_sqrt_s` the
/// temporal model's slide length), from the estimate's places and from
/// the true ones. `None` without frames, or where the link has no
/// continuous surface here.
#[must_use]
pub fn press_gap(
    estimator: &Estimator,
    robot: &Robot,
    link: LinkId,
    frames: &[GapFrame],
    slide_m_per_sqrt_s: f64,
) -> Option<PressGap> {
    let surface = &estimator.surface;
    let shape = surface.shape(link)?;
    let first = frames.first()?;
    let models: Vec<TorqueModel> = frames
        .iter()
        .map(|f| {
            let q = robot.joint_positions(f.joint_positions, &[]).ok()?;
            Some(TorqueModel::new(robot, &RobotPose::new(robot, &q), &estimator.links))
        })
        .collect::<Option<_>>()?;
    let weights = estimator.settings.weights();
    let settings = estimator.press_settings(&weights, slide_m_per_sqrt_s);
    let truths: Vec<DVec3> = frames.iter().map(|f| f.true_in_link).collect();
    let fit_from = |places: &[DVec3]| -> Option<PressFit> {
        let starts: Vec<MeshPoint> = places
            .iter()
            .map(|&p| {
                // The walk to the point starts at the sample whose patch holds it.
                let from = surface.location.get(surface.owner(link, p)?)?;
                Some(locate(shape, *from, p))
            })
            .collect::<Option<_>>()?;
        let press: Vec<PressFrame> = frames
            .iter()
            .zip(&models)
            .zip(starts)
            .map(|((f, torque_model), start)| PressFrame {
                t_secs: f.t_secs,
                torque_model,
                tau: f.tau,
                start,
            })
            .collect();
        let answer = explain_press(shape, link, &press, &settings)?;
        let mut errors: Vec<f64> = answer
            .contacts
            .iter()
            .zip(&truths)
            .map(|(c, t)| c.point_in_link.distance(*t))
            .collect();
        errors.sort_by(f64::total_cmp);
        Some(PressFit {
            cost: answer.cost,
            kinetic_friction: answer.kinetic_friction,
            median_error_m: *errors.get(errors.len() / 2)?,
        })
    };
    // Each frame's estimate on the link, else the nearest frame's (the
    // earlier of two as near): a place persists in its link's frame.
    let placed: Vec<(usize, DVec3)> = frames
        .iter()
        .enumerate()
        .filter_map(|(k, f)| Some((k, f.estimated_in_link?)))
        .collect();
    let estimated: Option<Vec<DVec3>> = (!placed.is_empty()).then(|| {
        (0..frames.len())
            .map(|k| {
                placed
                    .iter()
                    .min_by_key(|(j, _)| j.abs_diff(k))
                    .map_or(DVec3::ZERO, |&(_, p)| p)
            })
            .collect()
    });
    Some(PressGap {
        link,
        t_secs: first.t_secs,
        frames: frames.len(),
        from_estimate: estimated.as_deref().and_then(&fit_from),
        from_truth: fit_from(&truths),
    })
}

#[cfg(test)]
mod tests {
    // Test helpers may unwrap: a panic is a failed test with its message.
    #![allow(clippy::unwrap_used)]

    use super::*;
    use crate::core::config::estimator::EstimatorConfig;
    use crate::core::numerics::rng::Rng;
    use crate::core::over_time::sequence::Temporal;
    use crate::core::robot::builtin;
    use crate::core::surface::sampling::SurfaceRequest;

    /// A held press on link 4 (four joints sense it) with a fixed
    /// tangential force of 0.2 of the push, the arm swinging under it,
    /// and an estimate that stands `offset_m` (link frame) from it.
    fn held_press(offset_m: DVec3) -> PressGap {
        let robot = builtin::lwr4plus_generated().unwrap();
        let link = robot.link_id("lwr_4_link").unwrap();
        let config = EstimatorConfig::default();
        let request = SurfaceRequest {
            links: robot.default_candidate_links(),
            total_points: 2000,
            seed: 0,
        };
        let settings = config.settings(7, Temporal::Smooth).unwrap();
        let estimator = Estimator::new(&robot, &request, settings, None).unwrap();
        assert!(estimator.fits_presses(), "smoothing fits presses with friction");
        let surface = &estimator.surface;
        let k = (0..surface.len()).filter(|&k| surface.link[k] == link).nth(30).unwrap();
        let (place, normal) = (surface.point_in_link[k], surface.inward_normal_in_link[k]);
        let (tangent, _) = normal.any_orthonormal_pair();
        let mut rng = Rng::new(3);
        let (mut qs, mut taus) = (Vec::new(), Vec::new());
        for i in 0..60 {
            let t = f64::from(i) / 50.0;
            let q: Vec<f64> = (0..7)
                .map(|j| 0.3 - 0.1 * f64::from(j) + 0.3 * (t + f64::from(j)).sin())
                .collect();
            let pose = RobotPose::new(&robot, &robot.joint_positions(&q, &[]).unwrap());
            let model = TorqueModel::new(&robot, &pose, &estimator.links);
            let force = normal * 10.0 + tangent * 2.0;
            let tau: Vec<f64> = model
                .torques(link, place, force)
                .iter()
                .map(|x| x + 0.05 * rng.normal())
                .collect();
            qs.push(q);
            taus.push(tau);
        }
        let frames: Vec<GapFrame> = qs
            .iter()
            .zip(&taus)
            .zip(0_u32..)
            .map(|((q, tau), i)| GapFrame {
                t_secs: f64::from(i) / 50.0,
                joint_positions: q,
                tau,
                true_in_link: place,
                estimated_in_link: Some(place + offset_m),
            })
            .collect();
        press_gap(&estimator, &robot, link, &frames, 0.01).unwrap()
    }

    #[test]
    fn a_press_is_lost_by_the_search_from_far_along_its_link_not_from_around_it() {
        let near = held_press(DVec3::ZERO);
        let truth = near.from_truth.unwrap();
        assert!(truth.median_error_m < 0.01, "{near:?}");
        // From the same places, the same fit.
        assert_eq!(near.gap(), Some(0.0), "{near:?}");
        // 15 cm along the link: the search ends 8 cm or more away, at a
        // cost about ten times the truth's.
        let along = held_press(DVec3::Z * 0.15);
        assert!(along.from_estimate.unwrap().median_error_m > 0.05, "{along:?}");
        assert!(along.gap().unwrap() > 1000.0, "{along:?}");
        assert_eq!(along.from_truth, near.from_truth);
        // 10 cm around it: the search finds the truth's answer.
        let around = held_press(DVec3::Y * 0.1);
        assert!(around.from_estimate.unwrap().median_error_m < 0.01, "{around:?}");
        assert!(around.gap().unwrap().abs() < 5.0, "{around:?}");
    }
}
