//! Surface samples of the candidate links: points with inward unit normals
//! and area weights, evenly spread, with buried points removed.

use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};
use std::hash::{BuildHasherDefault, Hasher};
use std::sync::Arc;

use glam::DVec3;
use rayon::prelude::*;

use crate::core::geometry::bvh::Bvh;
use crate::core::geometry::mesh::{TriMesh, triangle_area};
use crate::core::geometry::shell::{MeshPoint, SmoothMesh, SurfaceFrame, segment_frame};
use crate::core::numerics::rng::Rng;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::{LinkId, Robot};

/// How far off the surface the buried test looks, m.
pub const BURIED_PROBE_M: f64 = 5e-4;

/// Candidates drawn per kept sample before thinning (more gives a more even
/// spread and costs time linearly).
pub const OVERSAMPLE: usize = 4;

/// Candidates per kept sample that are tested for burial: the draw is first
/// thinned to this many, since the inside tests cost more than thinning.
pub const TESTED_PER_SAMPLE: usize = 2;

/// The most surface points a request may ask for: sampling a million takes
/// about half a minute and an update about 10 ms per core.
pub const MAX_POINTS: usize = 1_000_000;

/// Force directions per point on a one-dimensional link (the simple robot).
pub const SEGMENT_DIRECTIONS: usize = 8;

/// The width (standard deviation) of the patch a sample stands for, as a
/// fraction of the spacing of the samples (`√area` per sample). Gaussian
/// windows of this width centred on evenly spread samples add up to an
/// almost constant total over the surface (for a hexagonal lattice the
/// ripple is below 0.2 %), so the samples' windowed masses partition the
/// posterior of the continuous surface.
pub const WINDOW_FRACTION: f64 = 0.5;

/// [`MeshPoint::triangle`] of a sample on a segment link: its weights are
/// then the distance along the segment, m, and the angle of the push
/// around it, rad.
pub const ON_SEGMENT: u32 = u32::MAX;

/// A candidate link's continuous surface.
#[derive(Debug, Clone, PartialEq)]
pub enum LinkShape {
    /// A triangle mesh with smooth normals.
    Mesh(SmoothMesh),
    /// A segment (the thesis' simple robot): pushes perpendicular to it.
    Segment {
        /// End points, link frame, m.
        segment: [DVec3; 2],
        /// Metres of tangent 2 per radian of turn around the segment:
        /// makes the angular spacing of the samples equal their spacing
        /// along the segment.
        radius_m: f64,
    },
}

impl LinkShape {
    /// The surface frame at a sample location (see [`ON_SEGMENT`]).
    #[must_use]
    pub fn frame(&self, at: MeshPoint) -> Option<SurfaceFrame> {
        match self {
            Self::Mesh(mesh) => mesh.frame(at),
            Self::Segment { segment, radius_m } => {
                let length = segment[0].distance(segment[1]);
                let along = at.weights[0].clamp(0.0, length);
                Some(segment_frame(*segment, along, at.weights[1], *radius_m))
            }
        }
    }

    /// Moves along the surface by `step` (link frame, m): across triangle
    /// edges on a mesh; along the segment and around it on a segment.
    #[must_use]
    pub fn walk(&self, at: MeshPoint, step: DVec3) -> MeshPoint {
        match self {
            Self::Mesh(mesh) => mesh.walk(at, step),
            Self::Segment { segment, radius_m } => {
                let length = segment[0].distance(segment[1]);
                let frame = segment_frame(*segment, at.weights[0].clamp(0.0, length), at.weights[1], *radius_m);
                MeshPoint {
                    triangle: ON_SEGMENT,
                    weights: [
                        (at.weights[0] + frame.tangents[0].dot(step)).clamp(0.0, length),
                        at.weights[1] + frame.tangents[1].dot(step) / radius_m.max(1e-9),
                    ],
                }
            }
        }
    }
}

/// What to sample.
#[derive(Debug, Clone, PartialEq)]
pub struct SurfaceRequest {
    /// Links on which contacts may lie.
    pub links: Vec<LinkId>,
    /// Total number of samples over those links.
    pub total_points: usize,
    /// Seed of the sampling; the same seed gives the same samples.
    pub seed: u64,
}

