//! The estimator on the thesis' collisions, the hard cases and the
//! recorded example session.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use proprioscope::core::estimator::Mode;
use proprioscope::core::metrics::{FrameOutcome, metrics};
use proprioscope::core::pipeline::{Estimator, Update};
use proprioscope::core::summary::Verdict;
use proprioscope::core::surface::SurfaceRequest;
use proprioscope::io::builtin::load_robot;
use proprioscope::io::scene::{LoadedScene, Scene};
use proprioscope::io::session::{Session, Truth};
use proprioscope::io::urdf::UrdfOptions;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn load(name: &str) -> LoadedScene {
    let path = root().join("scenes").join(format!("{name}.json"));
    Scene::read(&path).unwrap().load(&path).unwrap()
}

/// Estimates a scene's push (exact mode, the scene's σ unless given).
fn estimate_scene(scene: &LoadedScene, sigma: Option<f64>, points: usize) -> (Estimator, Update) {
    let joints = scene.robot.sensed().len();
    let mut settings = scene.scene.estimator.to_core(joints).unwrap();
    settings.mode = Mode::Exact;
    if let Some(s) = sigma {
        settings.sigma = vec![s; joints];
    }
    let request = SurfaceRequest {
        links: scene.candidate_links.clone(),
        total_points: points,
        seed: 0,
    };
    let estimator = Estimator::new(&scene.robot, &request, settings, None, None).unwrap();
    let update = estimator
        .update(&scene.robot, &scene.joint_positions, &scene.measured_torques())
        .unwrap();
    (estimator, update)
}

/// The credible set holds a point within the surface resolution of the
/// truth: the truth's distance to the nearest sample, plus one spacing.
fn credible_set_contains_truth(scene: &LoadedScene, estimator: &Estimator, update: &Update) {
    let push = scene.push.unwrap();
    let world = |k: usize| estimator.surface.point_world(&update.pose, k).unwrap();
    let nearest_sample = (0..estimator.surface.len())
        .filter(|&k| estimator.surface.link[k] == push.link)
        .map(|k| world(k).distance(push.point_world))
        .fold(f64::INFINITY, f64::min);
    let tolerance = nearest_sample + estimator.surface.spacing_m();
    let nearest_in_set = update
        .summary
        .credible90
        .points
        .iter()
        .map(|&k| world(k).distance(push.point_world))
        .fold(f64::INFINITY, f64::min);
    assert!(
        nearest_in_set <= tolerance,
        "{}: credible set ({} points) is {:.1} mm from the truth, tolerance {:.1} mm",
        scene.scene.name,
        update.summary.credible90.points.len(),
        nearest_in_set * 1e3,
        tolerance * 1e3
    );
}

#[test]
fn thesis_lwr_collisions_noise_free_sigma_0_1_credible_sets_contain_the_truth() {
    for k in 1..=3 {
        let scene = load(&format!("lwr-collision-{k}"));
        let (estimator, update) = estimate_scene(&scene, Some(0.1), 4605);
        assert!(update.posterior.probability.iter().all(|p| p.is_finite()));
        // Collisions 1 and 2 make 0.1 and 0.3 N·m: within σ = 0.1 of zero on
        // seven joints, so only collision 3 is a detectable contact.
        if k == 3 {
            assert_eq!(update.summary.verdict, Verdict::Contact);
        }
        credible_set_contains_truth(&scene, &estimator, &update);
    }
}

#[test]
fn push_on_link_1_keeps_the_truth_in_a_large_credible_set() {
    let scene = load("lwr-hard-link1");
    let (estimator, update) = estimate_scene(&scene, Some(0.05), 3000);
    credible_set_contains_truth(&scene, &estimator, &update);
    // One equation: a whole line of solutions, so the set is spread out.
    assert!(
        update.summary.credible90.radius_m > 0.03,
        "{}",
        update.summary.credible90.radius_m
    );
}

#[test]
fn push_through_a_joint_axis_gives_a_finite_answer_containing_the_truth() {
    let scene = load("lwr-hard-through-axis2");
    let (estimator, update) = estimate_scene(&scene, Some(0.05), 3000);
    assert!(update.posterior.log_likelihood.iter().all(|l| !l.is_nan()));
    credible_set_contains_truth(&scene, &estimator, &update);
}

/// What `estimate` measures on the recorded example session.
fn session_outcomes() -> Vec<FrameOutcome> {
    let path = root().join("../shared/sessions/lwr4plus_static_example.session.json");
    let session = Session::read(&path).unwrap();
    let urdf = path.parent().unwrap().join(session.robot.as_ref().unwrap());
    let mut robot = load_robot(urdf.to_str().unwrap(), Path::new("."), &UrdfOptions::default()).unwrap();
    robot.set_sensed(session.joints.as_ref().unwrap()).unwrap();
    let settings = proprioscope::core::estimator::EstimatorSettings {
        sigma: vec![0.05; 7],
        force_min_newtons: 1.0,
        force_max_newtons: 30.0,
        mode: Mode::Exact,
        phase_alpha: None,
        resolution_m: 0.0,
    };
    let request = SurfaceRequest {
        links: robot.default_candidate_links(),
        total_points: 5000,
        seed: 0,
    };
    let estimator = Estimator::new(&robot, &request, settings, None, None).unwrap();
    session
        .frames
        .iter()
        .filter_map(|f| {
            let Truth::Contact { link, point, force } = &f.truth else {
                return None;
            };
            let positions = robot.joint_positions(&f.q, &[]).unwrap();
            let update = estimator.update(&robot, &positions, &f.tau).unwrap();
            let map = update.summary.map;
            Some(FrameOutcome {
                sensing_joints: link
                    .trim_start_matches("lwr_")
                    .chars()
                    .next()
                    .and_then(|c| c.to_digit(10))
                    .unwrap() as usize,
                p_max: update.posterior.display[map.point],
                estimated_point: map.point_world,
                estimated_force: map.force_world,
                true_point: glam::DVec3::from_array(*point),
                true_force: glam::DVec3::from_array(*force),
                link_correct: robot.links[map.link].name == *link,
            })
        })
        .collect()
}

/// The accuracy targets (σ = 0.05 N·m, 5000 points).
#[test]
#[ignore = "needs ../shared"]
fn example_session_accuracy_targets() {
    let outcomes = session_outcomes();
    assert_eq!(outcomes.len(), 40);
    let all = metrics(&outcomes);
    let distal: Vec<FrameOutcome> = outcomes.iter().copied().filter(|o| o.sensing_joints >= 5).collect();
    let distal = metrics(&distal);
    assert!(
        all.position_median_m <= 0.035,
        "median {:.1} mm",
        all.position_median_m * 1e3
    );
    assert!(
        distal.position_median_m <= 0.015,
        "links 5-7 median {:.1} mm",
        distal.position_median_m * 1e3
    );
    assert!(
        all.link_accuracy >= 0.7,
        "link right in {:.0} %",
        all.link_accuracy * 100.0
    );
}
