//! Tests of [`super`]: `press.rs`.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use super::*;
use crate::core::estimate::explain::{explain_press, fit_press};
use crate::core::eval::metrics::percentile;
use crate::core::numerics::rng::Rng;
use crate::core::robot::builtin;
use crate::core::robot::kinematics::RobotPose;
use crate::core::surface::sampling::{Surface, SurfaceRequest};

/// A press on the LWR's link 5: 60 frames at 50 Hz while every joint
/// swings by up to 0.3 rad, a push of 5–15 N at one place plus
/// `ratio` (link frame) times it along the surface, σ = 0.05 N·m.
struct Press {
    surface: Surface,
    link: LinkId,
    truth: SurfaceFrame,
    times: Vec<f64>,
    models: Vec<TorqueModel>,
    taus: Vec<Vec<f64>>,
    pushes: Vec<f64>,
    /// The truth's place walked 6 mm along its first tangent.
    start: MeshPoint,
}

fn press(ratio_along_tangents: [f64; 2], noise: f64, seed: u64) -> Press {
    let robot = builtin::lwr4plus_generated().unwrap();
    let link = robot.link_id("lwr_5_link").unwrap();
    let links = robot.default_candidate_links();
    let request = SurfaceRequest {
        links: links.clone(),
        total_points: 2000,
        seed: 0,
    };
    let surface = Surface::sample(&robot, &request).unwrap();
    let shape = surface.shape(link).unwrap();
    let k = (0..surface.len()).filter(|&k| surface.link[k] == link).nth(40).unwrap();
    let location = surface.location[k];
    let truth = shape.frame(location).unwrap();
    let ratio = truth.tangents[0] * ratio_along_tangents[0] + truth.tangents[1] * ratio_along_tangents[1];
    let mut rng = Rng::new(seed);
    let phases: Vec<f64> = (0..7).map(|_| rng.uniform_in(0.0, std::f64::consts::TAU)).collect();
    let (mut times, mut models, mut taus, mut pushes) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for i in 0..60 {
        let t = f64::from(i) / 50.0;
        let q: Vec<f64> = phases
            .iter()
            .enumerate()
            .map(|(j, phase)| 0.4 - 0.1 * j as f64 + 0.3 * (std::f64::consts::TAU * 0.5 * t + phase).sin())
            .collect();
        let pose = RobotPose::new(&robot, &robot.joint_positions(&q, &[]).unwrap());
        let model = TorqueModel::new(&robot, &pose, &links);
        let push = 10.0 + 5.0 * (std::f64::consts::TAU * t).sin();
        let force = (truth.inward_normal + ratio) * push;
        let tau = model
            .torques(link, truth.point, force)
            .iter()
            .map(|x| x + noise * rng.normal())
            .collect();
        times.push(t);
        models.push(model);
        taus.push(tau);
        pushes.push(push);
    }
    let start = shape.walk(location, truth.tangents[0] * 0.006);
    Press {
        surface,
        link,
        truth,
        times,
        models,
        taus,
        pushes,
        start,
    }
}

const WEIGHTS: [f64; 7] = [400.0; 7];

fn settings(friction: f64) -> PressSettings<'static> {
    PressSettings {
        weights: &WEIGHTS,
        force_range_newtons: (1.0, 30.0),
        friction,
        slide_m_per_sqrt_s: 0.003,
    }
}

fn press_frames(p: &Press) -> Vec<PressFrame<'_>> {
    (0..p.times.len())
        .map(|i| PressFrame {
            t_secs: p.times[i],
            torque_model: &p.models[i],
            tau: &p.taus[i],
            start: p.start,
        })
        .collect()
}

