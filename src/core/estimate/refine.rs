//! The most probable contact below the sampling's resolution: from the
//! likeliest samples, Gauss–Newton steps move the contact over the link's
//! continuous surface (across triangle edges, on the posed link) and fit
//! its magnitude, until the step is below a micrometre. The answer is the
//! best point of the surface, not of the samples. With friction
//! ([`Measurement::friction`]) "best" is the friction model's: the steps
//! read the torques through that model's noise (`Metric`) and a step is
//! kept when it raises its marginal likelihood.

use glam::DVec3;

use crate::core::estimate::friction;
use crate::core::estimate::measurement::Measurement;
use crate::core::estimate::posterior::Posterior;
use crate::core::estimate::regions::{Region, regions};
use crate::core::geometry::shell::{MeshPoint, SurfaceFrame};
use crate::core::numerics::special::ln_erf_difference;
use crate::core::robot::model::LinkId;
use crate::core::robot::torque::{TorqueModel, weighted_dot as inner};
use crate::core::surface::sampling::{LinkShape, Surface};

/// Gauss–Newton steps per start.
const MAX_STEPS: usize = 30;

/// A step shorter than this ends the search, m.
const CONVERGED_M: f64 = 1e-7;

/// A step that lowers the residual by less than this ends the search
/// (χ², half a hundredth of a nat: no test or display tells the
/// difference; where the linear model is poor, steps zig-zag with gains
/// like this for many steps).
const CONVERGED_CHI2: f64 = 1e-2;

/// The refined contact.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RefinedContact {
    /// The link.
    pub link: LinkId,
    /// Where on the link's surface.
    pub location: MeshPoint,
    /// Contact point, link frame, m.
    pub point_in_link: DVec3,
    /// Inward unit normal, link frame.
    pub inward_normal_in_link: DVec3,
    /// Push magnitude along the inward normal, N.
    pub force_newtons: f64,
    /// Tangential force, link frame, N: zero for a frictionless contact
    /// (see [`crate::core::estimate::friction`]).
    pub tangential_in_link: DVec3,
    /// `Σ (τ - f u)² / σ²` at this point and magnitude (with friction,
    /// the marginal model's residual).
    pub residual_chi2: f64,
    /// ln of the posterior mass of a patch centred here (the likelihood
    /// integrated over a window as wide as the start's patch and over the
    /// magnitude): how starts that end in different places are compared.
    pub patch_log_mass: f64,
    /// The sample it started from.
    pub start: usize,
    /// Gauss–Newton steps taken.
    pub steps: usize,
}

/// Inner products of torque vectors under the noise the search assumes:
/// `xᵀWy`, or with friction (tangential torques `J` at the place, spread
/// `s = μ f`) under the marginal model's precision
/// `W - WJ(JᵀWJ + I/s²)⁻¹JᵀW`.
struct Metric<'a> {
    weights: &'a [f64],
    /// `J`'s two columns and `(JᵀWJ + I/s²)⁻¹` as (11, 12, 22).
    tangential: Option<([&'a [f64]; 2], [f64; 3])>,
}

impl<'a> Metric<'a> {
    /// The metric of noise precisions `weights` with tangential torques
    /// `tangential` (none: frictionless) whose force has the spread
    /// `spread`, N (below [`friction::TangentialPrecision::new`]'s floor:
    /// frictionless).
    fn new(weights: &'a [f64], tangential: Option<[&'a [f64]; 2]>, spread: f64) -> Self {
        let tangential = tangential.and_then(|[j1, j2]| {
            let jj = [inner(weights, j1, j1), inner(weights, j1, j2), inner(weights, j2, j2)];
            let q = friction::TangentialPrecision::new(jj, spread)?;
            Some(([j1, j2], q.inverse()))
        });
        Self { weights, tangential }
    }

    fn ip(&self, x: &[f64], y: &[f64]) -> f64 {
        let w = self.weights;
        let plain = inner(w, x, y);
        let Some(([j1, j2], q)) = self.tangential else {
            return plain;
        };
        let (x1, x2) = (inner(w, j1, x), inner(w, j2, x));
        let (y1, y2) = (inner(w, j1, y), inner(w, j2, y));
        plain - (x1 * (q[0] * y1 + q[1] * y2) + x2 * (q[1] * y1 + q[2] * y2))
    }
}

/// The best magnitude in range for unit torques `u` and its residual.
fn profile(m: &Measurement, u: &[f64]) -> (f64, f64) {
    let (a, b) = (inner(m.weights, u, u), inner(m.weights, u, m.tau));
    let c = inner(m.weights, m.tau, m.tau);
    let (lo, hi) = m.force_range_newtons;
    let f = if a > 0.0 { (b / a).clamp(lo, hi) } else { lo };
    (f, (c - 2.0 * b * f + a * f * f).max(0.0))
}

