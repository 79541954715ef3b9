//! Forward kinematics: where every link and joint is for given joint positions.

use glam::{DAffine3, DQuat, DVec3};

use crate::core::robot::model::{JointKind, LinkId, Robot};

/// The posed robot: a frame per link and per joint, in the world (root) frame.
#[derive(Debug, Clone, PartialEq)]
pub struct RobotPose {
    /// Link frames, indexed by link.
    pub world_from_link: Vec<DAffine3>,
    /// Joint frames (after the origin, before the joint's own motion),
    /// indexed by joint: the axis and the point on it live here.
    pub world_from_joint: Vec<DAffine3>,
}

impl RobotPose {
    /// Forward kinematics for every joint's position (see
    /// [`Robot::joint_positions`]); `joint_positions` shorter than the joint
    /// list leaves the missing joints at 0.
    #[must_use]
    pub fn new(robot: &Robot, joint_positions: &[f64]) -> Self {
        let mut world_from_link = vec![DAffine3::IDENTITY; robot.links.len()];
        let mut world_from_joint = vec![DAffine3::IDENTITY; robot.joints.len()];
        for &j in &robot.joint_order {
            let joint = &robot.joints[j];
            let q = joint_positions.get(j).copied().unwrap_or(0.0);
            let frame = world_from_link[joint.parent] * joint.parent_from_joint;
            let motion = match joint.kind {
                JointKind::Revolute | JointKind::Continuous => {
                    DAffine3::from_quat(DQuat::from_axis_angle(joint.axis, q))
                }
                JointKind::Prismatic => DAffine3::from_translation(joint.axis * q),
                JointKind::Fixed => DAffine3::IDENTITY,
            };
            world_from_joint[j] = frame;
            world_from_link[joint.child] = frame * motion;
        }
        Self {
            world_from_link,
            world_from_joint,
        }
    }

    /// Joint `j`'s unit axis in the world frame.
    #[must_use]
    pub fn joint_axis_world(&self, robot: &Robot, j: usize) -> DVec3 {
        self.world_from_joint[j]
            .transform_vector3(robot.joints[j].axis)
            .normalize_or_zero()
    }

    /// Joint `j`'s frame origin (a point on its axis) in the world frame.
    #[must_use]
    pub fn joint_origin_world(&self, j: usize) -> DVec3 {
        self.world_from_joint[j].translation
    }

    /// A point given in `link`'s frame, in the world frame.
    #[must_use]
    pub fn point_to_world(&self, link: LinkId, point_in_link: DVec3) -> DVec3 {
        self.world_from_link[link].transform_point3(point_in_link)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::robot::builtin;

    #[test]
    fn simple6_zero_pose_puts_joints_where_the_notes_say() {
        let robot = builtin::simple6().unwrap();
        let pose = RobotPose::new(&robot, &[0.0; 6]);
        let expected = [
            [0.0, 0.0, 0.0],
            [0.0, 0.0, 1.0],
            [1.0, 0.0, 1.0],
            [1.0, 1.0, 1.0],
            [1.0, 1.0, 2.0],
            [2.0, 2.0, 2.0],
        ];
        for (k, &j) in robot.sensed().iter().enumerate() {
            let o = pose.joint_origin_world(j);
            assert!((o - DVec3::from_array(expected[k])).length() < 1e-15, "joint {k}: {o}");
        }
    }

    #[test]
    fn rotating_joint_one_by_a_quarter_turn_moves_the_tip() {
        let robot = builtin::simple6().unwrap();
        let mut q = [0.0; 6];
        q[0] = std::f64::consts::FRAC_PI_2;
        let pose = RobotPose::new(&robot, &q);
        let last = robot.links.len() - 1;
        let tip = pose.point_to_world(last, DVec3::new(1.0, 0.0, 0.0));
        // Tip (3, 2, 2) turned by +90° about z is (-2, 3, 2).
        assert!((tip - DVec3::new(-2.0, 3.0, 2.0)).length() < 1e-12, "{tip}");
    }
}