/// What sampling found on one link.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkSurfaceStats {
    /// The link.
    pub link: LinkId,
    /// Total area of its mesh (or length of its segment), m² (m).
    pub mesh_area_m2: f64,
    /// Estimated area not buried inside its own other shells, m².
    pub exposed_area_m2: f64,
    /// Candidates tested for burial (after a first thinning of the draw).
    pub drawn: usize,
    /// Candidates whose outside lies inside the link's mesh.
    pub buried: usize,
    /// Candidates on open sheets (their inside is not inside).
    pub open_or_thin: usize,
    /// Samples kept.
    pub kept: usize,
    /// Closed shells found in the mesh.
    pub shells: usize,
    /// Shells that were wound inward and flipped.
    pub flipped_shells: usize,
    /// Degenerate triangles skipped.
    pub degenerate_triangles: usize,
}

/// Surface samples in structure-of-arrays form, grouped by link.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Surface {
    /// Link of each sample.
    pub link: Vec<LinkId>,
    /// Position in the link frame, m.
    pub point_in_link: Vec<DVec3>,
    /// Inward unit normal in the link frame: the direction of a push.
    pub inward_normal_in_link: Vec<DVec3>,
    /// `point × normal` in the link frame: the moment of a unit push about
    /// the link origin, precomputed because every update needs it.
    pub moment_in_link: Vec<DVec3>,
    /// The push lines `(moment, normal)` as six plain arrays (`mx, my, mz,
    /// nx, ny, nz`), so that per-point loops vectorise.
    pub push_lines: [Vec<f64>; 6],
    /// Area represented by the sample, m² (m of length on a segment link).
    pub area_m2: Vec<f64>,
    /// `ln` of each sample's area (its prior weight with patches), taken
    /// once here rather than in every update.
    pub ln_area: Vec<f64>,
    /// Where each sample lies on its link's [`LinkShape`].
    pub location: Vec<MeshPoint>,
    /// How each push line changes per metre along the sample's two
    /// tangents: `∂(p × n, n)/∂s_1` then `∂/∂s_2`, as twelve plain arrays.
    pub tangent_lines: [Vec<f64>; 12],
    /// Width (standard deviation) of the Gaussian patch each sample
    /// stands for, m (see [`WINDOW_FRACTION`]).
    pub window_m: Vec<f64>,
    /// Per sampled link, in the order of [`SurfaceRequest::links`] sorted.
    pub stats: Vec<LinkSurfaceStats>,
    /// Each sampled link's continuous surface, in the order of `stats`.
    pub shapes: Vec<Arc<LinkShape>>,
    /// The cell of each sample (see [`Cells`]).
    pub cell: Vec<u32>,
    /// Samples grouped into cells a few spacings wide, with their neighbours.
    pub cells: Cells,
}

/// A partition of the samples into cells about [`CELL_SPACINGS`] sample
/// spacings wide (one link each), and which cells touch: regions of a
/// posterior are found on these in time proportional to the samples with
/// mass, without a spatial search per update.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Cells {
    /// Link of each cell.
    pub link: Vec<LinkId>,
    /// Neighbours of cell c: `neighbours[start[c]..start[c + 1]]`.
    pub start: Vec<u32>,
    /// Flattened neighbour lists (each cell's sorted, without itself).
    pub neighbours: Vec<u32>,
}

impl Cells {
    /// Number of cells.
    #[must_use]
    pub fn len(&self) -> usize {
        self.link.len()
    }

    /// True without cells.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.link.is_empty()
    }

    /// The cells touching cell `c`.
    #[must_use]
    pub fn neighbours_of(&self, c: usize) -> &[u32] {
        let (Some(&a), Some(&b)) = (self.start.get(c), self.start.get(c + 1)) else {
            return &[];
        };
        self.neighbours.get(a as usize..b as usize).unwrap_or(&[])
    }
}

/// Width of a [`Cells`] cell, in sample spacings.
pub const CELL_SPACINGS: f64 = 3.0;