/// One Gauss–Newton step at `frame`: the offset along the tangents, m,
/// from the linearised model `f u + g₁ d₁ + g₂ d₂` (`g = f s`), with f in
/// range, residuals measured by `metric`. `None` when the tangents do not
/// change the torques.
fn step(metric: &Metric, m: &Measurement, u: &[f64], d1: &[f64], d2: &[f64]) -> Option<[f64; 2]> {
    let ip = |x: &[f64], y: &[f64]| metric.ip(x, y);
    let (a, h1, h2) = (ip(u, u), ip(u, d1), ip(u, d2));
    let (g11, g12, g22) = (ip(d1, d1), ip(d1, d2), ip(d2, d2));
    let (b, e1, e2) = (ip(u, m.tau), ip(d1, m.tau), ip(d2, m.tau));
    // A tiny ridge keeps directions the torques cannot see from moving.
    let ridge = 1e-12 * (g11 + g22).max(f64::MIN_POSITIVE);
    let (g11, g22) = (g11 + ridge, g22 + ridge);
    let det_g = g11 * g22 - g12 * g12;
    if det_g <= 0.0 || !det_g.is_finite() {
        return None;
    }
    // g for a given f: G g = e - f h.
    let solve_g = |f: f64| {
        let (r1, r2) = (e1 - f * h1, e2 - f * h2);
        [(g22 * r1 - g12 * r2) / det_g, (g11 * r2 - g12 * r1) / det_g]
    };
    // f from the Schur complement: (a - hᵀG⁻¹h) f = b - hᵀG⁻¹e.
    let gh = solve_g(0.0); // = G⁻¹e
    let (gh1, gh2) = ((g22 * h1 - g12 * h2) / det_g, (g11 * h2 - g12 * h1) / det_g);
    let a_s = a - (h1 * gh1 + h2 * gh2);
    let b_s = b - (h1 * gh[0] + h2 * gh[1]);
    let (lo, hi) = m.force_range_newtons;
    let f = if a_s > 0.0 { (b_s / a_s).clamp(lo, hi) } else { lo };
    if f <= 0.0 {
        return None;
    }
    let g = solve_g(f);
    let s = [g[0] / f, g[1] / f];
    s.iter().all(|x| x.is_finite()).then_some(s)
}

/// A frame's unit torques: of its line and of its two derivatives.
fn frame_torques(model: &TorqueModel, link: LinkId, frame: &SurfaceFrame, joints: usize) -> [Vec<f64>; 3] {
    let mut out = [vec![0.0; joints], vec![0.0; joints], vec![0.0; joints]];
    model.line_array_torques_into(link, &frame.line(), &mut out[0]);
    model.line_array_torques_into(link, &frame.line_derivatives[0], &mut out[1]);
    model.line_array_torques_into(link, &frame.line_derivatives[1], &mut out[2]);
    out
}

/// Where a search stands: the place and everything the next step needs.
#[derive(Clone)]
struct State {
    at: MeshPoint,
    frame: SurfaceFrame,
    torques: [Vec<f64>; 3],
    /// With friction: the torques of unit forces along the frame's tangents.
    tangential_torques: Option<[Vec<f64>; 2]>,
    f: f64,
    /// The tangential force along the frame's tangents, N (0 without friction).
    g: [f64; 2],
    /// The residual (with friction, the marginal model's).
    chi2: f64,
    /// What the search minimises: the residual, or with friction the
    /// marginal model's `-2 ln L`.
    objective: f64,
}

impl State {
    fn at(model: &TorqueModel, shape: &LinkShape, link: LinkId, m: &Measurement, at: MeshPoint) -> Option<Self> {
        let frame = shape.frame(at)?;
        let joints = model.sensed_count();
        let torques = frame_torques(model, link, &frame, joints);
        let frictionless = |frame: SurfaceFrame, torques: [Vec<f64>; 3]| {
            let (f, chi2) = profile(m, &torques[0]);
            Self {
                at,
                frame,
                torques,
                tangential_torques: None,
                f,
                g: [0.0; 2],
                chi2,
                objective: chi2,
            }
        };
        if m.friction.is_nan() || m.friction <= 0.0 {
            return Some(frictionless(frame, torques));
        }
        let tangential = frame.tangents.map(|t| {
            let moment = frame.point.cross(t);
            let mut out = vec![0.0; joints];
            model.line_array_torques_into(link, &[moment.x, moment.y, moment.z, t.x, t.y, t.z], &mut out);
            out
        });
        // A place whose push moves no sensed joint has no friction fit:
        // the frictionless state (as without friction).
        let Some(fit) = friction::fit(&torques[0], [&tangential[0], &tangential[1]], m, m.friction) else {
            return Some(frictionless(frame, torques));
        };
        Some(Self {
            at,
            frame,
            torques,
            tangential_torques: Some(tangential),
            f: fit.normal_newtons,
            g: fit.tangential,
            chi2: fit.residual_chi2,
            objective: fit.cost,
        })
    }

