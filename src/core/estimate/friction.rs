//! Friction at a contact: besides the push along the inward normal
//! (magnitude f), a tangential force g in the surface's plane.
//!
//! A uniform friction cone (|g| ≤ μ f) adds two free unknowns to every
//! point, and with them ambiguity: many more places explain the torques
//! and the position gets worse. Real presses mostly carry a small
//! tangential force (a few percent of the normal one, rarely near μ). The
//! model here is a Gaussian tangential force whose spread grows with the
//! push: g ~ N(0, (μ f)² I₂). At a place the normal magnitude maximises
//! the likelihood with g marginalised, and g is its posterior mean given
//! that magnitude; places are compared by that marginal likelihood (the
//! refinement's search on the surface, [`crate::core::estimate::refine`], minimises
//! `Fit::cost`), so a tangential force no longer drags the place to
//! where the normal lies along the whole force. With torques `u` per
//! newton of push and `J`
//! (two columns) per newton along the tangents, `W = 1/σ²`:
//!
//! `τ | f ~ N(f u, W⁻¹ + (μ f)² J Jᵀ)`, so
//! `-2 ln L(f) = ‖τ - f u‖²_W - rᵀQ⁻¹r + ln det(I + (μ f)² JᵀWJ)` + const,
//! with `Q = JᵀWJ + I/(μ f)²`, `r = JᵀW(τ - f u)`, and `E[g | f] = Q⁻¹r`.
//!
//! The first two terms are the Mahalanobis residual of the marginal model:
//! the χ² the fit test reads, so that a press with friction within the
//! model is not called poorly explained.

use glam::DVec3;

use crate::core::estimate::measurement::Measurement;
use crate::core::robot::model::LinkId;
use crate::core::robot::torque::{TorqueModel, weighted_dot as inner};

/// Magnitudes tried across the force range before the golden-section
/// polish (the marginal likelihood need not be unimodal over 1–30 N).
const GRID: usize = 32;

/// Golden-section steps (the bracket shrinks by 0.618 each: 30 steps take
/// the two grid cells around the best, 1.9 N over 1–30 N, below 1e-6 N,
/// where the cost is within 1e-9 of its minimum; the search on the
/// surface that calls this for every place it tries compares costs to
/// 1e-2).
const GOLDEN_STEPS: usize = 30;

/// Below this tangential spread, N, the tangential force is taken as 0
/// (its prior precision would overflow).
const NO_SPREAD_NEWTONS: f64 = 1e-9;

/// The force of a contact at a fixed place with friction.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrictionalForce {
    /// Push along the inward normal, N.
    pub normal_newtons: f64,
    /// Tangential force, link frame, N (perpendicular to the normal).
    pub tangential_in_link: DVec3,
    /// The marginal model's Mahalanobis residual at that magnitude:
    /// `‖τ - f u‖²_W - rᵀQ⁻¹r` (χ² with as many degrees of freedom as
    /// the frictionless fit: the tangential force is not free, it has a
    /// prior).
    pub residual_chi2: f64,
}

/// The inner products of one place.
struct Place {
    uu: f64,
    ut: f64,
    tt: f64,
    /// `JᵀWu`.
    ju: [f64; 2],
    /// `JᵀWτ`.
    jt: [f64; 2],
    /// `JᵀWJ` as (11, 12, 22).
    jj: [f64; 3],
}

/// `Q = JᵀWJ + I/s²` of a tangential force of spread `s`: the precision of
/// that force given the torques.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct TangentialPrecision {
    /// `Q` as (11, 12, 22).
    q: [f64; 3],
    /// `det Q`.
    det: f64,
    /// `1/s²`.
    prior: f64,
}

impl TangentialPrecision {
    /// From `JᵀWJ` as (11, 12, 22) and the spread, N; `None` at or below
    /// [`NO_SPREAD_NEWTONS`] (or not a number): no tangential force.
    pub(crate) fn new(jj: [f64; 3], spread: f64) -> Option<Self> {
        if spread.is_nan() || spread <= NO_SPREAD_NEWTONS {
            return None;
        }
        let prior = 1.0 / (spread * spread);
        let q = [jj[0] + prior, jj[1], jj[2] + prior];
        // Q is the sum of a positive semi-definite matrix and a positive
        // multiple of I: its determinant is at least prior².
        let det = (q[0] * q[2] - q[1] * q[1]).max(prior * prior);
        Some(Self { q, det, prior })
    }

