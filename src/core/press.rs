//! A press's friction, fitted over the whole press.
//!
//! A frame alone cannot tell a tangential force from a shifted place when
//! fewer than five joints sense the link, and integrating a fresh
//! tangential force out of every frame (the per-frame friction model of
//! [`crate::core::friction`]) lets each frame explain its misfit its own
//! way. A real press drags in one direction for its whole length: the
//! tangential force is a fixed fraction γ of the push, fixed in the link's
//! frame, while the arm moves under it. Over a press that is three
//! unknowns in all, and the arm's motion pins them.
//!
//! The unknowns are the place at every frame (on the link's surface, two
//! tangent coordinates each), γ (link frame; only its part along the
//! surface acts) and each frame's push magnitude (profiled out). The cost
//! is `-2 ln` of the posterior:
//!
//! `Σ_t ‖τ_t - f_t (u_t + C_t γ)‖²_W + Σ_t |p_t - p_{t-1}|²/(ℓ² Δt) + |γ|²/μ²`
//!
//! (`u_t`: torques per newton of the push along the inward normal at the
//! frame's place, `C_t`: per newton along the link's axes projected on the
//! surface; `ℓ`: the slide's length scale; `μ`: the friction setting, the
//! spread of γ per direction). Gauss–Newton steps solve a block
//! tridiagonal system (a frame's place is tied to its neighbours' by the
//! slide) bordered by γ, in `O(frames)`.
//!
//! The same search with γ held at zero is the frictionless answer; the
//! friction model is kept only when it explains the press by far better
//! ([`FRICTION_GAIN`]) with a plausible γ. A frictionless press then keeps
//! its estimate, and a press that our models explain poorly either way
//! (too few joints, another kind of error) is not moved.

use glam::{DMat2, DMat3, DVec2, DVec3};

use crate::core::robot::LinkId;
use crate::core::smooth::{MeshPoint, SurfaceFrame};
use crate::core::surface::LinkShape;
use crate::core::torque::{TorqueModel, weighted_dot as inner};

/// The drop in `-2 ln L` (the cost above, both searches started from the
/// same places, and the friction model's again from the frictionless
/// answer where it ended costlier) that the friction model must reach
/// over the frictionless one to be kept. Three more unknowns fitting
/// noise gain about 3; 30 is a likelihood ratio of e¹⁵ (χ² with three
/// degrees of freedom beyond it: a chance of 1e-6). Measured on synthetic
/// sessions (`synth --friction 0.15|0.3`, seeds 1–6) the answer moves
/// little between 15 and 60.
pub const FRICTION_GAIN: f64 = 30.0;

/// A fitted γ longer than this many spreads μ is taken for a model
/// failure, not friction (a push nearly along the surface explained as
/// friction), and the press keeps its frictionless estimate.
pub const RATIO_LIMIT_SPREADS: f64 = 4.0;

/// Gauss–Newton steps at most per search.
const MAX_STEPS: usize = 50;

/// Halvings of a step that does not lower the cost before giving up.
const MAX_HALVINGS: usize = 10;

/// No frame's place moves by more than this in one step, m: the surface
/// curves, and the linear model of the torques holds over about a patch.
const TRUST_M: f64 = 0.01;

/// A search stops once a step gains less than this in `-2 ln L`.
const CONVERGED: f64 = 1e-3;

/// Walks that [`locate`] takes (each lands within the surface's curvature
/// times the offset squared of the point: a patch-sized offset is within
/// micrometres after three).
const LOCATE_STEPS: usize = 4;

/// Shortest interval between frames the slide term divides by, s
/// (frames sharing a time stamp are tied this tightly).
const MIN_DT_SECS: f64 = 1e-6;

/// One frame of a press.
#[derive(Debug, Clone, Copy)]
pub struct PressFrame<'a> {
    /// Time, s.
    pub t_secs: f64,
    /// Torques per unit force at this frame's configuration.
    pub torque_model: &'a TorqueModel,
    /// Measured torques, sensed order, N·m.
    pub tau: &'a [f64],
    /// Where the search starts (the frame's estimate without this fit).
    pub start: MeshPoint,
}

/// What the fit needs besides the frames.
#[derive(Debug, Clone, Copy)]
pub struct PressSettings<'a> {
    /// `1/σ²` per sensed joint.
    pub weights: &'a [f64],
    /// Push magnitudes considered, N.
    pub force_range_newtons: (f64, f64),
    /// μ: spread of the tangential fraction γ per direction.
    pub friction: f64,
    /// ℓ: RMS slide of the place along each surface direction after 1 s,
    /// m/√s.
    pub slide_m_per_sqrt_s: f64,
}

/// One frame's contact under the fitted press.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PressContact {
    /// Where on the link's surface.
    pub location: MeshPoint,
    /// Contact point, link frame, m.
    pub point_in_link: DVec3,
    /// Inward unit normal, link frame.
    pub inward_normal_in_link: DVec3,
    /// Push along the inward normal, N.
    pub force_newtons: f64,
    /// Tangential force, link frame, N.
    pub tangential_in_link: DVec3,
    /// `Σ (τ - f (u + C γ))² / σ²` of this frame (χ² with one degree of
    /// freedom per sensed joint less the three the place and push fit).
    pub residual_chi2: f64,
    /// How far the whole press leaves this frame's place undetermined
    /// (see [`PlaceSpread`]); `None` where it cannot be computed.
    pub spread: Option<PlaceSpread>,
}

/// The uncertainty of one frame's place given the whole press: the
/// Laplace approximation of the posterior at the fit, with γ free under
/// its prior (spread μ per direction) even where the frictionless fit is
/// reported. A press that drags while the arm is still cannot tell a
/// tangential force from a shifted place (on the LWR's link 4, three
/// joints see a push: a place 50–70 mm off explains a drag of 17 % of the
/// push as well as the truth does); the place's spread along that
/// direction is then what μ allows, and the credible region says so
/// instead of shrinking with every frame of the press.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaceSpread {
    /// The surface's two unit tangents at the place, link frame.
    pub tangents_in_link: [DVec3; 2],
    /// Covariance of the place along the two tangents, m².
    pub covariance_m2: DMat2,
}

impl PlaceSpread {
    /// The points within `level` (a squared Mahalanobis distance) of the
    /// place, a patch of radius `rho_m` around it counted in: `dᵀ (Σ +
    /// ρ² I)⁻¹ d ≤ level` for an offset `d` projected on the tangents.
    /// `None` where the matrix is singular or not finite.
    #[must_use]
    pub fn region(&self, rho_m: f64, level: f64) -> Option<PlaceRegion> {
        let widened = self.covariance_m2 + DMat2::IDENTITY * (rho_m * rho_m);
        let det = widened.determinant();
        (det.is_finite() && det > 0.0).then(|| PlaceRegion {
            tangents_in_link: self.tangents_in_link,
            inverse_m2: widened.inverse(),
            level,
        })
    }
}

/// An ellipse around a place along its surface ([`PlaceSpread::region`]),
/// its inverse formed once for the many points tested against it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaceRegion {
    tangents_in_link: [DVec3; 2],
    inverse_m2: DMat2,
    level: f64,
}

