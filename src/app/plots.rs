//! The session's linked plots over time: each sensed joint's torque (less
//! the bias or model error taken off, which gets a plot of its own), the
//! contact's probability and the estimates, every line thinned to
//! [`PLOT_POINTS`] points so that long sessions draw at full frame rate.

use eframe::egui;

use super::{ProprioscopeApp, Replay};
use crate::batch::FrameEstimate;
use crate::core::estimate::summary::Verdict;
use crate::core::over_time::sequence::Temporal;
use crate::io::session::{Frame, Truth};

/// Named lines of a plot: (name, points).
type PlotLines = Vec<(String, Vec<[f64; 2]>)>;

/// Most points a plot line draws (long sessions are thinned).
const PLOT_POINTS: usize = 1500;

impl ProprioscopeApp {
    /// Per sensed joint, the torque over time (less the bias when it is
    /// taken off) and the bias, every `stride`-th frame.
    fn torque_and_bias_lines(&self, replay: &Replay, stride: usize) -> (PlotLines, Option<PlotLines>) {
        let frames = &replay.session.frames;
        let robot = &self.model.robot;
        // With the calibration's model error or the bias taken off, the
        // torques as the estimator sees them, and what was taken off in a
        // plot of its own.
        let correction = self.session_correction();
        let bias = correction.as_ref();
        let less_bias =
            |i: usize, j: usize, tau: f64| tau - bias.and_then(|b| b.get(i)?.get(j).copied()).unwrap_or(0.0);
        let torque_lines: Vec<(String, Vec<[f64; 2]>)> = (0..robot.sensed().len())
            .map(|j| {
                let name = format!("τ{}", j + 1);
                (
                    name,
                    frames
                        .iter()
                        .enumerate()
                        .step_by(stride)
                        .filter_map(|(i, f)| Some([f.t, less_bias(i, j, *f.tau.get(j)?)]))
                        .collect(),
                )
            })
            .collect();
        let bias_lines: Option<Vec<(String, Vec<[f64; 2]>)>> = bias.map(|b| {
            (0..robot.sensed().len())
                .map(|j| {
                    (
                        format!("b{}", j + 1),
                        frames
                            .iter()
                            .zip(b.iter())
                            .step_by(stride)
                            .filter_map(|(f, bias)| Some([f.t, *bias.get(j)?]))
                            .collect(),
                    )
                })
                .collect()
        });
        (torque_lines, bias_lines)
    }

    /// The titles of the torque plot and of the plot of what is taken off
    /// the torques (the calibration's model error, or the bias).
    fn torque_titles(&self, bias: bool) -> (&'static str, &'static str) {
        if self
            .session_calibration()
            .is_some_and(|c| c.applied && c.calibration.found)
        {
            (
                "torque less the model error, unlagged [N·m]",
                "taken off: model error and lag [N·m]",
            )
        } else if bias {
            ("measured torque less bias [N·m]", "estimated torque bias [N·m]")
        } else {
            ("measured torque [N·m]", "estimated torque bias [N·m]")
        }
    }