/// A press dragging sideways with a tangential force of 18 % of the
/// push (fixed in the link's frame) is found where it is, with its
/// tangential force; the frictionless search over the same press ends
/// where the normal leans along the whole force, a centimetre away.
/// Measured: 1.5 mm (0.65 mm without noise: the prior on γ shrinks it
/// a little), force 0.11 N, γ within 0.05, frictionless 10.9 mm.
#[test]
fn a_dragging_press_is_found_with_its_tangential_force() {
    let p = press([0.15, -0.1], 0.05, 3);
    let shape = p.surface.shape(p.link).unwrap();
    let frames = press_frames(&p);
    let settings = settings(0.1);
    let fit = fit_press(shape, p.link, &frames, &settings).unwrap();
    let place: Vec<f64> = fit
        .contacts
        .iter()
        .map(|c| c.point_in_link.distance(p.truth.point))
        .collect();
    let force: Vec<f64> = fit
        .contacts
        .iter()
        .zip(&p.pushes)
        .map(|(c, &push)| {
            let truth = (p.truth.inward_normal + p.truth.tangents[0] * 0.15 - p.truth.tangents[1] * 0.1) * push;
            (c.inward_normal_in_link * c.force_newtons + c.tangential_in_link).distance(truth)
        })
        .collect();
    let ratio = p.truth.tangents[0] * 0.15 - p.truth.tangents[1] * 0.1;
    let problem = Problem {
        shape,
        link: p.link,
        frames: &frames,
        settings: &settings,
    };
    let plain = problem
        .descend(frames.iter().map(|f| f.start).collect(), false)
        .unwrap();
    let plain_place: Vec<f64> = plain
        .normal
        .surface
        .iter()
        .map(|s| s.point.distance(p.truth.point))
        .collect();
    let (place, force, plain_place) = (
        percentile(&place, 0.5),
        percentile(&force, 0.5),
        percentile(&plain_place, 0.5),
    );
    eprintln!(
        "place {:.2} mm (frictionless {:.1} mm), force {force:.3} N, γ {:?} (true {ratio:?}), gain {:.0}",
        place * 1e3,
        plain_place * 1e3,
        fit.tangential_ratio_in_link,
        fit.gain
    );
    assert!(place < 2.5e-3, "{place}");
    assert!(force < 0.3, "{force}");
    let ratio_error = along_surface(fit.tangential_ratio_in_link, p.truth.inward_normal).distance(ratio);
    assert!(ratio_error < 0.08, "{ratio_error}");
    assert!(plain_place > 3.0 * place && plain_place > 3e-3, "{plain_place}");
    assert!(fit.gain > FRICTION_GAIN);
}

/// `explain_press` hands over what `fit_press` keeps, and otherwise the
/// frictionless fit with its cost, so that fits from other starts can
/// be weighed against it: the friction model's cost is the
/// frictionless one less the gain, and without a friction setting the
/// answer is frictionless with no gain.
#[test]
fn a_press_is_explained_with_its_cost() {
    let p = press([0.15, -0.1], 0.05, 3);
    let shape = p.surface.shape(p.link).unwrap();
    let frames = press_frames(&p);
    let answer = explain_press(shape, p.link, &frames, &settings(0.1)).unwrap();
    let fit = fit_press(shape, p.link, &frames, &settings(0.1)).unwrap();
    assert!(answer.friction);
    assert_eq!(answer.contacts, fit.contacts);
    assert!((answer.gain - fit.gain).abs() < 1e-9);
    let plain = explain_press(shape, p.link, &frames, &settings(0.0)).unwrap();
    assert!(!plain.friction && plain.gain.abs() < 1e-15);
    assert_eq!(plain.tangential_ratio_in_link, DVec3::ZERO);
    assert!(
        (plain.cost - answer.cost - answer.gain).abs() < 1e-6 * plain.cost,
        "{plain:?}"
    );
    // The residuals are the cost less the slide (and γ's prior).
    let residuals: f64 = plain.contacts.iter().map(|c| c.residual_chi2).sum();
    assert!(residuals <= plain.cost && residuals > 0.5 * plain.cost);
    let straight = press([0.0, 0.0], 0.05, 0);
    let frames = press_frames(&straight);
    let shape = straight.surface.shape(straight.link).unwrap();
    let kept = explain_press(shape, straight.link, &frames, &settings(0.1)).unwrap();
    assert!(!kept.friction);
    assert!(explain_press(shape, straight.link, &[], &settings(0.1)).is_none());
}

/// γ = 0 is the frictionless answer, so the friction model never
/// explains a press worse: where its search from the recording's
/// places ends in a costlier valley, it searches again from where the
/// frictionless search ended. Starts walked 2–8 cm from the press, in
/// eight directions, on presses dragging up to 40 % of the push.
#[test]
fn friction_never_explains_a_press_worse_than_none() {
    let mut worst = f64::INFINITY;
    for (seed, ratio) in [(1, [0.3, 0.2]), (2, [-0.4, 0.1]), (4, [0.0, 0.35])] {
        let p = press(ratio, 0.05, seed);
        let shape = p.surface.shape(p.link).unwrap();
        let truth = p.truth;
        for step in 0..8 {
            let angle = std::f64::consts::TAU * f64::from(step) / 8.0;
            let distance = 0.02 + 0.02 * f64::from(step % 4);
            let direction = truth.tangents[0] * angle.cos() + truth.tangents[1] * angle.sin();
            let start = shape.walk(p.start, direction * distance);
            let frames: Vec<PressFrame> = press_frames(&p)
                .into_iter()
                .map(|f| PressFrame { start, ..f })
                .collect();
            let answer = explain_press(shape, p.link, &frames, &settings(0.2)).unwrap();
            worst = worst.min(answer.gain);
        }
    }
    assert!(
        worst >= -1e-6,
        "a friction fit costlier than the frictionless one by {}",
        -worst
    );
}