impl PlaceRegion {
    /// Whether the point `offset_in_link` from the place (projected on the
    /// place's tangents) lies in the region.
    #[must_use]
    pub fn contains(&self, offset_in_link: DVec3) -> bool {
        let [t0, t1] = self.tangents_in_link;
        let d = DVec2::new(t0.dot(offset_in_link), t1.dot(offset_in_link));
        d.dot(self.inverse_m2 * d) <= self.level
    }
}

/// A press explained with a tangential force fixed in the link's frame.
#[derive(Debug, Clone, PartialEq)]
pub struct PressFit {
    /// Each frame's contact, in the frames' order.
    pub contacts: Vec<PressContact>,
    /// γ: the tangential force per newton of push, link frame (its part
    /// along the surface acts at each frame).
    pub tangential_ratio_in_link: DVec3,
    /// How much lower `-2 ln L` is with friction than without.
    pub gain: f64,
}

/// Fits the press `frames` (in time order, all on `link`) with a
/// tangential force fixed in the link's frame, and returns it when the
/// friction model explains the press by [`FRICTION_GAIN`] better than the
/// frictionless one with a plausible γ; `None` otherwise (also when μ is
/// 0, there are no frames, or the surface cannot be evaluated).
#[must_use]
pub fn fit_press(shape: &LinkShape, link: LinkId, frames: &[PressFrame], settings: &PressSettings) -> Option<PressFit> {
    let answer = explain_press(shape, link, frames, settings)?;
    answer.friction.then_some(PressFit {
        contacts: answer.contacts,
        tangential_ratio_in_link: answer.tangential_ratio_in_link,
        gain: answer.gain,
    })
}

/// The press's best explanation on one link from one start: the
/// frictionless fit, or the friction model's where it is kept (as in
/// [`fit_press`]), with its cost, so that explanations on other links or
/// from other starts can be weighed against it.
#[derive(Debug, Clone, PartialEq)]
pub struct PressAnswer {
    /// Each frame's contact, in the frames' order.
    pub contacts: Vec<PressContact>,
    /// γ, link frame (zero without friction).
    pub tangential_ratio_in_link: DVec3,
    /// `-2 ln` of the posterior at the fit (the cost of the module's
    /// documentation, γ's prior included when friction is kept).
    pub cost: f64,
    /// Whether the friction model was kept.
    pub friction: bool,
    /// How much lower the cost is with friction than without (0 without a
    /// friction setting).
    pub gain: f64,
}

/// Fits the press `frames` (in time order, all on `link`, each started at
/// its `start`) without friction and, with a friction setting, with it;
/// returns the friction model's fit where [`fit_press`] would keep it and
/// the frictionless one otherwise. `None` without frames, without a
/// positive finite slide length, or where the surface cannot be
/// evaluated.
#[must_use]
pub fn explain_press(
    shape: &LinkShape,
    link: LinkId,
    frames: &[PressFrame],
    settings: &PressSettings,
) -> Option<PressAnswer> {
    let problem = Problem::new(shape, link, frames, settings)?;
    let start: Vec<MeshPoint> = frames.iter().map(|f| f.start).collect();
    let frictionless = problem.descend(start.clone(), false)?;
    let with_friction = settings.friction > 0.0 && settings.friction.is_finite();
    // From the recording's places; where that search ends above the
    // frictionless cost (in another valley: γ = 0 is the frictionless
    // answer, so the friction model's best is never worse), again from
    // where the frictionless search ended, which ends at or below it.
    let frictional = if with_friction {
        match problem.descend(start, true) {
            Some(cold) if cold.normal.cost <= frictionless.normal.cost => Some(cold),
            cold => problem.descend(frictionless.locations.clone(), true).or(cold),
        }
    } else {
        None
    };
    let gain = frictional
        .as_ref()
        .map_or(0.0, |f| frictionless.normal.cost - f.normal.cost);
    let kept =
        frictional.filter(|f| gain > FRICTION_GAIN && f.ratio.length() <= RATIO_LIMIT_SPREADS * settings.friction);
    let friction = kept.is_some();
    let found = kept.unwrap_or(frictionless);
    let ratio = found.ratio;
    let spreads = problem.spreads(&found.locations, ratio, with_friction);
    let contacts = found
        .locations
        .iter()
        .zip(&found.normal.surface)
        .zip(&found.normal.magnitudes)
        .zip(&found.normal.residuals)
        .enumerate()
        .map(
            |(t, (((&location, surface), &force_newtons), &residual_chi2))| PressContact {
                location,
                point_in_link: surface.point,
                inward_normal_in_link: surface.inward_normal,
                force_newtons,
                tangential_in_link: along_surface(ratio, surface.inward_normal) * force_newtons,
                residual_chi2,
                spread: spreads
                    .as_ref()
                    .and_then(|all| all.get(t))
                    .map(|&covariance_m2| PlaceSpread {
                        tangents_in_link: surface.tangents,
                        covariance_m2,
                    }),
            },
        )
        .collect();
    Some(PressAnswer {
        contacts,
        tangential_ratio_in_link: ratio,
        cost: found.normal.cost,
        friction,
        gain,
    })
}

/// Each frame's [`PlaceSpread`] at the frames' `start` places with no
/// tangential force, γ marginalised under its prior where μ > 0: what
/// the frames leave undetermined of places already chosen (a filter's
/// press so far), without a search. `None` without frames, without a
/// positive finite slide length, or where the surface or the matrix
/// cannot be evaluated.
#[must_use]
pub fn press_spreads(
    shape: &LinkShape,
    link: LinkId,
    frames: &[PressFrame],
    settings: &PressSettings,
) -> Option<Vec<PlaceSpread>> {
    let problem = Problem::new(shape, link, frames, settings)?;
    let locations: Vec<MeshPoint> = frames.iter().map(|f| f.start).collect();
    let with_friction = settings.friction > 0.0 && settings.friction.is_finite();
    let covariances = problem.spreads(&locations, DVec3::ZERO, with_friction)?;
    locations
        .iter()
        .zip(covariances)
        .map(|(&at, covariance_m2)| {
            Some(PlaceSpread {
                tangents_in_link: shape.frame(at)?.tangents,
                covariance_m2,
            })
        })
        .collect()
}

/// The place on `shape` of `point_in_link` (a point on or next to the
/// surface), found by walking from `from` (a sample near it) along the
/// surface: a few steps, each the offset's part along the surface there.
#[must_use]
pub fn locate(shape: &LinkShape, from: MeshPoint, point_in_link: DVec3) -> MeshPoint {
    let mut at = from;
    for _ in 0..LOCATE_STEPS {
        let Some(here) = shape.frame(at) else {
            break;
        };
        let offset = along_surface(point_in_link - here.point, here.inward_normal);
        if offset.length() < 1e-9 {
            break;
        }
        at = shape.walk(at, offset);
    }
    at
}

