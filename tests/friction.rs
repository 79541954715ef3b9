//! Friction (`--friction μ`, `core::friction`): presses with a tangential
//! force drawn as `core::synth` draws them (up to 30 % of the normal force,
//! any direction), on the links that four or more joints sense.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use crate::common;

use proprioscope::core::estimate::estimator::Estimator;
use proprioscope::core::estimate::friction::frictional_force;
use proprioscope::core::estimate::measurement::Measurement;
use proprioscope::core::estimate::settings::EstimatorSettings;
use proprioscope::core::eval::metrics::percentile;
use proprioscope::core::eval::synth::{SynthSettings, as_sequence, joint_positions, synthesize};
use proprioscope::core::numerics::rng::Rng;
use proprioscope::core::over_time::sequence::Temporal;
use proprioscope::core::over_time::temporal::TemporalSettings;
use proprioscope::core::robot::builtin;
use proprioscope::core::robot::kinematics::RobotPose;
use proprioscope::core::robot::torque::TorqueModel;
use proprioscope::core::surface::sampling::{Surface, SurfaceRequest};

/// The estimator's settings of these tests: σ 0.05 N·m, 1–30 N.
fn settings(friction: f64) -> EstimatorSettings {
    EstimatorSettings {
        friction,
        ..EstimatorSettings::exact(vec![0.05; 7])
    }
}

/// At the place of the press (random poses, 300 presses of 5–25 N, a
/// tangential part uniform in 0–30 % of the normal one, σ = 0.05 N·m),
/// the friction model's force is far closer to the truth than the
/// frictionless one's: measured 0.43 N against 2.17 N (median, μ 0.1).
#[test]
fn at_the_place_friction_cuts_the_force_error() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links: Vec<usize> = ["lwr_4_link", "lwr_5_link", "lwr_6_link", "lwr_7_link"]
        .iter()
        .map(|n| robot.link_id(n).unwrap())
        .collect();
    let request = SurfaceRequest {
        links: links.clone(),
        total_points: 500,
        seed: 1,
    };
    let surface = Surface::sample(&robot, &request).unwrap();
    let mut rng = Rng::new(7);
    let (mut without, mut with) = (Vec::new(), Vec::new());
    let weights = [400.0; 7];
    for _ in 0..300 {
        let q: Vec<f64> = (0..7).map(|_| rng.uniform_in(-1.5, 1.5)).collect();
        let pose = RobotPose::new(&robot, &robot.joint_positions(&q, &[]).unwrap());
        let model = TorqueModel::new(&robot, &pose, &links);
        let k = rng.below(surface.len());
        let (link, point, normal) = (
            surface.link[k],
            surface.point_in_link[k],
            surface.inward_normal_in_link[k],
        );
        let (t1, t2) = normal.any_orthonormal_pair();
        let push = rng.uniform_in(5.0, 25.0);
        let tangential = rng.uniform_in(0.0, 0.3) * push;
        let angle = rng.uniform_in(0.0, std::f64::consts::TAU);
        let force = normal * push + (t1 * angle.cos() + t2 * angle.sin()) * tangential;
        let tau: Vec<f64> = model
            .torques(link, point, force)
            .iter()
            .map(|t| t + 0.05 * rng.normal())
            .collect();
        let m = Measurement {
            tau: &tau,
            weights: &weights,
            force_range_newtons: (1.0, 30.0),
            friction: 0.0,
        };
        for (friction, errors) in [(0.0, &mut without), (0.1, &mut with)] {
            let got = frictional_force(&model, link, (point, normal), &m, friction).unwrap();
            errors.push((normal * got.normal_newtons + got.tangential_in_link).distance(force));
        }
    }
    let (plain, frictional) = (percentile(&without, 0.5), percentile(&with, 0.5));
    eprintln!("median force error at the place: frictionless {plain:.3} N, μ 0.1 {frictional:.3} N");
    assert!(frictional < 0.4 * plain, "{frictional} vs {plain}");
}

/// The median position errors (m) and force errors (N) without and with
/// friction, in that order, printed under `what`.
fn medians(what: &str, position: &[Vec<f64>; 2], force: &[Vec<f64>; 2]) -> [f64; 4] {
    let [p0, p1, f0, f1] = [&position[0], &position[1], &force[0], &force[1]].map(|v| percentile(v, 0.5));
    eprintln!(
        "{what}: position {:.1} / {:.1} mm, force {f0:.2} / {f1:.2} N (frictionless / μ 0.1)",
        p0 * 1e3,
        p1 * 1e3
    );
    [p0, p1, f0, f1]
}

