//! Which link, and where on it, a ray from the camera meets: exact
//! triangle hits on the posed robot, for clicking a push onto the arm.

use glam::DVec3;

use crate::core::geometry::bvh::Bvh;
use crate::core::geometry::shell::{MeshPoint, SmoothMesh};
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{LinkId, Robot};

/// Per-link smooth shells and their BVHs in link frames, built once per
/// robot; a pose moves the ray into each link's frame instead of moving
/// the meshes.
#[derive(Debug, Clone)]
pub struct Picker {
    links: Vec<Option<(SmoothMesh, Bvh)>>,
}

/// Where a ray met the robot.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pick {
    /// The link hit.
    pub link: LinkId,
    /// Distance along the ray, m (the direction is unit length).
    pub distance_m: f64,
    /// Hit point in the world frame.
    pub point_world: DVec3,
    /// Hit point in the link frame.
    pub point_in_link: DVec3,
    /// Unit normal of the surface at the hit (the smooth shell's, as the
    /// estimator sees it), pointing into the robot, world frame.
    pub inward_normal_world: DVec3,
    /// True when the ray entered through the triangle's outer side (shells
    /// are oriented outward first); false when it came from inside.
    pub front_face: bool,
}

impl Picker {
    /// Shells and BVHs for every link with a mesh.
    #[must_use]
    pub fn new(robot: &Robot) -> Self {
        Self {
            links: robot
                .links
                .iter()
                .map(|l| {
                    (!l.mesh.is_empty()).then(|| {
                        let shell = SmoothMesh::new(&l.mesh);
                        let bvh = Bvh::new(&shell.mesh);
                        (shell, bvh)
                    })
                })
                .collect(),
        }
    }

