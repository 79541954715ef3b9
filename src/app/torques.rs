//! The torque plot: per joint the push's (or true contact's) torques,
//! the measured ones and those the estimate explains.

use super::{ProprioscopeApp, RobotPose, egui, joint_torques};

impl ProprioscopeApp {
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

    /// The torques the estimate explains: its two contacts' summed where
    /// the evidence calls two, else its most probable contact's.
    fn explained_torques(&self, pose: &crate::core::robot::kinematics::RobotPose) -> Option<Vec<f64>> {
        let outcome = self.current_outcome()?;
        if let Some(pair) = outcome
            .pair
            .as_ref()
            .and_then(|p| p.as_ref().ok())
            .filter(|p| p.has_two())
        {
            let [a, b] = &pair.contacts;
            return Some(
                a.placed
                    .torques
                    .iter()
                    .zip(&b.placed.torques)
                    .map(|(x, y)| x + y)
                    .collect(),
            );
        }
        let m = outcome.update.as_ref().ok()?.summary.map;
        Some(joint_torques(
            &self.model.robot,
            pose,
            m.link,
            m.point_world,
            m.force_world,
        ))
    }

    pub(super) fn torques_ui(&mut self, ui: &mut egui::Ui) {
        use egui_plot::{Bar, BarChart, Plot};
        // In a session the push shown is the recorded true contact.
        let applied_name = if self.model.replay.is_some() {
            "true contact"
        } else {
            "applied"
        };
        let pose = self.model.pose();
        let applied = self.model.applied_torques(&pose);
        let (measured, measured_name) = self.measured_shown(&pose);
        let explained = self.explained_torques(&pose);
        let path: Vec<_> = self
            .model
            .push
            .into_iter()
            .chain(self.model.second_push)
            .flat_map(|p| self.model.robot.path_joints(p.link))
            .collect();
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
        self.view.hovered_joint = hovered
            .and_then(|j| usize::try_from(j).ok())
            .filter(|&j| j < applied.len());
    }
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