/// A press without a tangential force keeps its frictionless estimate:
/// the friction model gains no more than noise.
#[test]
fn a_straight_press_is_left_alone() {
    for seed in 0..3 {
        let p = press([0.0, 0.0], 0.05, seed);
        let shape = p.surface.shape(p.link).unwrap();
        let frames = press_frames(&p);
        assert_eq!(fit_press(shape, p.link, &frames, &settings(0.1)), None, "seed {seed}");
        let problem = Problem {
            shape,
            link: p.link,
            frames: &frames,
            settings: &settings(0.1),
        };
        let start: Vec<MeshPoint> = frames.iter().map(|f| f.start).collect();
        let plain = problem.descend(start.clone(), false).unwrap();
        let frictional = problem.descend(start, true).unwrap();
        let gain = plain.normal.cost - frictional.normal.cost;
        eprintln!("seed {seed}: gain {gain:.2}");
        assert!((0.0..10.0).contains(&gain), "{gain}");
    }
}

/// The normal equations' right-hand sides are minus half the cost's
/// gradient (central differences: moving one frame's place along each
/// tangent, and γ along each axis; at γ = 0, where the place's columns
/// are exact), and γ's block is half its curvature where the model
/// fits exactly (there Gauss–Newton's curvature is the cost's).
#[test]
fn the_normal_equations_are_the_costs_derivatives() {
    let p = press([0.15, -0.1], 0.05, 5);
    let shape = p.surface.shape(p.link).unwrap();
    let frames = press_frames(&p);
    let settings = settings(0.1);
    let problem = Problem {
        shape,
        link: p.link,
        frames: &frames,
        settings: &settings,
    };
    // Places that differ from frame to frame, so that the slide's
    // terms count too.
    let at: Vec<MeshPoint> = frames
        .iter()
        .enumerate()
        .map(|(t, f)| shape.walk(f.start, p.truth.tangents[1] * (0.001 * (t as f64).sin())))
        .collect();
    let normal = problem.normal_at(&at, DVec3::ZERO, true).unwrap();
    let h = 1e-6;
    for t in [0, 17, 59] {
        for i in 0..2 {
            let cost = |sign: f64| {
                let mut moved = at.clone();
                moved[t] = shape.walk(at[t], normal.surface[t].tangents[i] * (sign * h));
                problem.normal_at(&moved, DVec3::ZERO, true).unwrap().cost
            };
            let slope = (cost(1.0) - cost(-1.0)) / (2.0 * h);
            let rhs = normal.rhs_places[t][i];
            assert!(
                (rhs + 0.5 * slope).abs() < 1e-4 * slope.abs().max(1.0),
                "frame {t}, tangent {i}: {rhs} vs {slope}"
            );
        }
    }
    for (axis, rhs) in [DVec3::X, DVec3::Y, DVec3::Z]
        .into_iter()
        .zip(normal.rhs_ratio.to_array())
    {
        let cost = |sign: f64| problem.normal_at(&at, axis * (sign * h), true).unwrap().cost;
        let slope = (cost(1.0) - cost(-1.0)) / (2.0 * h);
        assert!(
            (rhs + 0.5 * slope).abs() < 1e-4 * slope.abs().max(1.0),
            "{axis}: {rhs} vs {slope}"
        );
    }
    // Where the model fits exactly (noise-free, at the truth) the
    // Gauss–Newton curvature is the cost's.
    let exact = press([0.15, -0.1], 0.0, 5);
    let exact_frames = press_frames(&exact);
    let problem = Problem {
        shape,
        link: exact.link,
        frames: &exact_frames,
        settings: &settings,
    };
    let at = vec![shape.walk(exact.start, exact.truth.tangents[0] * -0.006); exact_frames.len()];
    let ratio = exact.truth.tangents[0] * 0.15 - exact.truth.tangents[1] * 0.1;
    let normal = problem.normal_at(&at, ratio, true).unwrap();
    let h = 1e-4;
    for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
        let cost = |sign: f64| problem.normal_at(&at, ratio + axis * (sign * h), true).unwrap().cost;
        let curvature = (cost(1.0) - 2.0 * normal.cost + cost(-1.0)) / (h * h);
        let diagonal = normal.corner.mul_vec3(axis).dot(axis);
        assert!(
            (diagonal - 0.5 * curvature).abs() < 1e-2 * diagonal,
            "{axis}: {diagonal} vs {curvature}"
        );
    }
}

