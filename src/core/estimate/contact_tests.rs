//! Tests of [`super`]: `contact.rs`.

use super::*;
use crate::core::robot::builtin;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::Robot;
use crate::core::robot::torque::joint_torques;
use crate::core::surface::sampling::SurfaceRequest;

/// The generated LWR, its candidate links, `points` samples of them
/// (surface seed `seed`) and one pose.
fn posed_lwr(points: usize, seed: u64) -> (Robot, Vec<usize>, Surface, RobotPose) {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let surface = Surface::sample(
        &robot,
        &SurfaceRequest {
            links: links.clone(),
            total_points: points,
            seed,
        },
    )
    .unwrap();
    let q = [0.4, -0.9, 0.2, 1.3, -0.6, 0.9, -2.0];
    let pose = RobotPose::new(&robot, &robot.joint_positions(&q, &[]).unwrap());
    (robot, links, surface, pose)
}

#[test]
fn unit_torques_match_the_direct_formula() {
    let (robot, links, surface, pose) = posed_lwr(300, 4);
    let model = ContactModel::new(&TorqueModel::new(&robot, &pose, &links), &surface);
    for k in (0..surface.len()).step_by(7) {
        let link = surface.link[k];
        let direct = joint_torques(
            &robot,
            &pose,
            link,
            pose.point_to_world(link, surface.point_in_link[k]),
            pose.world_from_link[link].transform_vector3(surface.inward_normal_in_link[k]),
        );
        let mut fused = vec![0.0; 7];
        PosedSurface {
            torque_model: &TorqueModel::new(&robot, &pose, &links),
            surface: &surface,
        }
        .unit_torques_into(k, &mut fused);
        for (j, d) in direct.iter().enumerate() {
            assert!((fused[j] - d).abs() < 1e-12);
            assert!(
                (model.unit_torque(j, k) - d).abs() < 1e-12,
                "point {k} joint {j}: {} vs {d}",
                model.unit_torque(j, k)
            );
        }
    }
    // The fused likelihood terms equal the stored model's.
    let (weights, tau) = (FORMS_WEIGHTS, FORMS_TAU);
    let (mut a1, mut b1, mut a2, mut b2) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    model.quadratic_forms(&weights, &tau, &mut a1, &mut b1);
    let tm = TorqueModel::new(&robot, &pose, &links);
    PosedSurface {
        torque_model: &tm,
        surface: &surface,
    }
    .quadratic_forms(&weights, &tau, &mut a2, &mut b2);
    for k in 0..surface.len() {
        assert!((a1[k] - a2[k]).abs() <= 1e-12 * a1[k].abs().max(1.0));
        assert!((b1[k] - b2[k]).abs() <= 1e-12 * b1[k].abs().max(1.0));
    }
}

/// Weights `1/σ²` per joint and torques the forms tests use.
const FORMS_WEIGHTS: [f64; 7] = [400.0, 100.0, 400.0, 25.0, 400.0, 100.0, 400.0];
const FORMS_TAU: [f64; 7] = [0.5, -1.2, 0.3, 0.8, -0.2, 0.1, 0.05];

/// A posed surface of 803 points of every candidate link and its
/// patch forms for [`FORMS_TAU`].
fn forms_setup() -> (Surface, TorqueModel, PatchForms) {
    let (robot, links, surface, pose) = posed_lwr(803, 9);
    let torque_model = TorqueModel::new(&robot, &pose, &links);
    let mut forms = PatchForms::default();
    let posed = PosedSurface {
        torque_model: &torque_model,
        surface: &surface,
    };
    assert!(posed.patch_forms(&FORMS_WEIGHTS, &FORMS_TAU, &mut forms));
    (surface, torque_model, forms)
}

fn column(c: &[Vec<f64>], k: usize) -> [f64; 6] {
    std::array::from_fn(|i| c[i][k])
}

fn forms_of(forms: &PatchForms, k: usize) -> [f64; 9] {
    [
        forms.a[k],
        forms.b[k],
        forms.h1[k],
        forms.h2[k],
        forms.e1[k],
        forms.e2[k],
        forms.g11[k],
        forms.g12[k],
        forms.g22[k],
    ]
}