impl Surface {
    /// Groups the samples into voxel cells per link; cells whose voxels
    /// touch (26-neighbourhood) are neighbours.
    fn build_cells(&mut self) {
        let mut ids: HashMap<(LinkId, [i64; 3]), u32> = HashMap::new();
        let mut cells = Cells::default();
        let mut cell_voxel: Vec<(LinkId, [i64; 3])> = Vec::new();
        self.cell = Vec::with_capacity(self.len());
        for k in 0..self.len() {
            let size = (CELL_SPACINGS * self.window_m[k] / WINDOW_FRACTION).max(1e-6);
            let p = self.point_in_link[k] / size;
            let key = (
                self.link[k],
                [p.x.floor() as i64, p.y.floor() as i64, p.z.floor() as i64],
            );
            let next = ids.len() as u32;
            let id = *ids.entry(key).or_insert_with(|| {
                cells.link.push(key.0);
                cell_voxel.push(key);
                next
            });
            self.cell.push(id);
        }
        for (link, v) in &cell_voxel {
            cells.start.push(cells.neighbours.len() as u32);
            let mut around = Vec::new();
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if (dx, dy, dz) == (0, 0, 0) {
                            continue;
                        }
                        if let Some(&n) = ids.get(&(*link, [v[0] + dx, v[1] + dy, v[2] + dz])) {
                            around.push(n);
                        }
                    }
                }
            }
            around.sort_unstable();
            cells.neighbours.extend(around);
        }
        cells.start.push(cells.neighbours.len() as u32);
        self.cells = cells;
    }
}

/// Why a surface could not be sampled.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SurfaceError {
    /// No candidate link was given.
    #[error("no candidate links: name at least one link that can be touched")]
    NoLinks,
    /// A candidate link index is not in the robot.
    #[error("candidate link index {link} is not a link of the robot")]
    BadLink {
        /// The index.
        link: LinkId,
    },
    /// A candidate link has no geometry to touch.
    #[error("candidate link '{link}' has no surface (no mesh and no segment)")]
    NoSurface {
        /// The link name.
        link: String,
    },
    /// More samples requested than [`MAX_POINTS`].
    #[error("the surface resolution is {requested} points; at most {MAX_POINTS} are sampled")]
    TooManyPoints {
        /// Points asked for.
        requested: usize,
    },
    /// Zero samples requested.
    #[error("the surface resolution must be at least 1 point per candidate link, got {requested} for {links} links")]
    TooFewPoints {
        /// Points asked for.
        requested: usize,
        /// Candidate links.
        links: usize,
    },
}

impl Surface {
    /// Number of samples.
    #[must_use]
    pub fn len(&self) -> usize {
        self.link.len()
    }

