//! The press queue: which frames a press holds, across hops to another
//! link and back, and that every frame comes out once, in order.

use super::*;
use crate::core::estimate::settings::EstimatorSettings;
use crate::core::estimate::summary::Verdict;
use crate::core::robot::builtin;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::torque::TorqueModel;
use crate::core::surface::sampling::SurfaceRequest;

/// What the queue handed on: a press's frame numbers, or a frame alone.
#[derive(Debug, PartialEq)]
enum Out {
    Press(Vec<usize>),
    Frame(usize),
}

/// Frames at 200 Hz whose contact lies on link 6 (`'a'`), on link
/// `b_link` (`'b'`) or nowhere (`'-'`), offered to a press queue: what it
/// hands on (each press's frames as held, or as its fit hands them on
/// where `fit`), and the pieces of each press.
fn queued(pattern: &str, a_link: &str, b_link: &str, fit: bool) -> (Vec<Out>, Vec<Vec<usize>>) {
    let robot = builtin::lwr4plus_generated().unwrap();
    let request = SurfaceRequest {
        links: robot.default_candidate_links(),
        total_points: 500,
        seed: 0,
    };
    let estimator = Estimator::new(&robot, &request, EstimatorSettings::exact(vec![0.05; 7]), None).unwrap();
    assert!(estimator.uses_patches());
    let (a, b) = (robot.link_id(a_link).unwrap(), robot.link_id(b_link).unwrap());
    let q = vec![0.4, -0.3, 0.5, -1.2, 0.6, 0.8, -0.2];
    // A push on link 6: refined, called a contact.
    let pose = RobotPose::new(&robot, &q);
    let model = TorqueModel::new(&robot, &pose, &estimator.links);
    let k = (0..estimator.surface.len())
        .find(|&k| estimator.surface.link[k] == a)
        .unwrap();
    let tau = model.torques(
        a,
        estimator.surface.point_in_link[k],
        estimator.surface.inward_normal_in_link[k] * 15.0,
    );
    let pressed = estimator.update(&robot, &q, &tau).unwrap();
    assert!(is_pressed(&pressed));
    let frames: Vec<SequenceFrame> = (0..pattern.len())
        .map(|i| SequenceFrame {
            t_secs: i as f64 * 0.005,
            joint_positions: &q,
            tau: &tau,
        })
        .collect();
    let mut queue = PressQueue::new(&estimator, &robot, &frames, 0.01);
    let mut out = Vec::new();
    let mut pieces = Vec::new();
    let mut take = |offered: Offered| match offered {
        Offered::Frame(i, _, _) => out.push(Out::Frame(i)),
        Offered::Press(job) => {
            // A bridged press holds its frames twice while fitted.
            let once = job.held.len() * (size_of::<Update>() + pressed.posterior.bytes());
            let copies = if job.pieces().len() > 1 { 2 } else { 1 };
            assert_eq!(job.bytes(), copies * once);
            pieces.push(job.pieces());
            let frames = if fit {
                job.fit().iter().map(|(i, _, _)| *i).collect()
            } else {
                job.held.iter().map(|(i, _, _)| *i).collect()
            };
            out.push(Out::Press(frames));
        }
    };
    for (i, c) in pattern.chars().enumerate() {
        let mut update = pressed.clone();
        match c {
            'a' => update.summary.map.link = a,
            'b' => update.summary.map.link = b,
            _ => update.summary.verdict = Verdict::NoContact,
        }
        queue.offer(i, (update, None), 0.0, &mut take);
    }
    queue.settle(&mut take);
    (out, pieces)
}

