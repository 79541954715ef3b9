//! Rigid-body dynamics of the arm from its links' inertials: the mass
//! matrix `M(q)`, the Coriolis matrix `C(q, q̇)` (Christoffel symbols, so
//! that `Ṁ = C + Cᵀ`), gravity `g(q)`, inverse dynamics
//! `τ = M q̈ + C q̇ + g` and the regressor `Y(q, q̇, q̈)` with `τ = Y π`
//! over every link's ten inertial parameters `π`.
//!
//! Everything is written with spatial vectors at the world origin
//! ([`crate::core::robot::spatial`]): a joint's screw `S` is its axis and
//! a point on it in the world, so no transform is carried from link to
//! link. The generalised coordinates are the sensed joints (`q`, `tau` of
//! a session); a mimic joint moves with its leader times its multiplier,
//! and other movable joints (a gripper's fingers) are held at 0.
//!
//! The Coriolis matrix is analytic: with `H_k` the momentum and `I^c_k`
//! the inertia of the bodies that joint `k` carries, and `v_k` the
//! velocity of the body after joint `k`, `C = ½ Ṁ + ½ (B − Bᵀ)` where
//! `B = ∂(M q̇)/∂q`; `B_kj = S_kᵀ I^c_k crm(v_j) S_j` when `j` is `k` or
//! above it, and `S_kᵀ (crf(S_j) H_j + I^c_j crm(v_j) S_j)` when `j` is
//! below `k`. `docs/method.md` ("Rigid-body dynamics") derives it.

use glam::DVec3;

use crate::core::numerics::linalg::independent_columns;
use crate::core::numerics::rng::Rng;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{JointId, JointKind, LinkId, Robot, RobotError};
use crate::core::robot::spatial::{Force, Motion, SpatialInertia};

/// Gravity in the world (root) frame, m/s²: the URDF convention, z up.
pub const STANDARD_GRAVITY: DVec3 = DVec3::new(0.0, 0.0, -9.81);

/// Why a dynamics quantity could not be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DynamicsError {
    /// The joint positions do not fit the robot.
    #[error(transparent)]
    Robot(#[from] RobotError),
    /// A velocity or acceleration vector of the wrong length.
    #[error("{what}: expected {expected} values (one per sensed joint), got {got}")]
    WrongLength {
        /// Which vector.
        what: &'static str,
        /// Sensed joints.
        expected: usize,
        /// Values given.
        got: usize,
    },
    /// A value that is NaN or infinite.
    #[error("{what}[{index}] is {value}, not a finite number")]
    NonFinite {
        /// Which vector.
        what: &'static str,
        /// Position in it.
        index: usize,
        /// The value.
        value: f64,
    },
}

/// A movable joint of the tree, as the dynamics see it.
#[derive(Debug, Clone)]
struct Body {
    /// The joint.
    joint: JointId,
    /// The nearest movable joint above it.
    parent: Option<usize>,
    /// The sensed joints that drive it and their gains.
    drives: Vec<(usize, f64)>,
}

/// The rigid-body model of a robot: which joints move which links, and the
/// links' inertial parameters. Build it once per robot; it borrows the robot.
#[derive(Debug, Clone)]
pub struct RigidBodies<'r> {
    robot: &'r Robot,
    bodies: Vec<Body>,
    /// Per link: the body (movable joint) that carries it; `None` for links
    /// fixed to the root, which no joint feels.
    carrier: Vec<Option<usize>>,
    /// Per link: its ten parameters (see [`crate::core::robot::spatial::Inertial::parameters`]).
    parameters: Vec<[f64; 10]>,
    gravity: DVec3,
}

/// Where every body is and how it moves at one instant.
struct Motions {
    /// World screws of the bodies' joints.
    screws: Vec<Motion>,
    /// Velocity of each body (after its joint).
    velocities: Vec<Motion>,
    /// Acceleration of each body, gravity included as an upward acceleration of the root.
    accelerations: Vec<Motion>,
    /// Each link's inertia at the world origin.
    inertias: Vec<SpatialInertia>,
    pose: RobotPose,
}

