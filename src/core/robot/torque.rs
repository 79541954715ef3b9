//! Joint torques of a point force, and the torque per newton of a surface
//! point in Plücker form.

use glam::DVec3;

use crate::core::numerics::rng::Rng;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{JointKind, LinkId, Robot};

/// Torques (N·m, or N for prismatic joints) on the sensed joints, in order,
/// of `force_world` (N, applied to the robot) at `point_world` (m) on
/// `link`: `tau = J_c(q)^T F`. Joints not on the link's path read 0.
#[must_use]
pub fn joint_torques(
    robot: &Robot,
    pose: &RobotPose,
    link: LinkId,
    point_world: DVec3,
    force_world: DVec3,
) -> Vec<f64> {
    let path = robot.path_joints(link);
    robot
        .sensed_drives()
        .iter()
        .map(|drives| {
            drives
                .iter()
                .filter(|(j, _)| path.contains(j))
                .map(|&(j, gain)| {
                    let axis = pose.joint_axis_world(robot, j);
                    let per_unit = match robot.joints[j].kind {
                        JointKind::Revolute | JointKind::Continuous => {
                            axis.dot((point_world - pose.joint_origin_world(j)).cross(force_world))
                        }
                        JointKind::Prismatic => axis.dot(force_world),
                        JointKind::Fixed => 0.0,
                    };
                    gain * per_unit
                })
                .sum::<f64>()
                // An empty sum is -0.0; users should read 0.
                + 0.0
        })
        .collect()
}

/// What torque sensors with Gaussian noise of `sigma` (N·m, the same on
/// every joint) read for the true torques `tau`; deterministic per seed.
#[must_use]
pub fn with_sensor_noise(tau: &[f64], sigma: f64, seed: u64) -> Vec<f64> {
    let mut rng = Rng::new(seed);
    tau.iter().map(|t| t + sigma * rng.normal()).collect()
}

/// One sensed joint's twist seen from a link's frame: the torque per newton
/// of a force line `(n, p × n)` is `w · (p × n) + v · n`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LinkTwist {
    /// Index into the sensed joints.
    pub sensed_index: usize,
    /// Angular part: the axis (0 for a prismatic joint), link frame.
    pub w: DVec3,
    /// Linear part: `o × a` for a revolute joint, the axis for a prismatic one.
    pub v: DVec3,
}

/// Per configuration, each link's sensed-joint twists in the link's own
/// frame, so that a surface point's torque per newton costs 6
/// multiply-adds per joint with no transform.
#[derive(Debug, Clone, PartialEq)]
pub struct TorqueModel {
    sensed_count: usize,
    twists_by_link: Vec<Vec<LinkTwist>>,
}

impl TorqueModel {
    /// Precomputes the twists of `links` (other links get none).
    #[must_use]
    pub fn new(robot: &Robot, pose: &RobotPose, links: &[LinkId]) -> Self {
        let drives = robot.sensed_drives();
        let mut twists_by_link = vec![Vec::new(); robot.links.len()];
        for &link in links {
            let Some(world_from_link) = pose.world_from_link.get(link) else {
                continue;
            };
            let link_from_world = world_from_link.inverse();
            let path = robot.path_joints(link);
            let mut twists = Vec::new();
            for (sensed_index, drive) in drives.iter().enumerate() {
                let (mut w, mut v) = (DVec3::ZERO, DVec3::ZERO);
                for &(j, gain) in drive.iter().filter(|(j, _)| path.contains(j)) {
                    let axis = link_from_world.transform_vector3(pose.joint_axis_world(robot, j));
                    match robot.joints[j].kind {
                        JointKind::Revolute | JointKind::Continuous => {
                            let origin = link_from_world.transform_point3(pose.joint_origin_world(j));
                            w += gain * axis;
                            v += gain * origin.cross(axis);
                        }
                        JointKind::Prismatic => v += gain * axis,
                        JointKind::Fixed => {}
                    }
                }
                if w != DVec3::ZERO || v != DVec3::ZERO {
                    twists.push(LinkTwist { sensed_index, w, v });
                }
            }
            twists_by_link[link] = twists;
        }
        Self {
            sensed_count: drives.len(),
            twists_by_link,
        }
    }

    /// Number of sensed joints.
    #[must_use]
    pub fn sensed_count(&self) -> usize {
        self.sensed_count
    }

    /// The twists that act on `link` (empty for links not precomputed).
    #[must_use]
    pub fn twists(&self, link: LinkId) -> &[LinkTwist] {
        self.twists_by_link.get(link).map_or(&[], Vec::as_slice)
    }

    /// Torque per newton on every sensed joint of a unit force along
    /// `direction_in_link` at `point_in_link`, written into `out` (length:
    /// the number of sensed joints).
    pub fn unit_torques_into(&self, link: LinkId, point_in_link: DVec3, direction_in_link: DVec3, out: &mut [f64]) {
        self.sum_into(link, point_in_link.cross(direction_in_link), direction_in_link, out);
    }

