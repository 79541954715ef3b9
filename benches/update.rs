//! One estimator update on the built-in LWR (exact mode, 5000 points, one
//! thread): with a new configuration (the whole update) and with a new
//! measurement at the same configuration (what a σ or torque change costs).

// Benchmarks may unwrap: a panic aborts the run with its message.
#![allow(clippy::unwrap_used, missing_docs)]

use criterion::{Criterion, criterion_group, criterion_main};
use proprioscope::core::estimate::contact::{ContactModel, PosedSurface};
use proprioscope::core::estimate::estimator::Estimator;
use proprioscope::core::estimate::posterior::estimate;
use proprioscope::core::estimate::settings::EstimatorSettings;
use proprioscope::core::robot::builtin;
use proprioscope::core::robot::kinematics::RobotPose;
use proprioscope::core::robot::torque::{TorqueModel, joint_torques};
use proprioscope::core::surface::sampling::SurfaceRequest;

fn update(c: &mut Criterion) {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let settings = EstimatorSettings::exact(vec![0.05; 7]);
    let request = SurfaceRequest {
        links: links.clone(),
        total_points: 5000,
        seed: 0,
    };
    let estimator = Estimator::new(&robot, &request, settings.clone(), None).unwrap();
    let q = [0.3, 0.6, -0.4, -1.2, 0.5, 0.9, 0.2];
    let positions = robot.joint_positions(&q, &[]).unwrap();
    let pose = RobotPose::new(&robot, &positions);
    let k = 3000;
    let link = estimator.surface.link[k];
    let point = pose.point_to_world(link, estimator.surface.point_in_link[k]);
    let normal = pose.world_from_link[link].transform_vector3(estimator.surface.inward_normal_in_link[k]);
    let tau = joint_torques(&robot, &pose, link, point, normal * 12.0);
    // Below 16k points the update runs on the calling thread alone.
    c.bench_function(
        "exact 5000 points: new configuration (pose, unit torques, posterior, summary)",
        |b| {
            b.iter(|| estimator.update(&robot, &positions, &tau).unwrap());
        },
    );
    let torque_model = TorqueModel::new(&robot, &pose, &links);
    let posed = PosedSurface {
        torque_model: &torque_model,
        surface: &estimator.surface,
    };
    c.bench_function("exact 5000 points: new measurement (posterior only)", |b| {
        b.iter(|| estimate(&posed, &tau, &settings, None).unwrap());
    });
    let model = ContactModel::new(&torque_model, &estimator.surface);
    c.bench_function("exact 5000 points: new measurement, stored unit torques", |b| {
        b.iter(|| estimate(&model, &tau, &settings, None).unwrap());
    });
}

criterion_group!(benches, update);
criterion_main!(benches);