    /// `Q⁻¹` as (11, 12, 22).
    pub(crate) fn inverse(&self) -> [f64; 3] {
        let [q11, q12, q22] = self.q;
        [q22 / self.det, -q12 / self.det, q11 / self.det]
    }

    /// `ln det(I + s² JᵀWJ)` (= `ln(s⁴ det Q)`).
    fn log_volume(&self) -> f64 {
        (self.det / (self.prior * self.prior)).max(1.0).ln()
    }
}

/// At magnitude f: the marginal's `-2 ln L` (up to a constant), its
/// Mahalanobis residual, and `E[g | f]` in tangent coordinates.
fn at_magnitude(p: &Place, f: f64, friction: f64) -> (f64, f64, [f64; 2]) {
    let plain = (p.tt - 2.0 * f * p.ut + f * f * p.uu).max(0.0);
    let Some(tangential) = TangentialPrecision::new(p.jj, friction * f.abs()) else {
        return (plain, plain, [0.0, 0.0]);
    };
    let [i11, i12, i22] = tangential.inverse();
    let r = [p.jt[0] - f * p.ju[0], p.jt[1] - f * p.ju[1]];
    let g = [i11 * r[0] + i12 * r[1], i12 * r[0] + i22 * r[1]];
    let explained = r[0] * g[0] + r[1] * g[1];
    let residual = (plain - explained).max(0.0);
    (residual + tangential.log_volume(), residual, g)
}

/// The force at `point_in_link` (inward normal `inward_normal_in_link`) of
/// `link` that best explains the measurement with friction μ = `friction`
/// (the tangential force's spread per newton of push, per tangent
/// direction; module docs). `None` for a zero normal or a contact that
/// moves no sensed joint.
#[must_use]
pub fn frictional_force(
    model: &TorqueModel,
    link: LinkId,
    (point_in_link, inward_normal_in_link): (DVec3, DVec3),
    m: &Measurement,
    friction: f64,
) -> Option<FrictionalForce> {
    let place = PlaceTorques::new(model, link, point_in_link, inward_normal_in_link)?;
    place.force(m, friction).map(|(force, _)| force)
}

/// At one place, the frictionless force and how much lower the friction
/// model's `-2 ln L` is than its (negative where the tangential force's
/// spread costs more than it explains): what a frame says for or against
/// friction there. `None` as [`frictional_force`].
#[must_use]
pub fn friction_evidence(
    model: &TorqueModel,
    link: LinkId,
    place: (DVec3, DVec3),
    m: &Measurement,
    friction: f64,
) -> Option<(FrictionalForce, f64)> {
    friction_fits(model, link, place, m, friction).map(|fits| (fits.without, fits.gain))
}

/// One place's forces with and without friction, and what friction buys.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrictionFits {
    /// The friction model's force ([`frictional_force`]).
    pub with: FrictionalForce,
    /// The push along the normal alone.
    pub without: FrictionalForce,
    /// How much lower `-2 ln L` is with friction than without (as
    /// [`friction_evidence`]'s).
    pub gain: f64,
}

/// [`friction_evidence`] with the friction model's force as well, from
/// one set of the place's torques. `None` as [`frictional_force`].
#[must_use]
pub fn friction_fits(
    model: &TorqueModel,
    link: LinkId,
    (point_in_link, inward_normal_in_link): (DVec3, DVec3),
    m: &Measurement,
    friction: f64,
) -> Option<FrictionFits> {
    let place = PlaceTorques::new(model, link, point_in_link, inward_normal_in_link)?;
    let (with, with_cost) = place.force(m, friction)?;
    let (without, without_cost) = place.force(m, 0.0)?;
    Some(FrictionFits {
        with,
        without,
        gain: without_cost - with_cost,
    })
}

/// The torques per newton of a push at a place and of forces along two
/// tangents there.
struct PlaceTorques {
    tangents: [DVec3; 2],
    push: Vec<f64>,
    along: [Vec<f64>; 2],
}

