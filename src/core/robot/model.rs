//! The kinematic tree of a robot: links, joints and the joints that sense torque.

use std::collections::HashMap;

use glam::{DAffine3, DVec3};

use crate::core::geometry::mesh::TriMesh;
use crate::core::robot::spatial::Inertial;

/// Index of a link in [`Robot::links`].
pub type LinkId = usize;
/// Index of a joint in [`Robot::joints`].
pub type JointId = usize;

/// How a joint moves its child.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum JointKind {
    /// Rotation about the axis within limits.
    Revolute,
    /// Rotation about the axis without limits.
    Continuous,
    /// Translation along the axis.
    Prismatic,
    /// No motion.
    Fixed,
}

impl JointKind {
    /// True for every kind but [`JointKind::Fixed`].
    #[must_use]
    pub fn is_movable(self) -> bool {
        self != Self::Fixed
    }

    /// True for revolute and continuous joints.
    #[must_use]
    pub fn is_rotational(self) -> bool {
        matches!(self, Self::Revolute | Self::Continuous)
    }
}

/// Position limits of a joint (rad or m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct JointLimits {
    /// Lowest position.
    pub lower: f64,
    /// Highest position.
    pub upper: f64,
}

/// A joint that copies another: `q = multiplier * q_leader + offset`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Mimic {
    /// The joint followed.
    pub leader: JointId,
    /// Gain on the leader's position.
    pub multiplier: f64,
    /// Offset added, rad or m.
    pub offset: f64,
}

/// A joint of the tree.
#[derive(Debug, Clone, PartialEq)]
pub struct Joint {
    /// Name, unique in the robot.
    pub name: String,
    /// How it moves.
    pub kind: JointKind,
    /// The link it hangs from.
    pub parent: LinkId,
    /// The link it moves.
    pub child: LinkId,
    /// The joint frame in the parent link's frame (URDF `<origin>`).
    pub parent_from_joint: DAffine3,
    /// Unit axis in the joint frame.
    pub axis: DVec3,
    /// Position limits; `None` for continuous and fixed joints.
    pub limits: Option<JointLimits>,
    /// Set when this joint follows another.
    pub mimic: Option<Mimic>,
}

/// A rigid body of the tree.
#[derive(Debug, Clone, PartialEq)]
pub struct Link {
    /// Name, unique in the robot.
    pub name: String,
    /// The joint that moves it; `None` for the root.
    pub parent_joint: Option<JointId>,
    /// Joints that hang from it, in declaration order.
    pub child_joints: Vec<JointId>,
    /// Visual surface in the link frame (may be empty).
    pub mesh: TriMesh,
    /// For one-dimensional links (the thesis' simple robot): the segment in
    /// the link frame on which contacts lie. The mesh is then only for display.
    pub segment: Option<[DVec3; 2]>,
    /// Mass properties (zero where the description gives none).
    pub inertial: Inertial,
}

/// A link as given to [`Robot::new`].
#[derive(Debug, Clone, Default)]
pub struct LinkSpec {
    /// Link name.
    pub name: String,
    /// Visual mesh in the link frame.
    pub mesh: TriMesh,
    /// See [`Link::segment`].
    pub segment: Option<[DVec3; 2]>,
    /// See [`Link::inertial`].
    pub inertial: Inertial,
}

/// A joint as given to [`Robot::new`], naming its links.
#[derive(Debug, Clone)]
pub struct JointSpec {
    /// Joint name.
    pub name: String,
    /// Joint kind.
    pub kind: JointKind,
    /// Parent link name.
    pub parent: String,
    /// Child link name.
    pub child: String,
    /// Joint frame in the parent link frame.
    pub parent_from_joint: DAffine3,
    /// Axis in the joint frame (normalised by [`Robot::new`]).
    pub axis: DVec3,
    /// Limits, for revolute and prismatic joints.
    pub limits: Option<JointLimits>,
    /// `(leader name, multiplier, offset)`.
    pub mimic: Option<(String, f64, f64)>,
}