impl<'r> RigidBodies<'r> {
    /// The model of `robot` under [`STANDARD_GRAVITY`].
    #[must_use]
    pub fn new(robot: &'r Robot) -> Self {
        let drives = robot.sensed_drives();
        let mut index_of = vec![None; robot.joints.len()];
        let mut bodies = Vec::new();
        for &j in &robot.joint_order {
            if !robot.joints[j].kind.is_movable() {
                continue;
            }
            let parent = robot
                .path_joints(robot.joints[j].parent)
                .last()
                .and_then(|&p| index_of.get(p).copied().flatten());
            let body_drives = drives
                .iter()
                .enumerate()
                .flat_map(|(dof, list)| {
                    list.iter()
                        .filter(|(pj, _)| *pj == j)
                        .map(move |&(_, gain)| (dof, gain))
                })
                .collect();
            index_of[j] = Some(bodies.len());
            bodies.push(Body {
                joint: j,
                parent,
                drives: body_drives,
            });
        }
        let carrier = (0..robot.links.len())
            .map(|l| robot.path_joints(l).last().and_then(|&j| index_of[j]))
            .collect();
        let parameters = robot.links.iter().map(|l| l.inertial.parameters()).collect();
        Self {
            robot,
            bodies,
            carrier,
            parameters,
            gravity: STANDARD_GRAVITY,
        }
    }

    /// The same model with other inertial parameters (ten per link, in link
    /// order): a perturbed plant, or a calibrated model.
    pub fn with_parameters(mut self, parameters: &[f64]) -> Result<Self, DynamicsError> {
        let expected = self.parameters.len() * 10;
        if parameters.len() != expected {
            return Err(DynamicsError::WrongLength {
                what: "inertial parameters",
                expected,
                got: parameters.len(),
            });
        }
        check_finite("inertial parameters", parameters)?;
        for (link, chunk) in self.parameters.iter_mut().zip(parameters.chunks_exact(10)) {
            link.copy_from_slice(chunk);
        }
        Ok(self)
    }

    /// The number of generalised coordinates (sensed joints).
    #[must_use]
    pub fn dof(&self) -> usize {
        self.robot.sensed().len()
    }

    /// Every link's ten inertial parameters, in link order.
    #[must_use]
    pub fn parameters(&self) -> Vec<f64> {
        self.parameters.iter().flatten().copied().collect()
    }

    /// The links, by number, that some sensed joint moves: only their
    /// parameters reach the torques.
    #[must_use]
    pub fn moving_links(&self) -> Vec<LinkId> {
        (0..self.carrier.len())
            .filter(|&l| self.carrier[l].is_some_and(|b| self.feels(b)))
            .collect()
    }

    /// True when some sensed joint drives body `b` or a body above it.
    fn feels(&self, b: usize) -> bool {
        let mut at = Some(b);
        while let Some(i) = at {
            if !self.bodies[i].drives.is_empty() {
                return true;
            }
            at = self.bodies[i].parent;
        }
        false
    }

    fn motions(&self, q: &[f64], qd: &[f64], qdd: &[f64], gravity: bool) -> Result<Motions, DynamicsError> {
        let n = self.dof();
        for (what, values) in [("joint velocities", qd), ("joint accelerations", qdd)] {
            if values.len() != n {
                return Err(DynamicsError::WrongLength {
                    what,
                    expected: n,
                    got: values.len(),
                });
            }
            check_finite(what, values)?;
        }
        let positions = self.robot.joint_positions(q, &[])?;
        let pose = RobotPose::new(self.robot, &positions);
        let root = Motion {
            angular: DVec3::ZERO,
            linear: if gravity { -self.gravity } else { DVec3::ZERO },
        };
        let count = self.bodies.len();
        let mut screws = Vec::with_capacity(count);
        let mut velocities: Vec<Motion> = Vec::with_capacity(count);
        let mut accelerations: Vec<Motion> = Vec::with_capacity(count);
        for body in &self.bodies {
            let joint = &self.robot.joints[body.joint];
            let axis = pose.joint_axis_world(self.robot, body.joint);
            let screw = if joint.kind == JointKind::Prismatic {
                Motion::prismatic(axis)
            } else {
                Motion::revolute(axis, pose.joint_origin_world(body.joint))
            };
            let (rate, rate_of_rate) = body.drives.iter().fold((0.0, 0.0), |(v, a), &(dof, gain)| {
                (v + gain * qd[dof], a + gain * qdd[dof])
            });
            let (v_parent, a_parent) = body
                .parent
                .map_or((Motion::default(), root), |p| (velocities[p], accelerations[p]));
            let velocity = v_parent.plus(screw.scaled(rate));
            let acceleration = a_parent
                .plus(screw.scaled(rate_of_rate))
                .plus(velocity.cross_motion(screw).scaled(rate));
            screws.push(screw);
            velocities.push(velocity);
            accelerations.push(acceleration);
        }
        let inertias = self
            .parameters
            .iter()
            .zip(&pose.world_from_link)
            .map(|(p, world_from_link)| SpatialInertia::from_link_parameters(p, world_from_link))
            .collect();
        Ok(Motions {
            screws,
            velocities,
            accelerations,
            inertias,
            pose,
        })
    }