    /// True without samples.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.link.is_empty()
    }

    /// Typical distance between neighbouring samples, m: the resolution of
    /// the surface (the largest over links).
    #[must_use]
    pub fn spacing_m(&self) -> f64 {
        self.stats
            .iter()
            .filter(|s| s.kept > 0)
            .map(|s| {
                if s.shells == 0 {
                    // A segment: positions carry SEGMENT_DIRECTIONS samples each.
                    s.exposed_area_m2 * SEGMENT_DIRECTIONS as f64 / s.kept as f64
                } else {
                    (s.exposed_area_m2 / s.kept as f64).sqrt()
                }
            })
            .fold(0.0, f64::max)
    }

    /// The continuous surface of `link`, if it was sampled.
    #[must_use]
    pub fn shape(&self, link: LinkId) -> Option<&LinkShape> {
        let i = self.stats.iter().position(|s| s.link == link)?;
        self.shapes.get(i).map(AsRef::as_ref)
    }

    /// The sample whose patch holds `point_in_link` on `link`: the nearest
    /// of that link's samples (`None` where the link has none). What a
    /// credible set must hold to hold a contact there.
    #[must_use]
    pub fn owner(&self, link: LinkId, point_in_link: DVec3) -> Option<usize> {
        self.link
            .iter()
            .zip(&self.point_in_link)
            .enumerate()
            .filter(|&(_, (&on, _))| on == link)
            .min_by(|(_, (_, a)), (_, (_, b))| a.distance(point_in_link).total_cmp(&b.distance(point_in_link)))
            .map(|(k, _)| k)
    }

    /// Sample `i`'s position in the world for a pose.
    #[must_use]
    pub fn point_world(&self, pose: &RobotPose, i: usize) -> Option<DVec3> {
        let link = *self.link.get(i)?;
        Some(pose.point_to_world(link, *self.point_in_link.get(i)?))
    }

    /// Samples a robot's candidate links, evenly spread.
    pub fn sample(robot: &Robot, request: &SurfaceRequest) -> Result<Self, SurfaceError> {
        Self::sample_with(robot, request, true)
    }

    /// Independent points, each uniform over the exposed surface of the
    /// candidate links (the links' shares in proportion to their exposed
    /// areas): contacts for generated sessions and benchmarks.
    pub fn sample_random(robot: &Robot, request: &SurfaceRequest) -> Result<Self, SurfaceError> {
        Self::sample_with(robot, request, false)
    }

    fn sample_with(robot: &Robot, request: &SurfaceRequest, even: bool) -> Result<Self, SurfaceError> {
        let mut links = request.links.clone();
        links.sort_unstable();
        links.dedup();
        if links.is_empty() {
            return Err(SurfaceError::NoLinks);
        }
        if request.total_points > MAX_POINTS {
            return Err(SurfaceError::TooManyPoints {
                requested: request.total_points,
            });
        }
        if request.total_points < links.len() {
            return Err(SurfaceError::TooFewPoints {
                requested: request.total_points,
                links: links.len(),
            });
        }
        let mut prepared = Vec::with_capacity(links.len());
        for &l in &links {
            let link = robot.links.get(l).ok_or(SurfaceError::BadLink { link: l })?;
            let p = if let Some(segment) = link.segment {
                Prepared::segment(l, segment)
            } else {
                Prepared::mesh(l, &link.mesh)
            };
            if p.area().is_nan() || p.area() <= 0.0 {
                return Err(SurfaceError::NoSurface {
                    link: link.name.clone(),
                });
            }
            prepared.push(p);
        }

        let mut rng = Rng::new(request.seed);
        // First pass: draw candidates in proportion to total area and find
        // what is exposed; second: share the points by exposed area.
        let areas: Vec<f64> = prepared.iter().map(Prepared::area).collect();
        let first = apportion(request.total_points, &areas, &vec![usize::MAX; areas.len()]);
        let mut drawn: Vec<Candidates> = prepared
            .iter()
            .zip(&first)
            .map(|(p, &n)| p.draw(n.max(1), even, &mut rng))
            .collect();
        let exposed: Vec<f64> = drawn.iter().map(|d| d.exposed_area_m2).collect();
        let caps: Vec<usize> = drawn.iter().map(|d| d.points.len()).collect();
        let second = apportion(request.total_points, &exposed, &caps);

        let mut surface = Self::default();
        for ((p, cands), &keep) in prepared.iter().zip(&mut drawn).zip(&second) {
            let kept = match p {
                Prepared::Mesh { .. } if even => eliminate(&cands.points, keep, cands.exposed_area_m2),
                Prepared::Mesh { .. } => (0..keep.min(cands.points.len())).collect(),
                Prepared::Segment { .. } => (0..cands.points.len()).collect(),
            };
            let weight = if kept.is_empty() {
                0.0
            } else {
                cands.exposed_area_m2 / kept.len() as f64
            };
            let shape = p.shape(cands);
            // The spacing of the samples: on a mesh √(area per sample); on
            // a segment the distance between positions along it.
            let spacing = match &shape {
                LinkShape::Mesh(_) => weight.sqrt(),
                LinkShape::Segment { radius_m, .. } => radius_m * std::f64::consts::TAU / SEGMENT_DIRECTIONS as f64,
            };
            for &i in &kept {
                let Some(frame) = shape.frame(cands.locations[i]) else {
                    continue;
                };
                surface.push_sample(p.link(), cands.locations[i], &frame, weight, WINDOW_FRACTION * spacing);
            }
            cands.stats.kept = kept.len();
            surface.stats.push(cands.stats.clone());
            surface.shapes.push(Arc::new(shape));
        }
        surface.build_cells();
        Ok(surface)
    }

    fn push_sample(&mut self, link: LinkId, at: MeshPoint, frame: &SurfaceFrame, area_m2: f64, window_m: f64) {
        self.link.push(link);
        self.point_in_link.push(frame.point);
        self.inward_normal_in_link.push(frame.inward_normal);
        self.moment_in_link.push(frame.point.cross(frame.inward_normal));
        for (column, value) in self.push_lines.iter_mut().zip(frame.line()) {
            column.push(value);
        }
        let [d1, d2] = frame.line_derivatives;
        for (column, value) in self.tangent_lines.iter_mut().zip(d1.iter().chain(&d2)) {
            column.push(*value);
        }
        self.area_m2.push(area_m2);
        self.ln_area.push(area_m2.max(f64::MIN_POSITIVE).ln());
        self.location.push(at);
        self.window_m.push(window_m);
    }
}

