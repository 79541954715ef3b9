//! Which surface samples neighbour which, and the random walk over them
//! that a sliding contact follows between frames (see
//! [`crate::core::over_time::temporal`]).

use crate::core::surface::sampling::{Surface, WINDOW_FRACTION};

/// Most Euler sub-steps of the random walk per frame interval; a gap
/// longer than this many sub-steps spreads the contact less than the
/// model says (after such a gap it is spread over the link anyway).
pub const MAX_SUBSTEPS: usize = 10_000;

/// Neighbours are the samples of the same link within this many sample
/// spacings (about 6–10 each for evenly spread samples).
pub const NEIGHBOUR_SPACINGS: f64 = 1.8;

/// Which samples neighbour which (same link, within
/// [`NEIGHBOUR_SPACINGS`], facing the same side), with the random walk's
/// hop weight per unit `ℓ²`: `(1/m_k + 1/m_j) / d²` for samples with `m_k`
/// and `m_j` neighbours `d` apart. The weights are symmetric, so the walk
/// keeps every total and its transpose is itself; for `m` neighbours at
/// distance `d` the spread grows by `2ℓ²` per second, `ℓ²` along each
/// surface direction.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SurfaceGraph {
    /// Neighbours of sample k: `neighbour[start[k]..start[k + 1]]`.
    pub(crate) start: Vec<u32>,
    pub(crate) neighbour: Vec<u32>,
    pub(crate) weight: Vec<f64>,
    /// Largest `Σ_j weight` of a sample: the fastest hop rate per `ℓ²`.
    pub(crate) max_rate: f64,
}

impl SurfaceGraph {
    /// The graph of `surface`'s samples.
    #[must_use]
    pub fn new(surface: &Surface) -> Self {
        let n = surface.len();
        // Members of each cell (cells are three spacings wide, so
        // neighbours lie in the same or a touching cell).
        let mut members: Vec<Vec<u32>> = vec![Vec::new(); surface.cells.len()];
        for (k, &c) in surface.cell.iter().enumerate() {
            if let Some(list) = members.get_mut(c as usize) {
                list.push(k as u32);
            }
        }
        let mut lists: Vec<Vec<(u32, f64)>> = vec![Vec::new(); n];
        for (k, list) in lists.iter_mut().enumerate() {
            let (Some(&c), Some(&p), Some(&normal), Some(&window)) = (
                surface.cell.get(k),
                surface.point_in_link.get(k),
                surface.inward_normal_in_link.get(k),
                surface.window_m.get(k),
            ) else {
                continue;
            };
            let spacing = window / WINDOW_FRACTION;
            let radius = NEIGHBOUR_SPACINGS * spacing;
            let c = c as usize;
            let around = std::iter::once(c as u32).chain(surface.cells.neighbours_of(c).iter().copied());
            for cell in around {
                for &j in members.get(cell as usize).map_or(&[][..], Vec::as_slice) {
                    let j_index = j as usize;
                    if j_index == k {
                        continue;
                    }
                    let (Some(&q), Some(&other)) = (
                        surface.point_in_link.get(j_index),
                        surface.inward_normal_in_link.get(j_index),
                    ) else {
                        continue;
                    };
                    let d2 = p.distance_squared(q);
                    // Facing the same side: not through a thin wall.
                    if d2 > 0.0 && d2 <= radius * radius && normal.dot(other) > 0.0 {
                        list.push((j, d2));
                    }
                }
            }
            list.sort_unstable_by_key(|&(j, _)| j);
        }
        // Symmetric: keep a pair only when each lists the other (radii
        // differ between links' spacings only across links, which never
        // pair, but rounding may still break a tie one way).
        let counts: Vec<f64> = lists.iter().map(|l| l.len() as f64).collect();
        let mut graph = Self {
            start: Vec::with_capacity(n + 1),
            ..Self::default()
        };
        for (k, list) in lists.iter().enumerate() {
            graph.start.push(graph.neighbour.len() as u32);
            let mut rate = 0.0;
            for &(j, d2) in list {
                let mutual = lists
                    .get(j as usize)
                    .is_some_and(|other| other.binary_search_by_key(&(k as u32), |&(i, _)| i).is_ok());
                if !mutual {
                    continue;
                }
                let (Some(&mk), Some(&mj)) = (counts.get(k), counts.get(j as usize)) else {
                    continue;
                };
                let w = (1.0 / mk + 1.0 / mj) / d2;
                graph.neighbour.push(j);
                graph.weight.push(w);
                rate += w;
            }
            graph.max_rate = graph.max_rate.max(rate);
        }
        graph.start.push(graph.neighbour.len() as u32);
        graph
    }

    /// Number of samples.
    #[must_use]
    pub fn len(&self) -> usize {
        self.start.len().saturating_sub(1)
    }

    /// True without samples.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The neighbours of sample k and their hop weights per `ℓ²`.
    #[must_use]
    pub fn neighbours(&self, k: usize) -> (&[u32], &[f64]) {
        let (Some(&a), Some(&b)) = (self.start.get(k), self.start.get(k + 1)) else {
            return (&[], &[]);
        };
        let range = a as usize..b as usize;
        (
            self.neighbour.get(range.clone()).unwrap_or(&[]),
            self.weight.get(range).unwrap_or(&[]),
        )
    }

    /// `values` after a random walk of `rate_scale · dt` (`rate_scale` = ℓ²):
    /// explicit Euler sub-steps short enough to keep every value ≥ 0.
    pub(crate) fn diffuse(&self, values: &mut Vec<f64>, rate_scale: f64, dt_secs: f64, scratch: &mut Vec<f64>) {
        let fastest = self.max_rate * rate_scale;
        if fastest <= 0.0 || dt_secs <= 0.0 || values.len() != self.len() {
            return;
        }
        let wanted = (fastest * dt_secs / 0.5).ceil();
        let steps = if wanted >= MAX_SUBSTEPS as f64 {
            MAX_SUBSTEPS
        } else {
            (wanted as usize).max(1)
        };
        let h = (dt_secs / steps as f64).min(0.5 / fastest) * rate_scale;
        for _ in 0..steps {
            scratch.clear();
            scratch.extend(values.iter().enumerate().map(|(k, &v)| {
                let (around, weights) = self.neighbours(k);
                let flow: f64 = around
                    .iter()
                    .zip(weights)
                    .map(|(&j, &w)| w * (values.get(j as usize).copied().unwrap_or(v) - v))
                    .sum();
                v + h * flow
            }));
            std::mem::swap(values, scratch);
        }
    }
}
