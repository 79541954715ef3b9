//! Two contacts in one frame and the chain of two states over frames: any
//! torques, σ and starts give a pair whose numbers are finite and whose
//! probability of two is a probability, or an error; never a panic; so
//! does that pair carried into the next frame's torques. Any
//! times and evidence ratios give the chain's probabilities in [0, 1].
//! Any torques and place give one contact's χ² with its force free
//! (what a pair must beat) that is finite and not negative, or none,
//! at the place alone or searched within any radius of it. Any two
//! pushes (places, forces, noise) are judged by the joints' rules
//! without a panic.
#![no_main]

use std::sync::OnceLock;

use glam::DVec3;
use proprioscope::core::estimate::contact::PosedSurface;
use proprioscope::core::estimate::estimator::Estimator;
use proprioscope::core::estimate::pair::{PairSettings, PairStart, estimate_pair};
use proprioscope::core::estimate::pair_held::estimate_pair_held;
use proprioscope::core::estimate::pair_identifiable::pushes_unidentifiable;
use proprioscope::core::estimate::posterior::estimate;
use proprioscope::core::estimate::settings::EstimatorSettings;
use proprioscope::core::over_time::pairs::SecondContactChain;
use proprioscope::core::robot::builtin;
use proprioscope::core::robot::kinematics::RobotPose;
use proprioscope::core::robot::model::Robot;
use proprioscope::core::robot::torque::TorqueModel;
use proprioscope::core::surface::sampling::{Surface, SurfaceRequest};

/// The built-in LWR, 80 samples of it and one pose.
fn scene() -> &'static (Robot, Surface, RobotPose) {
    static SCENE: OnceLock<(Robot, Surface, RobotPose)> = OnceLock::new();
    SCENE.get_or_init(|| {
        let Ok(robot) = builtin::lwr4plus_generated() else {
            std::process::abort()
        };
        let request = SurfaceRequest {
            links: robot.default_candidate_links(),
            total_points: 80,
            seed: 0,
        };
        let Ok(surface) = Surface::sample(&robot, &request) else {
            std::process::abort()
        };
        let Ok(q) = robot.joint_positions(&[1.2, 0.3, 0.8, -1.6, -1.0, -0.5, 0.9], &[]) else {
            std::process::abort()
        };
        let pose = RobotPose::new(&robot, &q);
        (robot, surface, pose)
    })
}

