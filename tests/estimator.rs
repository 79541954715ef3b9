//! The estimator on the thesis' collisions, the hard cases and the
//! recorded example session.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use proprioscope::core::estimate::estimator::{Estimator, Update};
use proprioscope::core::estimate::summary::Verdict;
use proprioscope::core::eval::metrics::percentile;
use proprioscope::core::surface::sampling::SurfaceRequest;
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
    let mut config = scene.scene.config();
    config.mode = proprioscope::core::config::estimator::ModeKind::Exact;
    let mut settings = config
        .settings(joints, proprioscope::core::over_time::sequence::Temporal::None)
        .unwrap();
    if let Some(s) = sigma {
        settings.sigma = vec![s; joints];
    }
    let request = SurfaceRequest {
        links: scene.candidate_links.clone(),
        total_points: points,
        seed: 0,
    };
    let estimator = Estimator::new(&scene.robot, &request, settings, None).unwrap();
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

/// The thesis' three LWR collisions at each scene's own settings (σ,
/// resolution, force range): the push lies in the reported 90 % credible
/// set (within one sample spacing of a member, plus the push's own
/// distance from the surface: collision 3's table point is 6 mm off our
/// surface and its force 37° off the normal), and the most probable
/// contact lies within the set's extent.
#[test]
fn thesis_lwr_collisions_lie_in_their_own_credible_sets() {
    for k in 1..=3 {
        let scene = load(&format!("lwr-collision-{k}"));
        let (estimator, update) = estimate_scene(&scene, None, scene.scene.surface_points);
        let push = scene.push.unwrap();
        let s = &estimator.surface;
        let world = |i: usize| s.point_world(&update.pose, i).unwrap();
        let off_surface = match s.shape(push.link).unwrap() {
            proprioscope::core::surface::sampling::LinkShape::Mesh(mesh) => {
                let in_link = update.pose.world_from_link[push.link]
                    .inverse()
                    .transform_point3(push.point_world);
                mesh.closest(in_link).unwrap().1.point.distance(in_link)
            }
            proprioscope::core::surface::sampling::LinkShape::Segment { .. } => 0.0,
        };
        let set = &update.summary.credible90;
        let push_to_set = set
            .points
            .iter()
            .map(|&i| world(i).distance(push.point_world))
            .fold(f64::INFINITY, f64::min);
        assert!(
            push_to_set <= off_surface + s.spacing_m(),
            "collision {k}: the push is {:.1} mm from its credible set ({} points)",
            push_to_set * 1e3,
            set.points.len()
        );
        let mean = set.points.iter().map(|&i| world(i)).sum::<glam::DVec3>() / set.points.len() as f64;
        assert!(
            update.summary.map.point_world.distance(mean) <= set.radius_m + s.spacing_m(),
            "collision {k}: the most probable contact lies outside its credible set"
        );
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

#[test]
fn torques_within_noise_are_not_refined_or_clustered() {
    let scene = load("lwr-collision-3");
    let (estimator, pushed) = estimate_scene(&scene, Some(0.05), 3000);
    assert_eq!(pushed.summary.verdict, Verdict::Contact);
    assert!(pushed.summary.refined);
    assert!(!pushed.summary.clusters.is_empty());

    let silent = vec![0.0; scene.robot.sensed().len()];
    let update = estimator.update(&scene.robot, &scene.joint_positions, &silent).unwrap();
    assert_eq!(update.summary.verdict, Verdict::NoContact);
    assert!(!update.summary.refined);
    assert!(update.summary.clusters.is_empty());
    assert!(update.posterior.probability.iter().all(|p| p.is_finite()));
}
/// An update alone says where its time went: disjoint parts of the
/// call, so they add up to no more than the call's own time, and a
/// refined contact's search took some of it.
#[test]
fn an_update_alone_reports_its_parts_within_its_time() {
    let scene = load("lwr-collision-3");
    let (estimator, _) = estimate_scene(&scene, Some(0.05), 3000);
    let started = std::time::Instant::now();
    let update = estimator
        .update(&scene.robot, &scene.joint_positions, &scene.measured_torques())
        .unwrap();
    let total_ms = started.elapsed().as_secs_f64() * 1e3;
    let stages = update.stages.unwrap();
    let parts = [stages.posterior_ms, stages.refine_ms, stages.summary_ms];
    assert!(parts.iter().all(|p| p.is_finite() && *p >= 0.0), "{stages:?}");
    assert!(parts.iter().sum::<f64>() <= total_ms, "{stages:?} > {total_ms} ms");
    assert!(update.summary.refined && stages.refine_ms > 0.0, "{stages:?}");
    // Torques within noise: nothing to refine, and no time for it.
    let silent = vec![0.0; scene.robot.sensed().len()];
    let quiet = estimator.update(&scene.robot, &scene.joint_positions, &silent).unwrap();
    assert!(!quiet.summary.refined);
    assert_eq!(quiet.stages.map(|s| s.refine_ms), Some(0.0));
}

/// Per surface seed, the median position error on a shared session
/// (σ = 0.05 N·m, 5000 points), and the share of frames called poorly
/// explained over all seeds.
fn session_medians(name: &str, seeds: &[u64]) -> (Vec<f64>, f64) {
    let path = root().join("../shared/sessions").join(name);
    let session = Session::read(&path).unwrap();
    let urdf = path.parent().unwrap().join(session.robot.as_ref().unwrap());
    let mut robot = load_robot(urdf.to_str().unwrap(), Path::new("."), &UrdfOptions::default()).unwrap();
    robot.set_sensed(session.joints.as_ref().unwrap()).unwrap();
    let mut medians = Vec::new();
    let (mut poor, mut frames) = (0usize, 0usize);
    for &seed in seeds {
        let settings = proprioscope::core::estimate::settings::EstimatorSettings::exact(vec![0.05; 7]);
        let request = SurfaceRequest {
            links: robot.default_candidate_links(),
            total_points: 5000,
            seed,
        };
        let estimator = Estimator::new(&robot, &request, settings, None).unwrap();
        let mut errors = Vec::new();
        for f in &session.frames {
            let positions = robot.joint_positions(&f.q, &[]).unwrap();
            let update = estimator.update(&robot, &positions, &f.tau).unwrap();
            frames += 1;
            poor += usize::from(update.summary.verdict == Verdict::PoorFit);
            if let Truth::Contact { point, .. } = &f.truth {
                errors.push(update.summary.map.point_world.distance(glam::DVec3::from_array(*point)));
            }
        }
        medians.push(percentile(&errors, 0.5));
    }
    (medians, poor as f64 / frames as f64)
}

/// Issue 10's targets (`proprioscope bench --session …` prints the
/// figures): the median position error at 5000 points varies by at most
/// 10 % (or 2 mm) over surface seeds 0–4, and is no worse than a grid of
/// 35,000 points gave (link 4: 62–82 mm, link 6: 6.6–7.8 mm, the static
/// example's median over the seeds 40.5 mm); few frames are called poorly
/// explained.
#[test]
#[ignore = "needs ../shared"]
fn example_sessions_are_estimated_alike_at_every_surface_seed() {
    let seeds = [0, 1, 2, 3, 4];
    for (name, worst_median_m) in [
        ("lwr4plus_dyn_example_link6.session.json", 0.0066),
        ("lwr4plus_dyn_example_link4.session.json", 0.062),
        // Pushes along the facet normals of the URDF's meshes, which our
        // smooth surface does not reproduce exactly (see the README).
        ("lwr4plus_static_example.session.json", 0.037),
    ] {
        let (medians, poor) = session_medians(name, &seeds);
        let (lo, hi) = medians.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), m| {
            (lo.min(*m), hi.max(*m))
        });
        println!("{name}: medians {medians:?} m, poorly explained {:.1} %", 100.0 * poor);
        assert!(hi <= worst_median_m, "{name}: medians {medians:?}");
        assert!(hi - lo <= (0.1 * lo).max(0.002), "{name}: medians {medians:?}");
        assert!(poor <= 0.05, "{name}: {:.1} % poorly explained", 100.0 * poor);
    }
}
