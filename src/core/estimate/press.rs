//! A press's friction, fitted over the whole press.
//!
//! A frame alone cannot tell a tangential force from a shifted place when
//! fewer than five joints sense the link, and integrating a fresh
//! tangential force out of every frame (the per-frame friction model of
//! [`crate::core::estimate::friction`]) lets each frame explain its misfit its own
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

use crate::core::estimate::place_spread::PlaceSpread;
use crate::core::estimate::settings::force_range_is_valid;
use crate::core::geometry::shell::{MeshPoint, SurfaceFrame};
use crate::core::robot::model::LinkId;
use crate::core::robot::torque::{TorqueModel, weighted_dot as inner};
use crate::core::surface::sampling::LinkShape;

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

/// The spread of `μ_k`'s prior (half-normal: `μ_k` ≥ 0). Dry contacts
/// between a hand, a tool or a probe and a robot's shell lie within
/// 0.1–1; a spread of 0.6 leaves `μ_k` = 0.5 at a prior cost of 0.7, so
/// that the torques, not the prior, set it.
pub const KINETIC_SPREAD: f64 = 0.6;

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

/// The slide term's length scale between two frames held still, as a
/// fraction of the press fit's (see [`Slides::held_still`]). A contact
/// that sticks does not move over the surface, and at the full scale
/// its place wanders by 0.1–1 mm every 50 ms through a rest, which the
/// slide's path takes in: the generated link 6 and 7 slides' median
/// paths are 1.06–1.23 times their true length at surface seed 0 at the
/// full scale, and 1.00–1.09 at this one but for link 7 seed 1, whose
/// press crosses the flange's rim (`docs/decisions.md`, *Rests held
/// still, and still*). Its prior's normalizer (`4 ln` of the fraction
/// for a step's two tangent coordinates) is in the cost, so fits that
/// hold different frames still are compared alike; against answers
/// that hold nothing still it is left out (`Normal::cost_as_moving`).
pub const STILL_SLIDE_FRACTION: f64 = 0.3;

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
pub(super) fn along_surface(v: DVec3, n: DVec3) -> DVec3 {
    v - v.dot(n) * n
}

/// Each frame's slide, from a track of places.
#[derive(Debug, Clone, PartialEq)]
pub struct Slides {
    /// The unit direction of the frame's slide, link frame, along the
    /// surface; zero where the press sticks or the place hardly moves.
    pub directions: Vec<DVec3>,
    /// The place's velocity over the surface, link frame, m/s.
    pub velocities_m_per_s: Vec<DVec3>,
    /// Frames held still: they stick in a fit whose rests are held
    /// still ([`crate::core::estimate::kinetic`]). The slide term holds a
    /// place between two such frames within [`STILL_SLIDE_FRACTION`] of
    /// the slide's length scale.
    pub held_still: Vec<bool>,
}

impl Slides {
    /// Each frame's drag direction: its own slide direction where it has
    /// one, else that of the nearest frame that has (the earlier of two
    /// as near): the way a press that sticks holds its drag. Zero where
    /// no frame slides.
    #[must_use]
    pub fn drag_directions(&self) -> Vec<DVec3> {
        let mut out = self.directions.clone();
        let mut gap = vec![usize::MAX; out.len()];
        let mut last: Option<(usize, DVec3)> = None;
        for (t, &d) in self.directions.iter().enumerate() {
            if d.length() > 0.0 {
                last = Some((t, d));
            } else if let (Some((k, dk)), Some(o), Some(g)) = (last, out.get_mut(t), gap.get_mut(t)) {
                *o = dk;
                *g = t - k;
            }
        }
        let mut next: Option<(usize, DVec3)> = None;
        for (t, &d) in self.directions.iter().enumerate().rev() {
            if d.length() > 0.0 {
                next = Some((t, d));
            } else if let (Some((k, dk)), Some(o), Some(g)) = (next, out.get_mut(t), gap.get_mut(t))
                && k - t < *g
            {
                *o = dk;
                *g = k - t;
            }
        }
        out
    }