impl PlaceTorques {
    fn new(model: &TorqueModel, link: LinkId, point_in_link: DVec3, inward_normal_in_link: DVec3) -> Option<Self> {
        let normal = inward_normal_in_link.try_normalize()?;
        let (t1, t2) = normal.any_orthonormal_pair();
        let joints = model.sensed_count();
        let (mut u, mut j1, mut j2) = (vec![0.0; joints], vec![0.0; joints], vec![0.0; joints]);
        model.unit_torques_into(link, point_in_link, normal, &mut u);
        model.unit_torques_into(link, point_in_link, t1, &mut j1);
        model.unit_torques_into(link, point_in_link, t2, &mut j2);
        Some(Self {
            tangents: [t1, t2],
            push: u,
            along: [j1, j2],
        })
    }

    /// The force with friction μ = `friction` and its `-2 ln L`.
    fn force(&self, m: &Measurement, friction: f64) -> Option<(FrictionalForce, f64)> {
        let [j1, j2] = &self.along;
        let fit = fit(&self.push, [j1, j2], m, friction)?;
        let [t1, t2] = self.tangents;
        Some((
            FrictionalForce {
                normal_newtons: fit.normal_newtons,
                tangential_in_link: t1 * fit.tangential[0] + t2 * fit.tangential[1],
                residual_chi2: fit.residual_chi2,
            },
            fit.cost,
        ))
    }
}

/// The friction model's fit at one place, from its torques per newton.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Fit {
    /// Push along the inward normal, N.
    pub normal_newtons: f64,
    /// `E[g | f]` along the two tangents whose torques were given, N.
    pub tangential: [f64; 2],
    /// The marginal model's Mahalanobis residual (see [`FrictionalForce`]).
    pub residual_chi2: f64,
    /// `-2 ln` of the marginal likelihood at that magnitude, up to a
    /// constant shared by every place: the residual plus the volume term
    /// (module docs). Places are compared by it.
    pub cost: f64,
}

/// The magnitude in the measurement's force range that maximises the
/// marginal likelihood of a place whose unit push makes torques `u` and
/// whose unit tangential forces make `tangential`, with friction μ =
/// `friction` (0 or not a number: frictionless). `None` for a place that
/// moves no sensed joint.
pub(crate) fn fit(u: &[f64], [j1, j2]: [&[f64]; 2], m: &Measurement, friction: f64) -> Option<Fit> {
    let w = m.weights;
    let place = Place {
        uu: inner(w, u, u),
        ut: inner(w, u, m.tau),
        tt: inner(w, m.tau, m.tau),
        ju: [inner(w, j1, u), inner(w, j2, u)],
        jt: [inner(w, j1, m.tau), inner(w, j2, m.tau)],
        jj: [inner(w, j1, j1), inner(w, j1, j2), inner(w, j2, j2)],
    };
    if place.uu.is_nan() || place.uu <= 0.0 || !place.tt.is_finite() {
        return None;
    }
    let (lo, hi) = m.force_range_newtons;
    let friction = if friction.is_finite() { friction.max(0.0) } else { 0.0 };
    let cost = |f: f64| at_magnitude(&place, f, friction).0;
    let f = if hi > lo {
        let magnitude = |i: usize| lo + (hi - lo) * i as f64 / (GRID - 1) as f64;
        let best = (0..GRID)
            .map(|i| (i, cost(magnitude(i))))
            .min_by(|x, y| x.1.total_cmp(&y.1).then(x.0.cmp(&y.0)))
            .map_or(0, |(i, _)| i);
        golden_minimum(
            cost,
            magnitude(best.saturating_sub(1)),
            magnitude((best + 1).min(GRID - 1)),
        )
    } else {
        lo
    };
    let (cost, residual_chi2, tangential) = at_magnitude(&place, f, friction);
    Some(Fit {
        normal_newtons: f,
        tangential,
        residual_chi2,
        cost,
    })
}