/// An estimator over the scene's robot (80 samples).
fn estimator() -> &'static Estimator {
    static ESTIMATOR: OnceLock<Estimator> = OnceLock::new();
    ESTIMATOR.get_or_init(|| {
        let (robot, _, _) = scene();
        let request = SurfaceRequest {
            links: robot.default_candidate_links(),
            total_points: 80,
            seed: 0,
        };
        let Ok(estimator) = Estimator::new(robot, &request, EstimatorSettings::exact(vec![0.05; 7]), None) else {
            std::process::abort()
        };
        estimator
    })
}

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let numbers: Vec<f64> = data
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
        .collect();
    let (Some(&sigma), Some(&start), Some(&force), Some(&friction), Some(rest)) = (
        numbers.first(),
        numbers.get(1),
        numbers.get(2),
        numbers.get(3),
        numbers.get(4..),
    ) else {
        return;
    };
    let (robot, surface, pose) = scene();
    let links = robot.default_candidate_links();
    let torque_model = TorqueModel::new(robot, pose, &links);
    let posed = PosedSurface {
        torque_model: &torque_model,
        surface,
    };
    let tau: Vec<f64> = rest.iter().copied().take(7).collect();
    if tau.len() == 7 {
        let settings = EstimatorSettings {
            friction: if friction.is_finite() { friction.abs() % 2.0 } else { 0.0 },
            ..EstimatorSettings::exact(vec![sigma.abs().clamp(1e-4, 100.0); 7])
        };
        if let Ok(single) = estimate(&posed, &tau, &settings, None) {
            let point = if start.is_finite() { (start.abs() as usize) % surface.len() } else { 0 };
            let starts = [PairStart::One { point, force_newtons: force }, PairStart::Unknown];
            if let Ok(Some(pair)) =
                estimate_pair(&posed, pose, &tau, &settings, None, &single, &PairSettings::default(), &starts)
            {
                assert!((0.0..=1.0).contains(&pair.probability_two), "{pair:?}");
                for c in &pair.contacts {
                    assert!(c.point_world.is_finite() && c.placed.force_newtons.is_finite(), "{pair:?}");
                }
                // The pair carried into the next frame (the torques that
                // follow), either contact the new one.
                let next: Vec<f64> = rest.iter().copied().skip(7).take(7).collect();
                let both = pair.contacts.clone().map(|c| c.placed);
                if next.len() == 7
                    && let Ok(next_single) = estimate(&posed, &next, &settings, None)
                {
                    for new in 0..3 {
                        let held = estimate_pair_held(
                            &posed,
                            pose,
                            &next,
                            &settings,
                            None,
                            &next_single,
                            &PairSettings::default(),
                            &both,
                            new,
                        );
                        if let Ok(Some(held)) = held {
                            assert!(new < 2, "{held:?}");
                            let a = &held.account;
                            assert!((0.0..=1.0).contains(&a.probability_two), "{held:?}");
                            assert!(!held.new_log_occam.is_nan(), "{held:?}");
                            for c in &a.contacts {
                                assert!(c.point_world.is_finite() && c.placed.force_newtons.is_finite(), "{held:?}");
                            }
                        }
                    }
                }
            }
        }
    }
    // One contact with its force free, at any place on any link.
    if let (Some(&link), Some(place)) = (numbers.get(4), rest.get(7..10)) {
        let (robot, _, _) = scene();
        let link = if link.is_finite() { (link.abs() as usize) % 9 } else { 0 };
        let at = |i: usize| place.get(i).copied().unwrap_or(0.0);
        let point_in_link = DVec3::new(at(0), at(1), at(2));
        let tau: Vec<f64> = rest.iter().copied().take(7).collect();
        if let Ok(q) = robot.joint_positions(&[1.2, 0.3, 0.8, -1.6, -1.0, -0.5, 0.9], &[])
            && let Some(chi2) = estimator().free_push_chi2(robot, &q, &tau, link, point_in_link)
        {
            assert!(chi2.is_finite() && chi2 >= -1e-9, "{chi2}");
        }
        // The same searched within any radius (NaN, negative, infinite).
        let radius_m = numbers.get(5).copied().unwrap_or(0.03);
        if let Ok(q) = robot.joint_positions(&[1.2, 0.3, 0.8, -1.6, -1.0, -0.5, 0.9], &[])
            && let Some(chi2) = estimator().free_push_chi2_near(robot, (&q, &tau), &[(link, point_in_link)], radius_m)
        {
            assert!(chi2.is_finite() && chi2 >= -1e-9, "{chi2}");
        }
    }
    // Two true pushes at any places, with any forces and noise, judged
    // by the joints' rules: a reason or none, never a panic.
    if let Some(values) = rest.get(0..12) {
        let (robot, _, pose) = scene();
        let links = robot.default_candidate_links();
        let link = |x: f64| {
            let k = if x.is_finite() { (x.abs() as usize) % links.len().max(1) } else { 0 };
            links.get(k).copied()
        };
        let v = |i: usize| values.get(i).copied().unwrap_or(0.0);
        let push = |i: usize| {
            link(v(i)).map(|l| (l, DVec3::new(v(i + 1), v(i + 2), v(i + 3)), DVec3::new(v(i + 4), v(i + 5), 0.0)))
        };
        let weights = vec![1.0 / (sigma * sigma); 7];
        if let (Some(a), Some(b)) = (push(0), push(6)) {
            let _ = pushes_unidentifiable(robot, pose, (&weights, friction > 0.0), [a, b]);
        }
    }
    // The chain: times and ratios from what is left.
    let times: Vec<f64> = rest.iter().step_by(2).copied().collect();
    let ratios: Vec<f64> = rest.iter().skip(1).step_by(2).copied().collect();
    let n = times.len().min(ratios.len());
    let chain = SecondContactChain {
        onset_per_s: 0.5,
        release_per_s: 2.0,
    };
    for p in chain.smooth(&times[..n], &ratios[..n], 0.1) {
        assert!((0.0..=1.0).contains(&p), "{p}");
    }
});
