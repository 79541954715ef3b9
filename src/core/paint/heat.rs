//! What the arm is painted with: the posterior as probability per cm²
//! (log or linear), or the observability map, over a neutral arm; and the
//! legend that gives the colours their numbers.

use super::colours::{ROBOT_GREY, red_green, viridis};
use crate::core::estimate::estimator::Update;
use crate::core::estimate::observability::position_widths_m;
use crate::core::estimate::pair::PairEstimate;
use crate::core::estimate::summary::Verdict;
use crate::core::robot::kinematics::RobotPose;
use crate::core::robot::model::Robot;
use crate::core::robot::torque::TorqueModel;
use crate::core::surface::sampling::Surface;

/// Log scale depth: from the densest point (top of the ramp) down to
/// e^-20 ≈ 2·10⁻⁹ of it (bottom, where the paint has faded out).
pub const HEAT_DEPTH: f64 = 20.0;

/// The observability map's range: 1 mm (top) to 1 m (bottom).
const WIDTH_RANGE_M: (f64, f64) = (1e-3, 1.0);

/// Colour of surface the sensed joints cannot locate a push on.
pub const UNOBSERVABLE_GREY: [f32; 4] = [0.32, 0.32, 0.35, 1.0];

/// How the posterior is painted: the app's view options, and what is
/// painted for Foxglove.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HeatStyle {
    /// Log scale (else linear in probability).
    pub log_scale: bool,
    /// Hide points below this fraction of the scale (0 shows all).
    pub threshold: f64,
    /// The thesis' red-to-green map instead of viridis.
    pub red_green: bool,
}

impl Default for HeatStyle {
    /// Log scale, nothing hidden, viridis: the app's view as it opens.
    fn default() -> Self {
        Self {
            log_scale: true,
            threshold: 0.0,
            red_green: false,
        }
    }
}

/// The colour ramp and how strongly it is laid over the arm.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Ramp {
    /// The thesis' red-green map instead of viridis.
    pub red_green: bool,
    /// Below this `t` the ramp fades into the arm's grey (0: never).
    pub fade_below: f64,
}

impl Ramp {
    /// The colour at `t` ∈ [0, 1] laid over the arm with `weight` ∈ [0, 1].
    #[must_use]
    pub fn colour(&self, t: f64, weight: f64) -> [f32; 4] {
        let paint = if self.red_green {
            red_green(t as f32)
        } else {
            viridis(t as f32)
        };
        let fade = if self.fade_below > 0.0 {
            smoothstep(t / self.fade_below)
        } else {
            1.0
        };
        mix(ROBOT_GREY, paint, (fade * weight.clamp(0.0, 1.0)) as f32)
    }
}

/// The legend drawn in the view: a ramp with its numbers.
#[derive(Debug, Clone, PartialEq)]
pub struct Legend {
    /// What the numbers are.
    pub title: String,
    /// Positions on the ramp (`t`, 0 bottom, 1 top) and their labels.
    pub ticks: Vec<(f64, String)>,
    /// The colours.
    pub ramp: Ramp,
    /// A line below the ramp (what grey means, why nothing is painted).
    pub note: Option<String>,
}

/// Per surface sample, its colour; and the legend.
#[derive(Debug, Clone, PartialEq)]
pub struct Heat {
    /// One colour per sample of the estimate's surface.
    pub colours: Vec<[f32; 4]>,
    /// The legend.
    pub legend: Legend,
}

fn smoothstep(x: f64) -> f64 {
    let x = x.clamp(0.0, 1.0);
    x * x * (3.0 - 2.0 * x)
}

fn mix(a: [f32; 4], b: [f32; 4], w: f32) -> [f32; 4] {
    std::array::from_fn(|i| a[i] + (b[i] - a[i]) * w)
}