    /// The inner products the next step uses: the marginal model's at this
    /// magnitude with friction.
    fn metric<'a>(&'a self, m: &'a Measurement) -> Metric<'a> {
        let tangential = self
            .tangential_torques
            .as_ref()
            .map(|[j1, j2]| [j1.as_slice(), j2.as_slice()]);
        Metric::new(m.weights, tangential, m.friction * self.f.abs())
    }
}

impl State {
    /// The contact found here, its patch mass taken over a window of
    /// `window_m`, from sample `start` in `steps` steps.
    fn contact(
        &self,
        link: LinkId,
        measurement: &Measurement,
        window_m: f64,
        start: usize,
        steps: usize,
    ) -> RefinedContact {
        let [u, d1, d2] = &self.torques;
        let metric = self.metric(measurement);
        RefinedContact {
            link,
            location: self.at,
            point_in_link: self.frame.point,
            inward_normal_in_link: self.frame.inward_normal,
            force_newtons: self.f,
            tangential_in_link: self.frame.tangents[0] * self.g[0] + self.frame.tangents[1] * self.g[1],
            residual_chi2: self.chi2,
            patch_log_mass: centred_patch_log_mass(
                &metric,
                measurement,
                [u, d1, d2],
                (self.objective, self.f),
                window_m,
            ),
            start,
            steps,
        }
    }
}

/// The search on one link's surface.
struct Search<'a> {
    model: &'a TorqueModel,
    shape: &'a LinkShape,
    link: LinkId,
    measurement: &'a Measurement<'a>,
    /// Longest step, m: the linear model holds within a patch width.
    trust: f64,
}

impl<'a> Search<'a> {
    /// A search on `link`'s continuous surface whose steps are as long as
    /// sample `start`'s patch is wide; `None` where the link has none.
    fn on(
        model: &'a TorqueModel,
        surface: &'a Surface,
        measurement: &'a Measurement<'a>,
        link: LinkId,
        start: usize,
    ) -> Option<Self> {
        Some(Self {
            model,
            shape: surface.shape(link)?,
            link,
            measurement,
            trust: surface.window_m.get(start).copied().unwrap_or(0.01).max(1e-4),
        })
    }

    fn state(&self, at: MeshPoint) -> Option<State> {
        State::at(self.model, self.shape, self.link, self.measurement, at)
    }

    /// Gauss–Newton steps until the step is below [`CONVERGED_M`] or no
    /// shortened step lowers the residual; returns the steps taken.
    fn descend(&self, state: &mut State) -> usize {
        let mut steps = 0;
        for _ in 0..MAX_STEPS {
            let [u, d1, d2] = &state.torques;
            let Some(s) = step(&state.metric(self.measurement), self.measurement, u, d1, d2) else {
                break;
            };
            let mut offset = state.frame.tangents[0] * s[0] + state.frame.tangents[1] * s[1];
            if offset.length() > self.trust {
                offset *= self.trust / offset.length();
            }
            let mut gain = 0.0;
            for _ in 0..8 {
                let Some(next) = self.state(self.shape.walk(state.at, offset)) else {
                    break;
                };
                if next.objective < state.objective {
                    gain = state.objective - next.objective;
                    *state = next;
                    break;
                }
                offset *= 0.5;
            }
            steps += 1;
            // Where the linear model is poor (a curved or creased surface)
            // the steps zig-zag with tiny gains: stop once one gains less.
            if gain <= CONVERGED_CHI2 || offset.length() < CONVERGED_M {
                break;
            }
        }
        steps
    }