    /// Each frame's tangential force under kinetic friction: its
    /// direction and which share of the push it carries. A frame that
    /// slides drags along its slide (`μ_k`); one that sticks holds a
    /// drag along [`Slides::drag_directions`], with one share after the
    /// press's first slide and one before it. `all_stick`: every frame
    /// as if it stuck (where the states are chosen).
    #[must_use]
    pub fn drag_plan(&self, all_stick: bool) -> Vec<(DVec3, DragShare)> {
        let first_slide = self
            .directions
            .iter()
            .position(|d| d.length() > 0.0)
            .unwrap_or(self.directions.len());
        self.drag_directions()
            .into_iter()
            .zip(&self.directions)
            .enumerate()
            .map(|(t, (held, own))| {
                let share = if own.length() > 0.0 && !all_stick {
                    DragShare::Slip
                } else if t < first_slide {
                    DragShare::HeldBefore
                } else {
                    DragShare::HeldAfter
                };
                (held, share)
            })
            .collect()
    }
}

/// Which share of the push a frame's drag carries under kinetic
/// friction: one of the press's three unknowns in its ratio.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DragShare {
    /// `μ_k` while the press slides (`ratio.x`).
    Slip,
    /// The drag held while it sticks after its first slide (`ratio.y`).
    HeldAfter,
    /// The drag held while it sticks before its first slide (`ratio.z`).
    HeldBefore,
}

impl DragShare {
    /// Its share from the press's `ratio`.
    #[must_use]
    pub fn of(self, ratio: DVec3) -> f64 {
        match self {
            Self::Slip => ratio.x,
            Self::HeldAfter => ratio.y,
            Self::HeldBefore => ratio.z,
        }
    }

    /// Its axis in the ratio (0, 1, 2).
    const fn axis(self) -> usize {
        match self {
            Self::Slip => 0,
            Self::HeldAfter => 1,
            Self::HeldBefore => 2,
        }
    }
}

/// The tangential force a search fits.
#[derive(Debug, Clone, Copy)]
pub(super) enum Drag<'d> {
    /// None: the push is along the normal.
    None,
    /// γ, fixed in the link's frame, under its prior (spread μ).
    Fixed,
    /// `μ_k` (`ratio.x`) times the push along each frame's slide, and
    /// where it sticks the held drag along [`Slides::drag_directions`]:
    /// `ratio.y` times the push after the first slide, `ratio.z` before it
    /// (see [`crate::core::estimate::kinetic`]); the places expected to
    /// move with the slides' velocities.
    Kinetic(&'d Slides),
    /// Every frame sticking, with the held drag of [`Drag::Kinetic`]: a
    /// sticking frame's residual where the states are chosen.
    Held(&'d Slides),
    /// No tangential force, the places expected to move with the slides'
    /// velocities: what kinetic friction is weighed against.
    Drift(&'d Slides),
    /// γ fixed in the link's frame while the press slips (a frame with a
    /// slide direction), none while it sticks; the places expected to
    /// move with the slides' velocities. Where the places are far off,
    /// their velocities are too: this finds the slide's direction from
    /// the torques alone, and kinetic friction starts from its places.
    Gated(&'d Slides),
}

impl Drag<'_> {
    /// The ratio's prior spread: μ for γ, [`KINETIC_SPREAD`] under the
    /// slides' states.
    fn spread(self, friction: f64) -> f64 {
        match self {
            Drag::Kinetic(_) | Drag::Gated(_) | Drag::Held(_) => KINETIC_SPREAD,
            Drag::None | Drag::Fixed | Drag::Drift(_) => friction,
        }
    }

    /// The move from frame `t - 1` to frame `t` (`dt_secs` apart) that
    /// the slide term expects: along the slides' mean velocity, or none.
    /// `None` where a frame has no slide.
    fn expected_move(self, t: usize, dt_secs: f64) -> Option<DVec3> {
        match self {
            Drag::Kinetic(slides) | Drag::Drift(slides) | Drag::Gated(slides) | Drag::Held(slides) => {
                let v = slides.velocities_m_per_s.get(t)?;
                let v_before = slides.velocities_m_per_s.get(t.checked_sub(1)?)?;
                Some((*v + *v_before) * (0.5 * dt_secs))
            }
            Drag::None | Drag::Fixed => Some(DVec3::ZERO),
        }
    }

    /// Whether frames `t - 1` and `t` are both held still
    /// ([`Slides::held_still`]).
    fn holds_still(self, t: usize) -> bool {
        match self {
            Drag::Kinetic(slides) | Drag::Drift(slides) | Drag::Gated(slides) | Drag::Held(slides) => {
                let held = |k: usize| slides.held_still.get(k).copied().unwrap_or(false);
                t.checked_sub(1).is_some_and(|before| held(before) && held(t))
            }
            Drag::None | Drag::Fixed => false,
        }
    }

    /// Whether the search moves a ratio (γ or `μ_k`).
    fn is_free(self) -> bool {
        matches!(self, Drag::Fixed | Drag::Kinetic(_) | Drag::Gated(_) | Drag::Held(_))
    }
}

/// The press and its settings.
pub(super) struct Problem<'a> {
    pub(super) shape: &'a LinkShape,
    link: LinkId,
    pub(super) frames: &'a [PressFrame<'a>],
    settings: &'a PressSettings<'a>,
}