/// What is wrong with a robot description.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum RobotError {
    /// The description has no link.
    #[error("the robot has no link")]
    NoLinks,
    /// Two links share a name.
    #[error("two links are named '{name}'")]
    DuplicateLink {
        /// The repeated name.
        name: String,
    },
    /// Two joints share a name.
    #[error("two joints are named '{name}'")]
    DuplicateJoint {
        /// The repeated name.
        name: String,
    },
    /// A joint names a link that does not exist.
    #[error("joint '{joint}' names link '{link}', which does not exist")]
    UnknownLink {
        /// The joint.
        joint: String,
        /// The missing link.
        link: String,
    },
    /// A link is the child of two joints.
    #[error("link '{link}' is the child of two joints, '{first}' and '{second}': a robot must be a tree")]
    TwoParents {
        /// The link.
        link: String,
        /// One parent joint.
        first: String,
        /// The other parent joint.
        second: String,
    },
    /// More than one link has no parent.
    #[error("the tree is disconnected: links {roots:?} have no parent joint (exactly one root is allowed)")]
    Disconnected {
        /// The links without parent.
        roots: Vec<String>,
    },
    /// The joints form a loop.
    #[error("the joints form a cycle through links {links:?}")]
    Cycle {
        /// Links on or below the cycle.
        links: Vec<String>,
    },
    /// A movable joint's axis is zero or not finite.
    #[error("joint '{joint}' has a zero or non-finite axis {axis:?}")]
    BadAxis {
        /// The joint.
        joint: String,
        /// The axis given.
        axis: [f64; 3],
    },
    /// A joint origin is not finite.
    #[error("joint '{joint}' has a non-finite origin")]
    BadOrigin {
        /// The joint.
        joint: String,
    },
    /// Lower limit above upper limit, or non-finite limits on a revolute joint.
    #[error("joint '{joint}' has limits [{lower}, {upper}], which are empty or not finite")]
    BadLimits {
        /// The joint.
        joint: String,
        /// Lower limit.
        lower: f64,
        /// Upper limit.
        upper: f64,
    },
    /// A mimic joint follows a joint that does not exist or cannot lead.
    #[error("joint '{joint}' mimics '{leader}', which is not a movable joint without mimic of its own")]
    BadMimic {
        /// The follower.
        joint: String,
        /// The leader named.
        leader: String,
    },
    /// A joint name was asked for and not found.
    #[error("the robot has no joint named '{name}' (joints: {known}; was the file made on another robot?)")]
    UnknownJoint {
        /// The name.
        name: String,
        /// The robot's joint names, comma separated.
        known: String,
    },
    /// A link name was asked for and not found.
    #[error("the robot has no link named '{name}' (links: {known})")]
    NoSuchLink {
        /// The name.
        name: String,
        /// The robot's link names, comma separated.
        known: String,
    },
    /// A joint chosen as sensed cannot carry a torque sensor.
    #[error("joint '{name}' cannot be a sensed joint: it is fixed or mimics another joint")]
    NotSensable {
        /// The joint.
        name: String,
    },
    /// The same joint is listed twice as sensed.
    #[error("joint '{name}' is listed twice among the sensed joints")]
    SensedTwice {
        /// The joint.
        name: String,
    },
    /// A joint value vector of the wrong length.
    #[error("expected {expected} joint values ({names}), got {got}")]
    WrongJointCount {
        /// Number of sensed joints.
        expected: usize,
        /// Number given.
        got: usize,
        /// The sensed joint names, comma separated.
        names: String,
    },
    /// A joint value that is NaN or infinite.
    #[error("joint '{joint}' has the non-finite value {value}")]
    NonFiniteJointValue {
        /// The joint.
        joint: String,
        /// The value.
        value: f64,
    },
}

