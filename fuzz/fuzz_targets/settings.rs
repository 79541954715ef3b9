//! The numeric settings that `torques` and `estimate` take from their
//! arguments (σ, the force range, friction, α, a pose, a push): any
//! numbers either fall outside their range (refused, as the command line
//! refuses them) or give finite torques and a finite estimate or an
//! error, never a panic, an overflow or a NaN.
#![no_main]

use std::sync::OnceLock;

use glam::DVec3;
use proprioscope::core::config::limits;
use proprioscope::core::estimate::estimator::Estimator;
use proprioscope::core::estimate::settings::EstimatorSettings;
use proprioscope::core::robot::builtin;
use proprioscope::core::robot::kinematics::RobotPose;
use proprioscope::core::robot::model::Robot;
use proprioscope::core::robot::torque::joint_torques;
use proprioscope::core::surface::sampling::SurfaceRequest;

/// The built-in LWR and an estimator on 300 of its surface points.
fn base() -> &'static (Robot, Estimator) {
    static BASE: OnceLock<(Robot, Estimator)> = OnceLock::new();
    BASE.get_or_init(|| {
        let Ok(robot) = builtin::lwr4plus_generated() else {
            std::process::abort()
        };
        let request = SurfaceRequest {
            links: robot.default_candidate_links(),
            total_points: 300,
            seed: 0,
        };
        let Ok(estimator) = Estimator::new(&robot, &request, EstimatorSettings::exact(vec![0.05; 7]), None) else {
            std::process::abort()
        };
        (robot, estimator)
    })
}

/// The data as f64s, eight bytes each.
fn numbers(data: &[u8]) -> Vec<f64> {
    data.chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
        .collect()
}

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Some((&selector, rest)) = data.split_first() else {
        return;
    };
    let n = numbers(rest);
    // 7 joint positions, a point, a force, σ, F min, F max, μ, α.
    if n.len() < 18 {
        return;
    }
    let (robot, base) = base();
    let q = &n[..7];
    let in_range = |range: &limits::Range, v: &[f64]| v.iter().all(|&x| range.check(x).is_ok());
    if !(in_range(&limits::JOINT_POSITION, q)
        && in_range(&limits::COORDINATE, &n[7..10])
        && in_range(&limits::FORCE_COMPONENT, &n[10..13]))
    {
        return;
    }
    let Ok(positions) = robot.joint_positions(q, &[]) else {
        return;
    };
    let pose = RobotPose::new(robot, &positions);
    let link = base.links[usize::from(selector) % base.links.len()];
    let point = DVec3::new(n[7], n[8], n[9]);
    let force = DVec3::new(n[10], n[11], n[12]);
    let tau = joint_torques(robot, &pose, link, point, force);
    assert!(tau.iter().all(|t| t.is_finite()), "{tau:?} from {point} {force}");
    let (sigma, f_min, f_max, mu, alpha) = (n[13], n[14], n[15], n[16], n[17]);
    if !(limits::SIGMA.contains(sigma)
        && limits::FORCE_MIN.contains(f_min)
        && limits::FORCE_MAX.contains(f_max)
        && f_min <= f_max
        && limits::FRICTION.contains(mu)
        && limits::ALPHA.contains(alpha))
    {
        return;
    }
    // Measured torques within their range (a push within range can exceed it).
    if !in_range(&limits::TORQUE, &tau) {
        return;
    }
    let mut estimator = base.clone();
    estimator.settings = EstimatorSettings {
        force_min_newtons: f_min,
        force_max_newtons: f_max,
        friction: mu,
        phase_alpha: (selector & 0x80 != 0).then_some(alpha),
        ..EstimatorSettings::exact(vec![sigma; 7])
    };
    if let Ok(update) = estimator.update(robot, &positions, &tau) {
        assert_eq!(update.summary.non_finite_field(), None);
    }
});