/// Per frame, friction moves the place as well as the force (the search
/// minimises the friction model's marginal likelihood): over synthetic
/// presses with tangential parts (seeds 1–4, 10 s at 20 Hz each, 394
/// contact frames, 1000 surface points) the median force error falls from
/// 2.40 to 2.12 N and the median position error from 28.4 to 24.0 mm.
/// Most of the force error left is that of frames placed on the wrong
/// part of the arm, which friction cannot mend. μ = 0 is the frictionless
/// estimate exactly, a force along the normal.
#[test]
fn per_frame_friction_lowers_the_force_error_and_keeps_the_place() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let pressed: Vec<usize> = links.iter().copied().filter(|&l| l >= 4).collect();
    let synth = SynthSettings {
        duration_secs: 10.0,
        rate_hz: 20.0,
        friction: 0.3,
        ..SynthSettings::default()
    };
    let estimator = |friction: f64| {
        let request = SurfaceRequest {
            links: links.clone(),
            total_points: 1000,
            seed: 0,
        };
        Estimator::new(&robot, &request, settings(friction), None).unwrap()
    };
    let (plain, frictional) = (estimator(0.0), estimator(0.1));
    let (mut position, mut force) = ([Vec::new(), Vec::new()], [Vec::new(), Vec::new()]);
    let mut tangential_seen = 0;
    for seed in 1..=4 {
        let frames = synthesize(&robot, &pressed, &synth, seed).unwrap();
        for f in &frames {
            let Some(truth) = &f.contact else {
                continue;
            };
            let positions = robot.joint_positions(&f.q, &[]).unwrap();
            let a = plain.update(&robot, &positions, &f.tau).unwrap().summary;
            let b = frictional.update(&robot, &positions, &f.tau).unwrap().summary;
            let normal_part = a.map.force_world.dot(a.map.inward_normal_world);
            assert!(a.map.force_world.distance(a.map.inward_normal_world * normal_part) < 1e-9);
            let tangential =
                b.map.force_world - b.map.inward_normal_world * b.map.force_world.dot(b.map.inward_normal_world);
            if tangential.length() > 0.05 {
                tangential_seen += 1;
            }
            for (i, s) in [&a, &b].into_iter().enumerate() {
                position[i].push(s.map.point_world.distance(truth.point_world));
                force[i].push(s.map.force_world.distance(truth.force_world));
            }
        }
    }
    let [p0, p1, f0, f1] = medians(&format!("{} frames", position[0].len()), &position, &force);
    assert!(f1 < 0.95 * f0, "force {f1} vs {f0}");
    assert!(p1 < 1.1 * p0 + 1e-3, "position {p1} vs {p0}");
    assert!(tangential_seen > 20, "{tangential_seen} frames with a tangential force");
}

/// A synthetic session of 10 s at 50 Hz whose presses on links 4–7
/// carry tangential parts of up to `friction` of the push.
fn presses(
    robot: &proprioscope::core::robot::model::Robot,
    friction: f64,
    seed: u64,
) -> Vec<proprioscope::core::eval::synth::SynthFrame> {
    let settings = SynthSettings {
        duration_secs: 10.0,
        rate_hz: 50.0,
        friction,
        ..SynthSettings::default()
    };
    presses_drawn(robot, &settings, seed)
}

/// 20 s at 50 Hz of presses on links 4–7 dragging by up to 30 % of the
/// push (`synth --seconds 20 --rate 50 --friction 0.3 --seed 1`).
fn dragging_presses(
    robot: &proprioscope::core::robot::model::Robot,
) -> Vec<proprioscope::core::eval::synth::SynthFrame> {
    presses_for_20_s(robot, 0.3, 1)
}

/// 20 s at 50 Hz of presses on links 4–7 whose tangential parts reach
/// `friction` of the push (`synth --seconds 20 --rate 50 --friction F
/// --seed S`).
fn presses_for_20_s(
    robot: &proprioscope::core::robot::model::Robot,
    friction: f64,
    seed: u64,
) -> Vec<proprioscope::core::eval::synth::SynthFrame> {
    let settings = SynthSettings {
        duration_secs: 20.0,
        rate_hz: 50.0,
        friction,
        ..SynthSettings::default()
    };
    presses_drawn(robot, &settings, seed)
}

/// A synthetic session drawn with `settings`, pressing links 4–7.
fn presses_drawn(
    robot: &proprioscope::core::robot::model::Robot,
    settings: &SynthSettings,
    seed: u64,
) -> Vec<proprioscope::core::eval::synth::SynthFrame> {
    let pressed: Vec<usize> = robot
        .default_candidate_links()
        .into_iter()
        .filter(|&l| l >= 4)
        .collect();
    synthesize(robot, &pressed, settings, seed).unwrap()
}

/// Sessions estimated over time (`temporal`) frictionless and with μ 0.1 over one
/// surface (1000 points, seed 0): per frame, the position error (m) and
/// force error (N) of the contact frames, and the map of every frame.
fn over_time(
    robot: &proprioscope::core::robot::model::Robot,
    frames: &[proprioscope::core::eval::synth::SynthFrame],
    temporal: proprioscope::core::over_time::sequence::Temporal,
    points: usize,
) -> [(
    Vec<f64>,
    Vec<f64>,
    Vec<proprioscope::core::estimate::summary::ContactEstimate>,
); 2] {
    [(temporal, 0.0), (temporal, 0.1)].map(|(t, friction)| estimated(robot, frames, t, friction, points))
}

/// A session estimated as `temporal` with friction μ over one surface
/// (`points`, seed 0): per frame, the position error (m) and force error
/// (N) of the contact frames, and the map of every frame.
fn estimated(
    robot: &proprioscope::core::robot::model::Robot,
    frames: &[proprioscope::core::eval::synth::SynthFrame],
    temporal: proprioscope::core::over_time::sequence::Temporal,
    friction: f64,
    points: usize,
) -> (
    Vec<f64>,
    Vec<f64>,
    Vec<proprioscope::core::estimate::summary::ContactEstimate>,
) {
    let surface = (points, 0);
    estimated_with(robot, frames, temporal, friction, surface, TemporalSettings::default())
}

