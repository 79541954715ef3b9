//! Whether the torques can tell a pair of contacts apart, and why not
//! where they cannot ([`Unidentifiable`]).
//!
//! Two contacts have six unknowns (two surface coordinates and a
//! magnitude each). Where fewer than six sensed joints feel either of
//! them, fewer than three feel one of them (its three unknowns then take
//! up any torques on its joints: on the `../shared` observer link-side
//! example, filtered, 119 of 123 false pairs put a push on link 1 or 2 to
//! take up the model error there), or their torques per newton point the
//! same way, the pair is not identifiable
//! ([`crate::core::estimate::pair::PairEstimate::identifiable`]): the
//! report says so rather than call it a confident pair. So is a pair on one link where contacts have
//! friction (μ > 0): the joints feel only the link's net wrench, and one
//! contact pushing sideways makes every such wrench but for one number
//! (its pitch, the moment along its own force), so a pair there is one
//! contact's friction, or a model error, told apart by that number alone
//! (on the `../shared` observer link-side example, smoothed, 26 of its 35
//! false pairs were on link 6 twice). For the same reason, where contacts
//! have friction, so is a pair whose contact farther out is not confirmed
//! by its own joints (those that do not feel the other's link): where all
//! of them, or all but one, read it within the noise, its torques fall on
//! the other contact's joints, where that contact's friction frees two
//! more unknowns (the false pairs of the `../shared` slides and dynamic
//! link-6 example sat there); and so is a pair one of whose contacts
//! alone, pushing sideways at its place, explains the torques within the
//! noise (the other is its friction, on whichever link).

use glam::DVec3;

use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{LinkId, Robot};
use crate::core::robot::torque::{TorqueModel, joint_torques, weighted_dot};

/// Two torques per newton whose cosine (in the noise's metric) is above
/// this trade their magnitudes: the pair is not identifiable.
pub const COLLINEAR_COSINE: f64 = 0.98;

/// Why a pair is not identifiable (see the module docs).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unidentifiable {
    /// Fewer than six sensed joints feel either contact.
    FewJoints,
    /// One contact's link is felt by fewer than three sensed joints: its
    /// place and magnitude (three unknowns) take up any torques there,
    /// as a model error near the base.
    FewJointsForOne {
        /// Sensed joints that feel that contact's link.
        joints: usize,
    },
    /// The two contacts' torques per newton point the same way.
    SameTorques,
    /// Both on one link where contacts have friction: one contact
    /// pushing sideways makes the same torques but for one number.
    OneLinkWithFriction,
    /// Where contacts have friction, a contact that its own joints (those
    /// that do not feel the other contact's link) do not confirm: none of
    /// them, or only one of several, reads it above the noise. Its
    /// torques fall on the other contact's joints, where that contact's
    /// friction frees two more unknowns: the pair is one contact pushing
    /// sideways, or a model error, told apart by one reading or none.
    Unconfirmed,
    /// Where contacts have friction, one of the two alone, pushing
    /// sideways at its place, explains the torques within the noise: the
    /// other push is its friction (on the `../shared` two-contact example,
    /// surface seed 1, a 4–5 N push on link 5 beside the link-7 probe
    /// while that probe's force turned 12° as it drifted).
    OneExplains,
    /// Neither contact is on the link of the push that last explained a
    /// frame alone, earlier in the same contact, and that push explains
    /// this frame too with its force's direction kept
    /// ([`crate::core::estimate::estimator::Estimator::held_push_explains`]):
    /// a slide whose kinetic friction drags beyond the friction cone.
    HeldExplains,
    /// The frame's single contact, its force free at its place (any
    /// direction: a slide's kinetic friction beyond the cone), leaves the
    /// torques within [`FREE_PUSH_MARGIN_CHI2`] of the pair's residual
    /// (or, where frames are called from the frames before them only, a
    /// free push within [`NEAR_FREE_PUSH_RADIUS_M`] of it, or of the last
    /// single contact to explain its frame where the pair left that
    /// contact's link, within [`NEAR_FREE_PUSH_MARGIN_CHI2`]): the pair is
    /// that contact's friction.
    FreeExplains,
}

