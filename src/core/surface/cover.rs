//! Samples that a neighbouring link covers at some angles of the joint
//! between them: no probe can reach a face that lies inside the next link.
//!
//! Around every joint the two links' meshes overlap, and which faces lie
//! inside the other link depends on the joint's angle alone (the two links
//! move with it and nothing else). So each sample near a joint gets a
//! table over [`COVER_BINS`] angles of that joint, made once when the
//! surface is sampled; at a pose, the covered samples are a lookup per
//! tabled sample. Generated sessions may be drawn with no press on a
//! covered face ([`crate::core::eval::synth::SynthSettings::avoid_covered`]).
//! The estimator does not read the table:
//! samples left out by it alone, with the refinement and the press fits
//! still free to place a contact there, measured mixed
//! (`docs/decisions.md`, session 68).

use glam::{DQuat, DVec3};
use rayon::prelude::*;

use crate::core::geometry::bvh::Bvh;
use crate::core::geometry::shell::SmoothMesh;
use crate::core::robot::model::{JointId, JointKind, LinkId, Robot};

/// Angles of a joint's range each tabled sample is tested at.
pub const COVER_BINS: usize = 64;

/// How far outside its face a sample's probe point lies, m: the point a
/// probe must reach.
pub const COVER_PROBE_M: f64 = 1e-3;

/// One sample's table against one neighbour: bit `b` is set where the
/// joint's angle in bin `b` puts the sample's outside inside the neighbour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct CoverEntry {
    /// The sample.
    pub sample: u32,
    /// The joint between the sample's link and the neighbour.
    pub joint: JointId,
    /// Covered angle bins.
    pub bins: u64,
}

/// A joint's tabled range, rad.
#[derive(Debug, Clone, Copy, PartialEq)]
struct BinRange {
    joint: JointId,
    lower_rad: f64,
    bin_width_rad: f64,
}

/// Every sample a neighbouring link may cover, with the angles that do.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct CoverTable {
    /// Sorted by sample, then joint; samples never covered are left out.
    entries: Vec<CoverEntry>,
    ranges: Vec<BinRange>,
}

/// A link's mesh, oriented, with its search structure.
struct Body {
    bvh: Bvh,
    /// Bounds of the mesh in its link's frame.
    low: DVec3,
    high: DVec3,
}

impl Body {
    fn of(robot: &Robot, link: LinkId) -> Option<Self> {
        let link = robot.links.get(link)?;
        if link.segment.is_some() || link.mesh.is_empty() {
            return None;
        }
        let mesh = SmoothMesh::new(&link.mesh);
        let (low, high) = mesh.mesh.bounds()?;
        Some(Self {
            bvh: Bvh::new(&mesh.mesh),
            low,
            high,
        })
    }

    /// Whether `p` (in the body's link frame) lies inside the body.
    fn holds(&self, p: DVec3) -> bool {
        p.cmpge(self.low).all() && p.cmple(self.high).all() && self.bvh.winding_number(p) > 0.5
    }
}

/// Bins tested first, [`COVER_STRIDE`] apart: between two that agree,
/// the bins are taken to agree too (a face covered over less than a
/// stride's turn, 21° of a 340° range, may be missed; the tests bound
/// what that leaves out).
const COVER_STRIDE: usize = 4;

/// The bins where `covered(bin)`: every [`COVER_STRIDE`]th bin and the
/// last, then every bin between two that differ.
fn covered_bins(covered: impl Fn(usize) -> bool) -> u64 {
    let mut bins = 0_u64;
    let mut previous: Option<(usize, bool)> = None;
    let mut at = 0;
    loop {
        let here = covered(at);
        if here {
            bins |= 1 << at;
        }
        if let Some((from, was)) = previous {
            for b in from + 1..at {
                if was == here {
                    if here {
                        bins |= 1 << b;
                    }
                } else if covered(b) {
                    bins |= 1 << b;
                }
            }
        }
        if at == COVER_BINS - 1 {
            return bins;
        }
        previous = Some((at, here));
        at = (at + COVER_STRIDE).min(COVER_BINS - 1);
    }
}

/// The surface's samples, as [`CoverTable::build`] takes them.
struct Samples<'a> {
    link: &'a [LinkId],
    point_in_link: &'a [DVec3],
    inward_normal_in_link: &'a [DVec3],
}