    /// The nearest hit of the ray `origin + t dir` (t > 0) on any link in
    /// `links` (every link when empty). `None` for a miss or a zero direction.
    #[must_use]
    pub fn pick(&self, pose: &RobotPose, origin: DVec3, dir: DVec3, links: &[LinkId]) -> Option<Pick> {
        let dir = dir.try_normalize()?;
        let mut best: Option<Pick> = None;
        for (link, entry) in self.links.iter().enumerate() {
            let Some((shell, bvh)) = entry else { continue };
            if !links.is_empty() && !links.contains(&link) {
                continue;
            }
            let world_from_link = pose.world_from_link[link];
            let link_from_world = world_from_link.inverse();
            let local_origin = link_from_world.transform_point3(origin);
            let local_dir = link_from_world.transform_vector3(dir);
            let limit = best.map_or(f64::INFINITY, |b| b.distance_m);
            let Some(hit) = bvh.ray_cast(local_origin, local_dir, limit) else {
                continue;
            };
            let (u, v) = hit.barycentric;
            let Some(frame) = shell.frame(MeshPoint {
                triangle: hit.triangle as u32,
                weights: [u, v],
            }) else {
                continue;
            };
            let point_in_link = frame.point;
            best = Some(Pick {
                link,
                distance_m: hit.t,
                point_world: world_from_link.transform_point3(point_in_link),
                point_in_link,
                inward_normal_world: world_from_link.transform_vector3(frame.inward_normal),
                front_face: hit.front_face,
            });
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::robot::builtin;

    fn lwr() -> (Robot, Picker) {
        let robot = builtin::lwr4plus_generated().unwrap();
        let picker = Picker::new(&robot);
        (robot, picker)
    }

    #[test]
    fn a_ray_at_the_forearm_hits_link_5_on_its_surface() {
        let (robot, picker) = lwr();
        let pose = RobotPose::new(&robot, &[0.0; 7]);
        // Joint 5 is at z = 0.9105 and its tube has a 6 cm radius.
        let hit = picker
            .pick(&pose, DVec3::new(1.0, 0.0, 0.95), DVec3::NEG_X, &[])
            .unwrap();
        assert_eq!(robot.links[hit.link].name, "lwr_5_link");
        assert!((hit.point_world.x - 0.06).abs() < 2e-3, "{}", hit.point_world);
        assert!((hit.distance_m - 0.94).abs() < 2e-3);
        assert!(hit.front_face);
        // The inward normal points back along the ray, into the arm.
        assert!(hit.inward_normal_world.dot(DVec3::NEG_X) > 0.99);
    }

    #[test]
    fn misses_and_filters() {
        let (robot, picker) = lwr();
        let pose = RobotPose::new(&robot, &[0.0; 7]);
        assert!(picker.pick(&pose, DVec3::new(1.0, 0.0, 0.95), DVec3::X, &[]).is_none());
        assert!(
            picker
                .pick(&pose, DVec3::new(1.0, 1.0, 0.95), DVec3::NEG_X, &[])
                .is_none()
        );
        assert!(
            picker
                .pick(&pose, DVec3::new(1.0, 0.0, 0.95), DVec3::ZERO, &[])
                .is_none()
        );
        // Only link 3 may be hit: the ray at link 5's height finds nothing.
        let l3 = robot.link_id("lwr_3_link").unwrap();
        assert!(
            picker
                .pick(&pose, DVec3::new(1.0, 0.0, 0.95), DVec3::NEG_X, &[l3])
                .is_none()
        );
    }

    #[test]
    fn grazing_ray_just_outside_the_tube_misses_and_just_inside_hits() {
        let (robot, picker) = lwr();
        let pose = RobotPose::new(&robot, &[0.0; 7]);
        // Tangent lines to the 6 cm tube at y = ±0.0601 and ±0.0590.
        assert!(
            picker
                .pick(&pose, DVec3::new(1.0, 0.0601, 0.95), DVec3::NEG_X, &[])
                .is_none()
        );
        let hit = picker
            .pick(&pose, DVec3::new(1.0, 0.059, 0.95), DVec3::NEG_X, &[])
            .unwrap();
        assert_eq!(robot.links[hit.link].name, "lwr_5_link");
    }

    #[test]
    fn from_inside_the_arm_the_hit_is_a_back_face() {
        let (robot, picker) = lwr();
        let pose = RobotPose::new(&robot, &[0.0; 7]);
        let hit = picker.pick(&pose, DVec3::new(0.0, 0.0, 0.95), DVec3::X, &[]).unwrap();
        assert!(!hit.front_face);
    }

    #[test]
    fn picking_follows_the_pose() {
        let (robot, picker) = lwr();
        // Joint 1 turned by 90°: link 5's housing side turns from +y to -x.
        let pose = RobotPose::new(&robot, &[std::f64::consts::FRAC_PI_2, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
        let hit = picker
            .pick(&pose, DVec3::new(1.0, 0.0, 0.95), DVec3::NEG_X, &[])
            .unwrap();
        assert_eq!(robot.links[hit.link].name, "lwr_5_link");
        let back = pose.point_to_world(hit.link, hit.point_in_link);
        assert!((back - hit.point_world).length() < 1e-12);
    }

    /// A mesh wound inward (as some exporters write them): the push must
    /// still point into the body (it pulled before shells were oriented).
    #[test]
    fn an_inward_wound_mesh_still_gives_an_inward_push() {
        use crate::core::geometry::primitives;
        use crate::core::robot::model::{JointKind, JointSpec, LinkSpec};
        let mut cube = primitives::cuboid(DVec3::splat(0.2));
        for t in &mut cube.triangles {
            t.swap(1, 2);
        }
        let robot = Robot::new(
            "one",
            &[
                LinkSpec {
                    name: "base".to_owned(),
                    ..LinkSpec::default()
                },
                LinkSpec {
                    name: "body".to_owned(),
                    mesh: cube,
                    segment: None,
                    ..LinkSpec::default()
                },
            ],
            &[JointSpec {
                name: "j".to_owned(),
                kind: JointKind::Continuous,
                parent: "base".to_owned(),
                child: "body".to_owned(),
                parent_from_joint: glam::DAffine3::IDENTITY,
                axis: DVec3::Z,
                limits: None,
                mimic: None,
            }],
        )
        .unwrap();
        let picker = Picker::new(&robot);
        let pose = RobotPose::new(&robot, &[0.0]);
        let hit = picker
            .pick(&pose, DVec3::new(1.0, 0.01, 0.02), DVec3::NEG_X, &[])
            .unwrap();
        assert!(hit.front_face);
        assert!(
            (hit.inward_normal_world - DVec3::NEG_X).length() < 1e-9,
            "{}",
            hit.inward_normal_world
        );
    }
}
