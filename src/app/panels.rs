//! The side panels: robot and push, estimator settings and summary,
//! heatmap options, the torque plot.

use super::{Command, HeatLayer, ModeChoice, ProprioscopeApp, RobotPose, Verdict, egui, joint_torques, phase_report};

impl ProprioscopeApp {
    pub(super) fn robot_panel_ui(&mut self, ui: &mut egui::Ui) -> Vec<Command> {
        let mut commands = Vec::new();
        ui.heading(&self.model.robot.name);
        ui.label("Joints (degrees)").on_hover_text(
            "drag; Shift+drag for fine steps; click and use the arrow keys; type a value and press Enter",
        );
        for (i, &j) in self.model.robot.sensed().iter().enumerate() {
            let joint = &self.model.robot.joints[j];
            let (lo, hi) = joint
                .limits
                .map_or((-180.0, 180.0), |l| (l.lower.to_degrees(), l.upper.to_degrees()));
            let mut deg = self.model.q[i].to_degrees();
            if fine_slider(ui, &mut deg, lo..=hi, "°", &joint.name) {
                commands.push(Command::SetJoint(i, deg.to_radians()));
            }
        }
        ui.horizontal(|ui| {
            if ui.button("Zero pose").clicked() {
                commands.push(Command::ZeroJoints);
            }
            if ui.button("Random pose").clicked() {
                self.pose_seed += 1;
                commands.push(Command::RandomPose(self.pose_seed));
            }
        });
        ui.separator();
        ui.label("Push (click the arm)");
        match self.model.push {
            Some(p) => {
                let mut f = p.force_newtons;
                if fine_slider(ui, &mut f, 0.0..=30.0, " N", "force") {
                    commands.push(Command::SetForce(f));
                }
                let positions = self.model.joint_positions();
                let pose = RobotPose::new(&self.model.robot, &positions);
                let at = pose.point_to_world(p.link, p.point_in_link);
                ui.label(format!(
                    "on {} at ({:.3}, {:.3}, {:.3}) m",
                    self.model.robot.links[p.link].name, at.x, at.y, at.z
                ));
                if ui.button("Clear push").clicked() {
                    commands.push(Command::ClearPush);
                }
            }
            None => {
                ui.label("none");
            }
        }
        ui.separator();
        ui.label("Links that can be touched");
        for link in self.model.robot.default_candidate_links() {
            let mut on = self.model.candidate_links.contains(&link);
            if ui.checkbox(&mut on, &self.model.robot.links[link].name).changed() {
                commands.push(Command::SetCandidate(link, on));
            }
        }
        ui.separator();
        let mut seed = self.model.noise_seed;
        if ui.add(egui::DragValue::new(&mut seed).prefix("noise seed ")).changed() {
            commands.push(Command::SetNoiseSeed(seed));
        }
        let mut noise = self.model.noise_sigma;
        if fine_slider(ui, &mut noise, 0.0..=0.5, "", "sensor noise σ [N·m]") {
            commands.push(Command::SetNoise(noise));
        }
        commands
    }

    pub(super) fn estimator_panel_ui(&mut self, ui: &mut egui::Ui) -> Vec<Command> {
        let mut commands = Vec::new();
        ui.heading("Estimator");
        let mut sigma = self.model.sigma.iter().copied().fold(0.0, f64::max);
        if ui
            .add(
                egui::Slider::new(&mut sigma, 0.005..=1.0)
                    .update_while_editing(false)
                    .logarithmic(true)
                    .text("σ [N·m]"),
            )
            .changed()
        {
            commands.push(Command::SetSigma(sigma));
        }
        egui::CollapsingHeader::new("σ per joint").show(ui, |ui| {
            for (i, value) in self.model.sigma.iter().enumerate() {
                let mut v = *value;
                let name = &self.model.robot.joints[self.model.robot.sensed()[i]].name;
                if ui
                    .add(
                        egui::DragValue::new(&mut v)
                            .update_while_editing(false)
                            .range(0.001..=10.0)
                            .speed(0.001)
                            .prefix(format!("{name}: ")),
                    )
                    .changed()
                {
                    commands.push(Command::SetJointSigma(i, v));
                }
            }
        });
        let mut points = self.model.surface_points;
        if ui
            .add(
                egui::Slider::new(&mut points, 200..=50_000)
                    .update_while_editing(false)
                    .logarithmic(true)
                    .text("N (surface points)"),
            )
            .changed()
        {
            commands.push(Command::SetSurfacePoints(points));
        }
        commands.extend(self.estimator_options_ui(ui));
        commands.extend(self.view_options_ui(ui));
        ui.separator();
        self.summary_ui(ui);
        commands
    }