    /// Where the torques cannot tell places apart (a valley of equally
    /// good contacts), moves along the valley towards `centre` (link
    /// frame), keeping the residual within [`VALLEY_CHI2`] of where it
    /// started: the answer is then the valley's point nearest the
    /// region's centre of mass, not wherever the search first met it.
    fn slide(&self, state: &mut State, centre: DVec3) -> usize {
        let best = state.objective;
        let mut steps = 0;
        for _ in 0..MAX_SLIDES {
            let metric = state.metric(self.measurement);
            let ip = |x: &[f64], y: &[f64]| metric.ip(x, y);
            let [u, d1, d2] = &state.torques;
            let a = ip(u, u).max(f64::MIN_POSITIVE);
            let (h1, h2) = (ip(u, d1), ip(u, d2));
            let f2 = state.f * state.f;
            // Curvature of χ²/2 in the tangent plane, the magnitude refitted.
            let s11 = f2 * (ip(d1, d1) - h1 * h1 / a);
            let s12 = f2 * (ip(d1, d2) - h1 * h2 / a);
            let s22 = f2 * (ip(d2, d2) - h2 * h2 / a);
            let to = centre - state.frame.point;
            let want = [state.frame.tangents[0].dot(to), state.frame.tangents[1].dot(to)];
            // Eigen-directions of the 2×2 curvature; along each, a move
            // that costs at most a quarter of a nat.
            let (mean, diff) = (0.5 * (s11 + s22), (0.25 * (s11 - s22).powi(2) + s12 * s12).sqrt());
            let angle = 0.5 * (2.0 * s12).atan2(s11 - s22);
            let dirs = [[angle.cos(), angle.sin()], [-angle.sin(), angle.cos()]];
            let lambdas = [mean + diff, mean - diff];
            let mut move2 = [0.0; 2];
            for (dir, lambda) in dirs.iter().zip(lambdas) {
                let along = dir[0] * want[0] + dir[1] * want[1];
                let limit = if lambda > 0.0 {
                    (0.5 / lambda).sqrt()
                } else {
                    f64::INFINITY
                };
                let x = along.clamp(-limit, limit);
                move2[0] += x * dir[0];
                move2[1] += x * dir[1];
            }
            let mut offset = state.frame.tangents[0] * move2[0] + state.frame.tangents[1] * move2[1];
            if offset.length() > self.trust {
                offset *= self.trust / offset.length();
            }
            if offset.length() < 1e-5 {
                break;
            }
            let Some(mut next) = self.state(self.shape.walk(state.at, offset)) else {
                break;
            };
            self.descend(&mut next);
            steps += 1;
            // Stop where the valley rises, turns away from the centre, or
            // the search returns where it was.
            if next.objective > best + VALLEY_CHI2
                || next.frame.point.distance(centre) >= state.frame.point.distance(centre)
                || next.frame.point.distance(state.frame.point) < CONVERGED_M
            {
                break;
            }
            *state = next;
        }
        steps
    }
}

/// Along a valley the residual may rise by this much (a quarter of a nat
/// of likelihood: no test tells such contacts apart).
const VALLEY_CHI2: f64 = 0.5;

/// Moves along a valley per refinement.
const MAX_SLIDES: usize = 12;

/// Refines from sample `start` and slides towards `centre` (link frame),
/// with the objective reached there; `None` if its link has no continuous
/// surface.
fn refine_from(
    model: &TorqueModel,
    surface: &Surface,
    measurement: &Measurement,
    start: usize,
    centre: DVec3,
) -> Option<(RefinedContact, f64)> {
    let link = *surface.link.get(start)?;
    let search = Search::on(model, surface, measurement, link, start)?;
    let mut state = search.state(*surface.location.get(start)?)?;
    let mut steps = search.descend(&mut state);
    steps += search.slide(&mut state, centre);
    Some((
        state.contact(link, measurement, search.trust, start, steps),
        state.objective,
    ))
}

/// The best contact on `link`'s continuous surface found by descending
/// from `location` (no slide, no region search), reported as if started
/// from sample `start`: how the two-contact search moves one contact
/// while the other holds. `None` if the link has no continuous surface.
pub(crate) fn refine_at(
    model: &TorqueModel,
    surface: &Surface,
    measurement: &Measurement,
    (link, location): (LinkId, MeshPoint),
    start: usize,
) -> Option<RefinedContact> {
    let search = Search::on(model, surface, measurement, link, start)?;
    let mut state = search.state(location)?;
    let steps = search.descend(&mut state);
    Some(state.contact(link, measurement, search.trust, start, steps))
}

/// ln of the posterior mass of a Gaussian patch of width `window_m`
/// centred on a contact with unit torques `u` (derivatives `d₁`, `d₂`
/// per metre along the tangents), objective (residual, or with friction
/// `-2 ln L` of the marginal model, whose inner products `metric` gives)
/// `chi2` and magnitude `f`: the
/// Gauss–Newton model of the likelihood around the contact, taken as
/// peaking there (the search has stopped there), integrated over the
/// window and the magnitude range. Up to the same constant as the
/// samples' masses (the area density is uniform).
fn centred_patch_log_mass(
    metric: &Metric,
    m: &Measurement,
    [u, d1, d2]: [&[f64]; 3],
    (chi2, f): (f64, f64),
    window_m: f64,
) -> f64 {
    let ip = |x: &[f64], y: &[f64]| metric.ip(x, y);
    let a = ip(u, u);
    let (h1, h2) = (ip(u, d1), ip(u, d2));
    let (g11, g12, g22) = (ip(d1, d1), ip(d1, d2), ip(d2, d2));
    // The window in g = f s has width f ρ; g integrated out (as in
    // `estimator::patch_terms`) leaves a' for f and a volume factor.
    let width = (f * window_m).max(1e-12);
    let q = 1.0 / (width * width);
    let (q11, q22) = (g11 + q, g22 + q);
    let det = (q11 * q22 - g12 * g12).max(q * q);
    let h_q_h = (h1 * (q22 * h1 - g12 * h2) + h2 * (q11 * h2 - g12 * h1)) / det;
    let a_f = (a - h_q_h).max(0.0);
    let ln_volume = -0.5 * (det / (q * q)).ln();
    let (lo, hi) = m.force_range_newtons;
    let range = hi - lo;
    let ln_f = if range <= 1e-12 * hi.max(1.0) || a_f * range * range < 1e-12 {
        0.0
    } else {
        let s = (0.5 * a_f).sqrt();
        0.5 * (std::f64::consts::PI / (2.0 * a_f)).ln() + ln_erf_difference(s * (lo - f), s * (hi - f)) - range.ln()
    };
    -0.5 * chi2 + ln_volume + ln_f
}