impl<'a> Problem<'a> {
    /// How many sensed joints feel the press's link (0 without frames).
    pub(super) fn sensing_joints(&self) -> usize {
        self.frames
            .first()
            .map_or(0, |f| f.torque_model.twists(self.link).len())
    }

    /// The press `frames` on `link`; `None` without frames, without a
    /// positive finite slide length (the slide prior divides by it), with
    /// a force range that is empty, negative or NaN (a push is clamped to
    /// it), with a weight that is negative or not finite, or with a time
    /// that is not finite (the slide's velocity divides by the times'
    /// differences).
    pub(super) fn new(
        shape: &'a LinkShape,
        link: LinkId,
        frames: &'a [PressFrame<'a>],
        settings: &'a PressSettings<'a>,
    ) -> Option<Self> {
        let slide = settings.slide_m_per_sqrt_s;
        let (f_min, f_max) = settings.force_range_newtons;
        let valid = !frames.is_empty()
            && slide > 0.0
            && slide.is_finite()
            && force_range_is_valid(f_min, f_max)
            && settings.weights.iter().all(|w| *w >= 0.0 && w.is_finite())
            && frames.iter().all(|f| f.t_secs.is_finite());
        valid.then_some(Self {
            shape,
            link,
            frames,
            settings,
        })
    }
}

