//! Tests of [`super`]: `cover.rs`.

use super::*;
use crate::core::numerics::rng::Rng;
use crate::core::robot::builtin;
use crate::core::robot::kinematics::RobotPose;
use crate::core::surface::sampling::{Surface, SurfaceRequest};

/// Against the primitives' exact distance functions at seeded poses: the
/// samples whose outside (1 mm out) lies inside the link across one joint
/// are the ones the table calls covered, but for those within a bin's
/// turn of the edge and the facets' chord error.
#[test]
fn covered_samples_match_the_primitives_at_random_poses() {
    let robot = builtin::lwr4plus_generated().unwrap();
    let links = robot.default_candidate_links();
    let surface = Surface::sample(
        &robot,
        &SurfaceRequest {
            links,
            total_points: 2000,
            seed: 11,
        },
    )
    .unwrap();
    let table = CoverTable::build(
        &robot,
        &surface.link,
        &surface.point_in_link,
        &surface.inward_normal_in_link,
    );
    assert!(table.tabled() > 0);
    let shapes = builtin::lwr4plus_primitives();
    let inside = |link: LinkId, p: DVec3| {
        builtin::primitives_signed_distance(&shapes, &robot.links[link].name, p).is_some_and(|d| d < 0.0)
    };
    let mut rng = Rng::new(4);
    let (mut agree, mut differ, mut covered_total) = (0, 0, 0);
    for _ in 0..4 {
        let q: Vec<f64> = robot
            .joints
            .iter()
            .map(|j| match j.limits {
                Some(l) if j.kind.is_rotational() => rng.uniform_in(l.lower, l.upper),
                _ => 0.0,
            })
            .collect();
        let pose = RobotPose::new(&robot, &q);
        let covered = table.covered_at(&q);
        covered_total += covered.len();
        for k in 0..surface.len() {
            let on = surface.link[k];
            let outside = surface.point_in_link[k] - surface.inward_normal_in_link[k] * COVER_PROBE_M;
            let world = pose.world_from_link[on].transform_point3(outside);
            let direct = robot
                .joints
                .iter()
                .filter(|j| j.kind.is_rotational())
                .filter_map(|j| {
                    if j.child == on {
                        Some(j.parent)
                    } else if j.parent == on {
                        Some(j.child)
                    } else {
                        None
                    }
                })
                .any(|n| inside(n, pose.world_from_link[n].inverse().transform_point3(world)));
            let tabled = covered.binary_search(&(k as u32)).is_ok();
            if direct == tabled {
                agree += 1;
            } else {
                differ += 1;
            }
        }
    }
    assert!(
        covered_total > 200,
        "the joints must cover some samples: {covered_total}"
    );
    assert!(
        differ * 20 < covered_total,
        "{differ} samples differ from the primitives ({agree} agree; {covered_total} covered)"
    );
}

#[test]
fn a_bin_follows_the_joint_angle_and_out_of_range_angles_take_the_end_bins() {
    let table = CoverTable {
        entries: vec![
            CoverEntry {
                sample: 3,
                joint: 1,
                bins: 1 << 10,
            },
            CoverEntry {
                sample: 3,
                joint: 2,
                bins: 1,
            },
            CoverEntry {
                sample: 7,
                joint: 1,
                bins: 1 << (COVER_BINS - 1),
            },
        ],
        ranges: vec![
            BinRange {
                joint: 1,
                lower_rad: -1.0,
                bin_width_rad: 2.0 / COVER_BINS as f64,
            },
            BinRange {
                joint: 2,
                lower_rad: 0.0,
                bin_width_rad: 1.0 / COVER_BINS as f64,
            },
        ],
    };
    let width = 2.0 / COVER_BINS as f64;
    let in_bin_10 = -1.0 + 10.5 * width;
    assert_eq!(table.covered_at(&[0.0, in_bin_10, 0.5]), vec![3]);
    // Sample 3 is listed once though both of its neighbours cover it.
    assert_eq!(table.covered_at(&[0.0, in_bin_10, -4.0]), vec![3]);
    assert_eq!(table.covered_at(&[0.0, 5.0, 0.5]), vec![7]);
    assert_eq!(table.covered_at(&[0.0, 0.0, 0.5]), Vec::<u32>::new());
    assert_eq!(table.covered_at(&[0.0, f64::NAN, f64::NAN]), Vec::<u32>::new());
}

#[test]
fn bins_tested_a_stride_apart_find_every_interval_a_stride_long() {
    let direct = |f: &dyn Fn(usize) -> bool| (0..COVER_BINS).filter(|&b| f(b)).fold(0_u64, |m, b| m | 1 << b);
    for start in 0..COVER_BINS {
        for len in COVER_STRIDE..=COVER_BINS - start {
            let inside = |b: usize| b >= start && b < start + len;
            assert_eq!(covered_bins(inside), direct(&inside), "bins {start}..{}", start + len);
            let outside = |b: usize| !inside(b);
            assert_eq!(
                covered_bins(outside),
                direct(&outside),
                "all but {start}..{}",
                start + len
            );
        }
    }
    assert_eq!(covered_bins(|_| true), u64::MAX);
    assert_eq!(covered_bins(|_| false), 0);
}