/// Torques per newton at `here` into `columns`: the push `u` along the
/// inward normal, its derivatives along the two tangents, and a push along
/// each of the link's axes projected on the surface. `None` unless there
/// are six columns.
fn columns_at(model: &TorqueModel, link: LinkId, here: &SurfaceFrame, columns: &mut [Vec<f64>]) -> Option<()> {
    let [u, d0, d1, c0, c1, c2] = columns else {
        return None;
    };
    model.line_array_torques_into(link, &here.line(), u);
    model.line_array_torques_into(link, &here.line_derivatives[0], d0);
    model.line_array_torques_into(link, &here.line_derivatives[1], d1);
    for (axis, out) in [DVec3::X, DVec3::Y, DVec3::Z].into_iter().zip([c0, c1, c2]) {
        let direction = along_surface(axis, here.inward_normal);
        let moment = here.point.cross(direction);
        let line = [moment.x, moment.y, moment.z, direction.x, direction.y, direction.z];
        model.line_array_torques_into(link, &line, out);
    }
    Some(())
}

/// The part of `v` perpendicular to the unit normal `n`.
fn along_surface(v: DVec3, n: DVec3) -> DVec3 {
    v - v.dot(n) * n
}

/// The press and its settings.
struct Problem<'a> {
    shape: &'a LinkShape,
    link: LinkId,
    frames: &'a [PressFrame<'a>],
    settings: &'a PressSettings<'a>,
}

impl<'a> Problem<'a> {
    /// The press `frames` on `link`; `None` without frames or without a
    /// positive finite slide length (the slide prior divides by it).
    fn new(
        shape: &'a LinkShape,
        link: LinkId,
        frames: &'a [PressFrame<'a>],
        settings: &'a PressSettings<'a>,
    ) -> Option<Self> {
        let slide = settings.slide_m_per_sqrt_s;
        (!frames.is_empty() && slide > 0.0 && slide.is_finite()).then_some(Self {
            shape,
            link,
            frames,
            settings,
        })
    }
}

/// The cost at a trajectory and its Gauss–Newton normal equations.
struct Normal {
    /// `-2 ln` posterior (up to a constant).
    cost: f64,
    /// Each frame's surface.
    surface: Vec<SurfaceFrame>,
    /// Each frame's profiled push, N.
    magnitudes: Vec<f64>,
    /// Each frame's `‖τ - f (u + C γ)‖²_W`.
    residuals: Vec<f64>,
    /// Diagonal 2×2 blocks (a frame's two tangent coordinates).
    diagonal: Vec<DMat2>,
    /// `lower[t]`: the block coupling frame t to frame t-1 (`lower[0]`
    /// unused).
    lower: Vec<DMat2>,
    /// Coupling of each frame's place to γ: one column per axis of γ.
    border: Vec<[DVec2; 3]>,
    /// γ's own block.
    corner: DMat3,
    /// Right-hand sides: places.
    rhs_places: Vec<DVec2>,
    /// Right-hand side: γ.
    rhs_ratio: DVec3,
}

impl Normal {
    /// Adds the slide from frame `t - 1` to frame `t`, `weight |p_t -
    /// p_{t-1}|²` (`weight`: 1/(ℓ² Δt)), to the cost and the normal
    /// equations.
    fn add_slide(&mut self, t: usize, weight: f64) -> Option<()> {
        let (here, before) = (self.surface.get(t)?, self.surface.get(t.checked_sub(1)?)?);
        let gap = here.point - before.point;
        let (tangents_here, tangents_before) = (here.tangents, before.tangents);
        self.cost += weight * gap.length_squared();
        *self.diagonal.get_mut(t)? += DMat2::IDENTITY * weight;
        *self.diagonal.get_mut(t - 1)? += DMat2::IDENTITY * weight;
        // Row: this frame's tangent i; column: the frame before's j.
        *self.lower.get_mut(t)? -= DMat2::from_cols(
            DVec2::new(
                tangents_here[0].dot(tangents_before[0]),
                tangents_here[1].dot(tangents_before[0]),
            ),
            DVec2::new(
                tangents_here[0].dot(tangents_before[1]),
                tangents_here[1].dot(tangents_before[1]),
            ),
        ) * weight;
        *self.rhs_places.get_mut(t)? -= DVec2::new(tangents_here[0].dot(gap), tangents_here[1].dot(gap)) * weight;
        *self.rhs_places.get_mut(t - 1)? +=
            DVec2::new(tangents_before[0].dot(gap), tangents_before[1].dot(gap)) * weight;
        Some(())
    }
}

/// The end of a search.
struct Found {
    locations: Vec<MeshPoint>,
    ratio: DVec3,
    normal: Normal,
}

