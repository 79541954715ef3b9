//! The estimator panel: σ, resolution, mode and phases, the estimate's
//! summary, and the heatmap's options.

use crate::core::over_time::sequence::OVER_TIME_FRICTION;

use super::{Command, EstimatorConfig, Friction, HeatLayer, ModeKind, Model, Outcome, Verdict, egui, phase_report};

/// Adds `slider` labelled `label`, its width chosen so that the slider,
/// its value and the label fit the panel (a narrow window keeps every row
/// readable instead of pushing the panel under the view).
/// A typed value outside the slider's span is passed on as typed (never
/// clamped): the command that carries it refuses it, naming its valid
/// range, if it lies outside that.
fn fitted_slider(ui: &mut egui::Ui, slider: egui::Slider<'_>, label: &str) -> egui::Response {
    let text = label_width(ui, label);
    ui.spacing_mut().slider_width = (ui.available_width() - text - 80.0).clamp(40.0, 220.0);
    ui.add(slider.clamping(egui::SliderClamping::Never).text(label))
}

/// The friction controls of the estimator panel (exact mode): auto, or
/// one μ (from 0 when auto is unticked).
fn friction_ui(ui: &mut egui::Ui, config: &mut EstimatorConfig) {
    let mut auto = config.friction == Friction::Auto;
    let mut mu = match config.friction {
        Friction::Auto => 0.0,
        Friction::Mu(mu) => mu,
    };
    ui.checkbox(&mut auto, "friction auto").on_hover_text(format!(
        "Friction by how frames are combined: none for a frame alone (one frame cannot pin \
         a tangential force and its place suffers), μ = {OVER_TIME_FRICTION} for a filtered or \
         smoothed session, where a press takes friction only where it explains the torques far \
         better than none."
    ));
    if auto {
        config.friction = Friction::Auto;
        // What auto takes, in place of a slider that would read 0.
        ui.weak(format!("friction μ: {OVER_TIME_FRICTION} over time, 0 per frame"));
        return;
    }
    fitted_slider(
        ui,
        egui::Slider::new(&mut mu, 0.0..=1.0).update_while_editing(false),
        "friction μ",
    )
    .on_hover_text(
        "The estimated force gets a tangential part, Gaussian with a spread of μ times the push \
         (0: frictionless), and a frame's contact is placed where that model explains the \
         torques best. Smoothed, each press is fitted as a whole with one tangential force \
         fixed on the link, kept where it explains the press far better than none; filtered, \
         the friction model's force is taken once the press so far supports it.",
    );
    config.friction = Friction::Mu(mu);
}

/// How wide `text` is laid out on one line in the body font, points.
pub(super) fn label_width(ui: &egui::Ui, text: &str) -> f32 {
    ui.painter()
        .layout_no_wrap(
            text.to_owned(),
            egui::TextStyle::Body.resolve(ui.style()),
            egui::Color32::WHITE,
        )
        .size()
        .x
}

/// The estimator panel's part: σ, resolution, mode and phases, the
/// heatmap's options, and what the estimate says. It keeps no state: it
/// draws the model and the estimate shown.
pub(crate) struct EstimatorPanel;

