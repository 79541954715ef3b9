//! Per configuration, the torque per newton of a push at every surface
//! point, in structure-of-arrays form for fast likelihoods.

use crate::core::surface::Surface;
use crate::core::torque::TorqueModel;

/// Unit torques of every surface point for one configuration: pushing
/// with `f` newtons along point k's inward normal produces `f · u_jk` on
/// sensed joint j.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactModel {
    joints: usize,
    points: usize,
    /// Joint-major: `unit_torque[j * points + k]`.
    unit_torque: Vec<f64>,
}

impl ContactModel {
    /// Evaluates the Plücker form for every point (6 multiply-adds per
    /// point and joint that moves its link; 0 elsewhere).
    #[must_use]
    pub fn new(torque_model: &TorqueModel, surface: &Surface) -> Self {
        let joints = torque_model.sensed_count();
        let points = surface.len();
        let mut unit_torque = vec![0.0; joints * points];
        let mut start = 0;
        while start < points {
            let link = surface.link[start];
            let end = start + surface.link[start..].iter().take_while(|l| **l == link).count();
            for twist in torque_model.twists(link) {
                let row = &mut unit_torque[twist.sensed_index * points..(twist.sensed_index + 1) * points];
                let points = surface.point_in_link[start..end].iter();
                let normals = surface.inward_normal_in_link[start..end].iter();
                for ((slot, p), n) in row[start..end].iter_mut().zip(points).zip(normals) {
                    *slot = twist.w.dot(p.cross(*n)) + twist.v.dot(*n);
                }
            }
            start = end;
        }
        Self {
            joints,
            points,
            unit_torque,
        }
    }

    /// Number of sensed joints.
    #[must_use]
    pub fn joints(&self) -> usize {
        self.joints
    }

    /// Number of surface points.
    #[must_use]
    pub fn points(&self) -> usize {
        self.points
    }

    /// Point k's unit torque on joint j.
    #[must_use]
    pub fn unit_torque(&self, joint: usize, point: usize) -> f64 {
        self.unit_torque
            .get(joint * self.points + point)
            .copied()
            .unwrap_or(0.0)
    }

    /// Point k's unit torques on every joint.
    #[must_use]
    pub fn unit_torques(&self, point: usize) -> Vec<f64> {
        (0..self.joints).map(|j| self.unit_torque(j, point)).collect()
    }

    /// For the measured `tau` and per-joint weights `1/σ²`, the quadratic
    /// form of every point's log-likelihood in the magnitude f:
    /// `-½ (c - 2 b_k f + a_k f²)` with `a_k = Σ w u²`, `b_k = Σ w u τ`.
    /// Fills `a` and `b` (resized to the number of points).
    pub fn quadratic_forms(&self, weights: &[f64], tau: &[f64], a: &mut Vec<f64>, b: &mut Vec<f64>) {
        a.clear();
        a.resize(self.points, 0.0);
        b.clear();
        b.resize(self.points, 0.0);
        for (j, (w, t)) in weights.iter().zip(tau).enumerate().take(self.joints) {
            let row = &self.unit_torque[j * self.points..(j + 1) * self.points];
            let wt = w * t;
            for ((ak, bk), u) in a.iter_mut().zip(b.iter_mut()).zip(row) {
                *ak += w * u * u;
                *bk += wt * u;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::builtin;
    use crate::core::kinematics::RobotPose;
    use crate::core::surface::SurfaceRequest;
    use crate::core::torque::joint_torques;

    #[test]
    fn unit_torques_match_the_direct_formula() {
        let robot = builtin::lwr4plus_generated().unwrap();
        let links = robot.default_candidate_links();
        let surface = Surface::sample(
            &robot,
            &SurfaceRequest {
                links: links.clone(),
                total_points: 300,
                seed: 4,
            },
        )
        .unwrap();
        let q = [0.4, -0.9, 0.2, 1.3, -0.6, 0.9, -2.0];
        let pose = RobotPose::new(&robot, &robot.joint_positions(&q, &[]).unwrap());
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
            for (j, d) in direct.iter().enumerate() {
                assert!((model.unit_torque(j, k) - d).abs() < 1e-12);
            }
        }
    }
}
