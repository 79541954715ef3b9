//! Tests of [`super`]: `kinetic.rs`.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use glam::DVec3;

use super::*;
use crate::core::estimate::explain::explain_press;
use crate::core::estimate::press::{PressFrame, PressSettings};
use crate::core::eval::metrics::percentile;
use crate::core::eval::slides::SlideTracker;
use crate::core::geometry::shell::SurfaceFrame;
use crate::core::numerics::rng::Rng;
use crate::core::robot::builtin;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::LinkId;
use crate::core::robot::torque::TorqueModel;
use crate::core::surface::sampling::{Surface, SurfaceRequest};

const RATE_HZ: f64 = 100.0;
/// The share of the push the test slide's drag holds after it stops.
const HELD: f64 = 0.15;
const WEIGHTS: [f64; 7] = [400.0; 7];

/// Frames the test press sticks before and after its slide: more than
/// the velocity's half window.
const STICK: usize = 70;

/// Frames the test press slides: longer than the velocity's window.
const SLIDE: usize = 120;

/// How fast the test press slides.
const SPEED_M_PER_S: f64 = 0.04;

/// A press on the LWR's link 5 at 100 Hz while every joint swings by up
/// to 0.3 rad: it sticks for `stick` frames, slides `slide` frames at
/// `speed` m/s along its first tangent with kinetic friction `mu` (the
/// arm dragged along the slide), and sticks `stick` frames again, static
/// friction holding `held` times the push along the slide's last
/// direction; a push of 8–12 N, σ = 0.05 N·m.
struct Slide {
    surface: Surface,
    link: LinkId,
    times: Vec<f64>,
    models: Vec<TorqueModel>,
    taus: Vec<Vec<f64>>,
    /// Each frame's true place and force (link frame).
    truth: Vec<(SurfaceFrame, DVec3)>,
    /// Each frame's true place, on the mesh.
    places: Vec<MeshPoint>,
}

impl Slide {
    /// Each frame's distance from `contacts`' place to the true one, m.
    fn place_errors_m(&self, contacts: &[crate::core::estimate::press::PressContact]) -> Vec<f64> {
        contacts
            .iter()
            .zip(&self.truth)
            .map(|(c, (here, _))| c.point_in_link.distance(here.point))
            .collect()
    }
}

fn slide(link_name: &str, stick: usize, slide: usize, speed: f64, (mu, held): (f64, f64), seed: u64) -> Slide {
    let robot = builtin::lwr4plus_generated().unwrap();
    let link = robot.link_id(link_name).unwrap();
    let links = robot.default_candidate_links();
    let request = SurfaceRequest {
        links: links.clone(),
        total_points: 2000,
        seed: 0,
    };
    let surface = Surface::sample(&robot, &request).unwrap();
    let shape = surface.shape(link).unwrap();
    let k = (0..surface.len()).filter(|&k| surface.link[k] == link).nth(40).unwrap();
    let mut at = surface.location[k];
    let heading = shape.frame(at).unwrap().tangents[0];
    let mut rng = Rng::new(seed);
    let phases: Vec<f64> = (0..7).map(|_| rng.uniform_in(0.0, std::f64::consts::TAU)).collect();
    let mut out = Slide {
        surface: surface.clone(),
        link,
        times: Vec::new(),
        models: Vec::new(),
        taus: Vec::new(),
        truth: Vec::new(),
        places: Vec::new(),
    };
    let mut last_along = DVec3::ZERO;
    for i in 0..(2 * stick + slide) {
        let t = i as f64 / RATE_HZ;
        let sliding = (stick..stick + slide).contains(&i);
        let here = shape.frame(at).unwrap();
        let along = (heading - heading.dot(here.inward_normal) * here.inward_normal).normalize();
        if sliding {
            last_along = along;
        }
        // The drag held after the slide, along the surface here.
        let kept = (last_along - last_along.dot(here.inward_normal) * here.inward_normal).normalize_or_zero();
        let q: Vec<f64> = phases
            .iter()
            .enumerate()
            .map(|(j, phase)| 0.4 - 0.1 * j as f64 + 0.3 * (std::f64::consts::TAU * 0.5 * t + phase).sin())
            .collect();
        let pose = RobotPose::new(&robot, &robot.joint_positions(&q, &[]).unwrap());
        let model = TorqueModel::new(&robot, &pose, &links);
        let push = 10.0 + 2.0 * (std::f64::consts::TAU * t).sin();
        let tangential = if sliding {
            along * (mu * push)
        } else {
            kept * (held * push)
        };
        let force = here.inward_normal * push + tangential;
        let tau = model
            .torques(link, here.point, force)
            .iter()
            .map(|x| x + 0.05 * rng.normal())
            .collect();
        out.times.push(t);
        out.models.push(model);
        out.taus.push(tau);
        out.truth.push((here, force));
        out.places.push(at);
        if sliding {
            at = shape.walk(at, along * (speed / RATE_HZ));
        }
    }
    out
}