impl EstimatorPanel {
    /// Draws the panel for `model` and the estimate shown; what the user
    /// changed, as commands.
    pub(crate) fn ui(ui: &mut egui::Ui, model: &Model, outcome: Option<&Outcome>) -> Vec<Command> {
        let mut commands = Vec::new();
        ui.heading("Estimator");
        let mut sigma = model.sigma().iter().copied().fold(0.0, f64::max);
        if fitted_slider(
            ui,
            egui::Slider::new(&mut sigma, 0.005..=1.0)
                .update_while_editing(false)
                .logarithmic(true),
            "σ [N·m]",
        )
        .changed()
        {
            commands.push(Command::SetSigma(sigma));
        }
        egui::CollapsingHeader::new("σ per joint").show(ui, |ui| {
            for (i, value) in model.sigma().iter().enumerate() {
                let mut v = *value;
                let name = &model.robot.joints[model.robot.sensed()[i]].name;
                if ui
                    .add(
                        // No range: a typed value is refused, not clamped.
                        egui::DragValue::new(&mut v)
                            .update_while_editing(false)
                            .speed(0.001)
                            .prefix(format!("{name}: ")),
                    )
                    .changed()
                {
                    commands.push(Command::SetJointSigma(i, v));
                }
            }
        });
        let mut points = model.config.surface_points;
        if fitted_slider(
            ui,
            egui::Slider::new(&mut points, 200..=50_000)
                .update_while_editing(false)
                .logarithmic(true),
            "N (surface points)",
        )
        .changed()
        {
            commands.push(Command::SetSurfacePoints(points));
        }
        commands.extend(Self::options_ui(ui, model));
        commands.extend(Self::view_options_ui(ui, model));
        ui.separator();
        Self::summary_ui(ui, model, outcome);
        commands
    }

    /// What the latest estimate says.
    pub(crate) fn summary_ui(ui: &mut egui::Ui, model: &Model, outcome: Option<&Outcome>) {
        match outcome {
            Some(o) => match &o.update {
                Ok(u) => {
                    let s = &u.summary;
                    let update = ui.label(format!(
                        "update: {:.2} ms ({:.0} Hz)",
                        o.update_ms,
                        1e3 / o.update_ms.max(1e-3)
                    ));
                    if let Some(p) = u.stages {
                        update.on_hover_text(format!(
                            "posterior over the samples {:.2} ms, refinement {:.2} ms, summary {:.2} ms",
                            p.posterior_ms, p.refine_ms, p.summary_ms
                        ));
                    }
                    ui.label(phase_report(&u.posterior.phases));
                    ui.label(match s.verdict {
                        Verdict::Contact => "contact".to_owned(),
                        Verdict::NoContact => "no contact: torques within noise".to_owned(),
                        Verdict::PoorFit => "no candidate explains these torques".to_owned(),
                    });
                    ui.label(format!(
                        "most probable: {} ({:.1} %), {:.1} N",
                        model.robot.links[s.map.link].name,
                        s.map.probability * 100.0,
                        s.map.force_newtons
                    ));
                    ui.label(format!(
                        "90 % credible set: {} points, radius {:.0} mm",
                        s.credible90.points.len(),
                        s.credible90.radius_m * 1e3
                    ));
                    let pose = model.pose();
                    if let Some((_, point, force)) = model.push_world(&pose) {
                        ui.label(format!(
                            "error: {:.0} mm, {:.1} N",
                            s.map.point_world.distance(point) * 1e3,
                            s.map.force_world.distance(force)
                        ));
                    }
                    if !s.clusters.is_empty() {
                        ui.label("Clusters of probable contacts (P ≥ 0.9 max)");
                        for (i, c) in s.clusters.iter().take(5).enumerate() {
                            ui.label(format!(
                                "{}: {} points, σ_r {:.0} mm, σ_F {:.1} N",
                                i + 1,
                                c.points.len(),
                                c.sigma_r_m * 1e3,
                                c.sigma_f_newtons
                            ));
                        }
                    }
                    if model.config.contacts_at_once >= 2 {
                        ui.separator();
                        Self::pair_ui(ui, model, o.pair.as_ref());
                    }
                    ui.separator();
                    ui.label("Probability per link (bar: summed; max: its best point)");
                    for share in &s.per_link {
                        ui.add(egui::ProgressBar::new(share.summed as f32).text(format!(
                            "{} {:.1} % (max {:.1e})",
                            model.robot.links[share.link].name,
                            share.summed * 100.0,
                            share.max
                        )));
                    }
                }
                Err(e) => {
                    ui.colored_label(egui::Color32::LIGHT_RED, e);
                }
            },
            None => {
                ui.label("estimating…");
            }
        }
    }