    /// Sums what each link needs into its carrying body, then each body's
    /// total into the body above it; returns the sensed joints' torques.
    fn joint_torques(&self, screws: &[Motion], per_link: impl Fn(LinkId) -> Force) -> Vec<f64> {
        let mut carried = vec![Force::default(); self.bodies.len()];
        for (link, carrier) in self.carrier.iter().enumerate() {
            if let Some(b) = *carrier {
                carried[b] = carried[b].plus(per_link(link));
            }
        }
        let mut tau = vec![0.0; self.dof()];
        for b in (0..self.bodies.len()).rev() {
            let torque = screws[b].dot(carried[b]);
            for &(dof, gain) in &self.bodies[b].drives {
                tau[dof] += gain * torque;
            }
            if let Some(p) = self.bodies[b].parent {
                carried[p] = carried[p].plus(carried[b]);
            }
        }
        tau
    }

    /// Inverse dynamics (recursive Newton–Euler): the joint torques that
    /// give accelerations `qdd` at `(q, qd)` under gravity, N·m.
    pub fn inverse_dynamics(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Result<Vec<f64>, DynamicsError> {
        let m = self.motions(q, qd, qdd, true)?;
        Ok(self.joint_torques(&m.screws, |link| {
            let Some(b) = self.carrier[link] else {
                return Force::default();
            };
            let inertia = &m.inertias[link];
            let v = m.velocities[b];
            inertia.apply(m.accelerations[b]).plus(v.cross_force(inertia.apply(v)))
        }))
    }

    /// Gravity's joint torques `g(q)`, N·m.
    pub fn gravity(&self, q: &[f64]) -> Result<Vec<f64>, DynamicsError> {
        let zero = vec![0.0; self.dof()];
        self.inverse_dynamics(q, &zero, &zero)
    }

    /// `C(q, q̇) q̇ + g(q)`, N·m.
    pub fn nonlinear_effects(&self, q: &[f64], qd: &[f64]) -> Result<Vec<f64>, DynamicsError> {
        let zero = vec![0.0; self.dof()];
        self.inverse_dynamics(q, qd, &zero)
    }

    /// The regressor: `Y` (row-major, one row per sensed joint, ten columns
    /// per link in link order) with `inverse_dynamics = Y · parameters`.
    pub fn regressor(&self, q: &[f64], qd: &[f64], qdd: &[f64]) -> Result<Vec<f64>, DynamicsError> {
        let m = self.motions(q, qd, qdd, true)?;
        let columns = self.parameters.len() * 10;
        let mut y = vec![0.0; self.dof() * columns];
        for (link, carrier) in self.carrier.iter().enumerate() {
            let Some(b) = *carrier else { continue };
            let world_from_link = m.pose.world_from_link[link];
            let v = m.velocities[b];
            for p in 0..10 {
                let mut unit = [0.0; 10];
                unit[p] = 1.0;
                let inertia = SpatialInertia::from_link_parameters(&unit, &world_from_link);
                let force = inertia.apply(m.accelerations[b]).plus(v.cross_force(inertia.apply(v)));
                let mut at = Some(b);
                while let Some(i) = at {
                    let torque = m.screws[i].dot(force);
                    for &(dof, gain) in &self.bodies[i].drives {
                        y[dof * columns + link * 10 + p] += gain * torque;
                    }
                    at = self.bodies[i].parent;
                }
            }
        }
        Ok(y)
    }

    /// The columns of the regressor that carry the base inertial
    /// parameters: a largest set of linearly independent columns, found
    /// numerically from the regressor at random states within the joint
    /// limits (seeded). Every other column is a combination of these (or
    /// zero), so a fit over these columns alone identifies everything the
    /// torques can tell about the inertials.
    #[must_use]
    pub fn base_columns(&self) -> Vec<usize> {
        let n = self.dof();
        let columns = self.parameters.len() * 10;
        let mut gram = vec![0.0; columns * columns];
        let mut rng = Rng::new(0x0ba5e);
        let limits: Vec<(f64, f64)> = self
            .robot
            .sensed()
            .iter()
            .map(|&j| {
                self.robot.joints[j]
                    .limits
                    .map_or((-std::f64::consts::PI, std::f64::consts::PI), |l| (l.lower, l.upper))
            })
            .collect();
        for _ in 0..(4 * columns).max(40) {
            let q: Vec<f64> = limits.iter().map(|&(lo, hi)| rng.uniform_in(lo, hi)).collect();
            let qd: Vec<f64> = (0..n).map(|_| rng.uniform_in(-2.0, 2.0)).collect();
            let qdd: Vec<f64> = (0..n).map(|_| rng.uniform_in(-5.0, 5.0)).collect();
            let Ok(y) = self.regressor(&q, &qd, &qdd) else {
                return Vec::new();
            };
            for row in y.chunks_exact(columns) {
                for (i, a) in row.iter().enumerate().filter(|(_, a)| **a != 0.0) {
                    for (j, b) in row.iter().enumerate() {
                        gram[i * columns + j] += a * b;
                    }
                }
            }
        }
        independent_columns(&gram, columns, 1e-10)
    }

    /// The bodies below body `b`, itself included, as a mask.
    fn subtree(&self, b: usize) -> Vec<bool> {
        let mut inside = vec![false; self.bodies.len()];
        inside[b] = true;
        for i in b + 1..self.bodies.len() {
            if let Some(p) = self.bodies[i].parent {
                inside[i] = inside[p];
            }
        }
        inside
    }

    /// The physical joints' matrices `M` and `C` (bodies × bodies, row-major).
    fn body_matrices(&self, m: &Motions, want_coriolis: bool) -> (Vec<f64>, Vec<f64>) {
        let count = self.bodies.len();
        let subtrees: Vec<Vec<bool>> = (0..count).map(|b| self.subtree(b)).collect();
        // Per body: the links it carries, each with the body that moves it.
        let carried: Vec<Vec<(LinkId, usize)>> = (0..count)
            .map(|b| {
                self.carrier
                    .iter()
                    .enumerate()
                    .filter_map(|(l, c)| c.filter(|&c| subtrees[b][c]).map(|c| (l, c)))
                    .collect()
            })
            .collect();
        let links_of = |b: usize| carried[b].iter().copied();
        let composite: Vec<SpatialInertia> = (0..count)
            .map(|b| links_of(b).fold(SpatialInertia::default(), |sum, (l, _)| sum.plus(&m.inertias[l])))
            .collect();
        let mut mass = vec![0.0; count * count];
        let mut mass_rate = vec![0.0; count * count];
        let mut b_matrix = vec![0.0; count * count];
        for k in 0..count {
            let s_k = m.screws[k];
            for j in 0..count {
                let j_above_k = subtrees[j][k];
                let k_above_j = subtrees[k][j] && j != k;
                if !j_above_k && !k_above_j {
                    continue;
                }
                let (deep, shallow) = if j_above_k { (k, j) } else { (j, k) };
                let s_j = m.screws[j];
                mass[k * count + j] = m.screws[deep].dot(composite[deep].apply(m.screws[shallow]));
                if !want_coriolis {
                    continue;
                }
                let v_j = m.velocities[j];
                b_matrix[k * count + j] = if j_above_k {
                    s_k.dot(composite[k].apply(v_j.cross_motion(s_j)))
                } else {
                    let momentum_j = links_of(j).fold(Force::default(), |sum, (l, c)| {
                        sum.plus(m.inertias[l].apply(m.velocities[c]))
                    });
                    s_k.dot(
                        s_j.cross_force(momentum_j)
                            .plus(composite[j].apply(v_j.cross_motion(s_j))),
                    )
                };
                // Ṁ for the deeper row against the shallower column.
                let (s_d, s_s) = (m.screws[deep], m.screws[shallow]);
                let (v_d, v_s) = (m.velocities[deep], m.velocities[shallow]);
                let rate_of_composite = links_of(deep).fold(Force::default(), |sum, (l, c)| {
                    sum.plus(m.inertias[l].rate_apply(m.velocities[c], s_s))
                });
                mass_rate[k * count + j] = v_d.cross_motion(s_d).dot(composite[deep].apply(s_s))
                    + s_d.dot(rate_of_composite)
                    + s_d.dot(composite[deep].apply(v_s.cross_motion(s_s)));
            }
        }
        let mut coriolis = vec![0.0; count * count];
        if want_coriolis {
            for k in 0..count {
                for j in 0..count {
                    coriolis[k * count + j] =
                        0.5 * mass_rate[k * count + j] + 0.5 * (b_matrix[k * count + j] - b_matrix[j * count + k]);
                }
            }
        }
        (mass, coriolis)
    }

    /// Maps a bodies × bodies matrix to the sensed joints: `Gᵀ A G`.
    fn to_sensed(&self, body_matrix: &[f64]) -> Vec<f64> {
        let (count, n) = (self.bodies.len(), self.dof());
        let mut out = vec![0.0; n * n];
        for (a, body_a) in self.bodies.iter().enumerate() {
            for (b, body_b) in self.bodies.iter().enumerate() {
                let value = body_matrix[a * count + b];
                if value == 0.0 {
                    continue;
                }
                for &(da, ga) in &body_a.drives {
                    for &(db, gb) in &body_b.drives {
                        out[da * n + db] += ga * gb * value;
                    }
                }
            }
        }
        out
    }

    /// The joint-space mass matrix `M(q)` (row-major, sensed joints), kg·m².
    pub fn mass_matrix(&self, q: &[f64]) -> Result<Vec<f64>, DynamicsError> {
        let zero = vec![0.0; self.dof()];
        let m = self.motions(q, &zero, &zero, false)?;
        Ok(self.to_sensed(&self.body_matrices(&m, false).0))
    }

    /// The Coriolis matrix `C(q, q̇)` from the Christoffel symbols
    /// (row-major, sensed joints): `C q̇` is the velocity product and
    /// `Ṁ = C + Cᵀ`.
    pub fn coriolis_matrix(&self, q: &[f64], qd: &[f64]) -> Result<Vec<f64>, DynamicsError> {
        let zero = vec![0.0; self.dof()];
        let m = self.motions(q, qd, &zero, false)?;
        Ok(self.to_sensed(&self.body_matrices(&m, true).1))
    }
}

fn check_finite(what: &'static str, values: &[f64]) -> Result<(), DynamicsError> {
    match values.iter().position(|v| !v.is_finite()) {
        Some(index) => Err(DynamicsError::NonFinite {
            what,
            index,
            value: values[index],
        }),
        None => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use glam::{DAffine3, DMat3};

    use super::*;
    use crate::core::robot::model::{JointSpec, LinkSpec};
    use crate::core::robot::spatial::Inertial;

    /// A branched arm: a revolute chain with a prismatic joint held at 0,
    /// a mimic joint and a fixed tool, every link with its own inertia.
    fn arm() -> Robot {
        let inertial = |k: f64| Inertial {
            mass_kg: 1.0 + 0.3 * k,
            com_in_link_m: DVec3::new(0.02 * k, -0.05, 0.1 + 0.01 * k),
            inertia_about_com: DMat3::from_cols_array(&[
                0.02 + 0.001 * k,
                0.001,
                -0.002,
                0.001,
                0.015,
                0.0005 * k,
                -0.002,
                0.0005 * k,
                0.01,
            ]),
        };
        let names = ["base", "a", "b", "c", "d", "finger", "tool"];
        let links: Vec<LinkSpec> = names
            .iter()
            .enumerate()
            .map(|(k, n)| LinkSpec {
                name: (*n).into(),
                inertial: inertial(k as f64),
                ..LinkSpec::default()
            })
            .collect();
        let joint = |name: &str, parent: &str, child: &str, kind, axis: DVec3, origin: DVec3, mimic| JointSpec {
            name: name.into(),
            kind,
            parent: parent.into(),
            child: child.into(),
            parent_from_joint: DAffine3::from_rotation_translation(glam::DQuat::from_rotation_x(0.3), origin),
            axis,
            limits: None,
            mimic,
        };
        let joints = [
            joint(
                "j1",
                "base",
                "a",
                JointKind::Continuous,
                DVec3::Z,
                DVec3::new(0.0, 0.0, 0.3),
                None,
            ),
            joint(
                "j2",
                "a",
                "b",
                JointKind::Continuous,
                DVec3::Y,
                DVec3::new(0.1, 0.0, 0.4),
                None,
            ),
            joint(
                "j3",
                "b",
                "c",
                JointKind::Continuous,
                DVec3::new(1.0, 1.0, 0.0),
                DVec3::new(0.0, 0.2, 0.3),
                None,
            ),
            joint(
                "j4",
                "c",
                "d",
                JointKind::Continuous,
                DVec3::X,
                DVec3::new(0.0, 0.0, 0.25),
                Some(("j2".to_owned(), -0.7, 0.1)),
            ),
            joint(
                "slide",
                "d",
                "finger",
                JointKind::Prismatic,
                DVec3::Z,
                DVec3::new(0.0, 0.0, 0.1),
                None,
            ),
            joint(
                "fixed",
                "c",
                "tool",
                JointKind::Fixed,
                DVec3::Z,
                DVec3::new(0.05, 0.0, 0.2),
                None,
            ),
        ];
        Robot::new("branched", &links, &joints).unwrap()
    }

    fn times(matrix: &[f64], v: &[f64]) -> Vec<f64> {
        let n = v.len();
        (0..n).map(|i| (0..n).map(|j| matrix[i * n + j] * v[j]).sum()).collect()
    }

    const Q: [f64; 3] = [0.4, -0.9, 1.3];
    const QD: [f64; 3] = [0.7, -1.1, 0.5];
    const QDD: [f64; 3] = [-2.0, 0.8, 1.5];

    #[test]
    fn inverse_dynamics_is_mass_matrix_coriolis_and_gravity() {
        let robot = arm();
        let bodies = RigidBodies::new(&robot);
        assert_eq!(bodies.dof(), 3);
        let tau = bodies.inverse_dynamics(&Q, &QD, &QDD).unwrap();
        let m = bodies.mass_matrix(&Q).unwrap();
        let c = bodies.coriolis_matrix(&Q, &QD).unwrap();
        let g = bodies.gravity(&Q).unwrap();
        let (mq, cq) = (times(&m, &QDD), times(&c, &QD));
        for i in 0..3 {
            let sum = mq[i] + cq[i] + g[i];
            assert!((tau[i] - sum).abs() < 1e-12, "joint {i}: {} vs {sum}", tau[i]);
            for j in 0..3 {
                assert!((m[i * 3 + j] - m[j * 3 + i]).abs() < 1e-14, "M symmetric");
            }
        }
    }

    /// `Ṁ = C + Cᵀ` by central differences along `q̇`, and the Christoffel
    /// form `C_ij = ½ Σ_k (∂M_ij/∂q_k + ∂M_ik/∂q_j − ∂M_jk/∂q_i) q̇_k`.
    #[test]
    fn the_coriolis_matrix_is_the_christoffel_one() {
        let robot = arm();
        let bodies = RigidBodies::new(&robot);
        let c = bodies.coriolis_matrix(&Q, &QD).unwrap();
        let h = 1e-5;
        let derivative = |k: usize| {
            let (mut ahead, mut behind) = (Q, Q);
            ahead[k] += h;
            behind[k] -= h;
            let (a, b) = (
                bodies.mass_matrix(&ahead).unwrap(),
                bodies.mass_matrix(&behind).unwrap(),
            );
            a.iter().zip(&b).map(|(x, y)| (x - y) / (2.0 * h)).collect::<Vec<_>>()
        };
        let dm: Vec<Vec<f64>> = (0..3).map(derivative).collect();
        for i in 0..3 {
            for j in 0..3 {
                let christoffel: f64 = (0..3)
                    .map(|k| 0.5 * (dm[k][i * 3 + j] + dm[j][i * 3 + k] - dm[i][j * 3 + k]) * QD[k])
                    .sum();
                assert!(
                    (c[i * 3 + j] - christoffel).abs() < 1e-7,
                    "C[{i}][{j}] {} vs {christoffel}",
                    c[i * 3 + j]
                );
                let m_dot: f64 = (0..3).map(|k| dm[k][i * 3 + j] * QD[k]).sum();
                assert!((m_dot - c[i * 3 + j] - c[j * 3 + i]).abs() < 1e-7, "Ṁ[{i}][{j}]");
            }
        }
    }

    #[test]
    fn the_regressor_times_the_parameters_is_inverse_dynamics() {
        let robot = arm();
        let bodies = RigidBodies::new(&robot);
        let y = bodies.regressor(&Q, &QD, &QDD).unwrap();
        let tau = bodies.inverse_dynamics(&Q, &QD, &QDD).unwrap();
        let pi = bodies.parameters();
        for (i, t) in tau.iter().enumerate() {
            let row: f64 = (0..pi.len()).map(|c| y[i * pi.len() + c] * pi[c]).sum();
            assert!((row - t).abs() < 1e-12, "joint {i}: {row} vs {t}");
        }
        // The base link and the held finger's parameters reach no torque
        // through velocity; the base's none at all.
        assert!((0..3).all(|i| (0..10).all(|c| y[i * pi.len() + c] == 0.0)));
        assert_eq!(bodies.moving_links(), vec![1, 2, 3, 4, 5, 6]);
    }

    /// The base columns reproduce every torque: a least-squares fit over
    /// them alone matches inverse dynamics at fresh states.
    #[test]
    fn the_base_columns_carry_every_torque() {
        use crate::core::numerics::linalg::solve_spd;
        let robot = arm();
        let bodies = RigidBodies::new(&robot);
        let base = bodies.base_columns();
        assert!(!base.is_empty() && base.len() < 70, "{base:?}");
        let pi = bodies.parameters();
        let columns = pi.len();
        let states: Vec<[[f64; 3]; 3]> = (0..40)
            .map(|k| {
                let f = f64::from(k);
                [
                    [0.1 * f, (0.37 * f).sin(), (0.21 * f).cos()],
                    [(0.5 * f).sin(), -0.3 + 0.02 * f, (1.3 * f).cos()],
                    [(0.9 * f).cos(), (0.4 * f).sin() * 2.0, 1.0 - 0.05 * f],
                ]
            })
            .collect();
        let p = base.len();
        let (mut gram, mut rhs) = (vec![0.0; p * p], vec![0.0; p]);
        for [q, qd, qdd] in &states[..30] {
            let y = bodies.regressor(q, qd, qdd).unwrap();
            let tau = bodies.inverse_dynamics(q, qd, qdd).unwrap();
            for (row, t) in y.chunks_exact(columns).zip(&tau) {
                for (a, &ca) in base.iter().enumerate() {
                    rhs[a] += row[ca] * t;
                    for (b, &cb) in base.iter().enumerate() {
                        gram[a * p + b] += row[ca] * row[cb];
                    }
                }
            }
        }
        let beta = solve_spd(&gram, &rhs).unwrap();
        for [q, qd, qdd] in &states[30..] {
            let y = bodies.regressor(q, qd, qdd).unwrap();
            let tau = bodies.inverse_dynamics(q, qd, qdd).unwrap();
            for (row, t) in y.chunks_exact(columns).zip(&tau) {
                let fitted: f64 = base.iter().zip(&beta).map(|(&c, b)| row[c] * b).sum();
                assert!((fitted - t).abs() < 1e-8, "{fitted} vs {t}");
            }
        }
    }

    #[test]
    fn bad_inputs_are_refused_by_name() {
        let robot = arm();
        let bodies = RigidBodies::new(&robot);
        let err = bodies.inverse_dynamics(&Q, &[0.0; 2], &QDD).unwrap_err();
        assert!(err.to_string().contains("joint velocities"), "{err}");
        let err = bodies.inverse_dynamics(&Q, &QD, &[0.0, f64::NAN, 0.0]).unwrap_err();
        assert!(err.to_string().contains("joint accelerations[1]"), "{err}");
        let err = bodies.gravity(&[0.0; 4]).unwrap_err();
        assert!(err.to_string().contains("expected 3"), "{err}");
        assert!(bodies.clone().with_parameters(&[0.0; 3]).is_err());
    }
}
