//! Turns the posed robot, the posterior and the pushes into plain vertex
//! lists for the renderer.

use glam::{DVec3, Vec3};

use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{LinkId, Robot};
use crate::render::renderer::{LineVertex, MeshVertex};

pub use crate::core::paint::colours::{ROBOT_GREY, red_green, viridis};
pub use crate::core::paint::vertices::{VertexSamples, nearest_samples};

/// The posed robot as lit triangles; `color(link, vertex)` colours each
/// mesh vertex.
pub fn robot_triangles(
    robot: &Robot,
    pose: &RobotPose,
    color: &dyn Fn(LinkId, usize) -> [f32; 4],
    out: &mut Vec<MeshVertex>,
) {
    for (link, l) in robot.links.iter().enumerate() {
        let frame = pose.world_from_link[link];
        for t in &l.mesh.triangles {
            let Some(c) = l.mesh.corners_of(t) else { continue };
            let world = c.map(|p| frame.transform_point3(p));
            let normal = (world[1] - world[0])
                .cross(world[2] - world[0])
                .normalize_or_zero()
                .as_vec3()
                .to_array();
            for (k, w) in world.iter().enumerate() {
                out.push(MeshVertex {
                    position: w.as_vec3().to_array(),
                    normal,
                    color: color(link, t[k] as usize),
                });
            }
        }
    }
}

/// A ground grid in the xy plane and the base axes (x red, y green, z blue).
pub fn grid_and_axes(half_size_m: f32, step_m: f32, out: &mut Vec<LineVertex>) {
    let grey = [0.42, 0.43, 0.45, 1.0];
    let steps = (half_size_m / step_m).round() as i32;
    for i in -steps..=steps {
        let x = i as f32 * step_m;
        line(
            out,
            Vec3::new(x, -half_size_m, 0.0),
            Vec3::new(x, half_size_m, 0.0),
            grey,
        );
        line(
            out,
            Vec3::new(-half_size_m, x, 0.0),
            Vec3::new(half_size_m, x, 0.0),
            grey,
        );
    }
    line(out, Vec3::ZERO, Vec3::new(0.3, 0.0, 0.0), [0.9, 0.2, 0.2, 1.0]);
    line(out, Vec3::ZERO, Vec3::new(0.0, 0.3, 0.0), [0.2, 0.8, 0.2, 1.0]);
    line(out, Vec3::ZERO, Vec3::new(0.0, 0.0, 0.3), [0.3, 0.4, 1.0, 1.0]);
}

/// An arrow whose tip touches `tip` (a push arrives at the surface),
/// `length_m` long along `direction`.
pub fn arrow(out: &mut Vec<LineVertex>, tip: DVec3, direction: DVec3, length_m: f64, color: [f32; 4]) {
    let Some(d) = direction.try_normalize() else { return };
    let tail = tip - d * length_m;
    let (u, v) = d.any_orthonormal_pair();
    let head = 0.2 * length_m.min(0.15);
    line(out, tail.as_vec3(), tip.as_vec3(), color);
    for side in [u, -u, v, -v] {
        line(
            out,
            tip.as_vec3(),
            (tip - d * head + side * head * 0.5).as_vec3(),
            color,
        );
    }
}

/// A line segment.
pub fn line(out: &mut Vec<LineVertex>, a: Vec3, b: Vec3, color: [f32; 4]) {
    out.push(LineVertex {
        position: a.to_array(),
        color,
    });
    out.push(LineVertex {
        position: b.to_array(),
        color,
    });
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::robot::builtin;
    use crate::core::surface::sampling::{Surface, SurfaceRequest};

    #[test]
    fn viridis_runs_from_purple_to_yellow() {
        let lo = viridis(0.0);
        let hi = viridis(1.0);
        assert!(lo[2] > lo[1] && hi[0] > 0.9 && hi[1] > 0.9 && hi[2] < 0.2);
        let same = |a: [f32; 4], b: [f32; 4]| a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-7);
        assert!(same(viridis(-1.0), lo));
        assert!(same(viridis(2.0), hi));
    }

    #[test]
    fn robot_triangles_cover_every_mesh_triangle_and_follow_the_pose() {
        let robot = builtin::lwr4plus_generated().unwrap();
        let pose = RobotPose::new(&robot, &[0.0; 7]);
        let mut out = Vec::new();
        robot_triangles(&robot, &pose, &|_, _| ROBOT_GREY, &mut out);
        let total: usize = robot.links.iter().map(|l| l.mesh.triangles.len()).sum();
        assert_eq!(out.len(), 3 * total);
        let top = out.iter().map(|v| v.position[2]).fold(f32::MIN, f32::max);
        // The flange's top face is at 1.1785 m with the arm upright.
        assert!((top - 1.1785).abs() < 1e-3, "{top}");
    }

    #[test]
    fn every_vertex_of_a_candidate_link_gets_a_nearby_sample() {
        let robot = builtin::lwr4plus_generated().unwrap();
        let links = robot.default_candidate_links();
        let surface = Surface::sample(
            &robot,
            &SurfaceRequest {
                links,
                total_points: 2000,
                seed: 0,
            },
        )
        .unwrap();
        let nearest = nearest_samples(&robot, &surface);
        let l5 = robot.link_id("lwr_5_link").unwrap();
        for (v, weights) in robot.links[l5].mesh.positions.iter().zip(&nearest[l5]) {
            assert!(!weights.is_empty() && weights.len() <= 3);
            assert!((weights.iter().map(|(_, w)| w).sum::<f64>() - 1.0).abs() < 1e-12);
            let (k, _) = weights[0];
            assert_eq!(surface.link[k], l5);
            // Buried vertices may sit a few centimetres from exposed samples.
            assert!(surface.point_in_link[k].distance(*v) < 0.08);
            // The nearest sample weighs most.
            assert!(weights.iter().all(|(_, w)| *w <= weights[0].1 + 1e-12));
        }
        assert!(nearest[0].iter().all(Vec::is_empty), "the base is no candidate");
    }
}
