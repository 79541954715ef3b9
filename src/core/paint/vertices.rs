//! Per-sample values spread over the arm's mesh: each mesh vertex takes a
//! weighted mean of its nearest surface samples.

use super::colours::ROBOT_GREY;
use crate::core::robot::model::Robot;
use crate::core::surface::sampling::Surface;

/// Per vertex, the candidates it takes its heat from and their weights.
pub type VertexSamples = Vec<(usize, f64)>;

/// For every link and mesh vertex, the three nearest surface samples on
/// that link (in the link frame) with inverse-distance weights summing to
/// 1, so that per-sample values paint the mesh smoothly.
#[must_use]
pub fn nearest_samples(robot: &Robot, surface: &Surface) -> Vec<Vec<VertexSamples>> {
    const NEIGHBOURS: usize = 3;
    robot
        .links
        .iter()
        .enumerate()
        .map(|(link, l)| {
            let samples: Vec<usize> = (0..surface.len()).filter(|&k| surface.link[k] == link).collect();
            l.mesh
                .positions
                .iter()
                .map(|v| {
                    let mut best: Vec<(f64, usize)> = Vec::with_capacity(NEIGHBOURS + 1);
                    for &k in &samples {
                        let d = surface.point_in_link[k].distance(*v);
                        if best.len() < NEIGHBOURS || d < best[best.len() - 1].0 {
                            let at = best.partition_point(|(bd, _)| *bd <= d);
                            best.insert(at, (d, k));
                            best.truncate(NEIGHBOURS);
                        }
                    }
                    // A vertex on a sample takes its value alone.
                    if let Some(&(d, k)) = best.first()
                        && d < 1e-9
                    {
                        return vec![(k, 1.0)];
                    }
                    let total: f64 = best.iter().map(|(d, _)| 1.0 / d).sum();
                    best.iter().map(|(d, k)| (*k, 1.0 / d / total)).collect()
                })
                .collect()
        })
        .collect()
}

/// A vertex's colour from the per-sample colours and its weights
/// ([`nearest_samples`]); grey where it has none.
#[must_use]
pub fn vertex_colour(weights: &[(usize, f64)], sample_colours: &[[f32; 4]]) -> [f32; 4] {
    if weights.is_empty() {
        return ROBOT_GREY;
    }
    let mut c = [0.0f32; 4];
    for &(k, w) in weights {
        let sample = sample_colours.get(k).copied().unwrap_or(ROBOT_GREY);
        for (ci, si) in c.iter_mut().zip(sample) {
            *ci += w as f32 * si;
        }
    }
    c
}