/// A robot arm as a kinematic tree.
#[derive(Debug, Clone, PartialEq)]
pub struct Robot {
    /// Robot name.
    pub name: String,
    /// All links; index with [`LinkId`].
    pub links: Vec<Link>,
    /// All joints; index with [`JointId`].
    pub joints: Vec<Joint>,
    /// The link without parent.
    pub root: LinkId,
    /// Joints in depth-first order from the root (parents before children).
    pub joint_order: Vec<JointId>,
    /// The joints with a torque sensor, in the order of `q` and `tau`.
    sensed: Vec<JointId>,
}

impl Robot {
    /// Builds and checks a robot: names unique, one root, no cycle, unit
    /// axes, sane limits. Sensed joints default to every revolute and
    /// continuous joint without mimic, depth-first from the root.
    #[allow(clippy::too_many_lines)] // One validation pass, best read top to bottom.
    pub fn new(name: &str, links: &[LinkSpec], joints: &[JointSpec]) -> Result<Self, RobotError> {
        if links.is_empty() {
            return Err(RobotError::NoLinks);
        }
        let mut link_index: HashMap<&str, LinkId> = HashMap::new();
        for (i, l) in links.iter().enumerate() {
            if link_index.insert(l.name.as_str(), i).is_some() {
                return Err(RobotError::DuplicateLink { name: l.name.clone() });
            }
        }
        let mut joint_index: HashMap<&str, JointId> = HashMap::new();
        for (i, j) in joints.iter().enumerate() {
            if joint_index.insert(j.name.as_str(), i).is_some() {
                return Err(RobotError::DuplicateJoint { name: j.name.clone() });
            }
        }
        let mut built_links: Vec<Link> = links
            .iter()
            .map(|l| Link {
                name: l.name.clone(),
                parent_joint: None,
                child_joints: Vec::new(),
                mesh: l.mesh.clone(),
                segment: l.segment,
                inertial: l.inertial,
            })
            .collect();
        let mut built_joints = Vec::with_capacity(joints.len());
        for (ji, j) in joints.iter().enumerate() {
            let lookup = |link: &str| {
                link_index.get(link).copied().ok_or_else(|| RobotError::UnknownLink {
                    joint: j.name.clone(),
                    link: link.to_owned(),
                })
            };
            let parent = lookup(&j.parent)?;
            let child = lookup(&j.child)?;
            if let Some(first) = built_links[child].parent_joint {
                return Err(RobotError::TwoParents {
                    link: j.child.clone(),
                    first: joints[first].name.clone(),
                    second: j.name.clone(),
                });
            }
            built_links[child].parent_joint = Some(ji);
            built_links[parent].child_joints.push(ji);
            if !j.parent_from_joint.is_finite() {
                return Err(RobotError::BadOrigin { joint: j.name.clone() });
            }
            let axis = if j.kind.is_movable() {
                j.axis.try_normalize().ok_or_else(|| RobotError::BadAxis {
                    joint: j.name.clone(),
                    axis: j.axis.to_array(),
                })?
            } else {
                j.axis.try_normalize().unwrap_or(DVec3::Z)
            };
            let limits = match j.kind {
                JointKind::Revolute | JointKind::Prismatic => j.limits,
                JointKind::Continuous | JointKind::Fixed => None,
            };
            if let Some(l) = limits
                && (l.lower > l.upper || l.lower.is_nan() || l.upper.is_nan())
            {
                return Err(RobotError::BadLimits {
                    joint: j.name.clone(),
                    lower: l.lower,
                    upper: l.upper,
                });
            }
            let mimic = match &j.mimic {
                None => None,
                Some((leader, multiplier, offset)) => {
                    let bad = || RobotError::BadMimic {
                        joint: j.name.clone(),
                        leader: leader.clone(),
                    };
                    let li = *joint_index.get(leader.as_str()).ok_or_else(bad)?;
                    let lj = &joints[li];
                    if !lj.kind.is_movable() || lj.mimic.is_some() || li == ji {
                        return Err(bad());
                    }
                    Some(Mimic {
                        leader: li,
                        multiplier: *multiplier,
                        offset: *offset,
                    })
                }
            };
            built_joints.push(Joint {
                name: j.name.clone(),
                kind: j.kind,
                parent,
                child,
                parent_from_joint: j.parent_from_joint,
                axis,
                limits,
                mimic,
            });
        }
        let roots: Vec<LinkId> = (0..built_links.len())
            .filter(|&i| built_links[i].parent_joint.is_none())
            .collect();
        let root = match roots.as_slice() {
            [r] => *r,
            [] => {
                return Err(RobotError::Cycle {
                    links: built_links.iter().map(|l| l.name.clone()).collect(),
                });
            }
            _ => {
                return Err(RobotError::Disconnected {
                    roots: roots.iter().map(|&r| built_links[r].name.clone()).collect(),
                });
            }
        };
        let mut joint_order = Vec::with_capacity(built_joints.len());
        let mut reached = vec![false; built_links.len()];
        let mut stack = vec![root];
        while let Some(l) = stack.pop() {
            reached[l] = true;
            // Reverse so that the first declared child is visited first.
            for &j in built_links[l].child_joints.iter().rev() {
                stack.push(built_joints[j].child);
            }
            if let Some(j) = built_links[l].parent_joint {
                joint_order.push(j);
            }
        }
        if reached.iter().any(|r| !r) {
            return Err(RobotError::Cycle {
                links: (0..built_links.len())
                    .filter(|&i| !reached[i])
                    .map(|i| built_links[i].name.clone())
                    .collect(),
            });
        }
        let sensed = joint_order
            .iter()
            .copied()
            .filter(|&j| built_joints[j].kind.is_rotational() && built_joints[j].mimic.is_none())
            .collect();
        Ok(Self {
            name: name.to_owned(),
            links: built_links,
            joints: built_joints,
            root,
            joint_order,
            sensed,
        })
    }