    /// One contact or two: the probability of two, the evidence ratio,
    /// and each contact given the other.
    fn pair_ui(
        ui: &mut egui::Ui,
        model: &Model,
        pair: Option<&Result<crate::core::estimate::pair::PairEstimate, String>>,
    ) {
        let pair = match pair {
            None => {
                ui.label("two contacts: no second place away from the first");
                return;
            }
            Some(Err(e)) => {
                ui.colored_label(egui::Color32::LIGHT_RED, format!("two contacts: {e}"));
                return;
            }
            Some(Ok(pair)) => pair,
        };
        let ratio = pair.log_evidence_ratio();
        ui.label(if pair.has_two() {
            "two contacts: the evidence calls two".to_owned()
        } else if let Some(why) = pair.unidentifiable {
            format!(
                "one contact: a pair here is not identifiable ({})",
                why.describe(pair.sensing_joints)
            )
        } else {
            "one contact: the evidence calls one".to_owned()
        })
        .on_hover_text(
            "The evidence of two contacts against one: each marginal likelihood over the places and \
             magnitudes, so each extra place pays its Occam factor. With the prior of two \
             (--prior-two), it gives the probability of two.",
        );
        ui.label(format!(
            "P(two) = {:.2}; evidence ratio Z₂/Z₁ = e^{ratio:.1}",
            pair.probability_two
        ));
        let pose = model.pose();
        let pushes: Vec<_> = model
            .push_world(&pose)
            .into_iter()
            .chain(model.second_push_world(&pose))
            .collect();
        for (name, c) in ["A", "B"].iter().zip(&pair.contacts) {
            let link = model.robot.links.get(c.placed.link).map_or("?", |l| l.name.as_str());
            let nearest = pushes
                .iter()
                .map(|(_, point, _)| c.point_world.distance(*point))
                .fold(f64::INFINITY, f64::min);
            let error = if nearest.is_finite() {
                format!(", {:.0} mm from the nearer push", nearest * 1e3)
            } else {
                String::new()
            };
            ui.label(format!(
                "{name}: {link}, {:.1} N, 90 % radius {:.0} mm{error}",
                c.placed.force_newtons,
                c.credible90.radius_m * 1e3
            ));
        }
    }