fn settings(friction: f64) -> PressSettings<'static> {
    PressSettings {
        weights: &WEIGHTS,
        force_range_newtons: (1.0, 30.0),
        friction,
        slide_m_per_sqrt_s: 0.003,
    }
}

fn frames<'a>(s: &'a Slide, starts: &[MeshPoint]) -> Vec<PressFrame<'a>> {
    (0..s.times.len())
        .map(|i| PressFrame {
            t_secs: s.times[i],
            torque_model: &s.models[i],
            tau: &s.taus[i],
            start: starts[i],
        })
        .collect()
}

/// A slide's directions: along the slide (unit vectors) while the place
/// moves at 4 cm/s for 1.2 s, and none where it stands, a window away
/// from the slide.
#[test]
fn directions_follow_the_slide_and_vanish_at_rest() {
    let s = slide("lwr_5_link", STICK, SLIDE, SPEED_M_PER_S, (0.5, 0.0), 1);
    let window = (WINDOW_SECS * RATE_HZ).round() as usize;
    let shape = s.surface.shape(s.link).unwrap();
    let settings = settings(0.2);
    let frames = frames(&s, &s.places);
    let problem = Problem::new(shape, s.link, &frames, &settings).unwrap();
    let directions = slides_at(&problem, &s.places).unwrap().directions;
    for (i, (d, (here, _))) in directions.iter().zip(&s.truth).enumerate() {
        if (STICK + window..STICK + SLIDE - window).contains(&i) {
            // The move over the window, along the surface here.
            let moved = s.truth[i + window].0.point - s.truth[i - window].0.point;
            let along = (moved - moved.dot(here.inward_normal) * here.inward_normal).normalize();
            assert!((d.length() - 1.0).abs() < 1e-9, "frame {i}: {d:?}");
            assert!(d.normalize().dot(along) > 0.99, "frame {i}: {d:?} against {along:?}");
        }
        if !(STICK - window..=STICK + SLIDE + window).contains(&i) {
            assert!(d.length() < 1e-9, "frame {i}: {d:?}");
        }
    }
}

/// A slide's pace over its own frames: with the frames around it held
/// still, each slipping frame's velocity refitted through its slip alone
/// is the true 4 cm/s within 3 %, where the window through the rests
/// reads the slide's first and last frames at under 80 % of it.
#[test]
fn a_slips_pace_comes_from_its_own_frames() {
    let s = slide("lwr_5_link", STICK, SLIDE, SPEED_M_PER_S, (0.5, 0.0), 1);
    let shape = s.surface.shape(s.link).unwrap();
    let settings = settings(0.2);
    let frames = frames(&s, &s.places);
    let problem = Problem::new(shape, s.link, &frames, &settings).unwrap();
    let mut slides = slides_at(&problem, &s.places).unwrap();
    let slipping = STICK..STICK + SLIDE;
    for (t, (d, v)) in slides
        .directions
        .iter_mut()
        .zip(&mut slides.velocities_m_per_s)
        .enumerate()
    {
        if !slipping.contains(&t) {
            *d = DVec3::ZERO;
            *v = DVec3::ZERO;
        }
    }
    for end in [STICK, STICK + SLIDE - 1] {
        let speed = slides.velocities_m_per_s[end].length();
        assert!(speed < 0.8 * SPEED_M_PER_S, "frame {end}: {speed}");
    }
    let paced = slip_velocities(&problem, &s.places, slides).unwrap();
    for (t, v) in paced.velocities_m_per_s.iter().enumerate() {
        if slipping.contains(&t) {
            assert!((v.length() / SPEED_M_PER_S - 1.0).abs() < 0.03, "frame {t}: {v:?}");
        } else {
            assert!(v.length() < 1e-12, "frame {t}: {v:?}");
        }
    }
}