/// [`estimated`] over a surface of `(points, seed)`, with the temporal
/// model's `settings`.
fn estimated_with(
    robot: &proprioscope::core::robot::model::Robot,
    frames: &[proprioscope::core::eval::synth::SynthFrame],
    temporal: proprioscope::core::over_time::sequence::Temporal,
    friction: f64,
    (points, seed): (usize, u64),
    temporal_settings: TemporalSettings,
) -> (
    Vec<f64>,
    Vec<f64>,
    Vec<proprioscope::core::estimate::summary::ContactEstimate>,
) {
    use proprioscope::core::over_time::sequence::estimate_sequence;
    use proprioscope::core::over_time::temporal::TemporalModel;
    let request = SurfaceRequest {
        links: robot.default_candidate_links(),
        total_points: points,
        seed,
    };
    let positions = joint_positions(robot, frames).unwrap();
    let sequence = as_sequence(frames, &positions);
    {
        let estimator = Estimator::new(robot, &request, settings(friction), None).unwrap();
        let model = TemporalModel::new(&estimator.surface, temporal_settings, true).unwrap();
        let (mut position, mut force, mut maps) = (Vec::new(), Vec::new(), Vec::new());
        estimate_sequence(&estimator, robot, Some(&model), temporal, &sequence, |i, update, _| {
            // Every frame once, in order, though a press's frames wait
            // for its end.
            assert_eq!(i, maps.len());
            if let Some(truth) = &frames[i].contact {
                position.push(update.summary.map.point_world.distance(truth.point_world));
                force.push(update.summary.map.force_world.distance(truth.force_world));
            }
            maps.push(update.summary.map);
        })
        .unwrap();
        assert_eq!(maps.len(), frames.len());
        (position, force, maps)
    }
}

/// Smoothed at the friction μ that `--friction auto` takes over time
/// (`pipeline::OVER_TIME_FRICTION`), presses dragging by up to 30 % of
/// the push are placed within half the per-frame (frictionless) error,
/// and frictionless presses no worse than per frame. Measured with
/// `estimate S --temporal none|smooth --friction 0|0.1|0.2 --seed 0–2` at
/// 5000 points on 20 s sessions (`synth --seconds 20 --rate 50 --friction
/// 0.3 --seed 1..6`, links 4–7): per frame 8.5–27.5 mm, smoothed at μ 0.2
/// 2.4–6.1 mm; at μ 0 seeds 1 and 3 smoothed to 16.5 and 20.6 mm. Here
/// seeds 1 and 3 of those sessions (surface seed 0: 18.7, 19.3 → 3.7, 3.0
/// mm), seed 1 without friction (3.7 → 0.7 mm) and seed 1 sliding at up to
/// 3 cm/s with up to 15 % (`--slide 0.03 --friction 0.15`: 10.6 → 2.2 mm).
/// Seed 3's force error, 0.24 N, was 0.56 N before presses were also
/// fitted from their frames' own places (`pipeline::ALTERNATIVE_*`); that
/// also took 10 s of seed 3 from 29.9 → 22.0 mm to 29.9 → 3.0 mm, and
/// the sliding session's smoothed error from 4.7 to 2.2 mm.
#[test]
fn smoothed_at_the_default_friction_halves_the_per_frame_error() {
    use proprioscope::core::over_time::sequence::OVER_TIME_FRICTION;
    let robot = builtin::lwr4plus_generated().unwrap();
    for (friction, slide_m_per_s, seed) in [(0.3, 0.0, 1), (0.3, 0.0, 3), (0.0, 0.0, 1), (0.15, 0.03, 1)] {
        let synth = SynthSettings {
            duration_secs: 20.0,
            rate_hz: 50.0,
            friction,
            slide_m_per_s,
            ..SynthSettings::default()
        };
        let frames = presses_drawn(&robot, &synth, seed);
        let per_frame = percentile(&estimated(&robot, &frames, Temporal::None, 0.0, 5000).0, 0.5);
        let mu = Temporal::Smooth.default_friction();
        let (position, force, _) = estimated(&robot, &frames, Temporal::Smooth, mu, 5000);
        let (smoothed, force) = (percentile(&position, 0.5), percentile(&force, 0.5));
        eprintln!(
            "friction up to {friction}, slide up to {slide_m_per_s} m/s, seed {seed}: per frame {:.1} mm, \
             smoothed at μ {OVER_TIME_FRICTION} {:.1} mm, {force:.2} N",
            per_frame * 1e3,
            smoothed * 1e3
        );
        if per_frame > 0.01 {
            assert!(smoothed <= 0.5 * per_frame, "{smoothed} vs {per_frame}");
        } else {
            assert!(smoothed <= per_frame, "{smoothed} vs {per_frame}");
        }
        if (friction, seed) == (0.3, 3) {
            // Fitted from its frames' own places too, a press that the
            // recording's places left dragging elsewhere is found.
            assert!(force < 0.4, "{force} N");
        }
    }
    assert!((Temporal::None.default_friction()).abs() < 1e-15);
    assert!((Temporal::Filter.default_friction() - OVER_TIME_FRICTION).abs() < 1e-15);
}

/// Contacts that slide a few centimetres a second are followed with a
/// slide length to match (README, *Contacts that slide*): 20 s of presses
/// sliding at up to 3 cm/s and dragging by up to 15 % (`synth --slide 0.03
/// --friction 0.15 --seed 4`, links 4–7) over surface seed 1, per frame
/// 26.8 mm, smoothed at μ 0.2 with the default length (1 cm/√s) 20.7 mm
/// while a press was fitted from its frames' own places only where a
/// quarter of them agreed (not half the per-frame error); since any three
/// frames that agree are a start (`pipeline::ALTERNATIVE_MIN_FRAMES`),
/// 7.9 mm: a link 4 press that the recording placed 43 mm off, its frames
/// alone scattered in groups of 10, 10 and 9 of 46, is found (5 mm).
/// With `--slide 0.03`, 4.3 mm.
#[test]
fn contacts_that_slide_are_followed_with_their_slide_length() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let synth = SynthSettings {
        duration_secs: 20.0,
        rate_hz: 50.0,
        friction: 0.15,
        slide_m_per_s: 0.03,
        ..SynthSettings::default()
    };
    let frames = presses_drawn(&robot, &synth, 4);
    let surface = (5000, 1);
    let median = |temporal, friction, settings| {
        percentile(
            &estimated_with(&robot, &frames, temporal, friction, surface, settings).0,
            0.5,
        )
    };
    let per_frame = median(Temporal::None, 0.0, TemporalSettings::default());
    let mu = Temporal::Smooth.default_friction();
    let default_length = median(Temporal::Smooth, mu, TemporalSettings::default());
    let sliding = TemporalSettings {
        slide_m_per_sqrt_s: 0.03,
        ..TemporalSettings::default()
    };
    let their_length = median(Temporal::Smooth, mu, sliding);
    eprintln!(
        "per frame {:.1} mm, smoothed with the default slide {:.1} mm, with 3 cm/√s {:.1} mm",
        per_frame * 1e3,
        default_length * 1e3,
        their_length * 1e3
    );
    assert!(per_frame > 0.02, "{per_frame}");
    assert!(their_length <= 0.5 * per_frame, "{their_length} vs {per_frame}");
    assert!(default_length <= 0.5 * per_frame, "{default_length} vs {per_frame}");
}