impl Problem<'_> {
    /// Gauss–Newton from `start` (γ = 0), moving γ only when
    /// `ratio_free`.
    fn descend(&self, start: Vec<MeshPoint>, ratio_free: bool) -> Option<Found> {
        let mut locations = start;
        let mut ratio = DVec3::ZERO;
        let mut normal = self.normal_at(&locations, ratio, ratio_free)?;
        for _ in 0..MAX_STEPS {
            let Some((places, ratio_step)) = step(&normal, ratio_free) else {
                break;
            };
            let largest = places.iter().map(|d| d.length()).fold(0.0, f64::max);
            let mut scale = if largest > TRUST_M { TRUST_M / largest } else { 1.0 };
            let mut gained = 0.0;
            for _ in 0..MAX_HALVINGS {
                let moved: Vec<MeshPoint> = locations
                    .iter()
                    .zip(&normal.surface)
                    .zip(&places)
                    .map(|((&at, surface), d)| {
                        let offset = (surface.tangents[0] * d.x + surface.tangents[1] * d.y) * scale;
                        self.shape.walk(at, offset)
                    })
                    .collect();
                let next_ratio = ratio + ratio_step * scale;
                if let Some(next) = self.normal_at(&moved, next_ratio, ratio_free)
                    && next.cost < normal.cost
                {
                    gained = normal.cost - next.cost;
                    locations = moved;
                    ratio = next_ratio;
                    normal = next;
                    break;
                }
                scale *= 0.5;
            }
            if gained < CONVERGED {
                break;
            }
        }
        Some(Found {
            locations,
            ratio,
            normal,
        })
    }

    /// Each frame's place covariance (tangent coordinates, m²) at
    /// `locations` and γ = `ratio`: the inverse of the Gauss–Newton
    /// matrix (the cost is `-2 ln` posterior and the matrix half its
    /// Hessian, so the inverse is the Laplace covariance) with γ
    /// marginalised where `ratio_free`. `None` where it is singular.
    fn spreads(&self, locations: &[MeshPoint], ratio: DVec3, ratio_free: bool) -> Option<Vec<DMat2>> {
        covariances(&self.normal_at(locations, ratio, ratio_free)?, ratio_free)
    }

    /// The cost at `locations` with γ = `ratio`, and its normal equations
    /// (γ's rows only when `ratio_free`). `None` where the surface cannot
    /// be evaluated or a number is not finite.
    fn normal_at(&self, locations: &[MeshPoint], ratio: DVec3, ratio_free: bool) -> Option<Normal> {
        let settings = self.settings;
        let w = settings.weights;
        let joints = w.len();
        let (f_min, f_max) = settings.force_range_newtons;
        let spread = settings.friction;
        let slide = settings.slide_m_per_sqrt_s;
        let n = self.frames.len();
        let surface: Vec<SurfaceFrame> = locations
            .iter()
            .map(|&at| self.shape.frame(at))
            .collect::<Option<_>>()?;
        let mut normal = Normal {
            cost: 0.0,
            surface,
            magnitudes: vec![0.0; n],
            residuals: vec![0.0; n],
            diagonal: vec![DMat2::ZERO; n],
            lower: vec![DMat2::ZERO; n],
            border: vec![[DVec2::ZERO; 3]; n],
            corner: DMat3::ZERO,
            rhs_places: vec![DVec2::ZERO; n],
            rhs_ratio: DVec3::ZERO,
        };
        if ratio_free {
            normal.cost += ratio.length_squared() / (spread * spread);
            normal.corner = DMat3::IDENTITY / (spread * spread);
            normal.rhs_ratio = -ratio / (spread * spread);
        }
        // u, ∂u/∂s₁, ∂u/∂s₂, then the three axes' tangential columns.
        let mut columns = vec![vec![0.0; joints]; 6];
        let mut pushed = vec![0.0; joints];
        let mut residual = vec![0.0; joints];
        for (t, frame) in self.frames.iter().enumerate() {
            let here = *normal.surface.get(t)?;
            let tau = frame.tau.get(..joints)?;
            columns_at(frame.torque_model, self.link, &here, &mut columns)?;
            let [u, d0, d1, c0, c1, c2] = columns.as_slice() else {
                return None;
            };
            for (j, p) in pushed.iter_mut().enumerate() {
                *p = u[j] + ratio.x * c0[j] + ratio.y * c1[j] + ratio.z * c2[j];
            }
            let lever = inner(w, &pushed, &pushed);
            let best = if lever > 0.0 {
                inner(w, &pushed, tau) / lever
            } else {
                f_min
            };
            let f = best.clamp(f_min, f_max);
            // Where the best magnitude is inside the range it moves with
            // the place: the step sees the residual with the push's
            // direction projected out.
            let profiled = lever > 0.0 && best > f_min && best < f_max;
            for ((r, &m), &p) in residual.iter_mut().zip(tau).zip(&pushed) {
                *r = m - f * p;
            }
            let chi2 = inner(w, &residual, &residual);
            normal.cost += chi2;
            *normal.residuals.get_mut(t)? = chi2;
            *normal.magnitudes.get_mut(t)? = f;
            let metric = |x: &[f64], y: &[f64]| {
                let plain = inner(w, x, y);
                if profiled {
                    plain - inner(w, x, &pushed) * inner(w, &pushed, y) / lever
                } else {
                    plain
                }
            };
            let places = [d0, d1];
            let axes = [c0, c1, c2];
            let f2 = f * f;
            let block = normal.diagonal.get_mut(t)?;
            *block += DMat2::from_cols(
                DVec2::new(metric(d0, d0), metric(d1, d0)),
                DVec2::new(metric(d0, d1), metric(d1, d1)),
            ) * f2;
            *normal.rhs_places.get_mut(t)? += DVec2::new(inner(w, d0, &residual), inner(w, d1, &residual)) * f;
            if ratio_free {
                let border = normal.border.get_mut(t)?;
                for (k, axis) in axes.iter().enumerate() {
                    border[k] += DVec2::new(metric(places[0], axis), metric(places[1], axis)) * f2;
                }
                normal.corner += DMat3::from_cols_array_2d(&std::array::from_fn(|k| {
                    std::array::from_fn(|l| metric(axes[k], axes[l]) * f2)
                }));
                normal.rhs_ratio += DVec3::new(
                    inner(w, c0, &residual),
                    inner(w, c1, &residual),
                    inner(w, c2, &residual),
                ) * f;
            }
            if t > 0 {
                let earlier = self.frames.get(t - 1)?;
                let dt_secs = (frame.t_secs - earlier.t_secs).max(MIN_DT_SECS);
                normal.add_slide(t, 1.0 / (slide * slide * dt_secs))?;
            }
        }
        normal.cost.is_finite().then_some(normal)
    }
}

/// Each frame's place covariance from `normal` (see
/// [`Problem::spreads`]): the diagonal blocks of the inverse of its
/// matrix, γ marginalised where `ratio_free`.
fn covariances(normal: &Normal, ratio_free: bool) -> Option<Vec<DMat2>> {
    let chain = Chain::factor(&normal.diagonal, &normal.lower)?;
    let mut covariances = chain.inverse_diagonal()?;
    if ratio_free {
        // (A - B C⁻¹ Bᵀ)⁻¹ = A⁻¹ + (A⁻¹B) S⁻¹ (A⁻¹B)ᵀ, S the Schur complement.
        let bordered = Bordered::of(normal, &chain)?;
        let schur_inverse = bordered.schur_inverse;
        for (t, covariance) in covariances.iter_mut().enumerate() {
            let columns: [DVec2; 3] = std::array::from_fn(|k| {
                bordered
                    .by_axis
                    .get(k)
                    .and_then(|column| column.get(t))
                    .copied()
                    .unwrap_or(DVec2::ZERO)
            });
            for (k, &x) in columns.iter().enumerate() {
                for (l, &y) in columns.iter().enumerate() {
                    let weight = schur_inverse.col(l)[k];
                    *covariance += DMat2::from_cols(x * y.x, x * y.y) * weight;
                }
            }
        }
    }
    covariances.iter().all(DMat2::is_finite).then_some(covariances)
}

/// The Gauss–Newton step of `normal`: each frame's move (tangent
/// coordinates, m) and γ's (zero unless `ratio_free`). `None` when the
/// system is singular.
fn step(normal: &Normal, ratio_free: bool) -> Option<(Vec<DVec2>, DVec3)> {
    let chain = Chain::factor(&normal.diagonal, &normal.lower)?;
    let places = chain.solve(&normal.rhs_places);
    if !ratio_free {
        return Some((places, DVec3::ZERO));
    }
    // γ by the Schur complement of the chain: (C - Bᵀ A⁻¹ B) dγ = r_γ - Bᵀ A⁻¹ r_p.
    let bordered = Bordered::of(normal, &chain)?;
    let mut rhs = normal.rhs_ratio;
    for (t, border) in normal.border.iter().enumerate() {
        let place = places.get(t).copied().unwrap_or(DVec2::ZERO);
        rhs -= DVec3::new(border[0].dot(place), border[1].dot(place), border[2].dot(place));
    }
    let ratio_step = bordered.schur_inverse * rhs;
    let moves = places
        .iter()
        .enumerate()
        .map(|(t, &p)| {
            let mut d = p;
            for (column, amount) in bordered.by_axis.iter().zip(ratio_step.to_array()) {
                d -= column.get(t).copied().unwrap_or(DVec2::ZERO) * amount;
            }
            d
        })
        .collect();
    ratio_step.is_finite().then_some((moves, ratio_step))
}

/// The border's part of the Gauss–Newton system: `A⁻¹ B` (one column of
/// 2-vectors per axis of γ) and the inverse of the Schur complement
/// `S = C - Bᵀ A⁻¹ B`.
struct Bordered {
    by_axis: Vec<Vec<DVec2>>,
    schur_inverse: DMat3,
}

