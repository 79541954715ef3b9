//! A press fitted as a whole, with kinetic friction along its slide: any
//! times (backwards, repeated, NaN), torques, poses, starts, noise,
//! force range, friction and slide length give an answer whose cost,
//! places, pushes, tangential forces and `μ_k` are finite, or none;
//! never a panic.
#![no_main]

use std::sync::OnceLock;

use proprioscope::core::estimate::explain::explain_press;
use proprioscope::core::estimate::press::{PressFrame, PressSettings};
use proprioscope::core::robot::builtin;
use proprioscope::core::robot::kinematics::RobotPose;
use proprioscope::core::robot::model::{LinkId, Robot};
use proprioscope::core::robot::torque::TorqueModel;
use proprioscope::core::surface::sampling::{Surface, SurfaceRequest};

/// The numbers a frame takes from the input: time, seven torques, seven
/// joint angles and a start.
const PER_FRAME: usize = 16;

/// The most frames a press takes from one input (the fit's time grows
/// with them).
const MAX_FRAMES: usize = 40;

/// The built-in LWR and 300 samples of it.
fn scene() -> &'static (Robot, Surface) {
    static SCENE: OnceLock<(Robot, Surface)> = OnceLock::new();
    SCENE.get_or_init(|| {
        let Ok(robot) = builtin::lwr4plus_generated() else {
            std::process::abort()
        };
        let request = SurfaceRequest {
            links: robot.default_candidate_links(),
            total_points: 300,
            seed: 0,
        };
        let Ok(surface) = Surface::sample(&robot, &request) else {
            std::process::abort()
        };
        (robot, surface)
    })
}

/// A number from the input folded into `0..n` (0 where it is not finite).
fn index(x: f64, n: usize) -> usize {
    if x.is_finite() && n > 0 {
        (x.abs() % n as f64) as usize
    } else {
        0
    }
}

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let numbers: Vec<f64> = data
        .chunks_exact(8)
        .map(|c| f64::from_le_bytes(c.try_into().unwrap_or([0; 8])))
        .collect();
    let (Some(&link_pick), Some(&sigma), Some(&force_min), Some(&force_max), Some(&friction), Some(&slide), Some(rest)) = (
        numbers.first(),
        numbers.get(1),
        numbers.get(2),
        numbers.get(3),
        numbers.get(4),
        numbers.get(5),
        numbers.get(6..),
    ) else {
        return;
    };
    let (robot, surface) = scene();
    let links = robot.default_candidate_links();
    let link: LinkId = links[index(link_pick, links.len())];
    let Some(shape) = surface.shape(link) else {
        return;
    };
    let on_link: Vec<usize> = (0..surface.len()).filter(|&k| surface.link[k] == link).collect();
    if on_link.is_empty() {
        return;
    }
    let frames: Vec<&[f64]> = rest.chunks_exact(PER_FRAME).take(MAX_FRAMES).collect();
    // Poses whose angles are not finite are the caller's to refuse; the
    // fit is given finite ones, any size.
    let models: Vec<TorqueModel> = frames
        .iter()
        .map(|f| {
            let angles: Vec<f64> = f[8..15]
                .iter()
                .map(|a| if a.is_finite() { *a % 100.0 } else { 0.0 })
                .collect();
            let q = robot
                .joint_positions(&angles, &[])
                .unwrap_or_else(|_| vec![0.0; robot.joints.len()]);
            TorqueModel::new(robot, &RobotPose::new(robot, &q), &links)
        })
        .collect();
    let press: Vec<PressFrame> = frames
        .iter()
        .zip(&models)
        .map(|(f, torque_model)| PressFrame {
            t_secs: f[0],
            torque_model,
            tau: &f[1..8],
            start: surface.location[on_link[index(f[15], on_link.len())]],
        })
        .collect();
    let weights = vec![1.0 / (sigma * sigma); 7];
    let settings = PressSettings {
        weights: &weights,
        force_range_newtons: (force_min, force_max),
        friction,
        slide_m_per_sqrt_s: slide,
    };
    let Some(answer) = explain_press(shape, link, &press, &settings) else {
        return;
    };
    assert!(answer.cost.is_finite(), "{answer:?}");
    assert!(answer.tangential_ratio_in_link.is_finite(), "{answer:?}");
    assert!(answer.kinetic_friction.is_none_or(f64::is_finite), "{answer:?}");
    assert_eq!(answer.contacts.len(), press.len());
    for c in &answer.contacts {
        assert!(
            c.point_in_link.is_finite()
                && c.inward_normal_in_link.is_finite()
                && c.force_newtons.is_finite()
                && c.tangential_in_link.is_finite(),
            "{c:?}"
        );
    }
});
