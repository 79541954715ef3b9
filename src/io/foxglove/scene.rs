//! One frame as Foxglove's 3-D panel shows it: the arm's links as
//! triangle lists attached to their frames (written once), the links'
//! transforms from the joint positions, the posterior painted over the
//! links, and the contacts as arrows. Plain protobuf messages of
//! Foxglove's schemas; [`super::Outgoing`] carries them to a file or a
//! socket.

use foxglove::messages::{
    ArrowPrimitive, Color, FrameTransform, FrameTransforms, KeyValuePair, Point3, Pose, Quaternion, SceneEntity,
    SceneEntityDeletion, SceneUpdate, TextPrimitive, Timestamp, TriangleListPrimitive, Vector3,
};
use glam::{DQuat, DVec3};

use crate::core::paint::colours::{ROBOT_GREY, arrow_length_m, arrow_rgb};
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::Robot;

/// How far the heat is laid out from the arm's surface, m: over the grey
/// links, never through them.
pub const HEAT_LIFT_M: f64 = 0.0008;

/// What an arrow stands for; its colour is the app's.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ArrowRole {
    /// The push applied (in the app), or a recording's true contact.
    Push,
    /// The estimate (of the frame alone, or of a second contact).
    Estimate,
    /// The estimate from the frames together (filtered or smoothed).
    OverTime,
    /// The over-time estimate's tangential force (friction).
    Tangential,
}

impl ArrowRole {
    fn rgb(self) -> [u8; 3] {
        match self {
            Self::Push => arrow_rgb::PUSH,
            Self::Estimate => arrow_rgb::ESTIMATE,
            Self::OverTime => arrow_rgb::OVER_TIME,
            Self::Tangential => arrow_rgb::TANGENTIAL,
        }
    }

    fn name(self) -> &'static str {
        match self {
            Self::Push => "true contact",
            Self::Estimate => "estimate",
            Self::OverTime => "over time",
            Self::Tangential => "its friction",
        }
    }
}

/// A force arriving at a surface point, world frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Arrow {
    /// What it is.
    pub role: ArrowRole,
    /// Where the force acts, m.
    pub point_world: DVec3,
    /// The force on the arm, N.
    pub force_world: DVec3,
}

impl Arrow {
    /// A recording's true contacts as push arrows.
    #[must_use]
    pub fn truths(truths: &[crate::io::session::ContactTruth]) -> Vec<Self> {
        truths
            .iter()
            .map(|t| Self {
                role: ArrowRole::Push,
                point_world: DVec3::from_array(t.point),
                force_world: DVec3::from_array(t.force),
            })
            .collect()
    }
}

/// A link's mesh as the scene draws it.
#[derive(Debug, Clone)]
struct LinkMesh {
    name: String,
    points: Vec<DVec3>,
    normals: Vec<DVec3>,
    indices: Vec<u32>,
}

/// The arm as Foxglove draws it, built once per robot.
#[derive(Debug, Clone)]
pub struct ArmScene {
    robot: Robot,
    meshes: Vec<LinkMesh>,
}

/// A timestamp from nanoseconds on the recording's clock (0 before 1970).
#[must_use]
pub fn timestamp(stamp_ns: i64) -> Timestamp {
    let ns = u64::try_from(stamp_ns).unwrap_or(0);
    let sec = u32::try_from(ns / 1_000_000_000).unwrap_or(u32::MAX);
    Timestamp::new_checked(sec, (ns % 1_000_000_000) as u32).unwrap_or(Timestamp::MAX)
}

fn vector3(v: DVec3) -> Vector3 {
    Vector3 { x: v.x, y: v.y, z: v.z }
}

fn point3(v: DVec3) -> Point3 {
    Point3 { x: v.x, y: v.y, z: v.z }
}

fn quaternion(q: DQuat) -> Quaternion {
    Quaternion {
        x: q.x,
        y: q.y,
        z: q.z,
        w: q.w,
    }
}

/// A display colour (as the app paints, RGBA in [0, 1]) as Foxglove's.
#[must_use]
pub fn color(c: [f32; 4]) -> Color {
    Color {
        r: f64::from(c[0]),
        g: f64::from(c[1]),
        b: f64::from(c[2]),
        a: f64::from(c[3]),
    }
}