/// The region of the posterior with the most mass.
fn best_region(surface: &Surface, posterior: &Posterior) -> Option<Region> {
    posterior_regions(surface, posterior).into_iter().next()
}

/// The regions of the posterior (its support, or its most probable sample
/// when it lists none), heaviest first.
fn posterior_regions(surface: &Surface, posterior: &Posterior) -> Vec<Region> {
    let support: &[usize] = if posterior.support.is_empty() {
        std::slice::from_ref(&posterior.map_point)
    } else {
        &posterior.support
    };
    let weight = |k: usize| {
        posterior
            .probability
            .get(k)
            .copied()
            .unwrap_or(0.0)
            .max(f64::MIN_POSITIVE)
    };
    regions(surface, support, weight, REGION_CELL_FRACTION)
}

/// The contact that a temporal model places: in the region of the
/// posterior with the most mass, its most probable sample
/// moved by that sample's believed offset along its tangents
/// (`offset_m(k)`, m: what every frame of the contact says, not only
/// this one; asked for that one sample only), with this frame's best
/// magnitude there (with friction, the friction model's force). No
/// search: the place is the whole recording's, the force this frame's.
/// (A search from there with friction was tried: each frame's place then
/// wandered along its own valley again; `docs/validation.md`, *Friction*.)
#[must_use]
pub fn contact_at_offsets(
    model: &TorqueModel,
    surface: &Surface,
    posterior: &Posterior,
    measurement: &Measurement,
    offset_m: impl Fn(usize) -> Option<[f64; 2]>,
) -> Option<RefinedContact> {
    let best = best_region(surface, posterior)?;
    let start = best.top;
    let link = *surface.link.get(start)?;
    let shape = surface.shape(link)?;
    let at = *surface.location.get(start)?;
    let frame = shape.frame(at)?;
    let offset = offset_m(start).unwrap_or([0.0, 0.0]);
    let state = walked_state(model, shape, (link, measurement), (at, &frame), offset)?;
    let window = surface.window_m.get(start).copied().unwrap_or(0.01).max(1e-4);
    Some(state.contact(link, measurement, window, start, 0))
}

/// How much worse (χ²) than the sample's own place a frame may find the
/// place its believed offset walks to across an edge.
const OFFSET_MISFIT_CHI2: f64 = 100.0;

/// The cosine of the turn of the surface normal, from the sample's, that
/// counts as an edge crossed (60°).
const EDGE_COS: f64 = 0.5;

/// Halvings of an offset before the sample itself is taken.
const OFFSET_HALVINGS: usize = 4;

/// The contact at the place `offset` (m, along the tangents of the
/// sample's `frame`) walks to from the sample `at`; where the walk
/// crosses an edge (the normal turns by more than 60°) and this frame
/// misses there by more than [`OFFSET_MISFIT_CHI2`] beyond its miss at
/// the sample itself, shortened by halves (at last to the sample). A
/// sample's offsets are a linear model of its patch, which fails across
/// an edge: on the LWR's flange a walk of 2 mm from a sample on the end
/// face crossed onto the rim, turning the normal by 90°, and the filter
/// read a 10 N push as 3 N, missing its frame by χ² 2,400 where the
/// sample's own place gave 2.6, for 7 frames in a row of the `../shared`
/// two-contact example. Either test alone did harm: the turn alone (30°)
/// moved filtered presses on the generated LWR's rounded links 14.0 →
/// 16.0 mm, the miss alone the smoothed observer motor-side example 9.1
/// → 10.5 mm (its model error misses by hundreds on no edge).
fn walked_state(
    model: &TorqueModel,
    shape: &LinkShape,
    (link, measurement): (LinkId, &Measurement),
    (at, frame): (MeshPoint, &SurfaceFrame),
    [s1, s2]: [f64; 2],
) -> Option<State> {
    let step = frame.tangents[0] * s1 + frame.tangents[1] * s2;
    let walked = |s: DVec3| State::at(model, shape, link, measurement, shape.walk(at, s));
    let first = walked(step)?;
    if step == DVec3::ZERO || first.frame.inward_normal.dot(frame.inward_normal) >= EDGE_COS {
        return Some(first);
    }
    let own = State::at(model, shape, link, measurement, at)?;
    let limit = own.chi2 + OFFSET_MISFIT_CHI2;
    if first.chi2 <= limit {
        return Some(first);
    }
    std::iter::successors(Some(step * 0.5), |&s| Some(s * 0.5))
        .take(OFFSET_HALVINGS)
        .filter_map(walked)
        .find(|w| w.frame.inward_normal.dot(frame.inward_normal) >= EDGE_COS || w.chi2 <= limit)
        .or(Some(own))
}