/// A number for a legend: plain between 0.01 and 1000, else in powers of ten.
#[must_use]
pub fn legend_number(x: f64) -> String {
    if x == 0.0 {
        "0".to_owned()
    } else if (0.01..1000.0).contains(&x.abs()) {
        let digits = (2 - x.abs().log10().floor() as i32).clamp(0, 4) as usize;
        format!("{x:.digits$}")
    } else {
        format!("{x:.1e}")
    }
}

/// The posterior as probability per cm² of surface.
///
/// Log scale: `t = 1 + ln(d / d_max) / HEAT_DEPTH`, faded into the arm's
/// grey over the lowest third, so that only where the posterior has mass
/// is painted; linear: `t = d / d_max`. Where the frame holds no contact
/// (its verdict, or a temporal model's contact probability) the paint is
/// weighed down by that: an arm with nothing touching stays grey.
#[must_use]
pub fn posterior_heat(update: &Update, surface: &Surface, log_scale: bool, threshold: f64, red_green: bool) -> Heat {
    let weight = match (update.summary.contact_probability, update.summary.verdict) {
        (Some(p), _) => p,
        (None, Verdict::NoContact) => 0.0,
        (None, _) => 1.0,
    };
    let mut heat = density_heat(
        &update.posterior.display,
        surface,
        weight,
        log_scale,
        threshold,
        red_green,
    );
    heat.legend.note = heat.legend.note.or_else(|| {
        (0.05..0.95)
            .contains(&weight)
            .then(|| format!("painted × P(contact) = {weight:.2}"))
    });
    heat
}

/// Two contacts' posteriors, each given the other, painted together as
/// probability per cm² (each contact's mass halved, so that the map holds
/// one unit as the posterior does): two blobs where the torques place two
/// pushes. The legend's note gives the probability of two contacts.
#[must_use]
pub fn contacts_heat(pair: &PairEstimate, surface: &Surface, log_scale: bool, threshold: f64, red_green: bool) -> Heat {
    let [a, b] = &pair.contacts;
    let mass: Vec<f64> = (0..surface.len())
        .map(|k| 0.5 * (a.probability.get(k).copied().unwrap_or(0.0) + b.probability.get(k).copied().unwrap_or(0.0)))
        .collect();
    let mut heat = density_heat(&mass, surface, 1.0, log_scale, threshold, red_green);
    heat.legend.title = format!(
        "each contact given the other, per cm² ({})",
        if log_scale { "log" } else { "linear" }
    );
    heat.legend.note = Some(match pair.unidentifiable {
        None => format!("P(two contacts) = {:.2}", pair.probability_two),
        Some(why) => format!("not identifiable ({})", why.describe(pair.sensing_joints)),
    });
    heat
}

/// Masses per surface sample as probability per cm², on the log or
/// linear ramp, the paint weighed by `weight` (a contact's probability).
fn density_heat(
    mass_per_sample: &[f64],
    surface: &Surface,
    weight: f64,
    log_scale: bool,
    threshold: f64,
    red_green: bool,
) -> Heat {
    let density_per_cm2: Vec<f64> = (0..surface.len())
        .map(|k| {
            let mass = mass_per_sample.get(k).copied().unwrap_or(0.0);
            let area_cm2 = surface.area_m2.get(k).copied().unwrap_or(0.0) * 1e4;
            if area_cm2 > 0.0 && mass.is_finite() {
                mass / area_cm2
            } else {
                0.0
            }
        })
        .collect();
    let top = density_per_cm2.iter().copied().fold(0.0, f64::max);
    let ramp = Ramp {
        red_green,
        fade_below: if log_scale { 0.35 } else { 0.1 },
    };
    let t_of = |d: f64| -> f64 {
        if top <= 0.0 || d <= 0.0 {
            0.0
        } else if log_scale {
            (1.0 + (d / top).ln() / HEAT_DEPTH).clamp(0.0, 1.0)
        } else {
            (d / top).clamp(0.0, 1.0)
        }
    };
    let colours = density_per_cm2
        .iter()
        .map(|&d| {
            let t = t_of(d);
            if t < threshold {
                ROBOT_GREY
            } else {
                ramp.colour(t, weight)
            }
        })
        .collect();
    let mut ticks = Vec::new();
    if top > 0.0 {
        if log_scale {
            let bottom = top * (-HEAT_DEPTH).exp();
            ticks.push((1.0, legend_number(top)));
            // Every power of ten between, at most five of them.
            let (lo, hi) = (bottom.log10().ceil() as i32, top.log10().floor() as i32);
            let stride = ((hi - lo + 3) / 4).max(1);
            let mut e = hi;
            while e >= lo {
                let value = 10f64.powi(e);
                let t = t_of(value);
                if t < 0.93 && t > 0.05 {
                    ticks.push((t, format!("1e{e}")));
                }
                e -= stride;
            }
            ticks.push((0.0, format!("{} and below", legend_number(bottom))));
        } else {
            ticks.push((1.0, legend_number(top)));
            ticks.push((0.5, legend_number(top / 2.0)));
            ticks.push((0.0, "0".to_owned()));
        }
    }
    let note = if top <= 0.0 {
        Some("no estimate".to_owned())
    } else if weight < 0.05 {
        Some("no contact: nothing painted".to_owned())
    } else {
        None
    };
    Heat {
        colours,
        legend: Legend {
            title: format!("probability per cm² ({})", if log_scale { "log" } else { "linear" }),
            ticks,
            ramp,
            note,
        },
    }
}

