//! Tests of the synthetic sessions.

use super::*;
use crate::core::robot::builtin;

#[test]
fn presses_come_and_go_hold_their_place_and_reproduce_per_seed() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let settings = SynthSettings::default();
    let a = synthesize(&robot, &links, &settings, 3).unwrap();
    assert_eq!(a, synthesize(&robot, &links, &settings, 3).unwrap());
    assert_eq!(a.len(), 1200);
    let contact = a.iter().filter(|f| f.contact.is_some()).count();
    assert!(contact > 200 && contact < 1000, "{contact}");
    // Onsets and releases both happen.
    let switches = a
        .windows(2)
        .filter(|w| w[0].contact.is_some() != w[1].contact.is_some())
        .count();
    assert!(switches >= 4, "{switches}");
    // Without slide, a press keeps its place on its link.
    for w in a.windows(2) {
        if let (Some(x), Some(y)) = (w[0].contact, w[1].contact)
            && x.link == y.link
            && x.point_in_link.distance(y.point_in_link) > 0.0
        {
            assert!(
                x.point_in_link.distance(y.point_in_link) > 0.05,
                "a press moved without sliding"
            );
        }
    }
    // Torques are the contact's plus noise: without contact, noise only.
    let quiet: Vec<f64> = a
        .iter()
        .filter(|f| f.contact.is_none())
        .flat_map(|f| f.tau.clone())
        .collect();
    let rms = (quiet.iter().map(|t| t * t).sum::<f64>() / quiet.len() as f64).sqrt();
    assert!((rms - 0.05).abs() < 0.005, "{rms}");
}

/// Each step of a contact that stays on one link from a frame to the
/// next, m; jumps of a centimetre or more (a new press) left out.
fn slide_steps(frames: &[SynthFrame]) -> Vec<f64> {
    frames
        .windows(2)
        .filter_map(|w| match (w[0].contact, w[1].contact) {
            (Some(x), Some(y)) if x.link == y.link => Some(x.point_in_link.distance(y.point_in_link)),
            _ => None,
        })
        .filter(|d| *d < 0.01)
        .collect()
}

#[test]
fn slides_move_the_contact_at_about_the_asked_speed() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let settings = SynthSettings {
        slide_m_per_s: 0.04,
        ..SynthSettings::default()
    };
    let a = synthesize(&robot, &links, &settings, 5).unwrap();
    let steps = slide_steps(&a);
    let fastest = steps.iter().copied().fold(0.0, f64::max);
    assert!(fastest > 0.0 && fastest <= 0.04 / 200.0 * 1.01, "{fastest}");
}

/// A sliding press keeps its heading: the place moves along a smooth
/// path (no turn at the mesh's triangle edges, where the tangents of
/// the surface frame change), and the tangential force keeps its
/// direction in the link's frame.
#[test]
fn slides_and_drags_keep_their_heading() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let settings = SynthSettings {
        slide_m_per_s: 0.04,
        friction: 0.3,
        ..SynthSettings::default()
    };
    let frames = synthesize(&robot, &links, &settings, 5).unwrap();
    let contacts: Vec<Option<(SynthContact, DVec3)>> = frames
        .iter()
        .map(|f| {
            let c = f.contact?;
            let pose = RobotPose::new(&robot, &robot.joint_positions(&f.q, &[]).ok()?);
            let link_from_world = pose.world_from_link.get(c.link)?.inverse();
            Some((c, link_from_world.transform_vector3(c.force_world)))
        })
        .collect();
    let (mut turns, mut drag_turns) = (Vec::new(), Vec::new());
    for w in contacts.windows(3) {
        let [Some((a, fa)), Some((b, fb)), Some((c, _))] = w else {
            continue;
        };
        if a.link != b.link || b.link != c.link {
            continue;
        }
        let (s1, s2) = (b.point_in_link - a.point_in_link, c.point_in_link - b.point_in_link);
        if s1.length() > 1e-6 && s2.length() > 1e-6 && s1.length() < 0.01 && s2.length() < 0.01 {
            turns.push(s1.angle_between(s2));
        }
        // The whole force, link frame: its normal part turns only by
        // a step over the surface's radius, so a turn of its
        // tangential part shows.
        if fa.length() > 1.0 && fb.length() > 1.0 {
            drag_turns.push(fa.angle_between(*fb));
        }
    }
    let most = |v: &[f64]| v.iter().copied().fold(0.0, f64::max).to_degrees();
    eprintln!(
        "{} steps, largest turn {:.1}°; {} forces, largest turn {:.1}°",
        turns.len(),
        most(&turns),
        drag_turns.len(),
        most(&drag_turns)
    );
    assert!(turns.len() > 100 && drag_turns.len() > 100);
    assert!(most(&turns) < 20.0, "{turns:?}");
    assert!(most(&drag_turns) < 2.0);
}

#[test]
fn bad_settings_are_named() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let settings = SynthSettings {
        rate_hz: f64::NAN,
        ..SynthSettings::default()
    };
    assert!(matches!(
        synthesize(&robot, &links, &settings, 0),
        Err(SynthError::BadSetting { name: "rate", .. })
    ));
}