enum Prepared {
    Mesh {
        link: LinkId,
        mesh: Box<SmoothMesh>,
        bvh: Bvh,
        cdf: Vec<f64>,
        stats: LinkSurfaceStats,
        /// No boundary edges: no point can lie on an open sheet.
        closed: bool,
    },
    Segment {
        link: LinkId,
        segment: [DVec3; 2],
    },
}

struct Candidates {
    points: Vec<DVec3>,
    locations: Vec<MeshPoint>,
    exposed_area_m2: f64,
    stats: LinkSurfaceStats,
}

impl Prepared {
    fn mesh(link: LinkId, mesh: &TriMesh) -> Self {
        let mesh = SmoothMesh::new(mesh);
        let report = mesh.report;
        let mut cdf = Vec::with_capacity(mesh.len());
        let mut total = 0.0;
        for c in mesh.mesh.triangle_corners() {
            total += triangle_area(&c);
            cdf.push(total);
        }
        let bvh = Bvh::new(&mesh.mesh);
        Self::Mesh {
            link,
            mesh: Box::new(mesh),
            bvh,
            cdf,
            closed: report.boundary_edges == 0,
            stats: LinkSurfaceStats {
                link,
                mesh_area_m2: total,
                exposed_area_m2: total,
                drawn: 0,
                buried: 0,
                open_or_thin: 0,
                kept: 0,
                shells: report.shells,
                flipped_shells: report.flipped,
                degenerate_triangles: report.degenerate,
            },
        }
    }

    fn segment(link: LinkId, segment: [DVec3; 2]) -> Self {
        Self::Segment { link, segment }
    }

    /// The continuous surface; a segment's tangent scale from how its
    /// samples were spread.
    fn shape(&self, cands: &Candidates) -> LinkShape {
        match self {
            Self::Mesh { mesh, .. } => LinkShape::Mesh(mesh.as_ref().clone()),
            Self::Segment { segment, .. } => {
                let positions = (cands.points.len() / SEGMENT_DIRECTIONS).max(1);
                let spacing = segment[0].distance(segment[1]) / positions as f64;
                LinkShape::Segment {
                    segment: *segment,
                    radius_m: spacing / (std::f64::consts::TAU / SEGMENT_DIRECTIONS as f64),
                }
            }
        }
    }

    fn link(&self) -> LinkId {
        match self {
            Self::Mesh { link, .. } | Self::Segment { link, .. } => *link,
        }
    }

    fn area(&self) -> f64 {
        match self {
            Self::Mesh { cdf, .. } => cdf.last().copied().unwrap_or(0.0),
            Self::Segment { segment, .. } => segment[0].distance(segment[1]),
        }
    }

    /// Candidates for about `target` final samples: thinned to an even
    /// spread before the burial test when `even`, else all independent.
    fn draw(&self, target: usize, even: bool, rng: &mut Rng) -> Candidates {
        match self {
            Self::Mesh {
                mesh,
                bvh,
                cdf,
                stats,
                closed,
                ..
            } => {
                let mut stats = stats.clone();
                let total = self.area();
                let n = (OVERSAMPLE * target).max(16);
                let (drawn, outward, locations) = draw_on_mesh(mesh, cdf, total, n, rng);
                // Thinning spreads the survivors evenly, so the buried share
                // among them estimates the buried share of the area.
                let tested = if even {
                    eliminate(&drawn, (TESTED_PER_SAMPLE * target).max(16), total)
                } else {
                    (0..drawn.len()).collect()
                };
                let verdicts: Vec<Verdict> = tested
                    .par_iter()
                    .map(|&i| classify(bvh, drawn[i], outward[i], *closed))
                    .collect();
                let mut points = Vec::with_capacity(tested.len());
                let mut kept_locations = Vec::with_capacity(tested.len());
                for (&i, verdict) in tested.iter().zip(&verdicts) {
                    match verdict {
                        Verdict::Buried => stats.buried += 1,
                        Verdict::Open => stats.open_or_thin += 1,
                        Verdict::Exposed => {
                            points.push(drawn[i]);
                            kept_locations.push(locations[i]);
                        }
                    }
                }
                stats.drawn = tested.len();
                let exposed = if stats.drawn > 0 {
                    total * points.len() as f64 / stats.drawn as f64
                } else {
                    0.0
                };
                stats.exposed_area_m2 = exposed;
                Candidates {
                    points,
                    locations: kept_locations,
                    exposed_area_m2: exposed,
                    stats,
                }
            }
            Self::Segment { link, segment } => {
                let positions = target.div_ceil(SEGMENT_DIRECTIONS).max(1);
                let phase = rng.uniform();
                let length = self.area();
                let mut points = Vec::with_capacity(positions * SEGMENT_DIRECTIONS);
                let mut locations = Vec::with_capacity(positions * SEGMENT_DIRECTIONS);
                for i in 0..positions {
                    let t = (i as f64 + 0.5) / positions as f64;
                    let p = segment[0].lerp(segment[1], t);
                    for d in 0..SEGMENT_DIRECTIONS {
                        let theta = std::f64::consts::TAU * (d as f64 + phase) / SEGMENT_DIRECTIONS as f64;
                        points.push(p);
                        locations.push(MeshPoint {
                            triangle: ON_SEGMENT,
                            weights: [t * length, theta],
                        });
                    }
                }
                Candidates {
                    stats: LinkSurfaceStats {
                        link: *link,
                        mesh_area_m2: length,
                        exposed_area_m2: length,
                        drawn: points.len(),
                        buried: 0,
                        open_or_thin: 0,
                        kept: 0,
                        shells: 0,
                        flipped_shells: 0,
                        degenerate_triangles: 0,
                    },
                    points,
                    locations,
                    exposed_area_m2: length,
                }
            }
        }
    }
}