impl Bordered {
    /// `None` where the Schur complement is singular.
    fn of(normal: &Normal, chain: &Chain) -> Option<Self> {
        let by_axis: Vec<Vec<DVec2>> = (0..3)
            .map(|k| {
                let column: Vec<DVec2> = normal.border.iter().map(|b| b[k]).collect();
                chain.solve(&column)
            })
            .collect();
        let mut schur = normal.corner.to_cols_array_2d();
        for (t, border) in normal.border.iter().enumerate() {
            for (k, b) in border.iter().enumerate() {
                for (column, solved) in schur.iter_mut().zip(&by_axis) {
                    let s = solved.get(t).copied().unwrap_or(DVec2::ZERO);
                    if let Some(entry) = column.get_mut(k) {
                        *entry -= b.dot(s);
                    }
                }
            }
        }
        let schur = DMat3::from_cols_array_2d(&schur);
        let det = schur.determinant();
        if !(det.is_finite() && det.abs() > f64::MIN_POSITIVE) {
            return None;
        }
        Some(Self {
            by_axis,
            schur_inverse: schur.inverse(),
        })
    }
}

/// A block tridiagonal symmetric matrix (2×2 blocks) factored for
/// solving: `diagonal[t] x_t + lower[t] x_{t-1} + lower[t+1]ᵀ x_{t+1}`.
struct Chain {
    /// The inverse of each pivot block.
    pivot_inverse: Vec<DMat2>,
    /// `lower[t] · pivot_inverse[t-1]`, used forward.
    gain: Vec<DMat2>,
    /// The sub-diagonal blocks.
    lower: Vec<DMat2>,
}

impl Chain {
    /// Block elimination from the first frame on. `None` when a pivot is
    /// singular (a ridge of 1e-12 of its trace keeps flat directions
    /// from being so).
    fn factor(diagonal: &[DMat2], lower: &[DMat2]) -> Option<Self> {
        let n = diagonal.len();
        let mut pivot_inverse: Vec<DMat2> = Vec::with_capacity(n);
        let mut gain = vec![DMat2::ZERO; n];
        for t in 0..n {
            let mut pivot = *diagonal.get(t)?;
            if t > 0 {
                let g = *lower.get(t)? * *pivot_inverse.get(t - 1)?;
                pivot -= g * lower.get(t)?.transpose();
                *gain.get_mut(t)? = g;
            }
            let ridge = 1e-12 * (pivot.x_axis.x + pivot.y_axis.y).abs();
            pivot += DMat2::IDENTITY * ridge;
            let det = pivot.determinant();
            if !(det.is_finite() && det.abs() > f64::MIN_POSITIVE) {
                return None;
            }
            pivot_inverse.push(pivot.inverse());
        }
        Some(Self {
            pivot_inverse,
            gain,
            lower: lower.to_vec(),
        })
    }

    /// The diagonal blocks of the matrix's inverse, from the last frame
    /// back: `X_t = P_t⁻¹ + G_t X_{t+1} G_tᵀ` with `G_t = P_t⁻¹ L_{t+1}ᵀ`
    /// (`P`: the pivots, `L`: the sub-diagonal blocks).
    fn inverse_diagonal(&self) -> Option<Vec<DMat2>> {
        let mut out = vec![DMat2::ZERO; self.pivot_inverse.len()];
        let mut after: Option<DMat2> = None;
        for (t, slot) in out.iter_mut().enumerate().rev() {
            let pivot_inverse = *self.pivot_inverse.get(t)?;
            let here = match after {
                None => pivot_inverse,
                Some(next) => {
                    let g = pivot_inverse * self.lower.get(t + 1)?.transpose();
                    pivot_inverse + g * next * g.transpose()
                }
            };
            *slot = here;
            after = Some(here);
        }
        Some(out)
    }

    /// The solution for the right-hand side `rhs` (one 2-vector a frame).
    fn solve(&self, rhs: &[DVec2]) -> Vec<DVec2> {
        let mut forward: Vec<DVec2> = Vec::with_capacity(rhs.len());
        let mut before = DVec2::ZERO;
        for (&r, &gain) in rhs.iter().zip(&self.gain) {
            before = r - gain * before;
            forward.push(before);
        }
        let mut x = vec![DVec2::ZERO; forward.len()];
        let (mut after, mut after_lower) = (DVec2::ZERO, DMat2::ZERO);
        for (((slot, &y), &pivot_inverse), &lower) in x
            .iter_mut()
            .zip(&forward)
            .zip(&self.pivot_inverse)
            .zip(&self.lower)
            .rev()
        {
            after = pivot_inverse * (y - after_lower.transpose() * after);
            *slot = after;
            after_lower = lower;
        }
        x
    }
}

#[cfg(test)]
mod tests {
    // Test helpers may unwrap: a panic is a failed test with its message.
    #![allow(clippy::unwrap_used)]

    use super::*;
    use crate::core::builtin;
    use crate::core::kinematics::RobotPose;
    use crate::core::metrics::percentile;
    use crate::core::rng::Rng;
    use crate::core::surface::{Surface, SurfaceRequest};

    /// The region is the ellipse `dᵀ(Σ + ρ²I)⁻¹d ≤ level` along the
    /// place's tangents: its edge along each axis of a diagonal `Σ` at
    /// `√(level (σᵢ² + ρ²))`, the normal direction ignored; a singular
    /// matrix has none.
    #[test]
    fn a_place_region_is_the_ellipse_of_its_spread_and_patch() {
        let spread = PlaceSpread {
            tangents_in_link: [DVec3::X, DVec3::Y],
            covariance_m2: DMat2::from_diagonal(DVec2::new(0.02 * 0.02, 0.005 * 0.005)),
        };
        let (rho_m, level) = (0.003, 4.61);
        let region = spread.region(rho_m, level).unwrap();
        let edge_x = (level * (0.02f64.powi(2) + rho_m * rho_m)).sqrt();
        let edge_y = (level * (0.005f64.powi(2) + rho_m * rho_m)).sqrt();
        assert!(region.contains(DVec3::new(0.999 * edge_x, 0.0, 0.0)));
        assert!(!region.contains(DVec3::new(1.001 * edge_x, 0.0, 0.0)));
        assert!(region.contains(DVec3::new(0.0, -0.999 * edge_y, 0.5)));
        assert!(!region.contains(DVec3::new(0.0, -1.001 * edge_y, 0.0)));
        // Halfway along both axes: (½)² + (½)² ≤ 1.
        assert!(region.contains(DVec3::new(0.5 * edge_x, 0.5 * edge_y, 0.0)));
        assert!(!region.contains(DVec3::new(0.75 * edge_x, 0.75 * edge_y, 0.0)));
        let flat = PlaceSpread {
            covariance_m2: DMat2::ZERO,
            ..spread
        };
        assert!(flat.region(0.0, level).is_none());
        let not_finite = PlaceSpread {
            covariance_m2: DMat2::from_diagonal(DVec2::new(f64::NAN, 1.0)),
            ..spread
        };
        assert!(not_finite.region(rho_m, level).is_none());
    }