/// Cells with less than this fraction of the heaviest cell's mass do not
/// join regions (a region is where the posterior is, not its faint tails).
const REGION_CELL_FRACTION: f64 = 1e-4;

/// Regions holding at least this fraction of the heaviest region's mass
/// are refined, and the best contact among them wins.
const RIVAL_REGION_FRACTION: f64 = 0.2;

/// At most this many regions are refined.
const MAX_RIVAL_REGIONS: usize = 3;

/// The most probable contact on the continuous surface. In each probable
/// region of the posterior (at least a fifth of the heaviest region's
/// mass; at most three), the best point found from the sample nearest its
/// centre of mass, or from its most probable sample when that ends clearly
/// better (by more than half a nat of patch mass); in a valley of equally
/// good contacts (a link that few joints sense) that is the valley's point
/// nearest the region's centre. Of these, the one with the smallest
/// residual (with friction, the smallest `-2 ln L` of the friction model):
/// the continuous optimum is a property of the arm and the
/// torques, while the masses of rival regions, summed over samples, still
/// move by tens of percent with the sampling where a peak is narrower than
/// the samples' spacing (on one static-example frame a region's share went
/// from 0.82 at 2000 samples to 0.28 at 50,000), which made the reported
/// contact jump between regions from one surface seed to the next. `None`
/// without a sample to start from.
#[must_use]
pub fn refine(
    model: &TorqueModel,
    surface: &Surface,
    posterior: &Posterior,
    measurement: &Measurement,
) -> Option<RefinedContact> {
    let all = posterior_regions(surface, posterior);
    let heaviest = all.first()?.weight;
    all.iter()
        .take(MAX_RIVAL_REGIONS)
        .filter(|r| r.weight >= RIVAL_REGION_FRACTION * heaviest)
        .filter_map(|r| refine_region(model, surface, measurement, r))
        .min_by(|x, y| x.1.total_cmp(&y.1))
        .map(|(contact, _)| contact)
}