fn rgb(c: [u8; 3]) -> Color {
    Color {
        r: f64::from(c[0]) / 255.0,
        g: f64::from(c[1]) / 255.0,
        b: f64::from(c[2]) / 255.0,
        a: 1.0,
    }
}

/// Area-weighted vertex normals of a mesh (zero where no triangle has area).
fn vertex_normals(points: &[DVec3], triangles: &[[u32; 3]]) -> Vec<DVec3> {
    let mut normals = vec![DVec3::ZERO; points.len()];
    for t in triangles {
        let [Some(a), Some(b), Some(c)] = t.map(|i| points.get(i as usize).copied()) else {
            continue;
        };
        let n = (b - a).cross(c - a);
        for &i in t {
            if let Some(slot) = normals.get_mut(i as usize) {
                *slot += n;
            }
        }
    }
    normals.iter().map(|n| n.normalize_or_zero()).collect()
}

impl ArmScene {
    /// The scene of `robot`: its meshes in their links' frames.
    #[must_use]
    pub fn new(robot: &Robot) -> Self {
        let meshes = robot
            .links
            .iter()
            .map(|link| {
                let valid: Vec<[u32; 3]> = link
                    .mesh
                    .triangles
                    .iter()
                    .filter(|t| link.mesh.corners_of(t).is_some())
                    .copied()
                    .collect();
                LinkMesh {
                    name: link.name.clone(),
                    normals: vertex_normals(&link.mesh.positions, &valid),
                    points: link.mesh.positions.clone(),
                    indices: valid.into_iter().flatten().collect(),
                }
            })
            .collect();
        Self {
            robot: robot.clone(),
            meshes,
        }
    }

    /// The robot this scene draws.
    #[must_use]
    pub fn robot(&self) -> &Robot {
        &self.robot
    }

    /// The root link's name: the fixed frame.
    #[must_use]
    pub fn root_frame(&self) -> &str {
        self.robot
            .links
            .get(self.robot.root)
            .map_or("world", |l| l.name.as_str())
    }

    /// The arm: one grey entity per link with a mesh, in that link's frame
    /// and following it, kept until replaced.
    #[must_use]
    pub fn arm(&self, stamp_ns: i64) -> SceneUpdate {
        let entities = self
            .meshes
            .iter()
            .filter(|m| !m.indices.is_empty())
            .map(|m| SceneEntity {
                timestamp: Some(timestamp(stamp_ns)),
                frame_id: m.name.clone(),
                id: format!("arm/{}", m.name),
                frame_locked: true,
                triangles: vec![TriangleListPrimitive {
                    pose: Some(identity_pose()),
                    points: m.points.iter().copied().map(point3).collect(),
                    color: Some(color(ROBOT_GREY)),
                    colors: Vec::new(),
                    indices: m.indices.clone(),
                }],
                ..SceneEntity::default()
            })
            .collect();
        SceneUpdate {
            deletions: Vec::new(),
            entities,
        }
    }

    /// Every link's transform from its parent link at the joint positions
    /// `joint_positions` (the robot's joint order), as a
    /// `robot_state_publisher` gives them.
    #[must_use]
    pub fn transforms(&self, joint_positions: &[f64], stamp_ns: i64) -> FrameTransforms {
        self.transforms_at(&RobotPose::new(&self.robot, joint_positions), stamp_ns)
    }

    /// [`Self::transforms`] of a posed arm.
    #[must_use]
    pub fn transforms_at(&self, pose: &RobotPose, stamp_ns: i64) -> FrameTransforms {
        let transforms = self
            .robot
            .joints
            .iter()
            .filter_map(|joint| {
                let parent = pose.world_from_link.get(joint.parent)?;
                let child = pose.world_from_link.get(joint.child)?;
                let parent_from_child = parent.inverse() * *child;
                let (_, rotation, translation) = parent_from_child.to_scale_rotation_translation();
                Some(FrameTransform {
                    timestamp: Some(timestamp(stamp_ns)),
                    parent_frame_id: self.robot.links.get(joint.parent)?.name.clone(),
                    child_frame_id: self.robot.links.get(joint.child)?.name.clone(),
                    translation: Some(vector3(translation)),
                    rotation: Some(quaternion(rotation.normalize())),
                })
            })
            .collect();
        FrameTransforms { transforms }
    }