impl Unidentifiable {
    /// In words, for a pair felt by `sensing_joints` joints.
    #[must_use]
    pub fn describe(self, sensing_joints: usize) -> String {
        match self {
            Self::FewJoints => format!("{sensing_joints} joints sense the pair"),
            Self::FewJointsForOne { joints } => format!("one push is felt by {joints} joints only"),
            Self::SameTorques => "its two pushes make the same torques".to_owned(),
            Self::OneLinkWithFriction => "with friction, two on one link are one pushing sideways".to_owned(),
            Self::Unconfirmed => "one push is not felt by the joints that only it moves".to_owned(),
            Self::OneExplains => "one push alone, with friction, explains the torques".to_owned(),
            Self::HeldExplains => "the push held before, its force's direction kept, explains the torques".to_owned(),
            Self::FreeExplains => "the single contact, its force free, explains the torques as well".to_owned(),
        }
    }
}

/// How much lower, χ², a frame's pair must leave the torques than its
/// single contact with its force free (three components fitted at its
/// place) to be told from that contact's friction: the 99th percentile
/// of χ² with three degrees of freedom, what the pair's three spare
/// unknowns take up by chance where one contact pushes. On a generated
/// link 7 slide with kinetic friction (`synth --seed 2 --links lwr_7_link
/// --slide 0.1 --slide-min 0.02 --kinetic-friction 0.3,0.6
/// --avoid-covered`) the 43 identifiable pairs its frames found were
/// from 78 lower to 10.9 higher than that; on two generated two-hand
/// sessions the 73 found where both hands press, 17.7 to 345 higher.
pub const FREE_PUSH_MARGIN_CHI2: f64 = 11.34;

/// How far from a filtered single contact, m, the free push that a pair
/// must beat is also searched (any link): a filtered slide's single
/// contact lags the slide by 15–24 mm, or sits across the joint from it,
/// on the generated links 6–7 slides. 6 cm also took the shared
/// two-contact example's pairs (0–1 of 83 frames called two, filtered),
/// whose two probes a push on link 6 between them explains.
pub const NEAR_FREE_PUSH_RADIUS_M: f64 = 0.03;

/// How much lower, χ², a filtered frame's pair must leave the torques
/// than the best free push within [`NEAR_FREE_PUSH_RADIUS_M`]: the 99th
/// percentile of χ² with one degree of freedom, as that push's place is
/// searched too (five unknowns against the pair's six).
pub const NEAR_FREE_PUSH_MARGIN_CHI2: f64 = 6.63;

/// Why the pair of pushes on links `a` and `b`, making `torques_a` and
/// `torques_b`, felt by `sensing_joints` sensed joints, cannot be told
/// apart by the torques, `friction` whether contacts have it (see the
/// module docs); all but the rule that one push alone explains the
/// torques, which needs the frame's torques and friction model
/// ([`Unidentifiable::OneExplains`]).
pub(super) fn unidentifiable_by_joints(
    torque_model: &TorqueModel,
    weights: &[f64],
    friction: bool,
    sensing_joints: usize,
    (a, torques_a): (LinkId, &[f64]),
    (b, torques_b): (LinkId, &[f64]),
) -> Option<Unidentifiable> {
    let fewest = sensing(torque_model, a, a).min(sensing(torque_model, b, b));
    if sensing_joints < 6 {
        Some(Unidentifiable::FewJoints)
    } else if fewest < 3 {
        Some(Unidentifiable::FewJointsForOne { joints: fewest })
    } else if weighted_cosine(torques_a, torques_b, weights).abs() >= COLLINEAR_COSINE {
        Some(Unidentifiable::SameTorques)
    } else if friction && a == b {
        Some(Unidentifiable::OneLinkWithFriction)
    } else if friction
        && !(confirmed(torque_model, (a, torques_a), b, weights) && confirmed(torque_model, (b, torques_b), a, weights))
    {
        Some(Unidentifiable::Unconfirmed)
    } else {
        None
    }
}