/// `n` points drawn uniformly by area on a mesh (`cdf`: its cumulative
/// triangle areas, `total` the last), with their facets' outward normals
/// (for the burial probe) and places on the mesh.
fn draw_on_mesh(
    mesh: &SmoothMesh,
    cdf: &[f64],
    total: f64,
    n: usize,
    rng: &mut Rng,
) -> (Vec<DVec3>, Vec<DVec3>, Vec<MeshPoint>) {
    let mut drawn = Vec::with_capacity(n);
    let mut outward = Vec::with_capacity(n);
    let mut locations = Vec::with_capacity(n);
    for _ in 0..n {
        let x = rng.uniform() * total;
        let tri = cdf.partition_point(|&c| c <= x).min(cdf.len().saturating_sub(1));
        let (u1, u2) = (rng.uniform(), rng.uniform());
        let Some(c) = mesh.mesh.corners(tri) else { continue };
        let s = u1.sqrt();
        let weights = [s * (1.0 - u2), s * u2];
        drawn.push(c[0] * (1.0 - s) + c[1] * weights[0] + c[2] * weights[1]);
        outward.push((c[1] - c[0]).cross(c[2] - c[0]).normalize_or_zero());
        locations.push(MeshPoint {
            triangle: tri as u32,
            weights,
        });
    }
    (drawn, outward, locations)
}

/// Where a candidate point stands.
enum Verdict {
    /// On the outer surface: a contact can happen here.
    Exposed,
    /// Its outside is inside the link (an internal wall, an overlapped shell).
    Buried,
    /// Its inside is not inside (an open sheet, a wall thinner than the probe).
    Open,
}

fn classify(bvh: &Bvh, p: DVec3, outward: DVec3, closed: bool) -> Verdict {
    if bvh.winding_number(p + outward * BURIED_PROBE_M) > 0.5 {
        Verdict::Buried
    } else if !closed && bvh.winding_number(p - outward * BURIED_PROBE_M) < 0.5 {
        Verdict::Open
    } else {
        Verdict::Exposed
    }
}

/// Shares `total` among parts in proportion to `weights` (largest
/// remainder), at least one each where the cap allows, never above `caps`.
fn apportion(total: usize, weights: &[f64], caps: &[usize]) -> Vec<usize> {
    let n = weights.len();
    let mut out = vec![0usize; n];
    let mut open: Vec<usize> = (0..n).filter(|&i| caps[i] > 0 && weights[i] > 0.0).collect();
    let mut left = total;
    while left > 0 && !open.is_empty() {
        let sum: f64 = open.iter().map(|&i| weights[i]).sum();
        let shares: Vec<f64> = open.iter().map(|&i| left as f64 * weights[i] / sum).collect();
        let mut given = 0;
        for (k, &i) in open.iter().enumerate() {
            let room = caps[i] - out[i];
            let add = (shares[k].floor() as usize).min(room);
            out[i] += add;
            given += add;
        }
        let mut rest = left - given;
        // Hand out the remainder by largest fractional part, then index.
        let mut order: Vec<usize> = (0..open.len()).collect();
        order.sort_by(|&a, &b| {
            let fa = shares[a] - shares[a].floor();
            let fb = shares[b] - shares[b].floor();
            fb.total_cmp(&fa).then(a.cmp(&b))
        });
        for k in order {
            if rest == 0 {
                break;
            }
            let i = open[k];
            if out[i] < caps[i] {
                out[i] += 1;
                rest -= 1;
            }
        }
        left = rest;
        open.retain(|&i| out[i] < caps[i]);
        if given == 0 && rest == left && left > 0 && open.is_empty() {
            break;
        }
    }
    out
}

