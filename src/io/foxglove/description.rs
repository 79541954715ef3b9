//! The robot as URDF text for `/robot_description`: for users who draw the
//! arm with Foxglove's URDF layer instead of the scene's meshes. The
//! joints are the model's; each link with a capsule axis gets a cylinder
//! along it (the meshes themselves are in the scene, not in files a
//! viewer could open).

use std::fmt::Write as _;

use glam::{DAffine3, DQuat, DVec3, EulerRot};

use crate::core::robot::model::{JointKind, Robot};

/// URDF's `xyz` and `rpy` of a rigid transform (rpy: fixed-axis roll,
/// pitch, yaw, that is R = Rz(yaw)·Ry(pitch)·Rx(roll)).
fn origin(transform: &DAffine3) -> String {
    let (_, rotation, translation) = transform.to_scale_rotation_translation();
    let (yaw, pitch, roll) = rotation.to_euler(EulerRot::ZYX);
    format!(
        "<origin xyz=\"{} {} {}\" rpy=\"{roll} {pitch} {yaw}\"/>",
        translation.x, translation.y, translation.z
    )
}

fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// The robot's URDF: its links, each with a cylinder along its capsule
/// axis where it has one, and its joints with origins, axes and limits.
#[must_use]
pub fn urdf_text(robot: &Robot) -> String {
    let mut out = format!("<?xml version=\"1.0\"?>\n<robot name=\"{}\">\n", escape(&robot.name));
    for link in &robot.links {
        let _ = writeln!(out, "  <link name=\"{}\">", escape(&link.name));
        if let Some([a, b]) = link.segment {
            let axis = b - a;
            let length = axis.length();
            if length > 1e-9 {
                // The cylinder's radius: the vertices' mean distance from the axis.
                let d = axis / length;
                let distances: Vec<f64> = link
                    .mesh
                    .positions
                    .iter()
                    .map(|p| (*p - a - d * (*p - a).dot(d)).length())
                    .collect();
                let radius = if distances.is_empty() {
                    0.05
                } else {
                    distances.iter().sum::<f64>() / distances.len() as f64
                };
                let frame = DAffine3::from_rotation_translation(DQuat::from_rotation_arc(DVec3::Z, d), (a + b) / 2.0);
                let _ = writeln!(
                    out,
                    "    <visual>{}<geometry><cylinder radius=\"{radius}\" length=\"{length}\"/></geometry></visual>",
                    origin(&frame)
                );
            }
        }
        out.push_str("  </link>\n");
    }
    for joint in &robot.joints {
        let kind = match joint.kind {
            JointKind::Revolute => "revolute",
            JointKind::Continuous => "continuous",
            JointKind::Prismatic => "prismatic",
            JointKind::Fixed => "fixed",
        };
        let (Some(parent), Some(child)) = (robot.links.get(joint.parent), robot.links.get(joint.child)) else {
            continue;
        };
        let _ = writeln!(out, "  <joint name=\"{}\" type=\"{kind}\">", escape(&joint.name));
        let _ = writeln!(
            out,
            "    <parent link=\"{}\"/><child link=\"{}\"/>",
            escape(&parent.name),
            escape(&child.name)
        );
        let _ = writeln!(out, "    {}", origin(&joint.parent_from_joint));
        if joint.kind.is_movable() {
            let a = joint.axis;
            let _ = writeln!(out, "    <axis xyz=\"{} {} {}\"/>", a.x, a.y, a.z);
        }
        if matches!(joint.kind, JointKind::Revolute | JointKind::Prismatic) {
            let (lower, upper) = joint
                .limits
                .map_or((-std::f64::consts::PI, std::f64::consts::PI), |l| (l.lower, l.upper));
            let _ = writeln!(
                out,
                "    <limit lower=\"{lower}\" upper=\"{upper}\" effort=\"1000\" velocity=\"10\"/>"
            );
        }
        out.push_str("  </joint>\n");
    }
    out.push_str("</robot>\n");
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::robot::builtin;
    use crate::core::robot::kinematics::RobotPose;
    use crate::io::urdf::{UrdfOptions, read_urdf};

    #[test]
    fn the_urdf_reads_back_as_the_same_kinematics() {
        let robot = builtin::simple6().unwrap();
        let text = urdf_text(&robot);
        let back = read_urdf(&text, std::path::Path::new("described.urdf"), &UrdfOptions::default()).unwrap();
        assert_eq!(back.joints.len(), robot.joints.len());
        let q: Vec<f64> = (0..robot.joints.len()).map(|j| 0.2 * j as f64 - 0.5).collect();
        let (a, b) = (RobotPose::new(&robot, &q), RobotPose::new(&back, &q));
        for (k, link) in robot.links.iter().enumerate() {
            let other = back.link_id(&link.name).unwrap();
            let (x, y) = (a.world_from_link[k], b.world_from_link[other]);
            assert!(x.translation.distance(y.translation) < 1e-9, "{}", link.name);
            assert!(x.matrix3.abs_diff_eq(y.matrix3, 1e-9), "{}", link.name);
        }
    }
}