/// A press whose recording (the frictionless smoother) settles on a place
/// its frames alone contradict is also fitted from their places
/// (`pipeline::ALTERNATIVE_*`): on 10 s of `synth --friction 0.3 --seed 3`
/// (links 4–7, 5000 points) a link 6 press was placed on link 5 and a link
/// 4 press 22 mm off, and the session smoothed from 29.9 to 22.0 mm; with
/// the second start, 3.0 mm (surface seeds 1, 2: 5.6, 4.1 mm).
#[test]
fn a_press_its_recording_misplaces_is_fitted_from_its_frames_own_places() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let frames = presses(&robot, 0.3, 3);
    let per_frame = percentile(&estimated(&robot, &frames, Temporal::None, 0.0, 5000).0, 0.5);
    let mu = Temporal::Smooth.default_friction();
    let smoothed = percentile(&estimated(&robot, &frames, Temporal::Smooth, mu, 5000).0, 0.5);
    eprintln!("per frame {:.1} mm, smoothed {:.1} mm", per_frame * 1e3, smoothed * 1e3);
    assert!(smoothed <= 0.5 * per_frame, "{smoothed} vs {per_frame}");
}

/// Over a recording, friction is fitted per press: one tangential force
/// fixed in the link's frame for the whole press (as `core::synth` draws
/// it), kept where it explains the press far better than none
/// (`core::press`). On synthetic sessions with tangential parts of up to
/// 30 % (seeds 1–3, 10 s at 50 Hz, 1000 surface points) the smoothed
/// median position error falls from 26.9 to 21.9 mm and the force error
/// from 1.92 to 1.33 N. Without a tangential part (seeds 1–2) 97 of 1000
/// frames change, presses that the frictionless search left a centimetre
/// off at this coarse sampling (1.2 → 1.0 mm, 0.27 → 0.19 N at the
/// median); at 5000 points 3 of 4000 frames changed on four such
/// sessions (`synth --seed 1..4`, 20 s at 50 Hz).
#[test]
fn smoothed_presses_are_fitted_with_their_friction() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let (mut position, mut force) = ([Vec::new(), Vec::new()], [Vec::new(), Vec::new()]);
    for seed in 1..=3 {
        let frames = presses(&robot, 0.3, seed);
        for (i, (p, f, _)) in over_time(&robot, &frames, Temporal::Smooth, 1000)
            .into_iter()
            .enumerate()
        {
            position[i].extend(p);
            force[i].extend(f);
        }
    }
    let [p0, p1, f0, f1] = medians(&format!("smoothed, {} frames", position[0].len()), &position, &force);
    assert!(f1 < 0.7 * f0, "force {f1} vs {f0}");
    assert!(p1 < p0, "position {p1} vs {p0}");
    let (mut position, mut force) = ([Vec::new(), Vec::new()], [Vec::new(), Vec::new()]);
    let (mut changed, mut total) = (0, 0);
    for seed in 1..=2 {
        let frames = presses(&robot, 0.0, seed);
        let [(p0, f0, plain), (p1, f1, frictional)] = over_time(&robot, &frames, Temporal::Smooth, 1000);
        changed += plain.iter().zip(&frictional).filter(|(a, b)| a != b).count();
        total += plain.len();
        position[0].extend(p0);
        position[1].extend(p1);
        force[0].extend(f0);
        force[1].extend(f1);
    }
    let [p0, p1, f0, f1] = medians(
        &format!("without friction, {changed} of {total} frames changed"),
        &position,
        &force,
    );
    assert!(changed * 5 < total, "{changed} of {total} frames changed");
    assert!(
        p1 <= p0 + 2e-4 && f1 <= f0 + 0.02,
        "position {p1} vs {p0}, force {f1} vs {f0}"
    );
}

/// Filtering with friction, a frame's force at the recording's place is
/// the friction model's once the press so far gives enough evidence for
/// friction, the frictionless one before. Measured (10 s at 50 Hz, 5000
/// surface points, seeds 1–2): with tangential parts up to 30 % the
/// median force error falls from 1.20 to 1.02 N (92 of 1000 frames take
/// friction); without, none does (0.15 N either way). Before this
/// gate every frame took the friction model's force: on 20 s sessions
/// without friction (`synth --seed 1|3`) 0.12 → 0.34 N and 0.11 → 0.35 N,
/// now 0.12 and 0.12 N.
#[test]
fn filtered_presses_take_friction_once_the_press_says_so() {
    let robot = builtin::lwr4plus_generated().unwrap();
    for (friction, seeds) in [(0.3, 1..=2), (0.0, 1..=2)] {
        let (mut position, mut force) = ([Vec::new(), Vec::new()], [Vec::new(), Vec::new()]);
        let (mut changed, mut total) = (0, 0);
        for seed in seeds {
            let frames = presses(&robot, friction, seed);
            let [(p0, f0, plain), (p1, f1, frictional)] = over_time(&robot, &frames, Temporal::Filter, 5000);
            changed += plain
                .iter()
                .zip(&frictional)
                .filter(|(a, b)| a.force_world.distance(b.force_world) > 1e-6)
                .count();
            total += plain.len();
            position[0].extend(p0);
            position[1].extend(p1);
            force[0].extend(f0);
            force[1].extend(f1);
        }
        let what = format!("filtered, tangential up to {friction}, {changed} of {total} frames changed");
        let [p0, p1, f0, f1] = medians(&what, &position, &force);
        assert!((p1 - p0).abs() < 1e-12, "the place is the recording's: {p1} vs {p0}");
        if friction > 0.0 {
            assert!(f1 < 0.9 * f0, "force {f1} vs {f0}");
        } else {
            assert!(f1 <= 1.2 * f0 && changed * 10 <= total, "force {f1} vs {f0}");
        }
    }
}