    pub(super) fn session_plots_ui(&self, ui: &mut egui::Ui, replay: &Replay) -> Option<f64> {
        let frames = &replay.session.frames;
        let now = frames.get(replay.frame).map_or(0.0, |f| f.t);
        let stride = frames.len().div_ceil(PLOT_POINTS).max(1);
        let robot = &self.model.robot;
        let estimates = &self.session.estimates;
        let sampled = || {
            frames
                .iter()
                .zip(estimates.iter().chain(std::iter::repeat(&None)))
                .step_by(stride)
        };
        let (torque_lines, bias_lines) = self.torque_and_bias_lines(replay, stride);
        let truth_force = |f: &Frame| match &f.truth {
            Truth::Contact { force, .. } => Some(glam::DVec3::from_array(*force).length()),
            Truth::NoContact => Some(0.0),
            Truth::Unknown => None,
        };
        let estimated_force = |e: &FrameEstimate| {
            if e.verdict == Verdict::NoContact {
                0.0
            } else {
                e.force_world.length()
            }
        };
        let force_lines = vec![
            (
                "estimated".to_owned(),
                sampled()
                    .filter_map(|(f, e)| Some([f.t, estimated_force(e.as_ref()?)]))
                    .collect(),
            ),
            (
                "true".to_owned(),
                sampled().filter_map(|(f, _)| Some([f.t, truth_force(f)?])).collect(),
            ),
        ];
        let error_lines = vec![(
            "position error".to_owned(),
            sampled()
                .filter_map(|(f, e)| {
                    let outcome = crate::batch::frame_outcome(robot, e.as_ref()?, &f.truth)?;
                    Some([f.t, outcome.estimated_point.distance(outcome.true_point) * 1e3])
                })
                .collect(),
        )];
        let mut probability_lines = vec![(
            "MAP probability".to_owned(),
            sampled()
                .filter_map(|(f, e)| Some([f.t, e.as_ref()?.probability]))
                .collect::<Vec<_>>(),
        )];
        if replay.over_time != Temporal::None {
            probability_lines.push((
                "contact probability".to_owned(),
                sampled()
                    .filter_map(|(f, e)| Some([f.t, e.as_ref()?.contact_probability?]))
                    .collect(),
            ));
            // A frame not searched for a second contact has none.
            if self.model.config.contacts_at_once >= 2 {
                probability_lines.push((
                    "two contacts".to_owned(),
                    sampled()
                        .filter_map(|(f, e)| Some([f.t, e.as_ref()?.second.map_or(0.0, |s| s.probability_two)]))
                        .collect(),
                ));
            }
        }
        // A pixel short of the panel below the titles (the timeline claims
        // the whole panel, `timeline_ui`): the plots never push it out.
        let title_height = ui.text_style_height(&egui::TextStyle::Body) + ui.spacing().item_spacing.y;
        let height = (ui.available_height() - title_height - 1.0).max(150.0);
        let mut clicked = None;
        let columns = if bias_lines.is_some() { 5 } else { 4 };
        let (torque_title, taken_off_title) = self.torque_titles(bias_lines.is_some());
        ui.columns(columns, |columns| {
            // The error exists only in frames with a contact: dots, so
            // that no line runs across the frames without one.
            let mut plots = vec![
                ("plot-torques", torque_title, torque_lines, false),
                ("plot-force", "force [N]: estimated, true", force_lines, false),
                ("plot-error", "position error [mm]", error_lines, true),
                (
                    "plot-probability",
                    if replay.over_time == Temporal::None {
                        "MAP probability"
                    } else {
                        "MAP and contact probability"
                    },
                    probability_lines,
                    false,
                ),
            ];
            if let Some(lines) = bias_lines {
                plots.push(("plot-bias", taken_off_title, lines, false));
            }
            for (ui, (id, title, lines, dots)) in columns.iter_mut().zip(plots) {
                ui.label(title);
                if let Some(t) = linked_plot_ui(ui, id, lines, dots, now, height) {
                    clicked = Some(t);
                }
            }
        });
        clicked
    }
}

/// One plot over session time, linked to the others, with a line at
/// `now` (series as lines, or as dots with `dots`); returns the time
/// clicked.
fn linked_plot_ui(
    ui: &mut egui::Ui,
    id: &str,
    lines: Vec<(String, Vec<[f64; 2]>)>,
    dots: bool,
    now: f64,
    height: f32,
) -> Option<f64> {
    use egui_plot::{Legend, Line, Plot, Points, VLine};
    let response = Plot::new(id)
        .height(height)
        .link_axis(egui::Id::unique("session-time"), [true, false])
        .link_cursor(egui::Id::unique("session-time"), [true, false])
        .legend(
            Legend::default()
                .position(egui_plot::Corner::LeftTop)
                .background_alpha(0.5),
        )
        .show(ui, |plot| {
            for (name, points) in lines {
                if dots {
                    plot.points(Points::new(name, points).radius(1.5));
                } else {
                    plot.line(Line::new(name, points));
                }
            }
            // Unnamed: the cursor stays out of the legend.
            plot.vline(VLine::new("", now).color(egui::Color32::from_rgb(240, 200, 60)));
            plot.pointer_coordinate()
        });
    if response.response.clicked() {
        response.inner.map(|p| p.x)
    } else {
        None
    }
}