    /// Torque on every sensed joint of a push line `(moment, direction)`
    /// about `link`'s origin in its frame, stored as six numbers `(mx, my,
    /// mz, nx, ny, nz)` as the surface keeps them: per newton, or, for the
    /// change of a line along the surface, per newton and metre.
    pub fn line_array_torques_into(&self, link: LinkId, line: &[f64; 6], out: &mut [f64]) {
        let moment = DVec3::new(line[0], line[1], line[2]);
        let direction = DVec3::new(line[3], line[4], line[5]);
        self.sum_into(link, moment, direction, out);
    }

    /// `out[j] = w_j · moment + v_j · direction` over the twists that move `link`.
    fn sum_into(&self, link: LinkId, moment: DVec3, direction: DVec3, out: &mut [f64]) {
        out.fill(0.0);
        for t in self.twists(link) {
            if let Some(slot) = out.get_mut(t.sensed_index) {
                *slot += t.w.dot(moment) + t.v.dot(direction);
            }
        }
    }

    /// Torques of a force (any magnitude) given in the link frame.
    #[must_use]
    pub fn torques(&self, link: LinkId, point_in_link: DVec3, force_in_link: DVec3) -> Vec<f64> {
        let mut out = vec![0.0; self.sensed_count];
        self.unit_torques_into(link, point_in_link, force_in_link, &mut out);
        out
    }
}