    /// The sensed joints, in the order of `q` and `tau`.
    #[must_use]
    pub fn sensed(&self) -> &[JointId] {
        &self.sensed
    }

    /// Names of the sensed joints, in order.
    #[must_use]
    pub fn sensed_names(&self) -> Vec<&str> {
        self.sensed.iter().map(|&j| self.joints[j].name.as_str()).collect()
    }

    /// Chooses the sensed joints by name (a session's `joints` list).
    pub fn set_sensed<S: AsRef<str>>(&mut self, names: &[S]) -> Result<(), RobotError> {
        let mut sensed = Vec::with_capacity(names.len());
        for name in names {
            let name = name.as_ref();
            let j = self.joint_id(name)?;
            let joint = &self.joints[j];
            if !joint.kind.is_movable() || joint.mimic.is_some() {
                return Err(RobotError::NotSensable { name: name.to_owned() });
            }
            if sensed.contains(&j) {
                return Err(RobotError::SensedTwice { name: name.to_owned() });
            }
            sensed.push(j);
        }
        self.sensed = sensed;
        Ok(())
    }

    /// The joint called `name`.
    pub fn joint_id(&self, name: &str) -> Result<JointId, RobotError> {
        self.joints
            .iter()
            .position(|j| j.name == name)
            .ok_or_else(|| RobotError::UnknownJoint {
                name: name.to_owned(),
                known: comma_separated(self.joints.iter().map(|j| j.name.as_str())),
            })
    }

    /// The link called `name`.
    pub fn link_id(&self, name: &str) -> Result<LinkId, RobotError> {
        self.links
            .iter()
            .position(|l| l.name == name)
            .ok_or_else(|| RobotError::NoSuchLink {
                name: name.to_owned(),
                known: comma_separated(self.links.iter().map(|l| l.name.as_str())),
            })
    }

    /// Movable joints from the root to `link`, root first.
    #[must_use]
    pub fn path_joints(&self, link: LinkId) -> Vec<JointId> {
        let mut path = Vec::new();
        let mut at = link;
        while let Some(j) = self.links.get(at).and_then(|l| l.parent_joint) {
            if self.joints[j].kind.is_movable() {
                path.push(j);
            }
            at = self.joints[j].parent;
        }
        path.reverse();
        path
    }

