//! How well the sensed joints pin down a push at each surface point, for
//! the current pose: the width of the posterior that a push of a given
//! magnitude there would give, from the Fisher information of the
//! torques (the Cramér–Rao bound of the contact position).
//!
//! Near a sample the torques of a push of magnitude `f` moved by `s` along
//! the surface's two tangents are, to first order, `f u + f s₁ d₁ + f s₂ d₂`
//! (`u` the torques per newton, `dᵢ` their change per metre). With
//! Gaussian noise of σ per joint, the information about `(s₁, s₂, f)` is
//! `Mᵀ W M` with `M = [f d₁, f d₂, u]` and `W = diag(1/σ²)`. The magnitude
//! is unknown too, so the position's information is the Schur complement
//! of the magnitude's entry; the reported width is the posterior's
//! standard deviation along its widest direction, `1/√λ_min`.
//!
//! This is local: it says how sharply a push is located near where it
//! is, not whether a distant point explains the same torques (the
//! posterior heatmap shows that). A point sensed by fewer than three
//! joints has no width (two position coordinates and a magnitude cannot
//! be found from fewer than three torques).

use crate::core::robot::torque::{TorqueModel, weighted_dot};
use crate::core::surface::sampling::Surface;

/// Widths above this are reported as unobservable: a metre is the size of
/// the arm itself.
pub const UNOBSERVABLE_M: f64 = 1.0;

/// Per sample, the posterior width (1σ along its widest direction, m)
/// that a push of `force_newtons` there would give with joint noise
/// `sigma` (N·m, one per sensed joint, or one for all); `None` where the
/// sensed joints cannot pin a push down (fewer than three independent
/// torque directions, or wider than [`UNOBSERVABLE_M`]).
///
/// `model` must have been built for the links of `surface`'s samples.
#[must_use]
pub fn position_widths_m(
    model: &TorqueModel,
    surface: &Surface,
    sigma: &[f64],
    force_newtons: f64,
) -> Vec<Option<f64>> {
    let joints = model.sensed_count();
    let weights: Vec<f64> = (0..joints)
        .map(|j| {
            let s = sigma.get(j).or(sigma.first()).copied().unwrap_or(0.0);
            if s > 0.0 { 1.0 / (s * s) } else { 0.0 }
        })
        .collect();
    let mut u = vec![0.0; joints];
    let mut d1 = vec![0.0; joints];
    let mut d2 = vec![0.0; joints];
    (0..surface.len())
        .map(|k| {
            let link = surface.link[k];
            let line = |columns: &[Vec<f64>]| -> [f64; 6] {
                std::array::from_fn(|c| columns.get(c).and_then(|col| col.get(k)).copied().unwrap_or(0.0))
            };
            model.line_array_torques_into(link, &line(&surface.push_lines), &mut u);
            model.line_array_torques_into(link, &line(&surface.tangent_lines[..6]), &mut d1);
            model.line_array_torques_into(link, &line(&surface.tangent_lines[6..]), &mut d2);
            width_from_rows(&weights, &u, &d1, &d2, force_newtons)
        })
        .collect()
}