    /// Mode, particles, phases and force range.
    fn options_ui(ui: &mut egui::Ui, model: &Model) -> Vec<Command> {
        let mut config = model.config.clone();
        egui::ComboBox::from_label("mode")
            .selected_text(match config.mode {
                ModeKind::Exact => "exact",
                ModeKind::ParticlesDeterministic => "particles, deterministic",
                ModeKind::ParticlesRandom => "particles, random",
            })
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut config.mode, ModeKind::Exact, "exact");
                ui.selectable_value(
                    &mut config.mode,
                    ModeKind::ParticlesDeterministic,
                    "particles, deterministic",
                );
                ui.selectable_value(&mut config.mode, ModeKind::ParticlesRandom, "particles, random");
            });
        match config.mode {
            ModeKind::Exact => {}
            ModeKind::ParticlesDeterministic => {
                fitted_slider(
                    ui,
                    egui::Slider::new(&mut config.magnitudes_per_point, 1..=20),
                    "m (magnitudes per point)",
                );
            }
            ModeKind::ParticlesRandom => {
                fitted_slider(
                    ui,
                    egui::Slider::new(&mut config.particles, 1000..=200_000)
                        .update_while_editing(false)
                        .logarithmic(true),
                    "N (particles)",
                );
            }
        }
        if config.mode == ModeKind::Exact {
            friction_ui(ui, &mut config);
        }
        ui.horizontal(|ui| {
            ui.label("contacts at once:");
            ui.radio_value(&mut config.contacts_at_once, 1, "1");
            ui.radio_value(&mut config.contacts_at_once, 2, "2").on_hover_text(
                "Also search for two contacts whose torques add up, and weigh one against two by \
                 their evidence (Shift+click the arm for a second push).",
            );
        });
        ui.checkbox(&mut config.phases, "phases A/B/C");
        if config.phases {
            fitted_slider(ui, egui::Slider::new(&mut config.alpha, 0.0..=0.99), "α");
            ui.horizontal(|ui| {
                ui.add(
                    egui::DragValue::new(&mut config.phase_sizes[0])
                        .update_while_editing(false)
                        .prefix("A: "),
                );
                ui.add(
                    egui::DragValue::new(&mut config.phase_sizes[1])
                        .update_while_editing(false)
                        .prefix("B: "),
                );
                ui.label("points");
            });
        }
        let (mut lo, mut hi) = model.config.force_range_newtons;
        let mut commands = Vec::new();
        ui.horizontal_wrapped(|ui| {
            let a = ui.add(
                egui::DragValue::new(&mut lo)
                    .update_while_editing(false)
                    .speed(0.1)
                    .prefix("F min "),
            );
            let b = ui.add(
                egui::DragValue::new(&mut hi)
                    .update_while_editing(false)
                    .speed(0.1)
                    .prefix("F max "),
            );
            ui.label("N");
            if a.changed() || b.changed() {
                commands.push(Command::SetForceRange(lo, hi));
            }
        });
        if config != model.config {
            commands.push(Command::SetConfig(config));
        }
        commands
    }

    /// Scale, threshold, colour map and candidate points.
    fn view_options_ui(ui: &mut egui::Ui, model: &Model) -> Vec<Command> {
        let mut view = model.view;
        ui.separator();
        ui.label("Heatmap");
        ui.horizontal_wrapped(|ui| {
            ui.radio_value(&mut view.layer, HeatLayer::Posterior, "posterior")
                .on_hover_text("where the contact is, given the torques: probability per cm² of surface");
            ui.radio_value(&mut view.layer, HeatLayer::Observability, "observability")
                .on_hover_text("how sharply the sensed joints would locate a push at each point, in this pose");
            ui.radio_value(&mut view.layer, HeatLayer::Contacts, "two contacts")
                .on_hover_text("each of two contacts' posterior given the other (with two contacts looked for)");
        });
        ui.horizontal_wrapped(|ui| {
            ui.add_enabled_ui(view.layer != HeatLayer::Observability, |ui| {
                ui.radio_value(&mut view.log_scale, true, "log");
                ui.radio_value(&mut view.log_scale, false, "linear");
            });
            ui.separator();
            ui.radio_value(&mut view.red_green, false, "viridis");
            ui.radio_value(&mut view.red_green, true, "red-green");
        });
        let (high, low) = if view.red_green {
            ("green", "red")
        } else {
            ("yellow", "purple")
        };
        ui.label(match (view.layer, view.log_scale) {
            (HeatLayer::Observability, _) => format!(
                "{high}: a push there is located to a millimetre; {low}: to a metre; dark grey: not at all (fewer than three joints feel it apart). The width is the posterior's (1σ) for the push's magnitude (10 N without a push) and σ."
            ),
            (HeatLayer::Posterior | HeatLayer::Contacts, true) => format!(
                "{high}: the densest; {low} fading into grey: e^-20 of it and less (the legend in the view gives the numbers)"
            ),
            (HeatLayer::Posterior | HeatLayer::Contacts, false) => {
                format!("{high}: the densest; {low} fading into grey: zero")
            }
        });
        fitted_slider(ui, egui::Slider::new(&mut view.threshold, 0.0..=0.99), "hide below");
        ui.checkbox(
            &mut view.show_points,
            "candidate points (A red, B orange, 90 % set white)",
        );
        ui.checkbox(
            &mut view.show_axes,
            "joint axes (hover a torque bar: its axis and lever arm)",
        );
        if view == model.view {
            Vec::new()
        } else {
            vec![Command::SetView(view)]
        }
    }
}