/// The chain's block elimination against a dense elimination of the
/// same matrix.
#[test]
fn the_chain_solves_as_a_dense_elimination() {
    let mut rng = Rng::new(11);
    let n = 6;
    let lower: Vec<DMat2> = (0..n)
        .map(|t| {
            if t == 0 {
                DMat2::ZERO
            } else {
                DMat2::from_cols_array(&std::array::from_fn(|_| rng.uniform_in(-1.0, 1.0)))
            }
        })
        .collect();
    let diagonal: Vec<DMat2> = (0..n)
        .map(|_| {
            let a = DMat2::from_cols_array(&std::array::from_fn(|_| rng.uniform_in(-1.0, 1.0)));
            a * a.transpose() + DMat2::IDENTITY * 5.0
        })
        .collect();
    let rhs: Vec<DVec2> = (0..n).map(|_| DVec2::new(rng.normal(), rng.normal())).collect();
    let x = Chain::factor(&diagonal, &lower).unwrap().solve(&rhs);
    let inverse = inverted(dense(&diagonal, &lower, None));
    for t in 0..n {
        for i in 0..2 {
            let dense: f64 = (0..n)
                .map(|s| inverse[2 * t + i][2 * s] * rhs[s].x + inverse[2 * t + i][2 * s + 1] * rhs[s].y)
                .sum();
            assert!((x[t][i] - dense).abs() < 1e-10, "{t} {i}: {} vs {dense}", x[t][i]);
        }
    }
}

/// The symmetric matrix of diagonal blocks `diagonal`, sub-diagonal
/// blocks `lower` and, when given, the border `(B, C)` (γ's rows and
/// columns last), as dense rows: row `2t + i` is frame t's tangent i.
fn dense(diagonal: &[DMat2], lower: &[DMat2], border: Option<(&[[DVec2; 3]], DMat3)>) -> Vec<Vec<f64>> {
    let frames = diagonal.len();
    let size = 2 * frames + if border.is_some() { 3 } else { 0 };
    let mut m = vec![vec![0.0; size]; size];
    for t in 0..frames {
        for (i, j) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
            m[2 * t + i][2 * t + j] = diagonal[t].col(j)[i];
            if t > 0 {
                m[2 * t + i][2 * (t - 1) + j] = lower[t].col(j)[i];
                m[2 * (t - 1) + j][2 * t + i] = lower[t].col(j)[i];
            }
        }
    }
    if let Some((columns, corner)) = border {
        for (t, b) in columns.iter().enumerate() {
            for (k, b) in b.iter().enumerate() {
                for i in 0..2 {
                    m[2 * t + i][2 * frames + k] = b[i];
                    m[2 * frames + k][2 * t + i] = b[i];
                }
            }
        }
        for k in 0..3 {
            for l in 0..3 {
                m[2 * frames + k][2 * frames + l] = corner.col(l)[k];
            }
        }
    }
    m
}

