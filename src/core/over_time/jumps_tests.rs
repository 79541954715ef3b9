//! Where a press's own places jump: a second push's arrival is found, a
//! slide, a scatter and a press's first frames are not.

use super::*;
use crate::core::estimate::estimator::Estimator;
use crate::core::estimate::settings::EstimatorSettings;
use crate::core::robot::builtin;
use crate::core::surface::sampling::SurfaceRequest;

/// A press of `n` frames at 100 Hz on link 6 whose frames alone lie at
/// `place(k)` (the world frame, which the still arm keeps fixed to the
/// link): where [`jumps`] cuts it.
fn jumps_of(n: usize, place: impl Fn(usize) -> DVec3) -> Vec<usize> {
    let robot = builtin::lwr4plus_generated().unwrap();
    let request = SurfaceRequest {
        links: robot.default_candidate_links(),
        total_points: 200,
        seed: 0,
    };
    let estimator = Estimator::new(&robot, &request, EstimatorSettings::exact(vec![0.05; 7]), None).unwrap();
    let link = robot.link_id("lwr_6_link").unwrap();
    let q = vec![0.4, -0.3, 0.5, -1.2, 0.6, 0.8, -0.2];
    let tau = vec![0.0; 7];
    let update = estimator.update(&robot, &q, &tau).unwrap();
    let frames: Vec<SequenceFrame> = (0..n)
        .map(|i| SequenceFrame {
            t_secs: i as f64 * 0.01,
            joint_positions: &q,
            tau: &tau,
        })
        .collect();
    let press: Vec<(usize, Update, f64)> = (0..n).map(|i| (i, update.clone(), 0.0)).collect();
    let alone: Vec<Option<Summary>> = (0..n)
        .map(|k| {
            let mut own = update.summary.clone();
            own.refined = true;
            own.map.link = link;
            own.map.point_world = place(k);
            Some(own)
        })
        .collect();
    jumps(&press, &alone, &frames, link)
}

/// A few millimetres of a frame's jitter, the same for every run.
fn jitter(k: usize) -> DVec3 {
    let s = |m: usize| ((k * m) % 7) as f64 - 3.0;
    DVec3::new(s(3), s(5), s(2)) * 0.001
}

#[test]
fn a_place_that_jumps_ten_centimetres_is_cut_where_it_jumps() {
    let cuts = jumps_of(40, |k| jitter(k) + if k < 22 { DVec3::ZERO } else { DVec3::X * 0.1 });
    assert_eq!(cuts, vec![22]);
}

#[test]
fn a_place_that_moves_over_four_frames_is_cut_once_within_them() {
    let cuts = jumps_of(40, |k| jitter(k) + DVec3::X * 0.025 * (k.clamp(20, 24) - 20) as f64);
    assert_eq!(cuts.len(), 1, "{cuts:?}");
    assert!((20..=24).contains(&cuts[0]), "{cuts:?}");
}

#[test]
fn a_slide_at_ten_centimetres_a_second_is_not_cut() {
    assert!(jumps_of(100, |k| jitter(k) + DVec3::X * 0.001 * k as f64).is_empty());
}

#[test]
fn places_that_scatter_along_the_link_are_not_cut() {
    // Each frame anywhere within 15 cm along the link, as frames alone
    // place a push that few joints pin: five frames' medians move by
    // centimetres, and so does each window's spread.
    let scatter = |k: usize| ((k * 2_654_435_761) % 1000) as f64 / 1000.0 * 0.15;
    let cuts = jumps_of(100, |k| DVec3::Z * scatter(k));
    assert!(cuts.is_empty(), "{cuts:?}");
}

#[test]
fn a_jump_in_a_press_s_first_or_last_frames_is_not_cut() {
    assert!(jumps_of(40, |k| jitter(k) + if k < 3 { DVec3::X * 0.1 } else { DVec3::ZERO }).is_empty());
    assert!(jumps_of(40, |k| jitter(k) + if k >= 37 { DVec3::X * 0.1 } else { DVec3::ZERO }).is_empty());
}