    /// A press on the LWR's link 5: 60 frames at 50 Hz while every joint
    /// swings by up to 0.3 rad, a push of 5–15 N at one place plus
    /// `ratio` (link frame) times it along the surface, σ = 0.05 N·m.
    struct Press {
        surface: Surface,
        link: LinkId,
        truth: SurfaceFrame,
        times: Vec<f64>,
        models: Vec<TorqueModel>,
        taus: Vec<Vec<f64>>,
        pushes: Vec<f64>,
        /// The truth's place walked 6 mm along its first tangent.
        start: MeshPoint,
    }

    fn press(ratio_along_tangents: [f64; 2], noise: f64, seed: u64) -> Press {
        let robot = builtin::lwr4plus_generated().unwrap();
        let link = robot.link_id("lwr_5_link").unwrap();
        let links = robot.default_candidate_links();
        let request = SurfaceRequest {
            links: links.clone(),
            total_points: 2000,
            seed: 0,
        };
        let surface = Surface::sample(&robot, &request).unwrap();
        let shape = surface.shape(link).unwrap();
        let k = (0..surface.len()).filter(|&k| surface.link[k] == link).nth(40).unwrap();
        let location = surface.location[k];
        let truth = shape.frame(location).unwrap();
        let ratio = truth.tangents[0] * ratio_along_tangents[0] + truth.tangents[1] * ratio_along_tangents[1];
        let mut rng = Rng::new(seed);
        let phases: Vec<f64> = (0..7).map(|_| rng.uniform_in(0.0, std::f64::consts::TAU)).collect();
        let (mut times, mut models, mut taus, mut pushes) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for i in 0..60 {
            let t = f64::from(i) / 50.0;
            let q: Vec<f64> = phases
                .iter()
                .enumerate()
                .map(|(j, phase)| 0.4 - 0.1 * j as f64 + 0.3 * (std::f64::consts::TAU * 0.5 * t + phase).sin())
                .collect();
            let pose = RobotPose::new(&robot, &robot.joint_positions(&q, &[]).unwrap());
            let model = TorqueModel::new(&robot, &pose, &links);
            let push = 10.0 + 5.0 * (std::f64::consts::TAU * t).sin();
            let force = (truth.inward_normal + ratio) * push;
            let tau = model
                .torques(link, truth.point, force)
                .iter()
                .map(|x| x + noise * rng.normal())
                .collect();
            times.push(t);
            models.push(model);
            taus.push(tau);
            pushes.push(push);
        }
        let start = shape.walk(location, truth.tangents[0] * 0.006);
        Press {
            surface,
            link,
            truth,
            times,
            models,
            taus,
            pushes,
            start,
        }
    }

    const WEIGHTS: [f64; 7] = [400.0; 7];