/// With two contacts at once, a second hand presses during the first's
/// presses on another link, and the first hand's presses, bias and noise
/// are those of the one-contact session of the same seed: the torques
/// differ by the second contact's exactly.
#[test]
fn a_second_hand_presses_with_the_first_and_adds_its_torques() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let one = synthesize(&robot, &links, &SynthSettings::default(), 3).unwrap();
    let settings = SynthSettings {
        contacts_at_once: 2,
        ..SynthSettings::default()
    };
    let two = synthesize(&robot, &links, &settings, 3).unwrap();
    assert_eq!(two, synthesize(&robot, &links, &settings, 3).unwrap());
    let (mut both, mut second_alone) = (0, 0);
    for (a, b) in one.iter().zip(&two) {
        assert_eq!(a.contact, b.contact);
        assert!(a.second.is_none());
        let extra = b.second.map_or_else(
            || vec![0.0; a.tau.len()],
            |c| {
                let pose = RobotPose::new(&robot, &robot.joint_positions(&b.q, &[]).unwrap());
                joint_torques(&robot, &pose, c.link, c.point_world, c.force_world)
            },
        );
        for ((x, y), e) in a.tau.iter().zip(&b.tau).zip(&extra) {
            assert!((y - x - e).abs() < 1e-9, "{x} + {e} != {y}");
        }
        match (b.contact, b.second) {
            (Some(first), Some(second)) => {
                both += 1;
                assert_ne!(first.link, second.link);
            }
            (None, Some(_)) => second_alone += 1,
            _ => {}
        }
        assert_eq!(
            b.contacts().count(),
            usize::from(b.contact.is_some()) + usize::from(b.second.is_some())
        );
    }
    // Both press in a good share of the frames; the second also outstays
    // the first.
    assert!(both > 150, "{both}");
    assert!(second_alone > 20, "{second_alone}");
    let bad = SynthSettings {
        contacts_at_once: 3,
        ..SynthSettings::default()
    };
    assert!(matches!(
        synthesize(&robot, &links, &bad, 0),
        Err(SynthError::BadSetting {
            name: "contacts at once",
            ..
        })
    ));
}

/// With kinetic friction a sliding press sticks at rest for its first
/// and last quarter and slides in between, its tangential force `μ_k` times
/// its push (`μ_k` within the range asked) along the way the place moves.
#[test]
fn sliding_presses_drag_the_arm_along_the_slide_with_kinetic_friction() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let settings = SynthSettings {
        slide_m_per_s: 0.08,
        friction: 0.2,
        kinetic_friction: Some((0.3, 0.6)),
        ramp_secs: 0.0,
        ..SynthSettings::default()
    };
    let frames = synthesize(&robot, &links, &settings, 7).unwrap();
    let in_link = |f: &SynthFrame| {
        let c = f.contact?;
        let pose = RobotPose::new(&robot, &robot.joint_positions(&f.q, &[]).ok()?);
        let link_from_world = pose.world_from_link.get(c.link)?.inverse();
        Some((c, link_from_world.transform_vector3(c.force_world)))
    };
    let (mut sliding, mut along_slide, mut sticking) = (0, 0, 0);
    for w in frames.windows(2) {
        let (Some((a, fa)), Some((b, _))) = (in_link(&w[0]), in_link(&w[1])) else {
            continue;
        };
        if a.link != b.link || a.normal_newtons < 1.0 {
            continue;
        }
        // The force is N (n + t) with n the unit inward normal and t
        // tangent: |t| = √(|F|²/N² − 1).
        let tangential = ((fa.length() / a.normal_newtons).powi(2) - 1.0).max(0.0).sqrt();
        let step = b.point_in_link - a.point_in_link;
        if step.length() > 1e-6 && step.length() < 0.01 {
            sliding += 1;
            assert!(
                (0.3 - 1e-9..=0.6 + 1e-9).contains(&tangential),
                "μ_k {tangential} while sliding"
            );
            // Along the slide: the force's part along the step is most of
            // its tangential part (the step lies in the mesh's flat
            // triangle, the force's tangent plane is the smoothed
            // normal's: they part by up to about 25°).
            let along = fa.dot(step.normalize()) / a.normal_newtons;
            along_slide += usize::from(along >= tangential * 30f64.to_radians().cos());
        } else if step.length() == 0.0 {
            sticking += 1;
            assert!(tangential <= 0.2 + 1e-9, "{tangential} while sticking");
        }
    }
    assert!(
        along_slide * 10 >= sliding * 9,
        "{along_slide} of {sliding} sliding frames pull along the slide"
    );
    assert!(
        sliding > 100 && sticking > 100,
        "{sliding} sliding, {sticking} sticking"
    );
}

