//! One frame's two-contact search on the built-in LWR (exact mode, 5000
//! points, one thread), beside the frame's one-contact update: from the
//! coarse grid (a frame alone), and followed from the frame before (a
//! session's frames). Issue 41 asks a frame under the two-contact model
//! to cost at most five times a frame alone.

// Benchmarks may unwrap: a panic aborts the run with its message.
#![allow(clippy::unwrap_used, missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use proprioscope::core::estimate::estimator::Estimator;
use proprioscope::core::estimate::pair::{PairSettings, PairStart};
use proprioscope::core::estimate::settings::EstimatorSettings;
use proprioscope::core::numerics::rng::Rng;
use proprioscope::core::robot::builtin;
use proprioscope::core::robot::kinematics::RobotPose;
use proprioscope::core::robot::torque::joint_torques;
use proprioscope::core::surface::sampling::SurfaceRequest;

fn pairs(c: &mut Criterion) {
    let robot = builtin::lwr4plus_generated().unwrap();
    let settings = EstimatorSettings::exact(vec![0.05; 7]);
    let request = SurfaceRequest {
        links: robot.default_candidate_links(),
        total_points: 5000,
        seed: 0,
    };
    let estimator = Estimator::new(&robot, &request, settings, None).unwrap();
    let q = [1.2, 0.3, 0.8, -1.6, -1.0, -0.5, 0.9];
    let positions = robot.joint_positions(&q, &[]).unwrap();
    let pose = RobotPose::new(&robot, &positions);
    // A firm push on link 5 and one on link 7, at samples of the surface
    // (the search's answers do not depend on where; its cost does little).
    let surface = &estimator.surface;
    let on = |name: &str| {
        let link = robot.link_id(name).unwrap();
        (0..surface.len()).find(|&k| surface.link[k] == link).unwrap()
    };
    let mut rng = Rng::new(3);
    let mut tau = [0.0; 7];
    for (k, newtons) in [(on("lwr_5_link"), 25.0), (on("lwr_7_link"), 20.0)] {
        let link = surface.link[k];
        let point = pose.point_to_world(link, surface.point_in_link[k]);
        let normal = pose.world_from_link[link].transform_vector3(surface.inward_normal_in_link[k]);
        for (t, u) in tau.iter_mut().zip(joint_torques(&robot, &pose, link, point, normal)) {
            *t += newtons * u;
        }
    }
    let tau: Vec<f64> = tau.iter().map(|t| t + 0.05 * rng.normal()).collect();
    let pair_settings = PairSettings::default();
    c.bench_function("frame alone: one contact (the update)", |b| {
        b.iter(|| estimator.update(&robot, &positions, &tau).unwrap());
    });
    c.bench_function("frame alone: the pair from the coarse grid", |b| {
        b.iter(|| {
            estimator
                .pair_at(&robot, &positions, &tau, &pair_settings, &[PairStart::Unknown])
                .unwrap()
        });
    });
    let found = estimator
        .pair_at(&robot, &positions, &tau, &pair_settings, &[PairStart::Unknown])
        .unwrap()
        .unwrap();
    let followed = [PairStart::Both(Box::new(found.contacts.map(|c| c.placed)))];
    c.bench_function("session frame: the pair followed from the frame before", |b| {
        b.iter(|| {
            estimator
                .pair_at(&robot, &positions, &tau, &pair_settings, &followed)
                .unwrap()
        });
    });
}

criterion_group!(benches, pairs);
criterion_main!(benches);