/// The minimum of `cost` on `[lo, hi]` by golden sections (for a cost
/// with one minimum in the bracket; otherwise a local one).
fn golden_minimum(cost: impl Fn(f64) -> f64, lo: f64, hi: f64) -> f64 {
    let ratio = 0.5 * (5f64.sqrt() - 1.0);
    let (mut a, mut b) = (lo, hi);
    let (mut x1, mut x2) = (b - ratio * (b - a), a + ratio * (b - a));
    let (mut c1, mut c2) = (cost(x1), cost(x2));
    for _ in 0..GOLDEN_STEPS {
        if c1 <= c2 {
            b = x2;
            x2 = x1;
            c2 = c1;
            x1 = b - ratio * (b - a);
            c1 = cost(x1);
        } else {
            a = x1;
            x1 = x2;
            c1 = c2;
            x2 = a + ratio * (b - a);
            c2 = cost(x2);
        }
    }
    // The ends too: a minimum at the range's edge is common (a 1 N floor).
    [(a, cost(a)), (0.5 * (a + b), cost(0.5 * (a + b))), (b, cost(b))]
        .into_iter()
        .min_by(|x, y| x.1.total_cmp(&y.1))
        .map_or(lo, |(x, _)| x)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::numerics::rng::Rng;
    use crate::core::robot::builtin;
    use crate::core::robot::kinematics::RobotPose;

    struct Setup {
        model: TorqueModel,
        link: LinkId,
        point: DVec3,
        normal: DVec3,
    }

    /// A point on the forearm's side of the built-in LWR in a bent pose.
    fn setup() -> Setup {
        let robot = builtin::lwr4plus_kinematics().unwrap();
        let q = [0.3, 0.7, -0.2, -1.1, 0.4, 0.9, 0.1];
        let positions = robot.joint_positions(&q, &[]).unwrap();
        let pose = RobotPose::new(&robot, &positions);
        let link = robot.link_id("lwr_5_link").unwrap();
        let model = TorqueModel::new(&robot, &pose, &[link]);
        Setup {
            model,
            link,
            point: DVec3::new(0.06, 0.01, 0.1),
            normal: DVec3::new(-1.0, -0.1, 0.0).normalize(),
        }
    }

    fn torques(s: &Setup, force_in_link: DVec3) -> Vec<f64> {
        s.model.torques(s.link, s.point, force_in_link)
    }

    fn measurement<'a>(tau: &'a [f64], weights: &'a [f64]) -> Measurement<'a> {
        Measurement {
            tau,
            weights,
            force_range_newtons: (1.0, 30.0),
            friction: 0.0,
        }
    }

    #[test]
    fn without_friction_it_is_the_least_squares_magnitude() {
        let s = setup();
        let tau: Vec<f64> = torques(&s, s.normal * 12.0).iter().map(|t| t + 0.01).collect();
        let weights = vec![400.0; tau.len()];
        let got = frictional_force(&s.model, s.link, (s.point, s.normal), &measurement(&tau, &weights), 0.0).unwrap();
        let u = torques(&s, s.normal);
        let (a, b) = (inner(&weights, &u, &u), inner(&weights, &u, &tau));
        // A minimum found from values alone is known to about √ε of its scale.
        assert!(
            (got.normal_newtons - b / a).abs() < 1e-6,
            "{} vs {}",
            got.normal_newtons,
            b / a
        );
        assert_eq!(got.tangential_in_link, DVec3::ZERO);
        let c = inner(&weights, &tau, &tau);
        let f = b / a;
        assert!((got.residual_chi2 - (c - 2.0 * b * f + a * f * f)).abs() < 1e-9);
    }

    #[test]
    fn a_noise_free_press_with_friction_is_recovered() {
        let s = setup();
        let (t1, t2) = s.normal.any_orthonormal_pair();
        let force = s.normal * 10.0 + t1 * 1.5 - t2 * 0.8;
        let tau = torques(&s, force);
        // Seven joints sense the link: five equations beyond the three
        // unknowns; a wide prior leaves the data to decide.
        let weights = vec![1e8; tau.len()];
        let got = frictional_force(&s.model, s.link, (s.point, s.normal), &measurement(&tau, &weights), 1.0);
        let Some(got) = got else {
            panic!("no force");
        };
        let total = s.normal * got.normal_newtons + got.tangential_in_link;
        assert!(total.distance(force) < 1e-3, "{total} vs {force}");
        assert!(got.tangential_in_link.dot(s.normal).abs() < 1e-12);
    }

    /// A frame's evidence for friction at the true place: negative for a
    /// straight push without noise (the frictionless push explains it
    /// exactly, the friction model pays the volume of its spread), large
    /// for a push with a 20 % tangential part; the frictionless force is
    /// the straight push's.
    #[test]
    fn friction_evidence_tells_a_drag_from_a_straight_push() {
        let s = setup();
        let (t1, _) = s.normal.any_orthonormal_pair();
        let weights = vec![400.0; 7];
        let evidence = |force: DVec3| {
            let tau = torques(&s, force);
            friction_evidence(&s.model, s.link, (s.point, s.normal), &measurement(&tau, &weights), 0.1).unwrap()
        };
        let (straight, straight_gain) = evidence(s.normal * 10.0);
        // The magnitude comes from the golden-section search (1e-6 N).
        assert!((straight.normal_newtons - 10.0).abs() < 1e-5, "{straight:?}");
        assert!(straight.residual_chi2 < 1e-9 && straight_gain < 0.0, "{straight_gain}");
        let (_, drag_gain) = evidence(s.normal * 10.0 + t1 * 2.0);
        assert!(drag_gain > 30.0, "{drag_gain}");
    }

    /// The marginal residual equals a brute-force minimum over the
    /// tangential force of the penalised residual, and the cost's
    /// minimum over f is not beaten by any magnitude of a fine scan.
    #[test]
    fn the_fit_matches_brute_force() {
        let s = setup();
        let (t1, t2) = s.normal.any_orthonormal_pair();
        let mut rng = Rng::new(5);
        let force = s.normal * 8.0 + t1 * 0.9 + t2 * 0.4;
        let tau: Vec<f64> = torques(&s, force).iter().map(|t| t + 0.05 * rng.normal()).collect();
        let weights = vec![400.0; tau.len()];
        let mu = 0.1;
        let m = measurement(&tau, &weights);
        let Some(got) = frictional_force(&s.model, s.link, (s.point, s.normal), &m, mu) else {
            panic!("no force");
        };
        let f = got.normal_newtons;
        let penalised = |g1: f64, g2: f64| {
            let r: Vec<f64> = tau
                .iter()
                .zip(torques(&s, s.normal * f + t1 * g1 + t2 * g2))
                .map(|(t, m)| t - m)
                .collect();
            inner(&weights, &r, &r) + (g1 * g1 + g2 * g2) / (mu * f).powi(2)
        };
        let g = [got.tangential_in_link.dot(t1), got.tangential_in_link.dot(t2)];
        let at = penalised(g[0], g[1]);
        assert!(
            (at - got.residual_chi2).abs() < 1e-6 * at.max(1.0),
            "{at} vs {}",
            got.residual_chi2
        );
        for (d1, d2) in [(1e-3, 0.0), (-1e-3, 0.0), (0.0, 1e-3), (0.0, -1e-3)] {
            assert!(penalised(g[0] + d1, g[1] + d2) >= at, "not the minimum over g");
        }
        let u = torques(&s, s.normal);
        let j = [torques(&s, t1), torques(&s, t2)];
        let place = Place {
            uu: inner(&weights, &u, &u),
            ut: inner(&weights, &u, &tau),
            tt: inner(&weights, &tau, &tau),
            ju: [inner(&weights, &j[0], &u), inner(&weights, &j[1], &u)],
            jt: [inner(&weights, &j[0], &tau), inner(&weights, &j[1], &tau)],
            jj: [
                inner(&weights, &j[0], &j[0]),
                inner(&weights, &j[0], &j[1]),
                inner(&weights, &j[1], &j[1]),
            ],
        };
        let best = at_magnitude(&place, f, mu).0;
        for i in 0..=2900 {
            let trial = 1.0 + 0.01 * f64::from(i);
            assert!(
                at_magnitude(&place, trial, mu).0 >= best - 1e-9,
                "{trial} N beats {f} N"
            );
        }
    }

    #[test]
    fn a_zero_normal_is_refused_without_nan() {
        let s = setup();
        let tau = vec![0.1; s.model.sensed_count()];
        let weights = vec![400.0; tau.len()];
        let m = measurement(&tau, &weights);
        assert!(frictional_force(&s.model, s.link, (s.point, DVec3::ZERO), &m, 0.2).is_none());
        let got = frictional_force(&s.model, s.link, (s.point, s.normal), &m, f64::NAN);
        assert!(got.is_some_and(|g| g.normal_newtons.is_finite() && g.tangential_in_link == DVec3::ZERO));
    }
}