#[test]
fn a_press_runs_on_across_a_short_hop_and_every_frame_comes_out_once_in_order() {
    // Link 3 has three sensed joints: a hop of two frames (10 ms) is
    // bridged; one of eight (40 ms) is a press of its own; a hop that the
    // press never comes back from is one too, at a frame without contact
    // and at the session's end.
    let (out, pieces) = queued("aaabbaabbbbbbbbaa-aabb", "lwr_6_link", "lwr_3_link", false);
    assert_eq!(
        out,
        vec![
            Out::Press((0..=6).collect()),
            Out::Press((7..=14).collect()),
            Out::Press(vec![15, 16]),
            Out::Frame(17),
            Out::Press(vec![18, 19]),
            Out::Press(vec![20, 21]),
        ]
    );
    // The bridged press's runs on one link: its pieces.
    assert_eq!(pieces.first(), Some(&vec![0, 3, 5]));
    assert!(pieces.iter().skip(1).all(|p| p == &vec![0]));
}

#[test]
fn a_press_runs_on_across_a_longer_hop_where_both_links_have_four_joints() {
    // Links 6 and 7, and links 5 and 4 either way round: the hop of eight
    // frames (40 ms) is bridged too.
    for (a, b) in [
        ("lwr_6_link", "lwr_7_link"),
        ("lwr_5_link", "lwr_4_link"),
        ("lwr_4_link", "lwr_5_link"),
    ] {
        let (out, pieces) = queued("aaabbaabbbbbbbbaa-aabb", a, b, false);
        assert_eq!(
            out,
            vec![
                Out::Press((0..=16).collect()),
                Out::Frame(17),
                Out::Press(vec![18, 19]),
                Out::Press(vec![20, 21]),
            ],
            "{a} and {b}"
        );
        assert_eq!(pieces.first(), Some(&vec![0, 3, 5, 7, 15]), "{a} and {b}");
    }
    // Links 4 and 3: three sensed joints feel link 3, so only the short
    // hop is bridged.
    let (out, _) = queued("aaabbaabbbbbbbbaa", "lwr_4_link", "lwr_3_link", false);
    assert_eq!(
        out,
        vec![
            Out::Press((0..=6).collect()),
            Out::Press((7..=14).collect()),
            Out::Press(vec![15, 16])
        ]
    );
    // A hop of 130 frames (0.65 s) is a press of its own.
    let long = format!("aa{}aa", "b".repeat(130));
    let (out, _) = queued(&long, "lwr_6_link", "lwr_7_link", false);
    assert_eq!(
        out,
        vec![
            Out::Press(vec![0, 1]),
            Out::Press((2..=131).collect()),
            Out::Press(vec![132, 133]),
        ]
    );
}

#[test]
fn a_bridged_press_is_fitted_and_hands_on_each_of_its_frames_once_in_order() {
    // Whole and piece by piece, one of the two kept.
    let (out, pieces) = queued("aaabbaa", "lwr_6_link", "lwr_7_link", true);
    assert_eq!(out, vec![Out::Press((0..=6).collect())]);
    assert_eq!(pieces, vec![vec![0, 3, 5]]);
}

#[test]
fn a_long_press_is_held_up_to_its_limit_and_cut_into_pieces_of_at_most_a_piece() {
    // 1,300 frames on link 6: held as 1,200 (`MAX_PRESS_FRAMES`) and
    // 100; after a frame without contact, 450 more. Each run on one link
    // is cut every 400 frames (`PRESS_PIECE_FRAMES`).
    let pattern = format!("{}-{}", "a".repeat(1300), "a".repeat(450));
    let (out, pieces) = queued(&pattern, "lwr_6_link", "lwr_7_link", false);
    assert_eq!(
        out,
        vec![
            Out::Press((0..1200).collect()),
            Out::Press((1200..1300).collect()),
            Out::Frame(1300),
            Out::Press((1301..1751).collect()),
        ]
    );
    assert_eq!(pieces, vec![vec![0, 400, 800], vec![0], vec![0, 400]]);
    // A bridged hop starts a piece, and so does the run after it, which
    // counts its frames afresh.
    let pattern = format!("{}bb{}", "a".repeat(402), "a".repeat(405));
    let (_, pieces) = queued(&pattern, "lwr_6_link", "lwr_7_link", false);
    assert_eq!(pieces, vec![vec![0, 400, 402, 404, 804]]);
}