/// [`refine`] in one region.
fn refine_region(
    model: &TorqueModel,
    surface: &Surface,
    measurement: &Measurement,
    best: &Region,
) -> Option<(RefinedContact, f64)> {
    let central = refine_from(model, surface, measurement, best.central, best.centre_in_link);
    if best.top == best.central {
        return central;
    }
    let top = refine_from(model, surface, measurement, best.top, best.centre_in_link);
    match (central, top) {
        (Some(c), Some(t)) => Some(if t.0.patch_log_mass > c.0.patch_log_mass + 0.5 {
            t
        } else {
            c
        }),
        (c, t) => c.or(t),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::robot::builtin;
    use crate::core::robot::kinematics::RobotPose;
    use crate::core::surface::sampling::SurfaceRequest;

    /// A posterior with mass on two samples only (each its own region).
    fn two_samples(n: usize, (a, mass_a): (usize, f64), (b, mass_b): (usize, f64)) -> Posterior {
        let mut probability = vec![0.0; n];
        probability[a] = mass_a;
        probability[b] = mass_b;
        let mut support = vec![a, b];
        support.sort_unstable();
        Posterior {
            display: probability.clone(),
            log_likelihood: probability.iter().map(|p| p.ln()).collect(),
            force_newtons: vec![10.0; n],
            phases: Vec::new(),
            phase_flags: vec![0; n],
            support,
            map_point: a,
            best_residual_chi2: 0.0,
            no_contact_chi2: 1e4,
            probability,
        }
    }

    /// The built-in LWR's surface (2000 samples, seed `seed`) and its
    /// torque model in a bent pose.
    fn posed_lwr(seed: u64) -> (crate::core::robot::model::Robot, Surface, TorqueModel) {
        let robot = builtin::lwr4plus_generated().unwrap();
        let links = robot.default_candidate_links();
        let request = SurfaceRequest {
            links: links.clone(),
            total_points: 2000,
            seed,
        };
        let surface = Surface::sample(&robot, &request).unwrap();
        let q = [0.3, 0.6, -0.4, -1.2, 0.5, 0.9, 0.2];
        let pose = RobotPose::new(&robot, &robot.joint_positions(&q, &[]).unwrap());
        let model = TorqueModel::new(&robot, &pose, &links);
        (robot, surface, model)
    }

    /// Of two probable regions, the contact that explains the torques
    /// wins even when its region holds less of the sampled mass (which
    /// moves with the sampling); a region below a fifth of the heaviest is
    /// not considered.
    #[test]
    fn the_best_contact_of_the_probable_regions_wins() {
        let (robot, surface, model) = posed_lwr(0);
        let on = |name: &str| {
            let link = robot.link_id(name).unwrap();
            (0..surface.len()).find(|&k| surface.link[k] == link).unwrap()
        };
        let (truth, rival) = (on("lwr_4_link"), on("lwr_7_link"));
        let tau = model.torques(
            surface.link[truth],
            surface.point_in_link[truth],
            surface.inward_normal_in_link[truth] * 10.0,
        );
        let weights = vec![400.0; tau.len()];
        let m = Measurement {
            tau: &tau,
            weights: &weights,
            force_range_newtons: (1.0, 30.0),
            friction: 0.0,
        };
        let found = |posterior: &Posterior| refine(&model, &surface, posterior, &m).unwrap().link;
        let lighter_but_right = two_samples(surface.len(), (rival, 0.6), (truth, 0.4));
        assert_eq!(found(&lighter_but_right), surface.link[truth]);
        let too_light = two_samples(surface.len(), (rival, 0.9), (truth, 0.1));
        assert_eq!(found(&too_light), surface.link[rival]);
    }

    /// Presses with a tangential part, noise-free, from their own sample:
    /// without friction the search moves the place until the normal
    /// explains what the tangential force did (17 mm away at the median);
    /// with it the place stays within a few millimetres (2 mm: the prior
    /// on the tangential force prefers a place that needs less of it) and
    /// the force is recovered, tangential part included (0.05 N).
    #[test]
    fn with_friction_the_search_keeps_a_sliding_press_in_place() {
        let (robot, surface, model) = posed_lwr(1);
        let forearm = robot.link_id("lwr_4_link").unwrap();
        let mut rng = crate::core::numerics::rng::Rng::new(9);
        let (mut moved, mut kept, mut force_errors) = (Vec::new(), Vec::new(), Vec::new());
        while moved.len() < 25 {
            let k = (rng.uniform() * surface.len() as f64) as usize % surface.len();
            if surface.link[k] < forearm || surface.shape(surface.link[k]).is_none() {
                continue;
            }
            let (link, point, normal) = (
                surface.link[k],
                surface.point_in_link[k],
                surface.inward_normal_in_link[k],
            );
            let (t1, t2) = normal.any_orthonormal_pair();
            let angle = rng.uniform() * std::f64::consts::TAU;
            let force = normal * 10.0 + (t1 * angle.cos() + t2 * angle.sin()) * 2.5;
            let tau = model.torques(link, point, force);
            let weights = vec![400.0; tau.len()];
            let posterior = two_samples(surface.len(), (k, 1.0), (k, 0.0));
            let found = |friction: f64| {
                let m = Measurement {
                    tau: &tau,
                    weights: &weights,
                    force_range_newtons: (1.0, 30.0),
                    friction,
                };
                refine(&model, &surface, &posterior, &m).unwrap()
            };
            let (plain, frictional) = (found(0.0), found(0.3));
            moved.push(plain.point_in_link.distance(point));
            kept.push(frictional.point_in_link.distance(point));
            let got = frictional.inward_normal_in_link * frictional.force_newtons + frictional.tangential_in_link;
            force_errors.push(got.distance(force));
        }
        let median = |v: &mut Vec<f64>| {
            v.sort_by(f64::total_cmp);
            v[v.len() / 2]
        };
        let (moved, kept, force_error) = (median(&mut moved), median(&mut kept), median(&mut force_errors));
        eprintln!(
            "median distance from the press: {moved:.4} m frictionless, {kept:.5} m with friction; force error {force_error:.3} N"
        );
        assert!(kept < 4e-3, "{kept}");
        assert!(moved > 4.0 * kept, "{moved} vs {kept}");
        assert!(force_error < 0.3, "{force_error}");
    }

    /// The marginal inner product is `xᵀ(W⁻¹ + s²JJᵀ)⁻¹y`, here solved
    /// directly by elimination on the 7×7 covariance.
    #[test]
    fn the_marginal_metric_inverts_the_marginal_covariance() {
        let mut rng = crate::core::numerics::rng::Rng::new(4);
        let draw = |rng: &mut crate::core::numerics::rng::Rng| -> Vec<f64> { (0..7).map(|_| rng.normal()).collect() };
        for spread in [0.0, 0.3, 2.0, 40.0] {
            let weights: Vec<f64> = (0..7).map(|_| rng.uniform_in(10.0, 1000.0)).collect();
            let (j1, j2, x, y) = (draw(&mut rng), draw(&mut rng), draw(&mut rng), draw(&mut rng));
            let metric = Metric::new(&weights, Some([&j1, &j2]), spread);
            // [C | y] with C = W⁻¹ + s²JJᵀ, then Gauss–Jordan.
            let mut rows: Vec<Vec<f64>> = (0..7)
                .map(|i| {
                    let mut row: Vec<f64> = (0..7)
                        .map(|k| {
                            spread * spread * (j1[i] * j1[k] + j2[i] * j2[k])
                                + if i == k { 1.0 / weights[i] } else { 0.0 }
                        })
                        .collect();
                    row.push(y[i]);
                    row
                })
                .collect();
            for col in 0..7 {
                let pivot = (col..7)
                    .max_by(|&a, &b| rows[a][col].abs().total_cmp(&rows[b][col].abs()))
                    .unwrap();
                rows.swap(col, pivot);
                let p = rows[col][col];
                for v in &mut rows[col] {
                    *v /= p;
                }
                for r in 0..7 {
                    if r != col {
                        let factor = rows[r][col];
                        let pivot_row = rows[col].clone();
                        for (v, pv) in rows[r].iter_mut().zip(&pivot_row) {
                            *v -= factor * pv;
                        }
                    }
                }
            }
            let direct: f64 = (0..7).map(|i| x[i] * rows[i][7]).sum();
            let got = metric.ip(&x, &y);
            assert!(
                (got - direct).abs() < 1e-9 * direct.abs().max(1.0),
                "spread {spread}: {got} vs {direct}"
            );
            assert!((metric.ip(&x, &y) - metric.ip(&y, &x)).abs() < 1e-9 * got.abs().max(1.0));
        }
    }

    /// A believed offset is shortened only where it crosses an edge that
    /// this frame contradicts. A 10 cm cube stands in for link 5's shape
    /// (its torques are the generated LWR's): from 2 mm inside the top
    /// face's edge, a push along the top's normal at the sample, an offset
    /// of 3 mm over the edge onto the side is halved to 1.5 mm (still on
    /// top); a push on the side, where the offset lands, keeps the walk;
    /// a 3 cm offset along the top, which the frame contradicts as much
    /// but crosses no edge, is walked whole.
    #[test]
    fn an_offset_over_an_edge_that_this_frame_contradicts_is_shortened() {
        use crate::core::geometry::primitives::cuboid;
        use crate::core::geometry::shell::SmoothMesh;
        let (robot, _, model) = posed_lwr(3);
        let link = robot.link_id("lwr_5_link").unwrap();
        let mesh = SmoothMesh::new(&cuboid(DVec3::splat(0.1)));
        let (at, frame) = mesh.closest(DVec3::new(0.048, 0.0, 0.06)).unwrap();
        let shape = LinkShape::Mesh(mesh);
        assert!(frame.inward_normal.z < -0.99, "{frame:?}");
        // The offset, along the sample's tangents, of a step of `m` along +x
        // (toward the edge) or +y (along it).
        let along = |axis: DVec3, m: f64| [frame.tangents[0].dot(axis) * m, frame.tangents[1].dot(axis) * m];
        let weights = vec![1.0 / 0.05_f64.powi(2); 7];
        let place = |push: &[f64], offset: [f64; 2]| {
            let measurement = Measurement {
                tau: push,
                weights: &weights,
                force_range_newtons: (1.0, 30.0),
                friction: 0.0,
            };
            let state = walked_state(&model, &shape, (link, &measurement), (at, &frame), offset).unwrap();
            (state.frame.point, state.frame.inward_normal)
        };
        let on_top = model.torques(link, frame.point, frame.inward_normal * 20.0);
        let (p, n) = place(&on_top, along(DVec3::X, 0.003));
        assert!((p.x - 0.0495).abs() < 1e-9 && n.z < -0.99, "{p:?} {n:?}");
        let side = DVec3::new(0.05, 0.0, 0.049);
        let on_side = model.torques(link, side, DVec3::NEG_X * 20.0);
        let (p, n) = place(&on_side, along(DVec3::X, 0.003));
        assert!(p.distance(side) < 1e-9 && n.x < -0.99, "{p:?} {n:?}");
        let (p, _) = place(&on_top, along(DVec3::Y, 0.03));
        assert!((p.y - 0.03).abs() < 1e-9, "{p:?}");
    }
}