/// Each point's patch forms against the sums over the joints written
/// out (an independent path: no triangular factor).
#[test]
fn patch_forms_match_the_sums_over_the_joints() {
    let (surface, torque_model, forms) = forms_setup();
    let (weights, tau) = (FORMS_WEIGHTS, FORMS_TAU);
    for k in 0..surface.len() {
        let lines = [
            column(&surface.push_lines, k),
            column(&surface.tangent_lines[..6], k),
            column(&surface.tangent_lines[6..], k),
        ];
        let mut sums = [0.0; 9];
        for t in torque_model.twists(surface.link[k]) {
            let j = t.sensed_index;
            let twist = [t.w.x, t.w.y, t.w.z, t.v.x, t.v.y, t.v.z];
            let [u, d1, d2] = lines.map(|l| twist.iter().zip(&l).map(|(x, y)| x * y).sum::<f64>());
            let w = weights[j];
            let terms = [
                u * u,
                u * tau[j],
                u * d1,
                u * d2,
                d1 * tau[j],
                d2 * tau[j],
                d1 * d1,
                d1 * d2,
                d2 * d2,
            ];
            for (s, x) in sums.iter_mut().zip(terms) {
                *s += w * x;
            }
        }
        let got = forms_of(&forms, k);
        for (name, (g, s)) in ["a", "b", "h1", "h2", "e1", "e2", "g11", "g12", "g22"]
            .iter()
            .zip(got.iter().zip(sums))
        {
            assert!((g - s).abs() <= 1e-9 * s.abs().max(1.0), "point {k} {name}: {g} vs {s}");
        }
    }
}

/// The points computed four at a time against the same code one at a
/// time, bit for bit (the lanes must not mix).
#[test]
fn patch_forms_in_lanes_are_those_of_each_point_alone() {
    fn alone<const N: usize>(r: &[[f64; 6]], beta: &[f64; 6], x: &[[[f64; 1]; 6]; 3]) -> [u64; 9] {
        let rows: [[f64; 6]; N] = std::array::from_fn(|i| r[i]);
        patch_forms_of::<N, 1>(&rows, beta, x).map(|[v]| v.to_bits())
    }
    let (surface, torque_model, forms) = forms_setup();
    let posed = PosedSurface {
        torque_model: &torque_model,
        surface: &surface,
    };
    let mut ranks = Vec::new();
    for (range, r, beta) in posed.link_factors(&FORMS_WEIGHTS, &FORMS_TAU) {
        ranks.push(r.len());
        for k in range {
            let x = [
                column(&surface.push_lines, k).map(|v| [v]),
                column(&surface.tangent_lines[..6], k).map(|v| [v]),
                column(&surface.tangent_lines[6..], k).map(|v| [v]),
            ];
            let bits = match r.len() {
                1 => alone::<1>(&r, &beta, &x),
                2 => alone::<2>(&r, &beta, &x),
                3 => alone::<3>(&r, &beta, &x),
                4 => alone::<4>(&r, &beta, &x),
                5 => alone::<5>(&r, &beta, &x),
                _ => alone::<6>(&r, &beta, &x),
            };
            let together = forms_of(&forms, k).map(f64::to_bits);
            assert_eq!(bits, together, "point {k}");
        }
    }
    // Links of several ranks, each with more points than one group of lanes.
    assert!(ranks.iter().any(|&n| n < 6) && ranks.contains(&6), "{ranks:?}");
}

#[test]
fn the_triangular_factor_keeps_every_squared_length() {
    use crate::core::numerics::rng::Rng;
    let mut rng = Rng::new(11);
    let mut random_row = || std::array::from_fn::<f64, 6, _>(|_| rng.uniform_in(-2.0, 2.0));
    let mut cases: Vec<Vec<[f64; 6]>> = (1..=8).map(|t| (0..t).map(|_| random_row()).collect()).collect();
    // Rank-deficient: repeated, zero and parallel rows.
    let r0 = random_row();
    cases.push(vec![r0, r0, [0.0; 6], r0.map(|x| -3.0 * x)]);
    cases.push(vec![[0.0; 6]; 3]);
    let mut check_rng = Rng::new(12);
    for rows in cases {
        let r = r_factor(&rows);
        assert_eq!(r.len(), rows.len().min(6));
        for (i, row) in r.iter().enumerate() {
            assert!(row[..i].iter().all(|x| *x == 0.0), "row {i} of {r:?}");
        }
        for _ in 0..20 {
            let l: [f64; 6] = std::array::from_fn(|_| check_rng.uniform_in(-1.0, 1.0));
            let dot = |row: &[f64; 6]| row.iter().zip(&l).map(|(x, y)| x * y).sum::<f64>();
            let direct: f64 = rows.iter().map(|row| dot(row).powi(2)).sum();
            let factored: f64 = r.iter().map(|row| dot(row).powi(2)).sum();
            assert!(
                (direct - factored).abs() <= 1e-12 * direct.max(1.0),
                "{direct} vs {factored}"
            );
        }
    }
}