/// A press that sticks, slides 4.8 cm at 4 cm/s with `μ_k` = 0.5, and
/// sticks again is explained by kinetic friction: found where it is at
/// every frame, with `μ_k` and its force; the frictionless fit of the same
/// press is centimetres off while it slides.
#[test]
fn a_sliding_press_is_found_with_its_kinetic_friction() {
    for seed in 1..=3 {
        let s = slide("lwr_5_link", STICK, SLIDE, SPEED_M_PER_S, (0.5, 0.0), seed);
        let shape = s.surface.shape(s.link).unwrap();
        let frames = frames(&s, &s.places);
        let answer = explain_press(shape, s.link, &frames, &settings(0.2)).unwrap();
        let plain = explain_press(shape, s.link, &frames, &settings(0.0)).unwrap();
        let error = |contacts: &[crate::core::estimate::press::PressContact]| {
            let place = s.place_errors_m(contacts);
            let force: Vec<f64> = contacts
                .iter()
                .zip(&s.truth)
                .map(|(c, (_, f))| (c.inward_normal_in_link * c.force_newtons + c.tangential_in_link).distance(*f))
                .collect();
            (
                percentile(&place, 0.5),
                percentile(&place, 0.9),
                percentile(&force, 0.5),
            )
        };
        let (place, place90, force) = error(&answer.contacts);
        let (plain_place, plain90, plain_force) = error(&plain.contacts);
        eprintln!(
            "seed {seed}: μ_k {:?}, gain {:.0}; place {:.1}/{:.1} mm, force {force:.2} N; frictionless {:.1}/{:.1} mm, {plain_force:.2} N",
            answer.kinetic_friction,
            answer.gain,
            place * 1e3,
            place90 * 1e3,
            plain_place * 1e3,
            plain90 * 1e3
        );
        let mu = answer.kinetic_friction.unwrap();
        assert!((mu - 0.5).abs() < 0.1, "{mu}");
        assert!(place90 < 5e-3, "{place90}");
        assert!(force < 0.5, "{force}");
        assert!(plain90 > 3.0 * place90, "{plain90}");
    }
}

/// A slide that stops with its drag held (static friction keeping
/// [`HELD`] of the push along the slide's last direction) is found with
/// that drag: `μ_k` within 0.1, the force of the frames after the slide
/// within 0.6 N at the median and the place within 5 mm at p90. Without
/// the held drag in the model the places move to explain it: 2.9 N and
/// 9.9 mm at seed 1. With drags of 0.25–0.3 the fit is less sure: at one
/// seed in three the press is not taken for a slide at all
/// (`docs/decisions.md`, *Friction while a slide sticks*).
#[test]
fn a_slide_that_stops_holding_its_drag_is_found_with_it() {
    for seed in 1..=3 {
        let s = slide("lwr_5_link", STICK, SLIDE, SPEED_M_PER_S, (0.5, HELD), seed);
        let shape = s.surface.shape(s.link).unwrap();
        let frames = frames(&s, &s.places);
        let answer = explain_press(shape, s.link, &frames, &settings(0.2)).unwrap();
        let after = STICK + SLIDE + (WINDOW_SECS * RATE_HZ).round() as usize;
        let force: Vec<f64> = answer.contacts[after..]
            .iter()
            .zip(&s.truth[after..])
            .map(|(c, (_, f))| (c.inward_normal_in_link * c.force_newtons + c.tangential_in_link).distance(*f))
            .collect();
        let place = s.place_errors_m(&answer.contacts);
        let (force, place90) = (percentile(&force, 0.5), percentile(&place, 0.9));
        eprintln!(
            "seed {seed}: μ_k {:?}, after the slide {force:.2} N, place p90 {:.1} mm",
            answer.kinetic_friction,
            place90 * 1e3
        );
        let mu = answer.kinetic_friction.unwrap();
        assert!((mu - 0.5).abs() < 0.1, "{mu}");
        assert!(force < 0.6, "{force}");
        assert!(place90 < 5e-3, "{place90}");
    }
}