/// Why two pushes known in full (each its link, world place, m, and the
/// world force on the robot, N), at `pose`, could not be told apart by
/// the joints' rules of a pair ([`Unidentifiable`] but for the rules
/// that need a frame's torques), with `weights` (1/σ²) and `friction`
/// whether contacts have it: what a session's true pair must pass for
/// any estimate to call it. `None`: the joints can tell them apart.
#[must_use]
pub fn pushes_unidentifiable(
    robot: &Robot,
    pose: &RobotPose,
    (weights, friction): (&[f64], bool),
    [(a, point_a, force_a), (b, point_b, force_b)]: [(LinkId, DVec3, DVec3); 2],
) -> Option<Unidentifiable> {
    let torque_model = TorqueModel::new(robot, pose, &[a, b]);
    let torques_a = joint_torques(robot, pose, a, point_a, force_a);
    let torques_b = joint_torques(robot, pose, b, point_b, force_b);
    unidentifiable_by_joints(
        &torque_model,
        weights,
        friction,
        sensing(&torque_model, a, b),
        (a, &torques_a),
        (b, &torques_b),
    )
}

/// A joint feels a contact when the contact's torque there is at least
/// this many noise σ. The false second contacts of the `../shared`
/// link-4 slide sat on link 6 where joints 5 and 6 read 0.1–0.2 σ of
/// them: pairs that their own joints do not confirm.
pub const FELT_SIGMAS: f64 = 1.0;

/// Sensed joints that feel a push on either of two links.
pub(super) fn sensing(torque_model: &TorqueModel, a: LinkId, b: LinkId) -> usize {
    let mut felt = vec![false; torque_model.sensed_count()];
    for link in [a, b] {
        for twist in torque_model.twists(link) {
            if let Some(slot) = felt.get_mut(twist.sensed_index) {
                *slot = true;
            }
        }
    }
    felt.iter().filter(|&&f| f).count()
}

/// Whether the push `one` (its link and torques) is confirmed by its own
/// joints (those that do not feel `other`, the other push's link): at least one, and all but one at most, read it above the
/// noise ([`FELT_SIGMAS`], `weights` = 1/σ²). True where it has no such
/// joint (a link nearer the base). Each own joint that reads nothing of
/// it is a constraint it happens to meet: two of them leave it one free
/// unknown, spent on the other contact's joints.
pub(super) fn confirmed(
    torque_model: &TorqueModel,
    (link, torques): (LinkId, &[f64]),
    other: LinkId,
    weights: &[f64],
) -> bool {
    let joints = |link: LinkId| -> Vec<usize> {
        torque_model
            .twists(link)
            .iter()
            .map(|twist| twist.sensed_index)
            .collect()
    };
    let theirs = joints(other);
    let own: Vec<usize> = joints(link).into_iter().filter(|j| !theirs.contains(j)).collect();
    let felt = own
        .iter()
        .filter(|&&j| match (torques.get(j), weights.get(j)) {
            (Some(t), Some(w)) => t.abs() * w.sqrt() >= FELT_SIGMAS,
            _ => false,
        })
        .count();
    own.is_empty() || (felt >= 1 && own.len() - felt <= 1)
}

/// `⟨x, y⟩ / (|x| |y|)` in the metric `Σ w x y` (0 for a zero vector).
fn weighted_cosine(x: &[f64], y: &[f64], weights: &[f64]) -> f64 {
    let norms = (weighted_dot(weights, x, x) * weighted_dot(weights, y, y)).sqrt();
    if norms > 0.0 {
        weighted_dot(weights, x, y) / norms
    } else {
        0.0
    }
}