    /// How many sensed joints lie on `link`'s path: the joints whose
    /// torques a push on it reaches.
    #[must_use]
    pub fn sensing_joints(&self, link: LinkId) -> usize {
        let path = self.path_joints(link);
        self.sensed.iter().filter(|j| path.contains(j)).count()
    }

    /// Links moved by at least one revolute or continuous joint and with a
    /// surface (mesh or segment): the default candidate links.
    #[must_use]
    pub fn default_candidate_links(&self) -> Vec<LinkId> {
        (0..self.links.len())
            .filter(|&l| {
                let link = &self.links[l];
                (!link.mesh.is_empty() || link.segment.is_some())
                    && self.path_joints(l).iter().any(|&j| self.joints[j].kind.is_rotational())
            })
            .collect()
    }

    /// Positions of every joint (indexed by [`JointId`]) from the sensed
    /// joints' values `q`; other movable joints take `others` by name or 0;
    /// mimic joints follow their leader.
    pub fn joint_positions(&self, q: &[f64], others: &[(String, f64)]) -> Result<Vec<f64>, RobotError> {
        if q.len() != self.sensed.len() {
            return Err(RobotError::WrongJointCount {
                expected: self.sensed.len(),
                got: q.len(),
                names: self.sensed_names().join(", "),
            });
        }
        let mut all = vec![0.0; self.joints.len()];
        for (name, value) in others {
            all[self.joint_id(name)?] = *value;
        }
        for (&j, &value) in self.sensed.iter().zip(q) {
            all[j] = value;
        }
        for (j, joint) in self.joints.iter().enumerate() {
            if let Some(m) = joint.mimic {
                all[j] = m.multiplier * all[m.leader] + m.offset;
            }
            if !all[j].is_finite() {
                return Err(RobotError::NonFiniteJointValue {
                    joint: joint.name.clone(),
                    value: all[j],
                });
            }
        }
        Ok(all)
    }

    /// For each sensed joint (in order), the physical joints it drives with
    /// their gains: itself with 1, and each mimic follower with its multiplier.
    #[must_use]
    pub fn sensed_drives(&self) -> Vec<Vec<(JointId, f64)>> {
        self.sensed
            .iter()
            .map(|&s| {
                let mut drives = vec![(s, 1.0)];
                drives.extend(
                    self.joints
                        .iter()
                        .enumerate()
                        .filter_map(|(j, joint)| joint.mimic.filter(|m| m.leader == s).map(|m| (j, m.multiplier))),
                );
                drives
            })
            .collect()
    }
}

/// Names joined with commas, for messages that list what there is.
fn comma_separated<'a>(names: impl Iterator<Item = &'a str>) -> String {
    names.collect::<Vec<_>>().join(", ")
}

#[cfg(test)]
mod tests {
    use super::*;

    fn link(name: &str) -> LinkSpec {
        LinkSpec {
            name: name.to_owned(),
            ..LinkSpec::default()
        }
    }

    fn joint(name: &str, kind: JointKind, parent: &str, child: &str) -> JointSpec {
        JointSpec {
            name: name.to_owned(),
            kind,
            parent: parent.to_owned(),
            child: child.to_owned(),
            parent_from_joint: DAffine3::IDENTITY,
            axis: DVec3::Z,
            limits: None,
            mimic: None,
        }
    }

    fn err(links: &[&str], joints: &[JointSpec]) -> String {
        Robot::new("r", &links.iter().map(|n| link(n)).collect::<Vec<_>>(), joints)
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
    }