/// A cheap hasher for grid cells (multiply-rotate); the standard `SipHash`
/// costs more than the distance tests it guards.
#[derive(Default)]
struct CellHasher(u64);

impl Hasher for CellHasher {
    fn finish(&self) -> u64 {
        // Fold the well-mixed high bits into the low ones the table indexes by.
        let x = self.0;
        (x ^ (x >> 29)).wrapping_mul(0xbf58_476d_1ce4_e5b9) ^ (x >> 32)
    }

    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.write_u64(u64::from(*b));
        }
    }

    fn write_u64(&mut self, i: u64) {
        self.0 = (self.0.rotate_left(5) ^ i).wrapping_mul(0x517c_c1b7_2722_0a95);
    }

    fn write_i64(&mut self, i: i64) {
        self.write_u64(i as u64);
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
struct Weight(f64, usize);
impl Eq for Weight {}
impl PartialOrd for Weight {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Weight {
    fn cmp(&self, other: &Self) -> Ordering {
        self.0.total_cmp(&other.0).then(other.1.cmp(&self.1))
    }
}

/// Weighted sample elimination: keeps `keep` of `points` spread as evenly
/// as possible over a surface of `area` (returns sorted indices).
fn eliminate(points: &[DVec3], keep: usize, area: f64) -> Vec<usize> {
    let n = points.len();
    if keep >= n {
        return (0..n).collect();
    }
    if keep == 0 {
        return Vec::new();
    }
    // Radius of a disk in the densest packing of `keep` disks on the area.
    let r_max = (area / (2.0 * 3f64.sqrt() * keep as f64)).sqrt();
    let d_max = 2.0 * r_max;
    let cell = |p: DVec3| {
        let c = (p / d_max).floor();
        (c.x as i64, c.y as i64, c.z as i64)
    };
    let mut grid: HashMap<(i64, i64, i64), Vec<usize>, BuildHasherDefault<CellHasher>> = HashMap::default();
    for (i, p) in points.iter().enumerate() {
        grid.entry(cell(*p)).or_default().push(i);
    }
    // Neighbour lists in one flat array: `start[i]..start[i + 1]`.
    let mut start = Vec::with_capacity(n + 1);
    let mut neighbours: Vec<(usize, f64)> = Vec::with_capacity(16 * n);
    for (i, p) in points.iter().enumerate() {
        start.push(neighbours.len());
        let (cx, cy, cz) = cell(*p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let Some(bucket) = grid.get(&(cx + dx, cy + dy, cz + dz)) else {
                        continue;
                    };
                    for &j in bucket {
                        let d = p.distance(points[j]);
                        if j != i && d < d_max {
                            neighbours.push((j, (1.0 - d / d_max).powi(8)));
                        }
                    }
                }
            }
        }
    }
    start.push(neighbours.len());
    let around = |i: usize| &neighbours[start[i]..start[i + 1]];
    let mut weight: Vec<f64> = (0..n).map(|i| around(i).iter().map(|(_, w)| w).sum()).collect();
    let mut heap: BinaryHeap<Weight> = weight.iter().enumerate().map(|(i, &w)| Weight(w, i)).collect();
    let mut removed = vec![false; n];
    let mut left = n;
    while left > keep {
        let Some(Weight(w, i)) = heap.pop() else { break };
        if removed[i] || w.to_bits() != weight[i].to_bits() {
            continue;
        }
        removed[i] = true;
        left -= 1;
        for &(j, wj) in around(i) {
            if !removed[j] {
                weight[j] -= wj;
                heap.push(Weight(weight[j], j));
            }
        }
    }
    (0..n).filter(|&i| !removed[i]).collect()
}

#[cfg(test)]
#[path = "sampling_tests.rs"]
mod tests;