/// Slides as fast as asked at least: with speeds in [2, 10] cm/s no
/// sliding step is shorter than 2 cm/s over a frame.
#[test]
fn slides_are_at_least_the_slowest_speed_asked() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let settings = SynthSettings {
        slide_m_per_s: 0.1,
        slide_min_m_per_s: 0.02,
        ..SynthSettings::default()
    };
    let frames = synthesize(&robot, &links, &settings, 5).unwrap();
    let steps = slide_steps(&frames);
    let slowest = steps.iter().copied().fold(f64::INFINITY, f64::min);
    // A step along a curved mesh is a chord of the walk: a little shorter.
    assert!(steps.len() > 100 && slowest >= 0.02 / 200.0 * 0.9, "{slowest}");
    let bad = SynthSettings {
        slide_min_m_per_s: 0.2,
        ..settings
    };
    assert!(matches!(
        synthesize(&robot, &links, &bad, 5),
        Err(SynthError::BadSetting {
            name: "slide speeds",
            ..
        })
    ));
}

/// Against the primitives' exact distance functions: no hand starts a
/// press (held, both hands) where its place lies inside the link across
/// a joint at that frame's pose (by more than 1 mm), where asked; without
/// it, 15 of the 105 presses below start inside a neighbouring link.
#[test]
fn no_press_starts_inside_a_neighbouring_link_where_asked() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let shapes = builtin::lwr4plus_primitives();
    let inside = |link: LinkId, p: DVec3| {
        builtin::primitives_signed_distance(&shapes, &robot.links[link].name, p).is_some_and(|d| d < -1e-3)
    };
    let buried_starts = |avoid_covered: bool| -> (usize, usize) {
        let settings = SynthSettings {
            contacts_at_once: 2,
            duration_secs: 12.0,
            avoid_covered,
            ..SynthSettings::default()
        };
        let (mut starts, mut buried) = (0, 0);
        for seed in 1..=6 {
            let frames = synthesize(&robot, &links, &settings, seed).unwrap();
            let mut before: [Option<LinkId>; 2] = [None, None];
            for f in &frames {
                let pose = RobotPose::new(&robot, &robot.joint_positions(&f.q, &[]).unwrap());
                for (hand, c) in [f.contact.as_ref(), f.second.as_ref()].into_iter().enumerate() {
                    let started = c.is_some() && before[hand].is_none();
                    before[hand] = c.map(|c| c.link);
                    let Some(c) = c.filter(|_| started) else { continue };
                    starts += 1;
                    let across = robot
                        .joints
                        .iter()
                        .filter_map(|j| match (j.parent == c.link, j.child == c.link) {
                            (true, _) => Some(j.child),
                            (_, true) => Some(j.parent),
                            _ => None,
                        })
                        .filter(|&n| inside(n, pose.world_from_link[n].inverse().transform_point3(c.point_world)));
                    buried += across.count();
                }
            }
        }
        (starts, buried)
    };
    let (starts, buried) = buried_starts(true);
    assert!(starts > 60, "{starts} presses");
    assert_eq!(
        buried, 0,
        "{buried} of {starts} presses start inside a neighbouring link"
    );
    let (starts, buried) = buried_starts(false);
    assert!(
        buried * 20 > starts,
        "without the test {buried} of {starts} presses start inside"
    );
}

/// A slide runs on over a rim or along a crease: its push never turns
/// by more than 20° from one frame to the next and back, by as much, to
/// within 20° of where it was at the frame after. Link 7 seed 3
/// (kinetic friction) slides over the flange's rim and link 4 seed 1 (no
/// friction) along a crease: with the heading taken along the surface
/// at every frame, their place and push go back and forth over the edge,
/// frame by frame, in 26 and 79 frames.
#[test]
fn a_slide_over_a_rim_or_along_a_crease_does_not_go_back_and_forth() {
    let robot = builtin::lwr4plus_generated().unwrap();
    for (link, seed, kinetic_friction) in [("lwr_7_link", 3, Some((0.3, 0.6))), ("lwr_4_link", 1, None)] {
        let settings = SynthSettings {
            slide_m_per_s: 0.1,
            slide_min_m_per_s: 0.02,
            kinetic_friction,
            ..SynthSettings::default()
        };
        let links = [robot.link_id(link).unwrap()];
        let frames = synthesize(&robot, &links, &settings, seed).unwrap();
        let pushes: Vec<Option<DVec3>> = frames
            .iter()
            .map(|f| f.contact.and_then(|c| c.force_world.try_normalize()))
            .collect();
        let turns = |a: DVec3, b: DVec3| a.dot(b) < 20f64.to_radians().cos();
        let back_and_forth = pushes
            .windows(3)
            .filter(|w| matches!(w, [Some(a), Some(b), Some(c)] if turns(*a, *b) && turns(*b, *c) && !turns(*a, *c)))
            .count();
        let slid = frames.windows(2).filter(|w| match (w[0].contact, w[1].contact) {
            (Some(a), Some(b)) => a.link == b.link && a.point_in_link != b.point_in_link,
            _ => false,
        });
        assert!(slid.count() > 200, "{link} seed {seed} hardly slid");
        assert_eq!(back_and_forth, 0, "{link} seed {seed}: frames back and forth");
    }
}
