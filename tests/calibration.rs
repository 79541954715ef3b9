//! Data drawn from the model itself: does the posterior say what it
//! should? A generator (random pose within the limits, a contact point
//! uniform over the exposed surface, a push along its inward normal of a
//! magnitude uniform in the estimator's range, Gaussian sensor noise)
//! feeds the estimator, and the verdicts and credible sets are checked
//! against the truth.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use glam::DVec3;
use proprioscope::core::estimate::estimator::Estimator;
use proprioscope::core::estimate::settings::{EstimatorSettings, Mode};
use proprioscope::core::estimate::summary::Verdict;
use proprioscope::core::eval::metrics::percentile;
use proprioscope::core::numerics::rng::Rng;
use proprioscope::core::robot::builtin;
use proprioscope::core::robot::kinematics::RobotPose;
use proprioscope::core::robot::model::{LinkId, Robot};
use proprioscope::core::robot::torque::joint_torques;
use proprioscope::core::surface::sampling::{Surface, SurfaceRequest};

/// One generated frame: where and how hard the arm was pushed, and what
/// its sensors read.
struct Generated {
    q: Vec<f64>,
    link: LinkId,
    point_in_link: DVec3,
    force_newtons: f64,
    tau: Vec<f64>,
}

/// `frames` frames from the model itself, deterministic per seed.
fn generate(
    robot: &Robot,
    links: &[LinkId],
    frames: usize,
    sigma: f64,
    force: (f64, f64),
    seed: u64,
) -> Vec<Generated> {
    let pool = Surface::sample_random(
        robot,
        &SurfaceRequest {
            links: links.to_vec(),
            total_points: frames.max(links.len()),
            seed: seed ^ 0x5eed,
        },
    )
    .unwrap();
    let mut rng = Rng::new(seed);
    (0..frames)
        .map(|_| {
            let q: Vec<f64> = robot
                .sensed()
                .iter()
                .map(|&j| {
                    let l = robot.joints[j].limits.unwrap();
                    rng.uniform_in(l.lower, l.upper)
                })
                .collect();
            let k = rng.below(pool.len());
            let f = rng.uniform_in(force.0, force.1);
            let pose = RobotPose::new(robot, &robot.joint_positions(&q, &[]).unwrap());
            let link = pool.link[k];
            let p = pose.point_to_world(link, pool.point_in_link[k]);
            let n = pose.world_from_link[link].transform_vector3(pool.inward_normal_in_link[k]);
            let tau = joint_torques(robot, &pose, link, p, n * f)
                .into_iter()
                .map(|t| t + sigma * rng.normal())
                .collect();
            Generated {
                q,
                link,
                point_in_link: pool.point_in_link[k],
                force_newtons: f,
                tau,
            }
        })
        .collect()
}

/// What the estimator made of generated frames.
#[derive(Debug, Default)]
struct Tally {
    frames: usize,
    poor_fit: usize,
    no_contact: usize,
    covered: usize,
    errors_m: Vec<f64>,
}

/// The estimator at `points` samples drawn with `surface_seed` on
/// `frames` frames generated with `seed`.
fn run(frames: usize, points: usize, seed: u64, surface_seed: u64) -> Tally {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let (sigma, force) = (0.05, (1.0, 30.0));
    let data = generate(&robot, &links, frames, sigma, force, seed);
    let settings = EstimatorSettings {
        sigma: vec![sigma; 7],
        force_min_newtons: force.0,
        force_max_newtons: force.1,
        mode: Mode::Exact,
        phase_alpha: None,
        patches: true,
        friction: 0.0,
    };
    let request = SurfaceRequest {
        links,
        total_points: points,
        seed: surface_seed,
    };
    let estimator = Estimator::new(&robot, &request, settings, None).unwrap();
    let s = &estimator.surface;
    let mut tally = Tally::default();
    for g in &data {
        let positions = robot.joint_positions(&g.q, &[]).unwrap();
        let update = estimator.update(&robot, &positions, &g.tau).unwrap();
        tally.frames += 1;
        match update.summary.verdict {
            Verdict::PoorFit => tally.poor_fit += 1,
            Verdict::NoContact => tally.no_contact += 1,
            Verdict::Contact => {}
        }
        // The sample whose patch holds the true contact: the nearest on its link.
        let owner = s.owner(g.link, g.point_in_link).unwrap();
        tally.covered += usize::from(update.summary.credible90.points.contains(&owner));
        let truth = update.pose.point_to_world(g.link, g.point_in_link);
        tally.errors_m.push(update.summary.map.point_world.distance(truth));
        let _ = g.force_newtons;
    }
    tally
}