    #[test]
    fn branching_tree_orders_joints_depth_first_and_senses_revolutes() {
        let mut finger = joint("f2", JointKind::Prismatic, "hand", "finger2");
        finger.mimic = Some(("f1".to_owned(), 1.0, 0.0));
        let robot = Robot::new(
            "r",
            &["base", "l1", "hand", "finger1", "finger2"]
                .iter()
                .map(|n| link(n))
                .collect::<Vec<_>>(),
            &[
                joint("j1", JointKind::Revolute, "base", "l1"),
                joint("fix", JointKind::Fixed, "l1", "hand"),
                joint("f1", JointKind::Prismatic, "hand", "finger1"),
                finger,
            ],
        );
        let robot = robot.unwrap_or_else(|e| panic!("{e}"));
        assert_eq!(robot.sensed_names(), vec!["j1"]);
        assert_eq!(robot.joint_order, vec![0, 1, 2, 3]);
        let f2 = robot.link_id("finger2").unwrap_or(0);
        assert_eq!(robot.path_joints(f2), vec![0, 3]);
        // Of its path, j1 is sensed; the finger's own joints are not.
        assert_eq!(robot.sensing_joints(f2), 1);
        let q = robot.joint_positions(&[0.3], &[("f1".to_owned(), 0.02)]);
        assert_eq!(q, Ok(vec![0.3, 0.0, 0.02, 0.02]));
    }

    #[test]
    fn an_unknown_joint_is_named_beside_the_robots_joints() {
        let robot = Robot::new(
            "r",
            &["base", "l1", "l2"].iter().map(|n| link(n)).collect::<Vec<_>>(),
            &[
                joint("j1", JointKind::Revolute, "base", "l1"),
                joint("j2", JointKind::Revolute, "l1", "l2"),
            ],
        )
        .unwrap_or_else(|e| panic!("{e}"));
        let e = robot
            .joint_id("lwr_a1_joint")
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(e.contains("'lwr_a1_joint'") && e.contains("joints: j1, j2"), "{e}");
    }

    #[test]
    fn cycle_is_named() {
        let e = err(
            &["base", "a", "b"],
            &[
                joint("j1", JointKind::Revolute, "a", "b"),
                joint("j2", JointKind::Revolute, "b", "a"),
            ],
        );
        assert!(e.contains("cycle") && e.contains("\"a\"") && e.contains("\"b\""), "{e}");
    }

    #[test]
    fn disconnected_tree_names_its_roots() {
        let e = err(
            &["base", "a", "island"],
            &[joint("j1", JointKind::Revolute, "base", "a")],
        );
        assert!(
            e.contains("disconnected") && e.contains("island") && e.contains("base"),
            "{e}"
        );
    }

    #[test]
    fn zero_axis_is_named() {
        let mut j = joint("elbow", JointKind::Revolute, "base", "a");
        j.axis = DVec3::ZERO;
        let e = err(&["base", "a"], &[j]);
        assert!(e.contains("elbow") && e.contains("zero"), "{e}");
    }

    #[test]
    fn two_parents_unknown_link_and_bad_limits_are_named() {
        let e = err(
            &["base", "a"],
            &[
                joint("j1", JointKind::Revolute, "base", "a"),
                joint("j2", JointKind::Revolute, "base", "a"),
            ],
        );
        assert!(e.contains("'a'") && e.contains("j1") && e.contains("j2"), "{e}");
        let e = err(&["base"], &[joint("j1", JointKind::Revolute, "base", "ghost")]);
        assert!(e.contains("ghost") && e.contains("j1"), "{e}");
        let mut j = joint("j1", JointKind::Revolute, "base", "a");
        j.limits = Some(JointLimits {
            lower: 1.0,
            upper: -1.0,
        });
        let e = err(&["base", "a"], &[j]);
        assert!(e.contains("j1") && e.contains("limits"), "{e}");
    }

    #[test]
    fn wrong_joint_count_and_nan_are_named() {
        let robot = Robot::new(
            "r",
            &[link("base"), link("a")],
            &[joint("shoulder", JointKind::Revolute, "base", "a")],
        );
        let robot = robot.unwrap_or_else(|e| panic!("{e}"));
        let e = robot
            .joint_positions(&[0.0, 1.0], &[])
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(
            e.contains("expected 1") && e.contains("got 2") && e.contains("shoulder"),
            "{e}"
        );
        let e = robot
            .joint_positions(&[f64::NAN], &[])
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default();
        assert!(e.contains("shoulder") && e.contains("NaN"), "{e}");
    }
}