/// A negative or non-finite μ is refused by name.
#[test]
fn a_bad_friction_is_refused() {
    let robot = builtin::lwr4plus_generated().unwrap();
    for friction in [-0.1, f64::NAN, f64::INFINITY] {
        let request = SurfaceRequest {
            links: robot.default_candidate_links(),
            total_points: 200,
            seed: 0,
        };
        let estimator = Estimator::new(&robot, &request, settings(friction), None).unwrap();
        let positions = robot.joint_positions(&[0.0; 7], &[]).unwrap();
        let err = estimator.update(&robot, &positions, &[0.1; 7]).unwrap_err();
        assert!(err.to_string().contains("friction"), "{err}");
    }
}

/// The `../shared` `MuJoCo` presses (probe friction 0.5) against our
/// surface: at the true contact (reached over the link's continuous
/// surface from its nearest sample; the same to 1e-12 at 5000, 20,000 and
/// 50,000 samples) the true force's tangential part is small beside the
/// normal one at the median (measured 2.1 % on link 4 and 4.7 % on link
/// 6, 0.19 N and 0.52 N; 15 % and 19 % at the 90th percentile), less than
/// the presses `synth` draws (up to 30 %). The frictionless estimate
/// takes up what there is by placing the push where the surface's normal
/// lies along the force (link 6 smoothed: 0.14 N force error, below the
/// median tangential part), which is why `--friction` cannot cut these
/// sessions' force errors by much (README, *Friction*).
#[test]
#[ignore = "needs ../shared"]
fn the_shared_presses_push_nearly_along_the_surface_normal() {
    use proprioscope::io::session::{Session, Truth};
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/sessions");
    for (name, median_below, median_above) in [
        ("lwr4plus_dyn_example_link4.session.json", 0.04, 0.01),
        ("lwr4plus_dyn_example_link6.session.json", 0.08, 0.03),
    ] {
        let session = Session::read(&root.join(name)).unwrap();
        let robot = proprioscope::batch::session_robot(&session, None, &[], &[]).unwrap();
        let request = SurfaceRequest {
            links: robot.default_candidate_links(),
            total_points: 5_000,
            seed: 0,
        };
        let surface = Surface::sample(&robot, &request).unwrap();
        let (mut shares, mut tangential) = (Vec::new(), Vec::new());
        for frame in &session.frames {
            let Truth::Contact { link, point, force } = &frame.truth else {
                continue;
            };
            let (point, force) = (glam::DVec3::from_array(*point), glam::DVec3::from_array(*force));
            let pose = RobotPose::new(&robot, &robot.joint_positions(&frame.q, &[]).unwrap());
            let link = robot.link_id(link).unwrap();
            let nearest = (0..surface.len())
                .filter(|&k| surface.link[k] == link)
                .min_by(|&x, &y| {
                    let distance = |k: usize| pose.point_to_world(link, surface.point_in_link[k]).distance(point);
                    distance(x).total_cmp(&distance(y))
                })
                .unwrap();
            // From the nearest sample, walk over the link's continuous
            // surface to the true point (its projection): the normal there.
            let shape = surface.shape(link).unwrap();
            let point_in_link = pose.world_from_link[link].inverse().transform_point3(point);
            let mut at = surface.location[nearest];
            for _ in 0..4 {
                let here = shape.frame(at).unwrap();
                let offset = point_in_link - here.point;
                at = shape.walk(at, offset - offset.dot(here.inward_normal) * here.inward_normal);
            }
            let normal = pose.world_from_link[link]
                .transform_vector3(shape.frame(at).unwrap().inward_normal)
                .normalize();
            let along = force.dot(normal);
            assert!(along > 0.0, "{name}: a pull, not a push");
            shares.push((force - along * normal).length() / along);
            tangential.push((force - along * normal).length());
        }
        let median = percentile(&shares, 0.5);
        assert!(shares.len() > 100, "{name}: {} contact frames", shares.len());
        eprintln!(
            "{name}: tangential share median {median}, p90 {}; tangential force median {} N",
            percentile(&shares, 0.9),
            percentile(&tangential, 0.5)
        );
        assert!(
            median < median_below && median >= median_above,
            "{name}: median tangential share {median}"
        );
    }
}

