//! The shipped scenes: they load, and their pushes give the thesis' tables
//! and the hard cases' defining properties.

// Test helpers may unwrap: a panic is a failed test with its message.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use glam::DVec3;
use proprioscope::core::surface::sampling::{Surface, SurfaceRequest};
use proprioscope::io::scene::{LoadedScene, Scene};

fn scene_path(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("scenes")
        .join(format!("{name}.json"))
}

fn load(name: &str) -> LoadedScene {
    let path = scene_path(name);
    Scene::read(&path)
        .unwrap()
        .load(&path)
        .unwrap_or_else(|e| panic!("{e}"))
}

#[test]
fn every_shipped_scene_loads_with_a_push() {
    let folder = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenes");
    let mut count = 0;
    for entry in std::fs::read_dir(folder).unwrap() {
        let path = entry.unwrap().path();
        let loaded = Scene::read(&path)
            .unwrap()
            .load(&path)
            .unwrap_or_else(|e| panic!("{e}"));
        assert!(loaded.push.is_some(), "{}", path.display());
        assert!(loaded.push_torques().iter().all(|t| t.is_finite()));
        count += 1;
    }
    assert!(count >= 11);
}

/// Table 3.2 (N·m), exactly.
#[test]
fn simple_scenes_give_table_3_2() {
    let expected = [[1.0, -0.5, 0.0, 0.0, 0.0, 0.0], [0.0, 2.0, -1.5, 0.0, 1.0, -0.5]];
    for (k, row) in expected.iter().enumerate() {
        let tau = load(&format!("simple-collision-{}", k + 1)).push_torques();
        for (t, e) in tau.iter().zip(row) {
            assert!((t - e).abs() <= 1e-12, "collision {}: {tau:?}", k + 1);
        }
    }
}

/// Table 3.4 (N·cm, within 0.3 of the printed values).
#[test]
fn lwr_scenes_give_table_3_4_and_gazebo_scenes_four_times_it() {
    let expected = [
        [9.6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
        [0.0, 28.7, 0.0, 0.0, 0.0, 0.0, 0.0],
        [9.5, -53.6, 9.5, 1.0, 0.0, 0.0, 0.0],
    ];
    for (k, row) in expected.iter().enumerate() {
        let tau = load(&format!("lwr-collision-{}", k + 1)).push_torques();
        for (t, e) in tau.iter().zip(row) {
            assert!((t * 100.0 - e).abs() <= 0.3, "collision {}: {tau:?}", k + 1);
        }
        let gazebo = load(&format!("lwr-gazebo-{}", k + 1)).push_torques();
        for (g, t) in gazebo.iter().zip(&tau) {
            assert!((g - 4.0 * t).abs() < 1e-9, "gazebo {}: {gazebo:?}", k + 1);
        }
    }
}

/// Each thesis contact point lies within 2.5 cm of the exposed surface of
/// the link the thesis names.
#[test]
fn thesis_contact_points_lie_on_their_links() {
    for k in 1..=3 {
        let loaded = load(&format!("lwr-collision-{k}"));
        let push = loaded.push.unwrap();
        let surface = Surface::sample(
            &loaded.robot,
            &SurfaceRequest {
                links: vec![push.link],
                total_points: 4000,
                seed: 1,
            },
        )
        .unwrap();
        let nearest = (0..surface.len())
            .map(|i| surface.point_world(&loaded.pose, i).unwrap().distance(push.point_world))
            .fold(f64::INFINITY, f64::min);
        assert!(
            nearest < 0.025,
            "collision {k}: {nearest} m from {}",
            loaded.robot.links[push.link].name
        );
    }
}

#[test]
fn hard_cases_have_their_defining_property() {
    let scale = 1e-12;
    let tau = load("lwr-hard-through-axis2").push_torques();
    assert!(tau[1].abs() < scale && tau[0].abs() > 0.1, "{tau:?}");

    let tau = load("lwr-hard-link1").push_torques();
    assert!(tau[0].abs() > 0.1 && tau[1..].iter().all(|t| *t == 0.0), "{tau:?}");

    let loaded = load("lwr-hard-parallel-axis");
    let push = loaded.push.unwrap();
    assert!(
        (push.force_world.normalize() - DVec3::NEG_Z).length() < 1e-6,
        "{}",
        push.force_world
    );
    let tau = loaded.push_torques();
    for (i, t) in tau.iter().enumerate() {
        if i % 2 == 0 {
            assert!(t.abs() < 1e-6, "joint {}: {tau:?}", i + 1);
        } else {
            assert!(t.abs() > 0.1, "joint {}: {tau:?}", i + 1);
        }
    }
}

/// The two-as-one scene's two parallel pushes have exactly the torques of
/// one push of their sum at their centre of force (within the scene's
/// rounding of the force to 0.1 mN).
#[test]
fn two_parallel_pushes_have_the_torques_of_one_at_their_centre_of_force() {
    let loaded = load("lwr-two-as-one");
    let (a, b) = (loaded.push.unwrap(), loaded.second_push.unwrap());
    assert_eq!(a.link, b.link);
    assert!(a.force_world.normalize().dot(b.force_world.normalize()) > 1.0 - 1e-9);
    let (fa, fb) = (a.force_world.length(), b.force_world.length());
    let centre = (a.point_world * fa + b.point_world * fb) / (fa + fb);
    let one = proprioscope::core::robot::torque::joint_torques(
        &loaded.robot,
        &loaded.pose,
        a.link,
        centre,
        a.force_world + b.force_world,
    );
    let two = loaded.push_torques();
    assert!(two.iter().any(|t| t.abs() > 0.5), "{two:?}");
    for (x, y) in one.iter().zip(&two) {
        assert!((x - y).abs() < 1e-4, "{one:?} vs {two:?}");
    }
}
