//! Tests of [`super`]: `sampling.rs`.

use super::*;
use crate::core::geometry::primitives::{self, Primitive};
use crate::core::robot::builtin;
use crate::core::robot::model::{JointKind, JointSpec, LinkSpec};
use glam::DAffine3;

fn one_link_robot(mesh: TriMesh) -> Robot {
    Robot::new(
        "one",
        &[
            LinkSpec {
                name: "base".to_owned(),
                ..LinkSpec::default()
            },
            LinkSpec {
                name: "body".to_owned(),
                mesh,
                segment: None,
                ..LinkSpec::default()
            },
        ],
        &[JointSpec {
            name: "j".to_owned(),
            kind: JointKind::Continuous,
            parent: "base".to_owned(),
            child: "body".to_owned(),
            parent_from_joint: DAffine3::IDENTITY,
            axis: DVec3::Z,
            limits: None,
            mimic: None,
        }],
    )
    .unwrap()
}

#[test]
fn area_weights_sum_to_the_closed_form_area_of_a_box() {
    let size = DVec3::new(0.1, 0.2, 0.3);
    let robot = one_link_robot(primitives::cuboid(size));
    let s = Surface::sample(
        &robot,
        &SurfaceRequest {
            links: vec![1],
            total_points: 500,
            seed: 3,
        },
    )
    .unwrap();
    let exact = 2.0 * (size.x * size.y + size.y * size.z + size.z * size.x);
    let sum: f64 = s.area_m2.iter().sum();
    assert_eq!(s.len(), 500);
    assert!((sum - exact).abs() <= 1e-9 * exact, "{sum} vs {exact}");
}

#[test]
fn inward_normals_of_a_box_point_inside_it() {
    let half = DVec3::new(0.05, 0.1, 0.15);
    let robot = one_link_robot(primitives::cuboid(2.0 * half));
    let s = Surface::sample(
        &robot,
        &SurfaceRequest {
            links: vec![1],
            total_points: 300,
            seed: 1,
        },
    )
    .unwrap();
    for (p, n) in s.point_in_link.iter().zip(&s.inward_normal_in_link) {
        let q = *p + *n * 1e-3;
        assert!(q.abs().cmple(half).all(), "{p} + 1 mm {n} is outside");
        assert!((n.length() - 1.0).abs() < 1e-12);
    }
}

#[test]
fn inward_wound_mesh_gives_the_same_normals() {
    let mut flipped = primitives::cuboid(DVec3::ONE);
    for t in &mut flipped.triangles {
        t.swap(1, 2);
    }
    let a = Surface::sample(
        &one_link_robot(primitives::cuboid(DVec3::ONE)),
        &SurfaceRequest {
            links: vec![1],
            total_points: 50,
            seed: 9,
        },
    )
    .unwrap();
    let b = Surface::sample(
        &one_link_robot(flipped),
        &SurfaceRequest {
            links: vec![1],
            total_points: 50,
            seed: 9,
        },
    )
    .unwrap();
    for (na, nb) in a.inward_normal_in_link.iter().zip(&b.inward_normal_in_link) {
        assert!((*na - *nb).length() < 1e-12);
    }
}

#[test]
fn sampling_is_deterministic_per_seed() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let req = SurfaceRequest {
        links,
        total_points: 700,
        seed: 42,
    };
    let a = Surface::sample(&robot, &req).unwrap();
    let b = Surface::sample(&robot, &req).unwrap();
    assert_eq!(a, b);
    let c = Surface::sample(&robot, &SurfaceRequest { seed: 43, ..req }).unwrap();
    assert_ne!(a.point_in_link, c.point_in_link);
    assert_eq!(a.len(), 700);
}

/// Against the primitives' exact distance functions: every kept sample
/// lies on the union's surface, is not buried in another primitive, and
/// 1 mm along its inward normal is inside.
#[test]
fn builtin_lwr_samples_are_exposed_and_normals_point_inside() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    assert_eq!(links.len(), 7);
    let s = Surface::sample(
        &robot,
        &SurfaceRequest {
            links,
            total_points: 2000,
            seed: 5,
        },
    )
    .unwrap();
    let shapes = builtin::lwr4plus_primitives();
    let mut buried_total = 0;
    for st in &s.stats {
        buried_total += st.buried;
    }
    assert!(buried_total > 0, "the overlapping primitives must bury some candidates");
    for i in 0..s.len() {
        let name = &robot.links[s.link[i]].name;
        let union = |p: DVec3| builtin::primitives_signed_distance(&shapes, name, p).unwrap();
        let p = s.point_in_link[i];
        let n = s.inward_normal_in_link[i];
        // On the faceted surface: within the chord error of a 40-gon.
        assert!(union(p).abs() < 2e-3, "{name} {p}: {}", union(p));
        assert!(union(p - n * 1e-3) > 0.0, "{name} {p} is buried");
        assert!(union(p + n * 1e-3) < 0.0, "{name} {p}: 1 mm inward is outside");
    }
}

#[test]
fn samples_are_evenly_spread() {
    // On a unit sphere, nearest-neighbour distances of an even spread
    // vary little; pure random sampling has many near-coincident pairs.
    let robot = one_link_robot(
        Primitive::Sphere {
            center: DVec3::ZERO,
            radius: 1.0,
        }
        .mesh(64),
    );
    let s = Surface::sample(
        &robot,
        &SurfaceRequest {
            links: vec![1],
            total_points: 400,
            seed: 2,
        },
    )
    .unwrap();
    let nn: Vec<f64> = s
        .point_in_link
        .iter()
        .map(|p| {
            s.point_in_link
                .iter()
                .filter(|q| *q != p)
                .map(|q| p.distance(*q))
                .fold(f64::INFINITY, f64::min)
        })
        .collect();
    let mean = nn.iter().sum::<f64>() / nn.len() as f64;
    let min = nn.iter().copied().fold(f64::INFINITY, f64::min);
    assert!(min > 0.5 * mean, "min {min} mean {mean}");
}

#[test]
fn simple6_samples_lie_on_the_segments_with_perpendicular_normals() {
    let robot = builtin::simple6().unwrap();
    let links = robot.default_candidate_links();
    assert_eq!(links.len(), 6);
    let s = Surface::sample(
        &robot,
        &SurfaceRequest {
            links,
            total_points: 480,
            seed: 0,
        },
    )
    .unwrap();
    let total_length: f64 = s.area_m2.iter().sum();
    assert!((total_length - (5.0 + 2f64.sqrt())).abs() < 1e-9);
    for i in 0..s.len() {
        let [a, b] = robot.links[s.link[i]].segment.unwrap();
        let axis = (b - a).normalize();
        let rel = s.point_in_link[i] - a;
        assert!(rel.cross(axis).length() < 1e-12);
        assert!(s.inward_normal_in_link[i].dot(axis).abs() < 1e-12);
    }
}

#[test]
fn bad_requests_are_named() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let e = Surface::sample(
        &robot,
        &SurfaceRequest {
            links: vec![],
            total_points: 10,
            seed: 0,
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("no candidate links"));
    let e = Surface::sample(
        &robot,
        &SurfaceRequest {
            links: vec![1, 2],
            total_points: 1,
            seed: 0,
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("resolution"));
    let kin = builtin::lwr4plus_kinematics().unwrap();
    let e = Surface::sample(
        &kin,
        &SurfaceRequest {
            links: vec![1],
            total_points: 10,
            seed: 0,
        },
    )
    .unwrap_err();
    assert!(e.to_string().contains("lwr_1_link"));
}