/// The inverse of `m` by Gauss–Jordan elimination with partial pivoting.
fn inverted(mut m: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
    let size = m.len();
    let mut inverse: Vec<Vec<f64>> = (0..size)
        .map(|i| (0..size).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
        .collect();
    for c in 0..size {
        let pivot = (c..size)
            .max_by(|&x, &y| m[x][c].abs().total_cmp(&m[y][c].abs()))
            .unwrap();
        m.swap(c, pivot);
        inverse.swap(c, pivot);
        let p = m[c][c];
        assert!(p.abs() > 1e-12, "singular");
        for j in 0..size {
            m[c][j] /= p;
            inverse[c][j] /= p;
        }
        for r in 0..size {
            if r != c {
                let factor = m[r][c];
                for j in 0..size {
                    m[r][j] -= factor * m[c][j];
                    inverse[r][j] -= factor * inverse[c][j];
                }
            }
        }
    }
    inverse
}

/// Nothing to fit, or nothing to fit with: no fit and no panic. Torques
/// of zero, frames at one instant, μ of 0 or not finite, no frames.
#[test]
fn hard_presses_give_no_fit_or_a_finite_one() {
    let p = press([0.15, -0.1], 0.05, 1);
    let shape = p.surface.shape(p.link).unwrap();
    let zeros = vec![0.0; 7];
    let mut frames = press_frames(&p);
    assert_eq!(fit_press(shape, p.link, &[], &settings(0.1)), None);
    assert_eq!(fit_press(shape, p.link, &frames, &settings(0.0)), None);
    assert_eq!(fit_press(shape, p.link, &frames, &settings(f64::NAN)), None);
    for f in &mut frames {
        f.t_secs = 1.0;
    }
    if let Some(fit) = fit_press(shape, p.link, &frames, &settings(0.1)) {
        assert!(
            fit.contacts
                .iter()
                .all(|c| c.point_in_link.is_finite() && c.force_newtons.is_finite())
        );
    }
    for f in &mut frames {
        f.tau = &zeros;
    }
    assert_eq!(fit_press(shape, p.link, &frames, &settings(0.1)), None);
}

/// A force range that is empty or NaN, a weight that is negative or not
/// finite, or a time that is not finite gives no fit, with and without
/// friction, rather than a panic (the push is clamped to the range) or
/// a NaN (`fuzz/fuzz_targets/press.rs` found the empty range).
#[test]
fn degenerate_settings_and_times_give_no_fit() {
    let p = press([0.15, -0.1], 0.05, 1);
    let shape = p.surface.shape(p.link).unwrap();
    let frames = press_frames(&p);
    for friction in [0.0, 0.2] {
        assert!(explain_press(shape, p.link, &frames, &settings(friction)).is_some());
        let narrow = 1.398_043_286_095_352_4e-76;
        for range in [
            (narrow, narrow * (1.0 - 1e-13)),
            (5.0, 1.0),
            (f64::NAN, 30.0),
            (1.0, f64::NAN),
            (-1.0, 30.0),
        ] {
            let settings = PressSettings {
                force_range_newtons: range,
                ..settings(friction)
            };
            assert_eq!(explain_press(shape, p.link, &frames, &settings), None, "{range:?}");
        }
        for bad in [-1.0, f64::NAN, f64::INFINITY] {
            let mut weights = WEIGHTS;
            weights[3] = bad;
            let settings = PressSettings {
                weights: &weights,
                ..settings(friction)
            };
            assert_eq!(explain_press(shape, p.link, &frames, &settings), None, "{bad}");
        }
        for bad in [f64::NAN, f64::NEG_INFINITY] {
            let mut frames = press_frames(&p);
            frames[7].t_secs = bad;
            assert_eq!(
                explain_press(shape, p.link, &frames, &settings(friction)),
                None,
                "{bad}"
            );
        }
    }
}

/// The place covariances are the diagonal blocks of the inverse of
/// the whole bordered system (checked against a dense inverse by
/// Gauss–Jordan elimination), with γ marginalised and without.
#[test]
fn place_covariances_are_the_inverse_s_diagonal_blocks() {
    let mut rng = Rng::new(3);
    let frames = 7;
    let mut sym = |scale: f64| {
        let (a, b, c) = (
            rng.uniform_in(-1.0, 1.0),
            rng.uniform_in(-1.0, 1.0),
            rng.uniform_in(-1.0, 1.0),
        );
        DMat2::from_cols(DVec2::new(a, b), DVec2::new(b, c)) * scale
    };
    let diagonal: Vec<DMat2> = (0..frames).map(|_| sym(1.0) + DMat2::IDENTITY * 6.0).collect();
    let lower: Vec<DMat2> = (0..frames)
        .map(|t| if t == 0 { DMat2::ZERO } else { sym(1.5) })
        .collect();
    let border: Vec<[DVec2; 3]> = (0..frames)
        .map(|_| std::array::from_fn(|_| DVec2::new(rng.uniform_in(-0.5, 0.5), rng.uniform_in(-0.5, 0.5))))
        .collect();
    let corner = DMat3::IDENTITY * 9.0 + DMat3::from_cols(DVec3::X, DVec3::Y, DVec3::ONE) * 0.1;
    let corner = (corner + corner.transpose()) * 0.5;
    let normal = Normal {
        cost: 0.0,
        held_still_normalizer: 0.0,
        surface: Vec::new(),
        magnitudes: Vec::new(),
        residuals: Vec::new(),
        diagonal: diagonal.clone(),
        lower: lower.clone(),
        border: border.clone(),
        corner,
        rhs_places: vec![DVec2::ZERO; frames],
        rhs_ratio: DVec3::ZERO,
    };
    for ratio_free in [false, true] {
        let inverse = inverted(dense(
            &diagonal,
            &lower,
            ratio_free.then_some((border.as_slice(), corner)),
        ));
        let covariances = covariances(&normal, ratio_free).unwrap();
        for (t, c) in covariances.iter().enumerate() {
            for (i, j) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                let expected = inverse[2 * t + i][2 * t + j];
                assert!(
                    (c.col(j)[i] - expected).abs() < 1e-12,
                    "frame {t} ({i},{j}): {} vs {expected}",
                    c.col(j)[i]
                );
            }
        }
    }
}
