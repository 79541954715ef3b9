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

use glam::{DAffine3, DQuat, DVec3};
use rayon::prelude::*;

use crate::core::geometry::bvh::Bvh;
use crate::core::geometry::mesh::TriMesh;
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

/// Slabs along a joint's axis that [`Reach`] splits a neighbour into.
const REACH_SLABS: usize = 32;

/// How far from a joint's axis a neighbour reaches, slab by slab along
/// the axis (in the joint's frame, where turning the joint moves neither):
/// a point beyond it lies outside the neighbour at every angle. A
/// triangle's farthest point from the axis is a corner (the distance is
/// convex), so the corners bound each slab they span.
struct Reach {
    axis: DVec3,
    z_low: f64,
    slab_m: f64,
    radius_m: [f64; REACH_SLABS],
}

impl Reach {
    fn of(mesh: &TriMesh, joint_from_link: DAffine3, axis: DVec3) -> Option<Self> {
        let axis = axis.normalize_or_zero();
        let corners: Vec<[DVec3; 3]> = mesh
            .triangle_corners()
            .map(|c| c.map(|v| joint_from_link.transform_point3(v)))
            .collect();
        let z = |v: DVec3| v.dot(axis);
        let (z_low, z_high) = corners
            .iter()
            .flatten()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(z(v)), hi.max(z(v)))
            });
        if !(z_high >= z_low && axis.length_squared() > 0.0) {
            return None;
        }
        let slab_m = ((z_high - z_low) / REACH_SLABS as f64).max(1e-9);
        let slab = |z: f64| (((z - z_low) / slab_m).floor().max(0.0) as usize).min(REACH_SLABS - 1);
        let mut radius_m = [0.0_f64; REACH_SLABS];
        for c in &corners {
            let r = c.iter().map(|&v| (v - axis * z(v)).length()).fold(0.0, f64::max);
            let (lo, hi) = c.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), &v| {
                (lo.min(z(v)), hi.max(z(v)))
            });
            for radius in radius_m.get_mut(slab(lo)..=slab(hi)).into_iter().flatten() {
                *radius = radius.max(r);
            }
        }
        Some(Self {
            axis,
            z_low,
            slab_m,
            radius_m,
        })
    }

    /// Whether `p` (in the joint's frame) may lie inside the neighbour at
    /// some angle.
    fn may_hold(&self, p: DVec3) -> bool {
        let z = p.dot(self.axis);
        let at = (z - self.z_low) / self.slab_m;
        if !(at >= 0.0 && at < REACH_SLABS as f64) {
            return false;
        }
        self.radius_m
            .get(at as usize)
            .is_some_and(|&r| (p - self.axis * z).length() <= r)
    }
}

/// A link's mesh, oriented, with its search structure.
struct Body {
    mesh: TriMesh,
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
            mesh: mesh.mesh,
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

impl CoverTable {
    /// The table of the samples (`link`, `point_in_link`,
    /// `inward_normal_in_link`, one entry each) of `robot`'s surface.
    #[must_use]
    pub fn build(robot: &Robot, link: &[LinkId], point_in_link: &[DVec3], inward_normal_in_link: &[DVec3]) -> Self {
        let mut table = Self::default();
        let mut bodies: Vec<Option<Option<Body>>> = (0..robot.links.len()).map(|_| None).collect();
        let mut body = |l: LinkId| -> bool {
            match bodies.get_mut(l) {
                Some(slot @ None) => {
                    *slot = Some(Body::of(robot, l));
                    slot.as_ref().is_some_and(Option::is_some)
                }
                Some(Some(b)) => b.is_some(),
                None => false,
            }
        };
        let mut jobs = Vec::new();
        for (j, joint) in robot.joints.iter().enumerate() {
            let (lower_rad, upper_rad) = match (joint.kind, joint.limits) {
                (JointKind::Revolute, Some(limits)) => (limits.lower, limits.upper),
                (JointKind::Revolute | JointKind::Continuous, _) => (-std::f64::consts::PI, std::f64::consts::PI),
                _ => continue,
            };
            if !(upper_rad > lower_rad && (upper_rad - lower_rad).is_finite()) {
                continue;
            }
            let (parent_ok, child_ok) = (body(joint.parent), body(joint.child));
            table.ranges.push(BinRange {
                joint: j,
                lower_rad,
                bin_width_rad: (upper_rad - lower_rad) / COVER_BINS as f64,
            });
            jobs.push((j, joint.parent, joint.child, parent_ok, child_ok, lower_rad, upper_rad));
        }
        let bodies: Vec<Option<Body>> = bodies.into_iter().map(Option::flatten).collect();
        let n = link.len().min(point_in_link.len()).min(inward_normal_in_link.len());
        let mut entries: Vec<CoverEntry> = jobs
            .par_iter()
            .flat_map_iter(|&(j, parent, child, parent_ok, child_ok, lower, upper)| {
                let Some(joint) = robot.joints.get(j) else {
                    return Vec::new();
                };
                let width = (upper - lower) / COVER_BINS as f64;
                let joint_from_parent = joint.parent_from_joint.inverse();
                let reach_of = |l: LinkId, joint_from_link: DAffine3| {
                    bodies
                        .get(l)
                        .and_then(Option::as_ref)
                        .and_then(|b| Reach::of(&b.mesh, joint_from_link, joint.axis))
                };
                let (parent_reach, child_reach) =
                    (reach_of(parent, joint_from_parent), reach_of(child, DAffine3::IDENTITY));
                let mut found = Vec::new();
                for k in 0..n {
                    let (Some(&on), Some(&p), Some(&inward)) =
                        (link.get(k), point_in_link.get(k), inward_normal_in_link.get(k))
                    else {
                        continue;
                    };
                    let outside = p - inward * COVER_PROBE_M;
                    // The sample in the joint's frame (at angle 0 on the
                    // child's side: the angle turns neither bound).
                    let (in_joint, reach) = if on == child {
                        (outside, parent_reach.as_ref())
                    } else {
                        (joint_from_parent.transform_point3(outside), child_reach.as_ref())
                    };
                    if !reach.is_some_and(|r| r.may_hold(in_joint)) {
                        continue;
                    }
                    // The neighbour's frame from the sample's at angle q.
                    let (neighbour, at_angle): (LinkId, Box<dyn Fn(f64) -> DVec3>) = if on == child && parent_ok {
                        let from = joint.parent_from_joint;
                        let axis = joint.axis;
                        (
                            parent,
                            Box::new(move |q| {
                                (from * DAffine3::from_quat(DQuat::from_axis_angle(axis, q))).transform_point3(outside)
                            }),
                        )
                    } else if on == parent && child_ok {
                        let axis = joint.axis;
                        let in_joint = joint_from_parent.transform_point3(outside);
                        (child, Box::new(move |q| DQuat::from_axis_angle(axis, -q) * in_joint))
                    } else {
                        continue;
                    };
                    let Some(Some(neighbour)) = bodies.get(neighbour) else {
                        continue;
                    };
                    let bins = covered_bins(|b| neighbour.holds(at_angle(lower + (b as f64 + 0.5) * width)));
                    if bins != 0 {
                        found.push(CoverEntry {
                            sample: u32::try_from(k).unwrap_or(u32::MAX),
                            joint: j,
                            bins,
                        });
                    }
                }
                found
            })
            .collect();
        entries.sort_unstable_by_key(|e| (e.sample, e.joint));
        table.entries = entries;
        table
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