/// The measure on the `../shared` presses, per frame (`estimate
/// --temporal none`, 5000 points, σ 0.05): with μ 0.1 the median force
/// error over the contact frames of surface seeds 0–2 falls by at least a
/// quarter on each session, and the median position error does not grow.
/// Measured (`estimate --seed S --temporal none --friction μ`, medians
/// over seeds 0–4): link 4 13.2 → 9.0 N, link 6 0.31 → 0.21 N, the static
/// example 2.56 → 1.36 N; positions 56 → 56 mm, 5.4 → 4.0 mm, 34 → 26 mm.
#[test]
#[ignore = "needs ../shared"]
fn on_the_shared_presses_per_frame_friction_cuts_the_force_error() {
    use proprioscope::io::session::{Session, Truth};
    let root = std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/sessions");
    for name in [
        "lwr4plus_dyn_example_link4.session.json",
        "lwr4plus_dyn_example_link6.session.json",
        "lwr4plus_static_example.session.json",
    ] {
        let session = Session::read(&root.join(name)).unwrap();
        let robot = proprioscope::batch::session_robot(&session, None, &[], &[]).unwrap();
        let (mut position, mut force) = ([Vec::new(), Vec::new()], [Vec::new(), Vec::new()]);
        for seed in 0..3 {
            let request = SurfaceRequest {
                links: robot.default_candidate_links(),
                total_points: 5_000,
                seed,
            };
            for (i, friction) in [0.0, 0.1].into_iter().enumerate() {
                let estimator = Estimator::new(&robot, &request, settings(friction), None).unwrap();
                for frame in &session.frames {
                    let Truth::Contact {
                        point, force: truth, ..
                    } = &frame.truth
                    else {
                        continue;
                    };
                    let positions = robot.joint_positions(&frame.q, &[]).unwrap();
                    let map = estimator.update(&robot, &positions, &frame.tau).unwrap().summary.map;
                    position[i].push(map.point_world.distance(glam::DVec3::from_array(*point)));
                    force[i].push(map.force_world.distance(glam::DVec3::from_array(*truth)));
                }
            }
        }
        let [p0, p1, f0, f1] = medians(name, &position, &force);
        assert!(f1 < 0.75 * f0, "{name}: force {f1} vs {f0}");
        assert!(p1 < 1.05 * p0 + 1e-3, "{name}: position {p1} vs {p0}");
    }
}

/// Friction on the hard cases: a σ far below and far above the torques,
/// torques of zero, a push through a joint's axis, μ up to the scene's
/// limit of 2. Every estimate is finite (or an error), never a NaN.
#[test]
fn friction_keeps_hard_cases_finite() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let request = SurfaceRequest {
        links: links.clone(),
        total_points: 400,
        seed: 2,
    };
    let q = [0.2, 0.5, -0.3, -1.0, 0.4, 0.8, 0.1];
    let positions = robot.joint_positions(&q, &[]).unwrap();
    let pose = RobotPose::new(&robot, &positions);
    let model = TorqueModel::new(&robot, &pose, &links);
    let forearm = robot.link_id("lwr_5_link").unwrap();
    let push = model.torques(
        forearm,
        glam::DVec3::new(0.05, 0.0, 0.1),
        glam::DVec3::new(-8.0, 1.5, 0.5),
    );
    let through_axis = model.torques(
        robot.link_id("lwr_2_link").unwrap(),
        glam::DVec3::ZERO,
        glam::DVec3::new(0.0, 0.0, 5.0),
    );
    for sigma in [1e-6, 0.05, 100.0] {
        for friction in [0.05, 0.5, 2.0] {
            let settings = EstimatorSettings {
                friction,
                ..EstimatorSettings::exact(vec![sigma; 7])
            };
            let estimator = Estimator::new(&robot, &request, settings, None).unwrap();
            for tau in [vec![0.0; 7], push.clone(), through_axis.clone()] {
                let Ok(update) = estimator.update(&robot, &positions, &tau) else {
                    continue;
                };
                let map = update.summary.map;
                assert!(
                    map.point_world.is_finite() && map.force_world.is_finite() && map.force_newtons.is_finite(),
                    "σ {sigma}, μ {friction}, τ {tau:?}: {map:?}"
                );
                assert!(!update.summary.fit.p_value.is_nan(), "σ {sigma}, μ {friction}");
                assert!(update.posterior.probability.iter().all(|p| p.is_finite()));
            }
        }
    }
}