/// The observability map: per sample, how wide the posterior of a push of
/// `force_newtons` there would be (1 mm at the top of the ramp, 1 m at the
/// bottom; dark grey where fewer than three independent torques see it).
#[must_use]
pub fn observability_heat(
    robot: &Robot,
    pose: &RobotPose,
    surface: &Surface,
    sigma: &[f64],
    force_newtons: f64,
    red_green: bool,
) -> Heat {
    let mut links: Vec<usize> = surface.link.clone();
    links.sort_unstable();
    links.dedup();
    let model = TorqueModel::new(robot, pose, &links);
    let widths = position_widths_m(&model, surface, sigma, force_newtons);
    let (lo, hi) = WIDTH_RANGE_M;
    let span = (hi / lo).log10();
    let t_of = |w: f64| (1.0 - (w / lo).log10() / span).clamp(0.0, 1.0);
    let ramp = Ramp {
        red_green,
        fade_below: 0.0,
    };
    let colours = widths
        .iter()
        .map(|w| w.map_or(UNOBSERVABLE_GREY, |w| ramp.colour(t_of(w), 1.0)))
        .collect();
    let ticks = [(1e-3, "1 mm"), (1e-2, "1 cm"), (1e-1, "10 cm"), (1.0, "1 m")]
        .into_iter()
        .map(|(w, label)| (t_of(w), label.to_owned()))
        .collect();
    Heat {
        colours,
        legend: Legend {
            title: format!("posterior width of a {} N push here (1σ)", legend_number(force_newtons)),
            ticks,
            ramp,
            note: Some("dark grey: the joints cannot locate it".to_owned()),
        },
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_ramp_fades_into_the_arm_below_its_threshold() {
        let ramp = Ramp {
            red_green: false,
            fade_below: 0.35,
        };
        let same = |a: [f32; 4], b: [f32; 4]| a.iter().zip(&b).all(|(x, y)| (x - y).abs() < 1e-6);
        assert!(same(ramp.colour(0.0, 1.0), ROBOT_GREY));
        assert!(same(ramp.colour(1.0, 1.0), viridis(1.0)));
        assert!(same(ramp.colour(1.0, 0.0), ROBOT_GREY));
        let half = ramp.colour(0.2, 1.0);
        assert!(!same(half, ROBOT_GREY) && !same(half, viridis(0.2)));
    }

    #[test]
    fn legend_numbers_read_plainly() {
        assert_eq!(legend_number(0.0), "0");
        assert_eq!(legend_number(0.5), "0.500");
        assert_eq!(legend_number(12.0), "12.0");
        assert_eq!(legend_number(3.2e-5), "3.2e-5");
    }
}