/// The targets, over 500 frames: at most 2 % poorly explained,
/// and the 90 % credible set holds the true contact in 85–95 % of frames.
#[test]
fn generated_frames_are_explained_and_credible_sets_are_calibrated() {
    let frames: usize = std::env::var("CALIBRATION_FRAMES").map_or(500, |v| v.parse().unwrap());
    let points: usize = std::env::var("CALIBRATION_POINTS").map_or(5000, |v| v.parse().unwrap());
    let t = run(frames, points, 11, 0);
    let mut e = t.errors_m.clone();
    e.sort_by(f64::total_cmp);
    let coverage = t.covered as f64 / t.frames as f64;
    println!(
        "{} frames: {} poorly explained, {} no contact, 90 % set covers the truth in {:.1} %, median error {:.1} mm",
        t.frames,
        t.poor_fit,
        t.no_contact,
        100.0 * coverage,
        1e3 * e[e.len() / 2]
    );
    assert!(
        t.poor_fit * 50 <= t.frames,
        "{} of {} poorly explained",
        t.poor_fit,
        t.frames
    );
    assert!((0.85..=0.95).contains(&coverage), "coverage {coverage}");
}

/// Issue 10's principle (the answer is a property of the arm and the
/// data, not of the sampling) where the truth is exact and the frames
/// many: over surface seeds 0–4, on 500 generated frames, the share of
/// frames placed within 20 mm of the push moves by at most 3 points, and
/// the quartiles of the position error by at most 10 % (or 0.5 mm).
/// Measured: within 20 mm 45.0–47.0 %, quartiles 3.5–3.9 and 105.2–108.9
/// mm. The median is printed, not held: it lies where the errors jump
/// from placed (p40 12–13 mm) to ambiguous (p60 59–67 mm), so ten frames
/// of 500 that tie either way move it by 5 mm, within 27–33 mm (README,
/// *The estimator*).
#[test]
fn generated_frames_are_placed_alike_at_every_surface_seed() {
    let frames: usize = std::env::var("CALIBRATION_FRAMES").map_or(500, |v| v.parse().unwrap());
    let (mut within, mut quartiles, mut medians) = (Vec::new(), Vec::new(), Vec::new());
    for surface_seed in 0..5 {
        let e = run(frames, 5000, 11, surface_seed).errors_m;
        within.push(e.iter().filter(|&&x| x < 0.02).count() as f64 / e.len() as f64);
        quartiles.push([percentile(&e, 0.25), percentile(&e, 0.75)]);
        medians.push(percentile(&e, 0.5));
    }
    println!("surface seeds 0-4: within 20 mm {within:?}, quartiles {quartiles:?} m, medians {medians:?} m");
    let spread = |v: &[f64]| {
        let (lo, hi) = v.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), x| {
            (lo.min(*x), hi.max(*x))
        });
        (lo, hi - lo)
    };
    let (_, share_spread) = spread(&within);
    assert!(share_spread <= 0.03, "within 20 mm: {within:?}");
    for q in 0..2 {
        let values: Vec<f64> = quartiles.iter().map(|pair| pair[q]).collect();
        let (lo, width) = spread(&values);
        assert!(width <= (0.1 * lo).max(5e-4), "quartile {}: {values:?} m", q + 1);
    }
}