    fn settings(friction: f64) -> PressSettings<'static> {
        PressSettings {
            weights: &WEIGHTS,
            force_range_newtons: (1.0, 30.0),
            friction,
            slide_m_per_sqrt_s: 0.003,
        }
    }

    fn press_frames(p: &Press) -> Vec<PressFrame<'_>> {
        (0..p.times.len())
            .map(|i| PressFrame {
                t_secs: p.times[i],
                torque_model: &p.models[i],
                tau: &p.taus[i],
                start: p.start,
            })
            .collect()
    }

    /// A press dragging sideways with a tangential force of 18 % of the
    /// push (fixed in the link's frame) is found where it is, with its
    /// tangential force; the frictionless search over the same press ends
    /// where the normal leans along the whole force, a centimetre away.
    /// Measured: 1.5 mm (0.65 mm without noise: the prior on γ shrinks it
    /// a little), force 0.11 N, γ within 0.05, frictionless 10.9 mm.
    #[test]
    fn a_dragging_press_is_found_with_its_tangential_force() {
        let p = press([0.15, -0.1], 0.05, 3);
        let shape = p.surface.shape(p.link).unwrap();
        let frames = press_frames(&p);
        let settings = settings(0.1);
        let fit = fit_press(shape, p.link, &frames, &settings).unwrap();
        let place: Vec<f64> = fit
            .contacts
            .iter()
            .map(|c| c.point_in_link.distance(p.truth.point))
            .collect();
        let force: Vec<f64> = fit
            .contacts
            .iter()
            .zip(&p.pushes)
            .map(|(c, &push)| {
                let truth = (p.truth.inward_normal + p.truth.tangents[0] * 0.15 - p.truth.tangents[1] * 0.1) * push;
                (c.inward_normal_in_link * c.force_newtons + c.tangential_in_link).distance(truth)
            })
            .collect();
        let ratio = p.truth.tangents[0] * 0.15 - p.truth.tangents[1] * 0.1;
        let problem = Problem {
            shape,
            link: p.link,
            frames: &frames,
            settings: &settings,
        };
        let plain = problem
            .descend(frames.iter().map(|f| f.start).collect(), false)
            .unwrap();
        let plain_place: Vec<f64> = plain
            .normal
            .surface
            .iter()
            .map(|s| s.point.distance(p.truth.point))
            .collect();
        let (place, force, plain_place) = (
            percentile(&place, 0.5),
            percentile(&force, 0.5),
            percentile(&plain_place, 0.5),
        );
        eprintln!(
            "place {:.2} mm (frictionless {:.1} mm), force {force:.3} N, γ {:?} (true {ratio:?}), gain {:.0}",
            place * 1e3,
            plain_place * 1e3,
            fit.tangential_ratio_in_link,
            fit.gain
        );
        assert!(place < 2.5e-3, "{place}");
        assert!(force < 0.3, "{force}");
        let ratio_error = along_surface(fit.tangential_ratio_in_link, p.truth.inward_normal).distance(ratio);
        assert!(ratio_error < 0.08, "{ratio_error}");
        assert!(plain_place > 3.0 * place && plain_place > 3e-3, "{plain_place}");
        assert!(fit.gain > FRICTION_GAIN);
    }

    /// `explain_press` hands over what `fit_press` keeps, and otherwise the
    /// frictionless fit with its cost, so that fits from other starts can
    /// be weighed against it: the friction model's cost is the
    /// frictionless one less the gain, and without a friction setting the
    /// answer is frictionless with no gain.
    #[test]
    fn a_press_is_explained_with_its_cost() {
        let p = press([0.15, -0.1], 0.05, 3);
        let shape = p.surface.shape(p.link).unwrap();
        let frames = press_frames(&p);
        let answer = explain_press(shape, p.link, &frames, &settings(0.1)).unwrap();
        let fit = fit_press(shape, p.link, &frames, &settings(0.1)).unwrap();
        assert!(answer.friction);
        assert_eq!(answer.contacts, fit.contacts);
        assert!((answer.gain - fit.gain).abs() < 1e-9);
        let plain = explain_press(shape, p.link, &frames, &settings(0.0)).unwrap();
        assert!(!plain.friction && plain.gain.abs() < 1e-15);
        assert_eq!(plain.tangential_ratio_in_link, DVec3::ZERO);
        assert!(
            (plain.cost - answer.cost - answer.gain).abs() < 1e-6 * plain.cost,
            "{plain:?}"
        );
        // The residuals are the cost less the slide (and γ's prior).
        let residuals: f64 = plain.contacts.iter().map(|c| c.residual_chi2).sum();
        assert!(residuals <= plain.cost && residuals > 0.5 * plain.cost);
        let straight = press([0.0, 0.0], 0.05, 0);
        let frames = press_frames(&straight);
        let shape = straight.surface.shape(straight.link).unwrap();
        let kept = explain_press(shape, straight.link, &frames, &settings(0.1)).unwrap();
        assert!(!kept.friction);
        assert!(explain_press(shape, straight.link, &[], &settings(0.1)).is_none());
    }

    /// γ = 0 is the frictionless answer, so the friction model never
    /// explains a press worse: where its search from the recording's
    /// places ends in a costlier valley, it searches again from where the
    /// frictionless search ended. Starts walked 2–8 cm from the press, in
    /// eight directions, on presses dragging up to 40 % of the push.
    #[test]
    fn friction_never_explains_a_press_worse_than_none() {
        let mut worst = f64::INFINITY;
        for (seed, ratio) in [(1, [0.3, 0.2]), (2, [-0.4, 0.1]), (4, [0.0, 0.35])] {
            let p = press(ratio, 0.05, seed);
            let shape = p.surface.shape(p.link).unwrap();
            let truth = p.truth;
            for step in 0..8 {
                let angle = std::f64::consts::TAU * f64::from(step) / 8.0;
                let distance = 0.02 + 0.02 * f64::from(step % 4);
                let direction = truth.tangents[0] * angle.cos() + truth.tangents[1] * angle.sin();
                let start = shape.walk(p.start, direction * distance);
                let frames: Vec<PressFrame> = press_frames(&p)
                    .into_iter()
                    .map(|f| PressFrame { start, ..f })
                    .collect();
                let answer = explain_press(shape, p.link, &frames, &settings(0.2)).unwrap();
                worst = worst.min(answer.gain);
            }
        }
        assert!(
            worst >= -1e-6,
            "a friction fit costlier than the frictionless one by {}",
            -worst
        );
    }

    /// A press without a tangential force keeps its frictionless estimate:
    /// the friction model gains no more than noise.
    #[test]
    fn a_straight_press_is_left_alone() {
        for seed in 0..3 {
            let p = press([0.0, 0.0], 0.05, seed);
            let shape = p.surface.shape(p.link).unwrap();
            let frames = press_frames(&p);
            assert_eq!(fit_press(shape, p.link, &frames, &settings(0.1)), None, "seed {seed}");
            let problem = Problem {
                shape,
                link: p.link,
                frames: &frames,
                settings: &settings(0.1),
            };
            let start: Vec<MeshPoint> = frames.iter().map(|f| f.start).collect();
            let plain = problem.descend(start.clone(), false).unwrap();
            let frictional = problem.descend(start, true).unwrap();
            let gain = plain.normal.cost - frictional.normal.cost;
            eprintln!("seed {seed}: gain {gain:.2}");
            assert!((0.0..10.0).contains(&gain), "{gain}");
        }
    }

    /// The normal equations' right-hand sides are minus half the cost's
    /// gradient (central differences: moving one frame's place along each
    /// tangent, and γ along each axis; at γ = 0, where the place's columns
    /// are exact), and γ's block is half its curvature where the model
    /// fits exactly (there Gauss–Newton's curvature is the cost's).
    #[test]
    fn the_normal_equations_are_the_costs_derivatives() {
        let p = press([0.15, -0.1], 0.05, 5);
        let shape = p.surface.shape(p.link).unwrap();
        let frames = press_frames(&p);
        let settings = settings(0.1);
        let problem = Problem {
            shape,
            link: p.link,
            frames: &frames,
            settings: &settings,
        };
        // Places that differ from frame to frame, so that the slide's
        // terms count too.
        let at: Vec<MeshPoint> = frames
            .iter()
            .enumerate()
            .map(|(t, f)| shape.walk(f.start, p.truth.tangents[1] * (0.001 * (t as f64).sin())))
            .collect();
        let normal = problem.normal_at(&at, DVec3::ZERO, true).unwrap();
        let h = 1e-6;
        for t in [0, 17, 59] {
            for i in 0..2 {
                let cost = |sign: f64| {
                    let mut moved = at.clone();
                    moved[t] = shape.walk(at[t], normal.surface[t].tangents[i] * (sign * h));
                    problem.normal_at(&moved, DVec3::ZERO, true).unwrap().cost
                };
                let slope = (cost(1.0) - cost(-1.0)) / (2.0 * h);
                let rhs = normal.rhs_places[t][i];
                assert!(
                    (rhs + 0.5 * slope).abs() < 1e-4 * slope.abs().max(1.0),
                    "frame {t}, tangent {i}: {rhs} vs {slope}"
                );
            }
        }
        for (axis, rhs) in [DVec3::X, DVec3::Y, DVec3::Z]
            .into_iter()
            .zip(normal.rhs_ratio.to_array())
        {
            let cost = |sign: f64| problem.normal_at(&at, axis * (sign * h), true).unwrap().cost;
            let slope = (cost(1.0) - cost(-1.0)) / (2.0 * h);
            assert!(
                (rhs + 0.5 * slope).abs() < 1e-4 * slope.abs().max(1.0),
                "{axis}: {rhs} vs {slope}"
            );
        }
        // Where the model fits exactly (noise-free, at the truth) the
        // Gauss–Newton curvature is the cost's.
        let exact = press([0.15, -0.1], 0.0, 5);
        let exact_frames = press_frames(&exact);
        let problem = Problem {
            shape,
            link: exact.link,
            frames: &exact_frames,
            settings: &settings,
        };
        let at = vec![shape.walk(exact.start, exact.truth.tangents[0] * -0.006); exact_frames.len()];
        let ratio = exact.truth.tangents[0] * 0.15 - exact.truth.tangents[1] * 0.1;
        let normal = problem.normal_at(&at, ratio, true).unwrap();
        let h = 1e-4;
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            let cost = |sign: f64| problem.normal_at(&at, ratio + axis * (sign * h), true).unwrap().cost;
            let curvature = (cost(1.0) - 2.0 * normal.cost + cost(-1.0)) / (h * h);
            let diagonal = normal.corner.mul_vec3(axis).dot(axis);
            assert!(
                (diagonal - 0.5 * curvature).abs() < 1e-2 * diagonal,
                "{axis}: {diagonal} vs {curvature}"
            );
        }
    }

    /// The chain's block elimination against a dense elimination of the
    /// same matrix.
    #[test]
    fn the_chain_solves_as_a_dense_elimination() {
        let mut rng = Rng::new(11);
        let n = 6;
        let lower: Vec<DMat2> = (0..n)
            .map(|t| {
                if t == 0 {
                    DMat2::ZERO
                } else {
                    DMat2::from_cols_array(&std::array::from_fn(|_| rng.uniform_in(-1.0, 1.0)))
                }
            })
            .collect();
        let diagonal: Vec<DMat2> = (0..n)
            .map(|_| {
                let a = DMat2::from_cols_array(&std::array::from_fn(|_| rng.uniform_in(-1.0, 1.0)));
                a * a.transpose() + DMat2::IDENTITY * 5.0
            })
            .collect();
        let rhs: Vec<DVec2> = (0..n).map(|_| DVec2::new(rng.normal(), rng.normal())).collect();
        let x = Chain::factor(&diagonal, &lower).unwrap().solve(&rhs);
        let inverse = inverted(dense(&diagonal, &lower, None));
        for t in 0..n {
            for i in 0..2 {
                let dense: f64 = (0..n)
                    .map(|s| inverse[2 * t + i][2 * s] * rhs[s].x + inverse[2 * t + i][2 * s + 1] * rhs[s].y)
                    .sum();
                assert!((x[t][i] - dense).abs() < 1e-10, "{t} {i}: {} vs {dense}", x[t][i]);
            }
        }
    }

    /// The symmetric matrix of diagonal blocks `diagonal`, sub-diagonal
    /// blocks `lower` and, when given, the border `(B, C)` (γ's rows and
    /// columns last), as dense rows: row `2t + i` is frame t's tangent i.
    fn dense(diagonal: &[DMat2], lower: &[DMat2], border: Option<(&[[DVec2; 3]], DMat3)>) -> Vec<Vec<f64>> {
        let frames = diagonal.len();
        let size = 2 * frames + if border.is_some() { 3 } else { 0 };
        let mut m = vec![vec![0.0; size]; size];
        for t in 0..frames {
            for (i, j) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                m[2 * t + i][2 * t + j] = diagonal[t].col(j)[i];
                if t > 0 {
                    m[2 * t + i][2 * (t - 1) + j] = lower[t].col(j)[i];
                    m[2 * (t - 1) + j][2 * t + i] = lower[t].col(j)[i];
                }
            }
        }
        if let Some((columns, corner)) = border {
            for (t, b) in columns.iter().enumerate() {
                for (k, b) in b.iter().enumerate() {
                    for i in 0..2 {
                        m[2 * t + i][2 * frames + k] = b[i];
                        m[2 * frames + k][2 * t + i] = b[i];
                    }
                }
            }
            for k in 0..3 {
                for l in 0..3 {
                    m[2 * frames + k][2 * frames + l] = corner.col(l)[k];
                }
            }
        }
        m
    }

    /// The inverse of `m` by Gauss–Jordan elimination with partial pivoting.
    fn inverted(mut m: Vec<Vec<f64>>) -> Vec<Vec<f64>> {
        let size = m.len();
        let mut inverse: Vec<Vec<f64>> = (0..size)
            .map(|i| (0..size).map(|j| if i == j { 1.0 } else { 0.0 }).collect())
            .collect();
        for c in 0..size {
            let pivot = (c..size)
                .max_by(|&x, &y| m[x][c].abs().total_cmp(&m[y][c].abs()))
                .unwrap();
            m.swap(c, pivot);
            inverse.swap(c, pivot);
            let p = m[c][c];
            assert!(p.abs() > 1e-12, "singular");
            for j in 0..size {
                m[c][j] /= p;
                inverse[c][j] /= p;
            }
            for r in 0..size {
                if r != c {
                    let factor = m[r][c];
                    for j in 0..size {
                        m[r][j] -= factor * m[c][j];
                        inverse[r][j] -= factor * inverse[c][j];
                    }
                }
            }
        }
        inverse
    }

    /// Nothing to fit, or nothing to fit with: no fit and no panic. Torques
    /// of zero, frames at one instant, μ of 0 or not finite, no frames.
    #[test]
    fn hard_presses_give_no_fit_or_a_finite_one() {
        let p = press([0.15, -0.1], 0.05, 1);
        let shape = p.surface.shape(p.link).unwrap();
        let zeros = vec![0.0; 7];
        let mut frames = press_frames(&p);
        assert_eq!(fit_press(shape, p.link, &[], &settings(0.1)), None);
        assert_eq!(fit_press(shape, p.link, &frames, &settings(0.0)), None);
        assert_eq!(fit_press(shape, p.link, &frames, &settings(f64::NAN)), None);
        for f in &mut frames {
            f.t_secs = 1.0;
        }
        if let Some(fit) = fit_press(shape, p.link, &frames, &settings(0.1)) {
            assert!(
                fit.contacts
                    .iter()
                    .all(|c| c.point_in_link.is_finite() && c.force_newtons.is_finite())
            );
        }
        for f in &mut frames {
            f.tau = &zeros;
        }
        assert_eq!(fit_press(shape, p.link, &frames, &settings(0.1)), None);
    }

    /// The place covariances are the diagonal blocks of the inverse of
    /// the whole bordered system (checked against a dense inverse by
    /// Gauss–Jordan elimination), with γ marginalised and without.
    #[test]
    fn place_covariances_are_the_inverse_s_diagonal_blocks() {
        let mut rng = Rng::new(3);
        let frames = 7;
        let mut sym = |scale: f64| {
            let (a, b, c) = (
                rng.uniform_in(-1.0, 1.0),
                rng.uniform_in(-1.0, 1.0),
                rng.uniform_in(-1.0, 1.0),
            );
            DMat2::from_cols(DVec2::new(a, b), DVec2::new(b, c)) * scale
        };
        let diagonal: Vec<DMat2> = (0..frames).map(|_| sym(1.0) + DMat2::IDENTITY * 6.0).collect();
        let lower: Vec<DMat2> = (0..frames)
            .map(|t| if t == 0 { DMat2::ZERO } else { sym(1.5) })
            .collect();
        let border: Vec<[DVec2; 3]> = (0..frames)
            .map(|_| std::array::from_fn(|_| DVec2::new(rng.uniform_in(-0.5, 0.5), rng.uniform_in(-0.5, 0.5))))
            .collect();
        let corner = DMat3::IDENTITY * 9.0 + DMat3::from_cols(DVec3::X, DVec3::Y, DVec3::ONE) * 0.1;
        let corner = (corner + corner.transpose()) * 0.5;
        let normal = Normal {
            cost: 0.0,
            surface: Vec::new(),
            magnitudes: Vec::new(),
            residuals: Vec::new(),
            diagonal: diagonal.clone(),
            lower: lower.clone(),
            border: border.clone(),
            corner,
            rhs_places: vec![DVec2::ZERO; frames],
            rhs_ratio: DVec3::ZERO,
        };
        for ratio_free in [false, true] {
            let inverse = inverted(dense(
                &diagonal,
                &lower,
                ratio_free.then_some((border.as_slice(), corner)),
            ));
            let covariances = covariances(&normal, ratio_free).unwrap();
            for (t, c) in covariances.iter().enumerate() {
                for (i, j) in [(0, 0), (0, 1), (1, 0), (1, 1)] {
                    let expected = inverse[2 * t + i][2 * t + j];
                    assert!(
                        (c.col(j)[i] - expected).abs() < 1e-12,
                        "frame {t} ({i},{j}): {} vs {expected}",
                        c.col(j)[i]
                    );
                }
            }
        }
    }
}