/// The cost at a trajectory and its Gauss–Newton normal equations.
pub(super) struct Normal {
    /// `-2 ln` posterior (up to a constant).
    pub(super) cost: f64,
    /// The part of `cost` that is the normalizer of the places held
    /// still ([`STILL_SLIDE_FRACTION`]; 0 or less).
    pub(super) held_still_normalizer: f64,
    /// Each frame's surface.
    pub(super) surface: Vec<SurfaceFrame>,
    /// Each frame's profiled push, N.
    pub(super) magnitudes: Vec<f64>,
    /// Each frame's `‖τ - f (u + C γ)‖²_W`.
    pub(super) residuals: Vec<f64>,
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
    /// The normal equations of the frames at `surface` before any frame
    /// is added: the ratio's prior alone, where it is free (`spread`).
    fn prior(surface: Vec<SurfaceFrame>, ratio: DVec3, spread: Option<f64>) -> Self {
        let n = surface.len();
        let mut normal = Normal {
            cost: 0.0,
            held_still_normalizer: 0.0,
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
        if let Some(spread) = spread {
            normal.cost += ratio.length_squared() / (spread * spread);
            normal.corner = DMat3::IDENTITY / (spread * spread);
            normal.rhs_ratio = -ratio / (spread * spread);
        }
        normal
    }

    /// `cost` without the normalizer of the places held still: what
    /// kinetic friction is weighed by against answers that hold no place
    /// still. Its normalizer compares only answers that may hold places
    /// still (the fit held still against the one that moves on); against
    /// others it would count each frame held still 4.8 lower, however
    /// well it fits, and keep kinetic friction on a generated press that
    /// slides throughout without friction (`docs/decisions.md`, *Rests
    /// held still, and still*).
    pub(super) fn cost_as_moving(&self) -> f64 {
        self.cost - self.held_still_normalizer
    }

    /// Adds the slide from frame `t - 1` to frame `t` (`dt_secs` apart)
    /// under `drag`'s expected move, at the length scale `slide` (m/√s),
    /// or [`STILL_SLIDE_FRACTION`] of it between two frames held still,
    /// whose prior's normalizer then goes into the cost.
    fn add_slide_under(&mut self, drag: Drag, t: usize, slide: f64, dt_secs: f64) -> Option<()> {
        let scale = if drag.holds_still(t) {
            let normalizer = 4.0 * STILL_SLIDE_FRACTION.ln();
            self.cost += normalizer;
            self.held_still_normalizer += normalizer;
            STILL_SLIDE_FRACTION
        } else {
            1.0
        };
        let spread = scale * slide;
        self.add_slide(t, 1.0 / (spread * spread * dt_secs), drag.expected_move(t, dt_secs)?)
    }

    /// Adds the slide from frame `t - 1` to frame `t`, `weight |p_t -
    /// p_{t-1} - e|²` (`weight`: 1/(ℓ² Δt); `e`: the move expected of a
    /// slide, zero for a place at rest), to the cost and the normal
    /// equations.
    fn add_slide(&mut self, t: usize, weight: f64, expected: DVec3) -> Option<()> {
        let (here, before) = (self.surface.get(t)?, self.surface.get(t.checked_sub(1)?)?);
        let gap = here.point - before.point - expected;
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
pub(super) struct Found {
    pub(super) locations: Vec<MeshPoint>,
    pub(super) ratio: DVec3,
    pub(super) normal: Normal,
}

impl Problem<'_> {
    /// Gauss–Newton from `start` (γ = 0), moving γ only when
    /// `ratio_free`.
    pub(super) fn descend(&self, start: Vec<MeshPoint>, ratio_free: bool) -> Option<Found> {
        self.descend_with(start, if ratio_free { Drag::Fixed } else { Drag::None })
    }

    /// Gauss–Newton from `start` (γ, or `μ_k`, = 0) under the tangential
    /// model `drag`; `μ_k` stays at or above 0 (friction drags the arm
    /// along the slide, never against it).
    pub(super) fn descend_with(&self, start: Vec<MeshPoint>, drag: Drag) -> Option<Found> {
        self.descend_from(start, DVec3::ZERO, drag)
    }

    /// [`Problem::descend_with`] from γ (or `μ_k`) = `ratio`.
    pub(super) fn descend_from(&self, start: Vec<MeshPoint>, ratio: DVec3, drag: Drag) -> Option<Found> {
        let ratio_free = drag.is_free();
        let mut locations = start;
        let mut ratio = ratio;
        let mut normal = self.normal_with(&locations, ratio, drag)?;
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
                let mut next_ratio = ratio + ratio_step * scale;
                if let Drag::Kinetic(_) | Drag::Held(_) = drag {
                    next_ratio.x = next_ratio.x.max(0.0);
                }
                if let Some(next) = self.normal_with(&moved, next_ratio, drag)
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
    pub(super) fn spreads(&self, locations: &[MeshPoint], ratio: DVec3, ratio_free: bool) -> Option<Vec<DMat2>> {
        let drag = if ratio_free { Drag::Fixed } else { Drag::None };
        self.spreads_with(locations, ratio, drag)
    }

    /// [`Problem::spreads`] under the tangential model `drag`.
    pub(super) fn spreads_with(&self, locations: &[MeshPoint], ratio: DVec3, drag: Drag) -> Option<Vec<DMat2>> {
        covariances(&self.normal_with(locations, ratio, drag)?, drag.is_free())
    }

    /// The cost at `locations` with γ = `ratio`, and its normal equations
    /// (γ's rows only when `ratio_free`). `None` where the surface cannot
    /// be evaluated or a number is not finite.
    #[cfg(test)]
    fn normal_at(&self, locations: &[MeshPoint], ratio: DVec3, ratio_free: bool) -> Option<Normal> {
        self.normal_with(locations, ratio, if ratio_free { Drag::Fixed } else { Drag::None })
    }

    /// The cost at `locations` with the ratio `ratio` under the
    /// tangential model `drag`, and its normal equations (the ratio's rows
    /// only where `drag` moves it). With [`Drag::Kinetic`], `ratio.x` is
    /// `μ_k` (its other axes unused, held at 0 by their prior). `None`
    /// where the surface cannot be evaluated or a number is not finite.
    pub(super) fn normal_with(&self, locations: &[MeshPoint], ratio: DVec3, drag: Drag) -> Option<Normal> {
        let ratio_free = drag.is_free();
        let settings = self.settings;
        let w = settings.weights;
        let joints = w.len();
        let (f_min, f_max) = settings.force_range_newtons;
        let spread = drag.spread(settings.friction);
        let slide = settings.slide_m_per_sqrt_s;
        let surface: Vec<SurfaceFrame> = locations
            .iter()
            .map(|&at| self.shape.frame(at))
            .collect::<Option<_>>()?;
        let mut normal = Normal::prior(surface, ratio, ratio_free.then_some(spread));
        // u, ∂u/∂s₁, ∂u/∂s₂, then the three axes' tangential columns.
        let mut columns = vec![vec![0.0; joints]; 6];
        // With kinetic friction: the push along the frame's slide (or,
        // where it sticks, along the drag it holds) on one axis, and the
        // axes that carry nothing.
        let mut along_slide = vec![0.0; joints];
        let plan = match drag {
            Drag::Kinetic(slides) => Some(slides.drag_plan(false)),
            Drag::Held(slides) => Some(slides.drag_plan(true)),
            _ => None,
        };
        let unused = vec![0.0; joints];
        let mut pushed = vec![0.0; joints];
        let mut residual = vec![0.0; joints];
        for (t, frame) in self.frames.iter().enumerate() {
            let here = *normal.surface.get(t)?;
            let tau = frame.tau.get(..joints)?;
            columns_at(frame.torque_model, self.link, &here, &mut columns)?;
            let [u, d0, d1, c0, c1, c2] = columns.as_slice() else {
                return None;
            };
            let axes: [&[f64]; 3] = if let Some(plan) = &plan {
                let &(d, share) = plan.get(t)?;
                for (j, a) in along_slide.iter_mut().enumerate() {
                    *a = d.x * c0.get(j)? + d.y * c1.get(j)? + d.z * c2.get(j)?;
                }
                let mut axes = [unused.as_slice(); 3];
                *axes.get_mut(share.axis())? = &along_slide;
                axes
            } else {
                match drag {
                    Drag::Gated(slides) if slides.directions.get(t)?.length() == 0.0 => [&unused, &unused, &unused],
                    _ => [c0, c1, c2],
                }
            };
            let [c0, c1, c2] = axes;
            for (j, p) in pushed.iter_mut().enumerate() {
                *p = u.get(j)? + ratio.x * c0.get(j)? + ratio.y * c1.get(j)? + ratio.z * c2.get(j)?;
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
            let metric = Metric {
                w,
                pushed: &pushed,
                lever,
                profiled,
            };
            let (p0, p1) = (metric.column(d0), metric.column(d1));
            let f2 = f * f;
            let block = normal.diagonal.get_mut(t)?;
            *block += DMat2::from_cols(
                DVec2::new(metric.between(p0, p0), metric.between(p1, p0)),
                DVec2::new(metric.between(p0, p1), metric.between(p1, p1)),
            ) * f2;
            *normal.rhs_places.get_mut(t)? += DVec2::new(inner(w, d0, &residual), inner(w, d1, &residual)) * f;
            if ratio_free {
                let axes = axes.map(|axis| metric.column(axis));
                let border = normal.border.get_mut(t)?;
                for (k, &axis) in axes.iter().enumerate() {
                    border[k] += DVec2::new(metric.between(p0, axis), metric.between(p1, axis)) * f2;
                }
                normal.corner += DMat3::from_cols_array_2d(&std::array::from_fn(|k| {
                    std::array::from_fn(|l| metric.between(axes[k], axes[l]) * f2)
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
                normal.add_slide_under(drag, t, slide, dt_secs)?;
            }
        }
        normal.cost.is_finite().then_some(normal)
    }
}

/// The weighted inner product of a frame's columns, with the push's
/// direction projected out where its magnitude is profiled (inside the
/// force range, the best magnitude moves with the place).
struct Metric<'a> {
    w: &'a [f64],
    pushed: &'a [f64],
    lever: f64,
    profiled: bool,
}

/// A column with its products with the push, both ways round.
#[derive(Clone, Copy)]
struct Column<'c> {
    values: &'c [f64],
    toward_push: f64,
    from_push: f64,
}

impl Metric<'_> {
    /// `values` with its products with the push: computed once a frame
    /// and reused by every [`Metric::between`], in the same order of
    /// operations as each product alone (so the same bits).
    fn column<'c>(&self, values: &'c [f64]) -> Column<'c> {
        let (toward_push, from_push) = if self.profiled {
            (inner(self.w, values, self.pushed), inner(self.w, self.pushed, values))
        } else {
            (0.0, 0.0)
        };
        Column {
            values,
            toward_push,
            from_push,
        }
    }

    /// ⟨x, y⟩ under the weights, less the part along the push where it
    /// is profiled.
    fn between(&self, x: Column<'_>, y: Column<'_>) -> f64 {
        let plain = inner(self.w, x.values, y.values);
        if self.profiled {
            plain - x.toward_push * y.from_push / self.lever
        } else {
            plain
        }
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
#[path = "press_tests.rs"]
mod tests;
