//! Per configuration, the torque per newton of a push at every surface
//! point, in structure-of-arrays form for fast likelihoods.

use rayon::prelude::*;

use crate::core::surface::Surface;

/// From this many points on, the per-point work is shared among threads
/// (below, thread hand-off costs more than it saves).
pub const PARALLEL_MIN_POINTS: usize = 16_384;
use crate::core::torque::TorqueModel;

/// Unit torques of every surface point for one configuration: pushing
/// with `f` newtons along point k's inward normal produces `f · u_jk` on
/// sensed joint j.
#[derive(Debug, Clone, PartialEq)]
pub struct ContactModel {
    joints: usize,
    points: usize,
    /// Point-major: `unit_torque[k * joints + j]`, so that one point's
    /// torques are contiguous and its likelihood terms accumulate in registers.
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
        let fill = |(k, row): (usize, &mut [f64])| {
            let link = surface.link[k];
            let p = surface.point_in_link[k];
            let n = surface.inward_normal_in_link[k];
            let moment = p.cross(n);
            for twist in torque_model.twists(link) {
                if let Some(slot) = row.get_mut(twist.sensed_index) {
                    *slot = twist.w.dot(moment) + twist.v.dot(n);
                }
            }
        };
        if joints > 0 {
            if points >= PARALLEL_MIN_POINTS {
                unit_torque.par_chunks_exact_mut(joints).enumerate().for_each(fill);
            } else {
                unit_torque.chunks_exact_mut(joints).enumerate().for_each(fill);
            }
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
        self.unit_torques(point).get(joint).copied().unwrap_or(0.0)
    }

    /// Point k's unit torques on every joint (empty past the last point).
    #[must_use]
    pub fn unit_torques(&self, point: usize) -> &[f64] {
        self.unit_torque
            .get(point * self.joints..(point + 1) * self.joints)
            .unwrap_or(&[])
    }

    /// For the measured `tau` and per-joint weights `1/σ²`, the quadratic
    /// form of every point's log-likelihood in the magnitude f:
    /// `-½ (c - 2 b_k f + a_k f²)` with `a_k = Σ w u²`, `b_k = Σ w u τ`.
    /// Fills `a` and `b` (resized to the number of points).
    pub fn quadratic_forms(&self, weights: &[f64], tau: &[f64], a: &mut Vec<f64>, b: &mut Vec<f64>) {
        let wt: Vec<f64> = weights.iter().zip(tau).map(|(w, t)| w * t).collect();
        a.clear();
        b.clear();
        a.reserve(self.points);
        b.reserve(self.points);
        // Fixed joint counts unroll into straight-line code.
        match self.joints {
            6 => self.quadratic_fixed::<6>(weights, &wt, a, b),
            7 => self.quadratic_fixed::<7>(weights, &wt, a, b),
            _ => {
                for row in self.unit_torque.chunks_exact(self.joints.max(1)) {
                    let (mut ak, mut bk) = (0.0, 0.0);
                    for ((u, w), wt) in row.iter().zip(weights).zip(&wt) {
                        ak += w * u * u;
                        bk += wt * u;
                    }
                    a.push(ak);
                    b.push(bk);
                }
                a.resize(self.points, 0.0);
                b.resize(self.points, 0.0);
            }
        }
    }

    fn quadratic_fixed<const J: usize>(&self, weights: &[f64], wt: &[f64], a: &mut Vec<f64>, b: &mut Vec<f64>) {
        let (Ok(w), Ok(wt)) = (<[f64; J]>::try_from(weights), <[f64; J]>::try_from(wt)) else {
            return;
        };
        let form = |row: &[f64]| {
            let (mut ak, mut bk) = (0.0, 0.0);
            for j in 0..J {
                ak += w[j] * row[j] * row[j];
                bk += wt[j] * row[j];
            }
            (ak, bk)
        };
        if self.points >= PARALLEL_MIN_POINTS {
            let (pa, pb): (Vec<f64>, Vec<f64>) = self.unit_torque.par_chunks_exact(J).map(form).unzip();
            *a = pa;
            *b = pb;
        } else {
            for row in self.unit_torque.chunks_exact(J) {
                let (ak, bk) = form(row);
                a.push(ak);
                b.push(bk);
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
                assert!(
                    (model.unit_torque(j, k) - d).abs() < 1e-12,
                    "point {k} joint {j}: {} vs {d}",
                    model.unit_torque(j, k)
                );
            }
        }
    }
}