    /// The posterior over the arm: per link, its painted mesh vertices
    /// with their colours (`paint[link]`: vertex and colour, as the app
    /// paints them; the others are grey). Only the triangles with a
    /// painted corner are sent, lifted [`HEAT_LIFT_M`] off the surface;
    /// the update first clears the last one.
    #[must_use]
    pub fn heat(&self, paint: &[Vec<(u32, [f32; 4])>], stamp_ns: i64) -> SceneUpdate {
        let mut entities = Vec::new();
        for (mesh, link_paint) in self.meshes.iter().zip(paint) {
            if link_paint.is_empty() {
                continue;
            }
            let mut link_colours = vec![None; mesh.points.len()];
            for &(v, c) in link_paint {
                if let Some(slot) = link_colours.get_mut(v as usize) {
                    *slot = Some(c);
                }
            }
            let painted = |i: u32| link_colours.get(i as usize).is_some_and(Option::is_some);
            let mut remap = vec![u32::MAX; mesh.points.len()];
            let (mut points, mut colors, mut indices) = (Vec::new(), Vec::new(), Vec::new());
            for t in mesh.indices.chunks_exact(3) {
                if !t.iter().any(|&i| painted(i)) {
                    continue;
                }
                for &i in t {
                    let k = i as usize;
                    let (Some(slot), Some(p), Some(n)) = (remap.get_mut(k), mesh.points.get(k), mesh.normals.get(k))
                    else {
                        continue;
                    };
                    if *slot == u32::MAX {
                        *slot = points.len() as u32;
                        points.push(point3(*p + *n * HEAT_LIFT_M));
                        // The corners left unpainted are the arm's grey, as 8 bits show it.
                        let c = link_colours.get(k).copied().flatten();
                        colors.push(color(c.unwrap_or_else(|| super::as_8_bit(ROBOT_GREY))));
                    }
                    indices.push(*slot);
                }
            }
            if indices.is_empty() {
                continue;
            }
            entities.push(SceneEntity {
                timestamp: Some(timestamp(stamp_ns)),
                frame_id: mesh.name.clone(),
                id: format!("heat/{}", mesh.name),
                frame_locked: true,
                triangles: vec![TriangleListPrimitive {
                    pose: Some(identity_pose()),
                    points,
                    color: None,
                    colors,
                    indices,
                }],
                ..SceneEntity::default()
            });
        }
        SceneUpdate {
            deletions: vec![clear_all(stamp_ns)],
            entities,
        }
    }

    /// The contacts as arrows, world frame: each ends at its point, its
    /// length by the app's rule ([`arrow_length_m`]), labelled in newtons.
    #[must_use]
    pub fn arrows(&self, arrows: &[Arrow], stamp_ns: i64) -> SceneUpdate {
        let entities = arrows
            .iter()
            .enumerate()
            .filter_map(|(k, a)| {
                let newtons = a.force_world.length();
                let direction = a.force_world.try_normalize()?;
                let length = arrow_length_m(newtons);
                let tail = a.point_world - direction * length;
                let head = (0.25 * length).min(0.03);
                let rotation = DQuat::from_rotation_arc(DVec3::X, direction);
                Some(SceneEntity {
                    timestamp: Some(timestamp(stamp_ns)),
                    frame_id: self.root_frame().to_owned(),
                    id: format!("arrow/{k}"),
                    metadata: vec![KeyValuePair {
                        key: "role".to_owned(),
                        value: a.role.name().to_owned(),
                    }],
                    arrows: vec![ArrowPrimitive {
                        pose: Some(Pose {
                            position: Some(vector3(tail)),
                            orientation: Some(quaternion(rotation)),
                        }),
                        shaft_length: length - head,
                        shaft_diameter: 0.006,
                        head_length: head,
                        head_diameter: 0.016,
                        color: Some(rgb(a.role.rgb())),
                    }],
                    texts: vec![TextPrimitive {
                        pose: Some(Pose {
                            position: Some(vector3(tail)),
                            orientation: Some(quaternion(DQuat::IDENTITY)),
                        }),
                        billboard: true,
                        font_size: 14.0,
                        scale_invariant: true,
                        color: Some(rgb(a.role.rgb())),
                        text: format!("{newtons:.1} N ({})", a.role.name()),
                    }],
                    ..SceneEntity::default()
                })
            })
            .collect();
        SceneUpdate {
            deletions: vec![clear_all(stamp_ns)],
            entities,
        }
    }
}