impl Samples<'_> {
    /// The entries of the samples on either side of `range`'s joint that
    /// the link across it covers at some angle.
    fn covered_across(&self, robot: &Robot, bodies: &[Option<Body>], range: &BinRange) -> Vec<CoverEntry> {
        let Some(joint) = robot.joints.get(range.joint) else {
            return Vec::new();
        };
        let joint_from_parent = joint.parent_from_joint.inverse();
        let n = self
            .link
            .len()
            .min(self.point_in_link.len())
            .min(self.inward_normal_in_link.len());
        let mut found = Vec::new();
        for k in 0..n {
            let (Some(&on), Some(&p), Some(&inward)) = (
                self.link.get(k),
                self.point_in_link.get(k),
                self.inward_normal_in_link.get(k),
            ) else {
                continue;
            };
            let on_child = on == joint.child;
            let neighbour = if on_child {
                joint.parent
            } else if on == joint.parent {
                joint.child
            } else {
                continue;
            };
            let Some(Some(body)) = bodies.get(neighbour) else {
                continue;
            };
            let outside = p - inward * COVER_PROBE_M;
            // The sample's outside in the neighbour's frame at angle q: the
            // child's frame is the joint's turned by q about the axis.
            let in_joint = if on_child {
                outside
            } else {
                joint_from_parent.transform_point3(outside)
            };
            let in_neighbour = |q: f64| {
                if on_child {
                    joint
                        .parent_from_joint
                        .transform_point3(DQuat::from_axis_angle(joint.axis, q) * in_joint)
                } else {
                    DQuat::from_axis_angle(joint.axis, -q) * in_joint
                }
            };
            let bins =
                covered_bins(|b| body.holds(in_neighbour(range.lower_rad + (b as f64 + 0.5) * range.bin_width_rad)));
            if bins != 0 {
                found.push(CoverEntry {
                    sample: u32::try_from(k).unwrap_or(u32::MAX),
                    joint: range.joint,
                    bins,
                });
            }
        }
        found
    }
}

impl CoverTable {
    /// The table of the samples (`link`, `point_in_link`,
    /// `inward_normal_in_link`, one entry each) of `robot`'s surface.
    #[must_use]
    pub fn build(robot: &Robot, link: &[LinkId], point_in_link: &[DVec3], inward_normal_in_link: &[DVec3]) -> Self {
        let ranges: Vec<BinRange> = robot
            .joints
            .iter()
            .enumerate()
            .filter_map(|(j, joint)| {
                let (lower_rad, upper_rad) = match (joint.kind, joint.limits) {
                    (JointKind::Revolute, Some(limits)) => (limits.lower, limits.upper),
                    (JointKind::Revolute | JointKind::Continuous, _) => (-std::f64::consts::PI, std::f64::consts::PI),
                    _ => return None,
                };
                (upper_rad > lower_rad && (upper_rad - lower_rad).is_finite()).then(|| BinRange {
                    joint: j,
                    lower_rad,
                    bin_width_rad: (upper_rad - lower_rad) / COVER_BINS as f64,
                })
            })
            .collect();
        // The bodies of the links on either side of a tabled joint.
        let bodies: Vec<Option<Body>> = (0..robot.links.len())
            .map(|l| {
                let jointed = ranges
                    .iter()
                    .any(|r| robot.joints.get(r.joint).is_some_and(|j| j.parent == l || j.child == l));
                if jointed { Body::of(robot, l) } else { None }
            })
            .collect();
        let samples = Samples {
            link,
            point_in_link,
            inward_normal_in_link,
        };
        let mut entries: Vec<CoverEntry> = ranges
            .par_iter()
            .flat_map_iter(|range| samples.covered_across(robot, &bodies, range))
            .collect();
        entries.sort_unstable_by_key(|e| (e.sample, e.joint));
        Self { entries, ranges }
    }

    /// Samples with a table.
    #[must_use]
    pub fn tabled(&self) -> usize {
        self.entries.len()
    }

    /// The samples covered at `joint_positions` (indexed by joint, as
    /// [`crate::core::robot::kinematics::RobotPose::new`] takes them),
    /// sorted, each once.
    #[must_use]
    pub fn covered_at(&self, joint_positions: &[f64]) -> Vec<u32> {
        let mut out: Vec<u32> = Vec::new();
        for entry in &self.entries {
            let Some(range) = self.ranges.iter().find(|r| r.joint == entry.joint) else {
                continue;
            };
            let q = joint_positions.get(entry.joint).copied().unwrap_or(0.0);
            if !q.is_finite() {
                continue;
            }
            let bin = ((q - range.lower_rad) / range.bin_width_rad).floor();
            let bin = if bin < 0.0 {
                0
            } else if bin >= (COVER_BINS - 1) as f64 {
                COVER_BINS - 1
            } else {
                bin as usize
            };
            if entry.bins & (1 << bin) != 0 && out.last() != Some(&entry.sample) {
                out.push(entry.sample);
            }
        }
        out
    }
}

#[cfg(test)]
#[path = "cover_tests.rs"]
mod tests;