/// The width for torque rows `u` (per newton) and `d₁`, `d₂` (per newton
/// and metre), weights `1/σ²`, magnitude `f`.
fn width_from_rows(w: &[f64], u: &[f64], d1: &[f64], d2: &[f64], f: f64) -> Option<f64> {
    let inner = |x: &[f64], y: &[f64]| weighted_dot(w, x, y);
    let a = inner(u, u);
    let (h1, h2) = (f * inner(d1, u), f * inner(d2, u));
    let f2 = f * f;
    let (g11, g12, g22) = (f2 * inner(d1, d1), f2 * inner(d1, d2), f2 * inner(d2, d2));
    if a <= 0.0 || !a.is_finite() {
        return None;
    }
    // The position's information with the magnitude unknown.
    let (s11, s12, s22) = (g11 - h1 * h1 / a, g12 - h1 * h2 / a, g22 - h2 * h2 / a);
    // Smallest eigenvalue of the symmetric 2×2.
    let mean = 0.5 * (s11 + s22);
    let spread = (0.25 * (s11 - s22) * (s11 - s22) + s12 * s12).sqrt();
    let smallest = mean - spread;
    // Relative to the largest: what rounding leaves of a rank deficit.
    let scale = (mean + spread).max(f64::MIN_POSITIVE);
    if smallest.is_nan() || smallest <= 1e-12 * scale {
        return None;
    }
    let width = 1.0 / smallest.sqrt();
    (width.is_finite() && width <= UNOBSERVABLE_M).then_some(width)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::robot::builtin;
    use crate::core::robot::kinematics::RobotPose;
    use crate::core::surface::sampling::SurfaceRequest;

    fn setup(points: usize) -> (crate::core::robot::model::Robot, RobotPose, Surface, TorqueModel) {
        let robot = builtin::lwr4plus_generated().unwrap();
        let links = robot.default_candidate_links();
        let q = [0.3, 0.6, -0.4, -1.2, 0.5, 0.9, 0.2];
        let positions = robot.joint_positions(&q, &[]).unwrap();
        let pose = RobotPose::new(&robot, &positions);
        let surface = Surface::sample(
            &robot,
            &SurfaceRequest {
                links: links.clone(),
                total_points: points,
                seed: 0,
            },
        )
        .unwrap();
        let model = TorqueModel::new(&robot, &pose, &links);
        (robot, pose, surface, model)
    }

    /// The width from finite differences of the torque function itself:
    /// the push moved along two tangents with its direction kept, and a
    /// brute-force 3×3 information matrix whose inverse's position block
    /// gives the width. Agrees with the closed form where the surface is
    /// flat (the tangent rows there do not turn the normal).
    #[test]
    fn widths_match_finite_differences_of_the_torques() {
        let (robot, _, surface, model) = setup(3000);
        let sigma = [0.05];
        let f = 10.0;
        let widths = position_widths_m(&model, &surface, &sigma, f);
        let mut checked = 0;
        for (k, width) in widths.iter().enumerate() {
            // Only where the normal does not turn along the surface.
            let turning: f64 = (9..12).chain(3..6).map(|c| surface.tangent_lines[c][k].abs()).sum();
            if turning > 1e-9 {
                continue;
            }
            let link = surface.link[k];
            let p = surface.point_in_link[k];
            let n = surface.inward_normal_in_link[k];
            let (t1, t2) = n.any_orthonormal_pair();
            let torques = |point: glam::DVec3| model.torques(link, point, n * f);
            let h = 1e-6;
            let col = |t: glam::DVec3| -> Vec<f64> {
                let (a, b) = (torques(p + t * h), torques(p - t * h));
                a.iter().zip(&b).map(|(a, b)| (a - b) / (2.0 * h)).collect()
            };
            let (c1, c2) = (col(t1), col(t2));
            let u = model.torques(link, p, n);
            let cols = [c1, c2, u];
            let w = 1.0 / (sigma[0] * sigma[0]);
            let info = glam::DMat3::from_cols_array_2d(&std::array::from_fn(|i| {
                std::array::from_fn(|j| w * cols[i].iter().zip(&cols[j]).map(|(x, y)| x * y).sum::<f64>())
            }));
            let det = info.determinant();
            let expected = if det.abs() > 1e-9 * info.col(0).length().powi(3) {
                let cov = info.inverse();
                // Largest eigenvalue of the position block.
                let (a, b, d) = (cov.col(0).x, cov.col(1).x, cov.col(1).y);
                let mean = 0.5 * (a + d);
                let spread = (0.25 * (a - d) * (a - d) + b * b).sqrt();
                Some((mean + spread).sqrt()).filter(|w| *w <= UNOBSERVABLE_M)
            } else {
                None
            };
            match (*width, expected) {
                (Some(got), Some(want)) => assert!(
                    (got - want).abs() < 1e-4 * want,
                    "{} sample {k}: {got} vs {want}",
                    robot.links[link].name
                ),
                (None, None) => {}
                (got, want) => panic!("sample {k}: {got:?} vs {want:?}"),
            }
            checked += 1;
        }
        assert!(checked > 50, "{checked} flat samples checked");
    }

    #[test]
    fn widths_scale_with_the_noise_and_inversely_with_the_push() {
        let (_, _, surface, model) = setup(1500);
        let base = position_widths_m(&model, &surface, &[0.05], 10.0);
        let noisier = position_widths_m(&model, &surface, &[0.1], 10.0);
        let harder = position_widths_m(&model, &surface, &[0.05], 20.0);
        let mut compared = 0;
        for ((b, n), h) in base.iter().zip(&noisier).zip(&harder) {
            if let (Some(b), Some(n), Some(h)) = (b, n, h) {
                assert!((n / b - 2.0).abs() < 1e-9 && (h / b - 0.5).abs() < 1e-9);
                compared += 1;
            }
        }
        assert!(compared > 500, "{compared}");
    }

    #[test]
    fn links_that_fewer_than_three_joints_sense_have_no_width() {
        let (robot, _, surface, model) = setup(3000);
        let widths = position_widths_m(&model, &surface, &[0.05], 10.0);
        for (k, width) in widths.iter().enumerate() {
            let sensing = robot.path_joints(surface.link[k]).len();
            if sensing < 3 {
                assert_eq!(*width, None, "{}", robot.links[surface.link[k]].name);
            }
        }
        // The wrist links, sensed by all seven joints, are mostly pinned down
        // to a few millimetres by a 10 N push.
        let l6 = robot.link_id("lwr_6_link").unwrap();
        let mut on_6: Vec<f64> = (0..surface.len())
            .filter(|&k| surface.link[k] == l6)
            .filter_map(|k| widths[k])
            .collect();
        on_6.sort_by(f64::total_cmp);
        assert!(!on_6.is_empty());
        let median = on_6[on_6.len() / 2];
        assert!(median < 0.02, "median width on link 6: {median} m");
    }
}