fn identity_pose() -> Pose {
    Pose {
        position: Some(vector3(DVec3::ZERO)),
        orientation: Some(quaternion(DQuat::IDENTITY)),
    }
}

/// A deletion of every entity the topic showed before.
fn clear_all(stamp_ns: i64) -> SceneEntityDeletion {
    SceneEntityDeletion {
        timestamp: Some(timestamp(stamp_ns)),
        r#type: foxglove::messages::scene_entity_deletion::Type::All as i32,
        id: String::new(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::robot::builtin;

    #[test]
    fn transforms_chain_back_to_the_links_poses() {
        let robot = builtin::simple6().unwrap();
        let scene = ArmScene::new(&robot);
        let q: Vec<f64> = (0..robot.joints.len()).map(|j| 0.3 * j as f64 - 0.4).collect();
        let pose = RobotPose::new(&robot, &q);
        let tf = scene.transforms(&q, 5);
        assert_eq!(tf.transforms.len(), robot.joints.len());
        // Composing parent-from-child from the root gives each link's pose.
        let mut world = std::collections::HashMap::new();
        world.insert(scene.root_frame().to_owned(), glam::DAffine3::IDENTITY);
        for _ in 0..robot.joints.len() {
            for t in &tf.transforms {
                if let Some(parent) = world.get(&t.parent_frame_id).copied() {
                    let (tr, r) = (t.translation.unwrap(), t.rotation.unwrap());
                    let local = glam::DAffine3::from_rotation_translation(
                        DQuat::from_xyzw(r.x, r.y, r.z, r.w),
                        DVec3::new(tr.x, tr.y, tr.z),
                    );
                    world.insert(t.child_frame_id.clone(), parent * local);
                }
            }
        }
        for (k, link) in robot.links.iter().enumerate() {
            let got = world[&link.name];
            let want = pose.world_from_link[k];
            assert!(got.translation.distance(want.translation) < 1e-12, "{}", link.name);
            assert!(got.matrix3.abs_diff_eq(want.matrix3, 1e-12), "{}", link.name);
        }
    }

    #[test]
    fn heat_sends_only_painted_triangles_with_their_colours() {
        let robot = builtin::simple6().unwrap();
        let scene = ArmScene::new(&robot);
        let mut paint: Vec<Vec<(u32, [f32; 4])>> = vec![Vec::new(); robot.links.len()];
        let link = robot.links.iter().position(|l| !l.mesh.triangles.is_empty()).unwrap();
        let painted = robot.links[link].mesh.triangles[0][1];
        paint[link].push((painted, [1.0, 0.0, 0.5, 1.0]));
        let update = scene.heat(&paint, 0);
        assert_eq!(update.entities.len(), 1);
        let triangles = &update.entities[0].triangles[0];
        assert!(!triangles.indices.is_empty() && triangles.indices.len().is_multiple_of(3));
        assert_eq!(triangles.points.len(), triangles.colors.len());
        assert!(triangles.colors.iter().any(|c| (c.r, c.g, c.b) == (1.0, 0.0, 0.5)));
        assert_eq!(update.deletions.len(), 1);
        // Nothing painted: only the deletion.
        assert!(scene.heat(&vec![Vec::new(); robot.links.len()], 0).entities.is_empty());
    }

    #[test]
    fn an_arrow_ends_at_its_point_and_follows_the_app_s_length() {
        let robot = builtin::simple6().unwrap();
        let scene = ArmScene::new(&robot);
        let arrow = Arrow {
            role: ArrowRole::OverTime,
            point_world: DVec3::new(0.1, 0.2, 0.3),
            force_world: DVec3::new(0.0, -10.0, 0.0),
        };
        let update = scene.arrows(&[arrow], 0);
        let a = &update.entities[0].arrows[0];
        let pose = a.pose.unwrap();
        let (p, o) = (pose.position.unwrap(), pose.orientation.unwrap());
        let direction = DQuat::from_xyzw(o.x, o.y, o.z, o.w) * DVec3::X;
        let tip = DVec3::new(p.x, p.y, p.z) + direction * (a.shaft_length + a.head_length);
        assert!(tip.distance(arrow.point_world) < 1e-12);
        assert!((a.shaft_length + a.head_length - arrow_length_m(10.0)).abs() < 1e-12);
        assert!(scene.arrows(&[], 0).entities.is_empty());
    }
}