    /// What the latest estimate says.
    pub(super) fn summary_ui(&self, ui: &mut egui::Ui) {
        match self.current_outcome() {
            Some(o) => match &o.update {
                Ok(u) => {
                    let s = &u.summary;
                    ui.label(format!(
                        "update: {:.2} ms ({:.0} Hz)",
                        o.update_ms,
                        1e3 / o.update_ms.max(1e-3)
                    ));
                    ui.label(phase_report(&u.posterior.phases));
                    ui.label(match s.verdict {
                        Verdict::Contact => "contact".to_owned(),
                        Verdict::NoContact => "no contact: torques within noise".to_owned(),
                        Verdict::PoorFit => "no candidate explains these torques".to_owned(),
                    });
                    ui.label(format!(
                        "most probable: {} ({:.1} %), {:.1} N",
                        self.model.robot.links[s.map.link].name,
                        s.map.probability * 100.0,
                        s.map.force_newtons
                    ));
                    ui.label(format!(
                        "90 % credible set: {} points, radius {:.0} mm",
                        s.credible90.points.len(),
                        s.credible90.radius_m * 1e3
                    ));
                    let positions = self.model.joint_positions();
                    let pose = RobotPose::new(&self.model.robot, &positions);
                    if let Some((_, point, force)) = self.model.push_world(&pose) {
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
                    ui.separator();
                    ui.label("Probability per link (bar: summed; max: its best point)");
                    for share in &s.per_link {
                        ui.add(egui::ProgressBar::new(share.summed as f32).text(format!(
                            "{} {:.1} % (max {:.1e})",
                            self.model.robot.links[share.link].name,
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

    /// Mode, particles, phases and force range.
    pub(super) fn estimator_options_ui(&self, ui: &mut egui::Ui) -> Vec<Command> {
        let mut choice = self.model.estimator;
        egui::ComboBox::from_label("mode")
            .selected_text(match choice.mode {
                ModeChoice::Exact => "exact",
                ModeChoice::ParticlesDeterministic => "particles, deterministic",
                ModeChoice::ParticlesRandom => "particles, random",
            })
            .show_ui(ui, |ui| {
                ui.selectable_value(&mut choice.mode, ModeChoice::Exact, "exact");
                ui.selectable_value(
                    &mut choice.mode,
                    ModeChoice::ParticlesDeterministic,
                    "particles, deterministic",
                );
                ui.selectable_value(&mut choice.mode, ModeChoice::ParticlesRandom, "particles, random");
            });
        match choice.mode {
            ModeChoice::Exact => {}
            ModeChoice::ParticlesDeterministic => {
                ui.add(egui::Slider::new(&mut choice.magnitudes_per_point, 1..=20).text("m (magnitudes per point)"));
            }
            ModeChoice::ParticlesRandom => {
                ui.add(
                    egui::Slider::new(&mut choice.particles, 1000..=200_000)
                        .update_while_editing(false)
                        .logarithmic(true)
                        .text("N (particles)"),
                );
            }
        }
        ui.checkbox(&mut choice.phases, "phases A/B/C");
        if choice.phases {
            ui.add(egui::Slider::new(&mut choice.alpha, 0.0..=0.99).text("α"));
            ui.horizontal(|ui| {
                ui.add(
                    egui::DragValue::new(&mut choice.phase_sizes[0])
                        .update_while_editing(false)
                        .range(10..=5000)
                        .prefix("A: "),
                );
                ui.add(
                    egui::DragValue::new(&mut choice.phase_sizes[1])
                        .update_while_editing(false)
                        .range(10..=20000)
                        .prefix("B: "),
                );
                ui.label("points");
            });
        }
        let (mut lo, mut hi) = self.model.force_range_newtons;
        let mut commands = Vec::new();
        ui.horizontal(|ui| {
            let a = ui.add(
                egui::DragValue::new(&mut lo)
                    .update_while_editing(false)
                    .range(0.0..=1000.0)
                    .speed(0.1)
                    .prefix("F min "),
            );
            let b = ui.add(
                egui::DragValue::new(&mut hi)
                    .update_while_editing(false)
                    .range(0.0..=1000.0)
                    .speed(0.1)
                    .prefix("F max "),
            );
            ui.label("N");
            if a.changed() || b.changed() {
                commands.push(Command::SetForceRange(lo, hi));
            }
        });
        if choice != self.model.estimator {
            commands.push(Command::SetEstimator(choice));
        }
        commands
    }

    /// Scale, threshold, colour map and candidate points.
    pub(super) fn view_options_ui(&self, ui: &mut egui::Ui) -> Vec<Command> {
        let mut view = self.model.view;
        ui.separator();
        ui.label("Heatmap");
        ui.horizontal(|ui| {
            ui.radio_value(&mut view.layer, HeatLayer::Posterior, "posterior")
                .on_hover_text("where the contact is, given the torques: probability per cm² of surface");
            ui.radio_value(&mut view.layer, HeatLayer::Observability, "observability")
                .on_hover_text("how sharply the sensed joints would locate a push at each point, in this pose");
        });
        ui.horizontal(|ui| {
            ui.add_enabled_ui(view.layer == HeatLayer::Posterior, |ui| {
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
            (HeatLayer::Posterior, true) => format!(
                "{high}: the densest; {low} fading into grey: e^-20 of it and less (the legend in the view gives the numbers)"
            ),
            (HeatLayer::Posterior, false) => format!("{high}: the densest; {low} fading into grey: zero"),
        });
        ui.add(egui::Slider::new(&mut view.threshold, 0.0..=0.99).text("hide below"));
        ui.checkbox(
            &mut view.show_points,
            "candidate points (A red, B orange, 90 % set white)",
        );
        ui.checkbox(
            &mut view.show_axes,
            "joint axes (hover a torque bar: its axis and lever arm)",
        );
        if view == self.model.view {
            Vec::new()
        } else {
            vec![Command::SetView(view)]
        }
    }

    /// The measured torques as the estimator is given them (less the
    /// session's bias when it is taken off), and their name.
    fn measured_shown(&self, pose: &RobotPose) -> (Vec<f64>, &'static str) {
        let mut measured = self.model.measured_torques(pose);
        match self.model.replay.as_ref().and_then(|r| self.frame_bias(r.frame)) {
            Some(bias) => {
                for (m, b) in measured.iter_mut().zip(bias) {
                    *m -= b;
                }
                (measured, "measured less bias")
            }
            None => (measured, "measured"),
        }
    }

    pub(super) fn torques_ui(&mut self, ui: &mut egui::Ui) {
        use egui_plot::{Bar, BarChart, Plot};
        // In a session the push shown is the recorded true contact.
        let applied_name = if self.model.replay.is_some() {
            "true contact"
        } else {
            "applied"
        };
        let positions = self.model.joint_positions();
        let pose = RobotPose::new(&self.model.robot, &positions);
        let applied = self.model.applied_torques(&pose);
        let (measured, measured_name) = self.measured_shown(&pose);
        let explained: Option<Vec<f64>> = self.current_outcome().and_then(|o| o.update.as_ref().ok()).map(|u| {
            let m = u.summary.map;
            joint_torques(&self.model.robot, &pose, m.link, m.point_world, m.force_world)
        });
        let path = self
            .model
            .push
            .map(|p| self.model.robot.path_joints(p.link))
            .unwrap_or_default();
        let bars = |values: &[f64], offset: f64, colour: egui::Color32| -> Vec<Bar> {
            values
                .iter()
                .enumerate()
                .map(|(i, v)| {
                    let senses = self.model.robot.sensed().get(i).is_some_and(|j| path.contains(j));
                    Bar::new(i as f64 + 1.0 + offset, *v).width(0.25).fill(if senses {
                        colour
                    } else {
                        colour.gamma_multiply(0.3)
                    })
                })
                .collect()
        };
        let series = [
            (
                applied_name,
                Some(&applied),
                -0.27,
                egui::Color32::from_rgb(90, 140, 230),
            ),
            (
                measured_name,
                Some(&measured),
                0.0,
                egui::Color32::from_rgb(230, 160, 60),
            ),
            (
                "explained by the estimate",
                explained.as_ref(),
                0.27,
                egui::Color32::from_rgb(110, 200, 120),
            ),
        ];
        // The legend as a line of its own: inside the plot it hid the last joints.
        ui.horizontal_wrapped(|ui| {
            for (name, values, _, colour) in &series {
                if values.is_some() {
                    let (swatch, _) = ui.allocate_exact_size(egui::vec2(10.0, 10.0), egui::Sense::hover());
                    ui.painter().rect_filled(swatch, 1.0, *colour);
                    ui.label(*name);
                }
            }
        });
        // Room for the bars and a margin, symmetric about 0, so that the
        // axis always shows numbers on both sides of zero.
        let largest = series
            .iter()
            .filter_map(|(_, v, _, _)| *v)
            .flat_map(|v| v.iter().map(|x| x.abs()))
            .fold(0.0, f64::max);
        // Below a micro-newton-metre the bars are rounding: a unit scale reads better.
        let reach = if largest > 1e-6 { largest * 1.15 } else { 1.0 };
        let response = Plot::new("torques")
            .height(ui.available_height().max(110.0))
            .include_y(reach)
            .include_y(-reach)
            .include_x(0.4)
            .include_x(applied.len() as f64 + 0.6)
            .y_axis_min_width(36.0)
            .y_grid_spacer(move |_| torque_grid(reach))
            .y_axis_formatter(|mark, _| {
                let decimals = (-mark.step_size.log10().floor()).max(0.0) as usize;
                format!("{:.*}", decimals, mark.value)
            })
            .y_axis_label("N·m")
            .x_axis_label("joint")
            .allow_drag(false)
            .allow_zoom(false)
            .allow_scroll(false)
            .show(ui, |plot| {
                for (name, values, offset, colour) in series {
                    if let Some(values) = values {
                        plot.bar_chart(BarChart::new(name, bars(values, offset, colour)).color(colour));
                    }
                }
                plot.pointer_coordinate().map(|p| p.x.round() as i64 - 1)
            });
        // Only a pointer over the plot picks a joint (the plot reports a
        // coordinate for the pointer anywhere in the window).
        let hovered = response.inner.filter(|_| response.response.hovered());
        self.hovered_joint = hovered
            .and_then(|j| usize::try_from(j).ok())
            .filter(|&j| j < applied.len());
    }
}

/// A slider as wide as the panel with its number beside it: Shift while
/// dragging moves it ten times slower, the arrow keys step it by a
/// thousandth of its range once it has focus, and a typed number counts when Enter is pressed or the field is
/// left (not at every keystroke). True when the value changed.
pub(super) fn fine_slider(
    ui: &mut egui::Ui,
    value: &mut f64,
    range: std::ops::RangeInclusive<f64>,
    suffix: &str,
    text: &str,
) -> bool {
    let before = *value;
    // What the name and the number take; the slider gets the rest.
    let name = ui
        .painter()
        .layout_no_wrap(
            text.to_owned(),
            egui::TextStyle::Body.resolve(ui.style()),
            egui::Color32::WHITE,
        )
        .size()
        .x;
    let width = (ui.available_width() - name - 90.0).max(60.0);
    ui.spacing_mut().slider_width = width;
    let response = ui.add(
        egui::Slider::new(value, range.clone())
            .suffix(suffix)
            .text(text)
            .update_while_editing(false),
    );
    let mut changed = response.changed();
    // The slider follows the pointer while the button is down on it (not
    // only once a drag has begun) and where it is let go: with Shift, undo
    // that and move by a tenth of the pointer's motion instead.
    // The arrow keys step a focused slider by a thousandth of its range
    // (a third of a degree on a joint), not by a point of its width.
    if response.has_focus() {
        let (left, right) = ui.input(|i| {
            (
                i.key_pressed(egui::Key::ArrowLeft),
                i.key_pressed(egui::Key::ArrowRight),
            )
        });
        if left != right {
            let step = (range.end() - range.start()) / 1000.0;
            *value = (before + if right { step } else { -step }).clamp(*range.start(), *range.end());
            return (*value - before).abs() > 0.0;
        }
    }
    let held = response.is_pointer_button_down_on() || response.drag_stopped() || response.clicked();
    if held && ui.input(|i| i.modifiers.shift) {
        let span = range.end() - range.start();
        let step = f64::from(ui.input(|i| i.pointer.delta().x)) * span / f64::from(width) / 10.0;
        *value = (before + step).clamp(*range.start(), *range.end());
        changed = (*value - before).abs() > 0.0;
    }
    changed
}

/// Grid marks for the torque plot: four or so steps of a round size on
/// each side of zero, so that numbers show on both sides at any height.
fn torque_grid(reach: f64) -> Vec<egui_plot::GridMark> {
    // The largest round step that leaves at least one mark beside zero
    // on each side (1 to 7 of them).
    let target = reach / 1.5;
    let magnitude = 10f64.powf(target.log10().floor());
    let step = [5.0, 2.0, 1.0]
        .into_iter()
        .map(|m| m * magnitude)
        .find(|s| *s <= target)
        .unwrap_or(magnitude);
    let n = (reach / step).floor() as i64;
    (-n..=n)
        .map(|i| egui_plot::GridMark {
            value: i as f64 * step,
            step_size: step,
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::torque_grid;

    #[test]
    fn the_torque_axis_has_round_marks_on_both_sides_of_zero() {
        for reach in [0.011, 0.62, 1.0, 4.44, 6.1, 17.0, 99.0] {
            let marks: Vec<f64> = torque_grid(reach).iter().map(|m| m.value).collect();
            let beside = marks.iter().filter(|v| **v > 0.0).count();
            assert!((1..=7).contains(&beside), "{reach}: {marks:?}");
            assert!(marks.iter().all(|v| v.abs() <= reach), "{reach}: {marks:?}");
            assert!(marks.contains(&0.0));
        }
    }
}