/// A press that slides and drags can leave the frictionless smoother on a
/// place its frames contradict (synthetic `--slide 0.03 --friction 0.15
/// --seed 1`: a link 7 press whose smoothed contacts missed the torques
/// by χ² 8988 a frame more than each frame's own, its force 25 N off).
/// Such a press reports each frame's own contact: no smoothed press
/// misses its frames by more than `PRESS_MISFIT_PER_FRAME` a frame
/// beyond the frames' own contacts, and its forces are each frame's.
/// Made to fail by raising that limit out of reach: two pieces of the
/// link 7 press then miss by 7538 and 5878 a frame.
#[test]
fn a_smoothed_press_its_frames_contradict_reports_their_own_contacts() {
    use proprioscope::core::estimate::summary::Verdict;
    use proprioscope::core::over_time::presses::{PRESS_MISFIT_MARGIN, PRESS_MISFIT_PER_FRAME};
    use proprioscope::core::over_time::sequence::estimate_sequence;
    use proprioscope::core::over_time::temporal::{TemporalModel, TemporalSettings};
    let robot = builtin::lwr4plus_generated().unwrap();
    let synth = SynthSettings {
        duration_secs: 6.0,
        rate_hz: 50.0,
        friction: 0.15,
        slide_m_per_s: 0.03,
        ..SynthSettings::default()
    };
    let frames = presses_drawn(&robot, &synth, 1);
    let positions = joint_positions(&robot, &frames).unwrap();
    let sequence = as_sequence(&frames, &positions);
    let request = SurfaceRequest {
        links: robot.default_candidate_links(),
        total_points: 5000,
        seed: 0,
    };
    let estimator = Estimator::new(&robot, &request, settings(0.0), None).unwrap();
    let model = TemporalModel::new(&estimator.surface, TemporalSettings::default(), true).unwrap();
    let [alone, smoothed] = [Temporal::None, Temporal::Smooth].map(|temporal| {
        let mut out = vec![None; frames.len()];
        estimate_sequence(&estimator, &robot, Some(&model), temporal, &sequence, |i, update, _| {
            out[i] = Some(update.summary);
        })
        .unwrap();
        out.into_iter().map(Option::unwrap).collect::<Vec<_>>()
    });
    // Presses as the smoother reports them: consecutive placed contacts
    // on one link.
    let mut presses: Vec<Vec<usize>> = Vec::new();
    for (i, s) in smoothed.iter().enumerate() {
        if !(s.refined && s.verdict != Verdict::NoContact) {
            continue;
        }
        match presses.last_mut() {
            Some(p) if p.last() == Some(&(i - 1)) && smoothed[i - 1].map.link == s.map.link => p.push(i),
            _ => presses.push(vec![i]),
        }
    }
    let mut taken = 0;
    for press in &presses {
        let together: f64 = press.iter().map(|&i| smoothed[i].fit.best_residual_chi2).sum();
        let apart: f64 = press.iter().map(|&i| alone[i].fit.best_residual_chi2).sum();
        let excess = together - apart;
        eprintln!(
            "press {}..{}: excess {:.0} a frame",
            press[0],
            press[press.len() - 1],
            excess / press.len() as f64
        );
        assert!(
            excess <= PRESS_MISFIT_PER_FRAME * press.len() as f64 + PRESS_MISFIT_MARGIN,
            "press {press:?}: its frames' own contacts explain them by {excess} better"
        );
        if press.iter().all(|&i| smoothed[i].map == alone[i].map) {
            taken += 1;
        }
    }
    // The forces reported on frames called contacts: p90 measured 12.6 N,
    // 23.5 N without the check (the rest is a link 4 press smoothed onto
    // link 3, which explains its frames as well as their own contacts),
    // on the session as `synth` drew slides before it kept their
    // directions; 7.0 N as drawn now.
    let force_errors: Vec<f64> = frames
        .iter()
        .zip(&smoothed)
        .filter(|(_, s)| s.verdict != Verdict::NoContact)
        .filter_map(|(f, s)| f.contact.map(|c| (s.map.force_world - c.force_world).length()))
        .collect();
    let p90 = percentile(&force_errors, 0.9);
    eprintln!("force error p90 {p90:.2} N over {} contact frames", force_errors.len());
    assert!(taken >= 1, "no press took its frames' own contacts");
    assert!(p90 < 15.0, "{p90}");
}

/// A press is moved to another link by a few of its frames only where that
/// explains it by far (`pipeline::LINK_SWITCH_GAIN`): on 20 s of presses
/// dragging by up to 30 % (`synth --seconds 20 --rate 50 --friction 0.3
/// --seed 1`, links 4–7, surface seed 2) three frames of a link 7 press
/// (frames 247–284) placed it on link 6, and a fit from their places
/// explained the press better by 36: taken at the recording's gain (30),
/// the press moved 6.5 → 117 mm from the truth. Presses that such groups
/// rightly moved to another link gained 134 and 245.
#[test]
fn a_press_stays_on_its_link_unless_another_explains_it_by_far() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let frames = dragging_presses(&robot);
    let mu = Temporal::Smooth.default_friction();
    let (_, _, maps) = estimated_with(
        &robot,
        &frames,
        Temporal::Smooth,
        mu,
        (5000, 2),
        TemporalSettings::default(),
    );
    let link7 = robot.link_id("lwr_7_link").unwrap();
    let press: Vec<f64> = (247..=284)
        .filter_map(|i| {
            let truth = frames[i].contact.as_ref()?;
            assert_eq!(truth.link, link7, "frame {i}");
            Some(maps[i].point_world.distance(truth.point_world))
        })
        .collect();
    let on_link = (247..=284).filter(|&i| maps[i].link == link7).count();
    let median = percentile(&press, 0.5);
    eprintln!(
        "link 7 press: median {:.1} mm, {on_link} of 38 frames on link 7",
        median * 1e3
    );
    assert!(press.len() >= 30, "{} contact frames", press.len());
    assert!(median < 0.02, "{median}");
}

/// The share of a session's contact frames whose 90 % credible set holds
/// the push (the sample whose patch holds it), estimated as `temporal` at
/// friction μ (5000 points, surface seed 0), with the contact frames'
/// count and the sets' median radius, m.
fn credible_sets_hold(
    robot: &proprioscope::core::robot::model::Robot,
    frames: &[proprioscope::core::eval::synth::SynthFrame],
    temporal: Temporal,
    friction: f64,
) -> (f64, usize, f64) {
    use proprioscope::core::over_time::sequence::estimate_sequence;
    use proprioscope::core::over_time::temporal::TemporalModel;
    let request = SurfaceRequest {
        links: robot.default_candidate_links(),
        total_points: 5000,
        seed: 0,
    };
    let estimator = Estimator::new(robot, &request, settings(friction), None).unwrap();
    let model = TemporalModel::new(&estimator.surface, TemporalSettings::default(), true).unwrap();
    let positions = joint_positions(robot, frames).unwrap();
    let sequence = as_sequence(frames, &positions);
    let surface = &estimator.surface;
    let (mut held, mut radii) = (Vec::new(), Vec::new());
    estimate_sequence(&estimator, robot, Some(&model), temporal, &sequence, |i, update, _| {
        let Some(truth) = &frames[i].contact else {
            return;
        };
        let owner = surface.owner(truth.link, truth.point_in_link).unwrap();
        held.push(update.summary.credible90.points.contains(&owner));
        radii.push(update.summary.credible90.radius_m);
    })
    .unwrap();
    let share = held.iter().filter(|&&h| h).count() as f64 / held.len() as f64;
    (share, held.len(), percentile(&radii, 0.5))
}