/// Weighted inner product of two torque vectors, `Σ w x y` (weights
/// `1/σ²` per joint: the metric of the likelihood).
#[must_use]
pub fn weighted_dot(w: &[f64], x: &[f64], y: &[f64]) -> f64 {
    w.iter().zip(x).zip(y).map(|((w, x), y)| w * x * y).sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::robot::builtin;

    /// Table 3.1 → Table 3.2 of the thesis, both rows, exactly.
    #[test]
    fn simple_robot_reproduces_table_3_2() {
        let robot = builtin::simple6().unwrap();
        let pose = RobotPose::new(&robot, &[0.0; 7]);
        let rows = [
            (
                "link_3",
                [1.0, 1.0, 1.5],
                [0.0, 1.0, 0.0],
                [1.0, -0.5, 0.0, 0.0, 0.0, 0.0],
            ),
            (
                "link_5",
                [2.5, 2.0, 2.0],
                [0.0, 0.0, 1.0],
                [0.0, 2.0, -1.5, 0.0, 1.0, -0.5],
            ),
        ];
        for (link, r, f, expected) in rows {
            let link = robot.link_id(link).unwrap_or(usize::MAX);
            let tau = joint_torques(&robot, &pose, link, DVec3::from_array(r), DVec3::from_array(f));
            for (t, e) in tau.iter().zip(expected) {
                assert!((t - e).abs() <= 1e-12, "{tau:?} vs {expected:?}");
            }
        }
    }

    /// Table 3.3 → Table 3.4 (N·cm), thesis axis convention; the notes
    /// computed 9.588; 28.725; 9.516, -53.78, 9.516, 1.017.
    #[test]
    fn builtin_lwr_reproduces_table_3_4() {
        let robot = builtin::lwr4plus_kinematics().unwrap();
        let pose = RobotPose::new(&robot, &[0.0; 7]);
        let joint1_height = builtin::LWR_JOINT1_HEIGHT_M;
        let rows = [
            (
                "lwr_1_link",
                [-2.11, -0.09, -0.58],
                [6.0, 4.8, 21.3],
                [9.6, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            ),
            (
                "lwr_2_link",
                [1.50, 0.00, 0.00],
                [-6.0, 0.0, 39.2],
                [0.0, 28.7, 0.0, 0.0, 0.0, 0.0, 0.0],
            ),
            (
                "lwr_4_link",
                [-1.37, -0.85, 0.33],
                [4.6, 9.8, 58.2],
                [9.5, -53.6, 9.5, 1.0, 0.0, 0.0, 0.0],
            ),
        ];
        for (link, f, r_cm, expected_ncm) in rows {
            let link = robot.link_id(link).unwrap_or(usize::MAX);
            let r = DVec3::from_array(r_cm) / 100.0 + DVec3::new(0.0, 0.0, joint1_height);
            let tau = joint_torques(&robot, &pose, link, r, DVec3::from_array(f));
            for (t, e) in tau.iter().zip(expected_ncm) {
                assert!((t * 100.0 - e).abs() <= 0.3, "{tau:?} vs {expected_ncm:?} N·cm");
            }
        }
    }

    use crate::core::robot::model::{JointKind, JointSpec, LinkSpec, Robot};
    use glam::{DAffine3, DQuat};
    use proptest::prelude::*;

    fn kind_of(k: u8) -> JointKind {
        match k % 4 {
            0 => JointKind::Revolute,
            1 => JointKind::Continuous,
            2 => JointKind::Prismatic,
            _ => JointKind::Fixed,
        }
    }

    fn vec3() -> impl Strategy<Value = DVec3> {
        (-1.0..1.0f64, -1.0..1.0f64, -1.0..1.0f64).prop_map(|(x, y, z)| DVec3::new(x, y, z))
    }

    /// A random serial chain (some joints mimic an earlier one), every
    /// movable non-mimic joint sensed.
    fn chain() -> impl Strategy<Value = Robot> {
        prop::collection::vec((any::<u8>(), vec3(), vec3(), vec3(), any::<u8>()), 1..7).prop_map(|specs| {
            let mut links = vec![LinkSpec {
                name: "l0".to_owned(),
                ..LinkSpec::default()
            }];
            let mut joints: Vec<JointSpec> = Vec::new();
            for (i, (kind, t, r, axis, mimic)) in specs.into_iter().enumerate() {
                links.push(LinkSpec {
                    name: format!("l{}", i + 1),
                    ..LinkSpec::default()
                });
                let leader = joints
                    .iter()
                    .filter(|j| j.kind.is_movable() && j.mimic.is_none())
                    .map(|j| j.name.clone())
                    .next_back();
                let kind = kind_of(kind);
                joints.push(JointSpec {
                    name: format!("j{i}"),
                    kind,
                    parent: format!("l{i}"),
                    child: format!("l{}", i + 1),
                    parent_from_joint: DAffine3::from_rotation_translation(DQuat::from_scaled_axis(r * 2.0), t * 0.5),
                    axis: axis + DVec3::new(0.0, 0.0, 1.5),
                    limits: None,
                    mimic: leader
                        .filter(|_| mimic % 3 == 0 && kind.is_movable())
                        .map(|l| (l, -1.5, 0.2)),
                });
            }
            let mut robot = Robot::new("chain", &links, &joints).unwrap();
            let sensed: Vec<String> = robot
                .joints
                .iter()
                .filter(|j| j.kind.is_movable() && j.mimic.is_none())
                .map(|j| j.name.clone())
                .collect();
            robot.set_sensed(&sensed).unwrap();
            robot
        })
    }

    proptest! {
        /// tau_i is the derivative of the force's work F · p(q) with
        /// respect to q_i (virtual work), by central differences.
        #[test]
        fn torques_equal_the_virtual_work_derivative(
            robot in chain(),
            q_seed in prop::collection::vec(-3.0..3.0f64, 7),
            link_pick in any::<usize>(),
            p_link in vec3(),
            force in vec3(),
        ) {
            let n = robot.sensed().len();
            let q: Vec<f64> = q_seed[..n].to_vec();
            let link = 1 + link_pick % (robot.links.len() - 1);
            let force = force * 10.0;
            let work = |q: &[f64]| {
                let pose = RobotPose::new(&robot, &robot.joint_positions(q, &[]).unwrap());
                force.dot(pose.point_to_world(link, p_link))
            };
            let pose = RobotPose::new(&robot, &robot.joint_positions(&q, &[]).unwrap());
            let tau = joint_torques(&robot, &pose, link, pose.point_to_world(link, p_link), force);
            let all: Vec<usize> = (0..robot.links.len()).collect();
            let fast = TorqueModel::new(&robot, &pose, &all).torques(
                link,
                p_link,
                pose.world_from_link[link].inverse().transform_vector3(force),
            );
            let h = 1e-6;
            for i in 0..n {
                let (mut up, mut down) = (q.clone(), q.clone());
                up[i] += h;
                down[i] -= h;
                let fd = (work(&up) - work(&down)) / (2.0 * h);
                let scale = tau[i].abs().max(force.length());
                prop_assert!((fd - tau[i]).abs() <= 1e-6 * scale, "joint {i}: fd {fd} vs tau {}", tau[i]);
                prop_assert!((fast[i] - tau[i]).abs() <= 1e-12 * scale, "joint {i}: plucker {} vs tau {}", fast[i], tau[i]);
            }
        }
    }

    #[test]
    fn sensor_noise_is_seeded_and_of_the_right_size() {
        let tau = vec![0.0; 20_000];
        let a = with_sensor_noise(&tau, 0.05, 1);
        assert_eq!(a, with_sensor_noise(&tau, 0.05, 1));
        assert_ne!(a, with_sensor_noise(&tau, 0.05, 2));
        let var = a.iter().map(|x| x * x).sum::<f64>() / a.len() as f64;
        assert!((var.sqrt() - 0.05).abs() < 0.002);
    }

    #[test]
    fn plucker_form_matches_the_direct_formula_on_the_lwr() {
        let robot = builtin::lwr4plus_kinematics().unwrap();
        let q = [0.3, -0.7, 1.1, 0.4, -1.9, 0.8, 2.5];
        let pose = RobotPose::new(&robot, &q);
        let links: Vec<usize> = (0..robot.links.len()).collect();
        let model = TorqueModel::new(&robot, &pose, &links);
        for link in links {
            let p_link = DVec3::new(0.03, -0.05, 0.12);
            let f_link = DVec3::new(-4.0, 2.5, 7.0);
            let direct = joint_torques(
                &robot,
                &pose,
                link,
                pose.point_to_world(link, p_link),
                pose.world_from_link[link].transform_vector3(f_link),
            );
            let fast = model.torques(link, p_link, f_link);
            for (a, b) in direct.iter().zip(&fast) {
                assert!((a - b).abs() < 1e-12, "link {link}: {direct:?} vs {fast:?}");
            }
        }
    }
}