/// A short fast slide (30 frames at 8 cm/s: 2.4 cm, shorter than the
/// velocity's window) between rests, fitted from the true places: the
/// places stay within 1 mm of where the press starts until it slides,
/// and the path through them (measured as `estimate` scores a slide) is
/// within 10 % of the true one at the median over seeds 1–3. They are
/// 0.6 / 0.2 / 0.2 mm and 1.02 / 1.05 / 1.08. With a rest's places held
/// at the full slide length (`press::STILL_SLIDE_FRACTION` 1), 1.2 / 1.1 /
/// 0.8 mm and 1.20 / 1.23 / 1.24; with the rests expected to move on at
/// the track's velocity, as before both fits were tried, 2.6 / 3.4 / 8.5
/// mm and 1.49 / 1.28 / 1.74; with the slip's pace fitted through the
/// rests too, 2.9 / 1.2 / 0.9 mm and 2.15 / 1.18 / 1.19.
#[test]
fn a_short_slide_leaves_its_rests_still() {
    let mut ratios = Vec::new();
    for seed in 1..=3 {
        let s = slide("lwr_5_link", STICK, 30, 0.08, (0.5, HELD), seed);
        let shape = s.surface.shape(s.link).unwrap();
        let frames = frames(&s, &s.places);
        let settings = settings(0.2);
        let problem = Problem::new(shape, s.link, &frames, &settings).unwrap();
        let found = descend_kinetic(&problem, s.places.clone()).unwrap().found;
        let points: Vec<DVec3> = found.locations.iter().map(|&m| shape.frame(m).unwrap().point).collect();
        // Both paths as `estimate` scores a slide: through the places
        // taken every 50 ms.
        let mut tracker = SlideTracker::default();
        for ((&t, (here, _)), &point) in s.times.iter().zip(&s.truth).zip(&points) {
            tracker.push(t, Some((s.link, here.point)), Some(point));
        }
        let path = tracker.finish()[0];
        let rest = points[..STICK]
            .iter()
            .map(|p| p.distance(points[0]))
            .fold(0.0, f64::max);
        let ratio = path.estimated_length_m / path.true_length_m;
        eprintln!(
            "seed {seed}: rests within {:.1} mm, path {ratio:.2} of the true one",
            rest * 1e3
        );
        assert!(rest < 1e-3, "seed {seed}: {rest}");
        ratios.push(ratio);
    }
    let median = percentile(&ratios, 0.5);
    assert!((median - 1.0).abs() < 0.1, "{ratios:?}");
}

/// A slip shorter than 1 cm (24 frames at 3.5 cm/s: 8.4 mm, as the
/// generated link 7 seed 2 slide's first press slips) at `μ_k` 0.5
/// between rests of 12 frames (a press that sticks its first and last
/// quarter, as `synth` draws it), on link 7 (seven joints feel it),
/// fitted from the true places at seeds 1–3: where no fixed γ within
/// the cone explains it (seeds 2 and 3) it is found with its kinetic
/// friction (`μ_k` within 0.2), and where one does (seed 1) the fixed γ
/// keeps it; the median of the seeds' median place errors is under
/// 15 mm. While a kinetic fit needed a slide of 1 cm, seeds 2 and 3 were
/// fitted without friction and the places were 3.9 / 21.2 / 22.4 mm off
/// (now 3.9 / 12.8 / 18.1 mm: from the true places the model still
/// prefers places farther off at seeds 2 and 3).
#[test]
fn a_slip_shorter_than_a_centimetre_is_found() {
    let mut medians = Vec::new();
    for seed in 1..=3 {
        let s = slide("lwr_7_link", 12, 24, 0.035, (0.5, 0.0), seed);
        let shape = s.surface.shape(s.link).unwrap();
        let frames = frames(&s, &s.places);
        let answer = explain_press(shape, s.link, &frames, &settings(0.2)).unwrap();
        let place = s.place_errors_m(&answer.contacts);
        let median = percentile(&place, 0.5);
        eprintln!(
            "seed {seed}: μ_k {:?}, friction {}, place median {:.1} mm",
            answer.kinetic_friction,
            answer.friction,
            median * 1e3
        );
        match answer.kinetic_friction {
            Some(mu) => assert!((mu - 0.5).abs() < 0.2, "seed {seed}: μ_k {mu}"),
            None => assert!(answer.friction, "seed {seed}: neither kinetic friction nor a fixed γ"),
        }
        medians.push(median);
    }
    let median = percentile(&medians, 0.5);
    assert!(median < 0.015, "{medians:?}");
}