/// Smoothed, a press's 90 % credible set holds the push though friction
/// shifts every frame's apparent place the same way: the smoother
/// multiplies its frames' likelihoods as if each frame's misfit were
/// fresh noise, and the press's fit (`core::press::PlaceSpread`, γ free
/// under its prior) widens the set by what the whole press leaves
/// undetermined. On 20 s of presses dragging by up to 30 % (`synth
/// --seconds 20 --rate 50 --friction 0.3 --seed 1`, links 4–7, surface
/// seed 0, 5000 points) the set held the sample whose patch holds the push
/// in 12 % of the contact frames before; now in 86 %, the set's median
/// radius 24 mm.
#[test]
fn smoothed_credible_sets_hold_presses_that_drag() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let frames = dragging_presses(&robot);
    sets_hold_at_least(
        &robot,
        &frames,
        Temporal::Smooth,
        Temporal::Smooth.default_friction(),
        0.75,
    );
}

/// Filtered, each frame's set is widened by the spread that the press's
/// latest frames (`pipeline::PRESS_WINDOW`) leave its place. On 20 s of
/// frictionless presses (`synth --seconds 20 --rate 50 --seed 2`, links
/// 4–7, surface seed 0) the set held the push in 61 % of the contact
/// frames before (a single sample at the median), now in 90 %, median
/// radius 17 mm; 30 mm since each frame's own spread is added too
/// (`filtered_credible_sets_take_each_frames_own_spread`).
#[test]
fn filtered_credible_sets_hold_the_push() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let frames = presses_for_20_s(&robot, 0.0, 2);
    sets_hold_at_least(
        &robot,
        &frames,
        Temporal::Filter,
        Temporal::Filter.default_friction(),
        0.8,
    );
}

/// Frames alone with a friction setting, each contact frame's set is
/// widened by the spread its own torques leave the place once a
/// tangential force under its prior is let in (`core::press::PlaceSpread`
/// of one frame): the posterior over samples is the frictionless one, sure
/// of a place that a drag has shifted. On 20 s of presses dragging by up
/// to 30 % (`synth --seconds 20 --rate 50 --friction 0.3 --seed 1`, links
/// 4–7, surface seed 0, 5000 points) the set held the push in 34 % of the
/// contact frames at every μ before; with μ 0.2 now in 66 %, median radius
/// 35 mm. Without friction (μ 0) the sets are the posterior's, as before.
#[test]
fn per_frame_credible_sets_widen_with_friction() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let frames = dragging_presses(&robot);
    let (share_0, _, _) = credible_sets_hold(&robot, &frames, Temporal::None, 0.0);
    eprintln!(
        "frames alone at μ 0: the set holds the push in {:.1} %",
        share_0 * 100.0
    );
    assert!(share_0 < 0.45, "{share_0}");
    sets_hold_at_least(&robot, &frames, Temporal::None, 0.2, 0.6);
}

/// Filtered with friction (the default over time), each frame's set also
/// takes the spread of the frame's own torques, γ free (as a frame alone
/// with friction): the window's spread holds one γ around places that the
/// frictionless filter chose, and a drag shifts them. On 20 s of presses
/// dragging by up to 15 % (`synth --seconds 20 --rate 50 --friction 0.15
/// --seed 1`, links 4–7, surface seed 0, 5000 points) the set held the
/// push in 60.0 % of the contact frames with the window alone, now in
/// 75.4 %.
#[test]
fn filtered_credible_sets_take_each_frames_own_spread() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let frames = presses_for_20_s(&robot, 0.15, 1);
    sets_hold_at_least(
        &robot,
        &frames,
        Temporal::Filter,
        Temporal::Filter.default_friction(),
        0.7,
    );
}

/// [`credible_sets_hold`], checked: at least 300 contact frames, the set
/// holding the push in at least `least` of them, and not by taking the
/// whole link (median radius under 5 cm).
fn sets_hold_at_least(
    robot: &proprioscope::core::robot::model::Robot,
    frames: &[proprioscope::core::eval::synth::SynthFrame],
    temporal: Temporal,
    friction: f64,
    least: f64,
) {
    let (share, count, radius) = credible_sets_hold(robot, frames, temporal, friction);
    eprintln!(
        "{temporal:?} at μ {friction}, {count} contact frames: the set holds the push in {:.1} %, median radius {:.1} mm",
        share * 100.0,
        radius * 1e3
    );
    assert!(count >= 300, "{count} contact frames");
    assert!(share >= least, "{share}");
    assert!(radius < 0.05, "{radius}");
}

/// Issue 42's force target on the `../shared` link 4 slide (`MuJoCo`, μ
/// 0.5, four joints sense it): smoothed, the median force error is at
/// most 4 N at each of surface seeds 0–2 (measured 3.40, 3.14, 2.79 N;
/// 12.17, 6.88, 12.30 N with the slide's direction read over 50 ms
/// either side), and the place stays within 10 mm (7.3, 6.1, 5.4 mm).
#[test]
#[ignore = "needs ../shared"]
fn the_shared_link_4_slide_is_found_with_its_force() {
    let session = common::shared().join("sessions/lwr4plus_slide_example_link4.session.json");
    for seed in ["0", "1", "2"] {
        let (ok, out, err) = common::run_out(&[
            "estimate",
            session.to_str().unwrap(),
            "--temporal",
            "smooth",
            "--seed",
            seed,
        ]);
        assert!(ok, "{err}");
        let row = common::all_row(&out);
        let (place_mm, force_n) = (row[0], row[2]);
        assert!(force_n <= 4.0, "seed {seed}: {out}");
        assert!(place_mm <= 10.0, "seed {seed}: {out}");
    }
}
