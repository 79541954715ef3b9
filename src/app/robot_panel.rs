//! The robot panel: joints, push, touchable links, sensor noise; and the
//! fine slider it is built of.

use super::{Command, Model, egui};

/// The robot panel's part: the seed of the last random pose.
#[derive(Debug, Default)]
pub(crate) struct RobotPanel {
    pub(crate) pose_seed: u64,
}

impl RobotPanel {
    /// Draws the panel for `model`; what the user changed, as commands.
    pub(crate) fn ui(&mut self, ui: &mut egui::Ui, model: &Model) -> Vec<Command> {
        let mut commands = Vec::new();
        ui.heading(&model.robot.name);
        ui.label("Joints (degrees)").on_hover_text(
            "drag; Shift+drag for fine steps; click and use the arrow keys; type a value and press Enter",
        );
        for (i, &j) in model.robot.sensed().iter().enumerate() {
            let joint = &model.robot.joints[j];
            let (lo, hi) = joint
                .limits
                .map_or((-180.0, 180.0), |l| (l.lower.to_degrees(), l.upper.to_degrees()));
            let mut deg = model.q[i].to_degrees();
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
        ui.label("Push (click the arm; Shift+click: a second push)");
        match model.push {
            Some(p) => {
                let mut f = p.force_newtons;
                if fine_slider(ui, &mut f, 0.0..=30.0, " N", "force") {
                    commands.push(Command::SetForce(f));
                }
                let pose = model.pose();
                let at = pose.point_to_world(p.link, p.point_in_link);
                ui.label(format!(
                    "on {} at ({:.3}, {:.3}, {:.3}) m",
                    model.robot.links[p.link].name, at.x, at.y, at.z
                ));
                if ui.button("Clear push").clicked() {
                    commands.push(Command::ClearPush);
                }
            }
            None => {
                ui.label("none");
            }
        }
        if let Some(p) = model.second_push {
            ui.label("Second push (Shift+click)");
            let mut f = p.force_newtons;
            if fine_slider(ui, &mut f, 0.0..=30.0, " N", "second force") {
                commands.push(Command::SetSecondForce(f));
            }
            let at = model.pose().point_to_world(p.link, p.point_in_link);
            ui.label(format!(
                "on {} at ({:.3}, {:.3}, {:.3}) m",
                model.robot.links.get(p.link).map_or("?", |l| l.name.as_str()),
                at.x,
                at.y,
                at.z
            ));
            if ui.button("Clear second push").clicked() {
                commands.push(Command::ClearSecondPush);
            }
        }
        ui.separator();
        ui.label("Links that can be touched");
        for link in model.robot.default_candidate_links() {
            let mut on = model.candidate_links.contains(&link);
            if ui.checkbox(&mut on, &model.robot.links[link].name).changed() {
                commands.push(Command::SetCandidate(link, on));
            }
        }
        ui.separator();
        let mut seed = model.noise_seed;
        if ui.add(egui::DragValue::new(&mut seed).prefix("noise seed ")).changed() {
            commands.push(Command::SetNoiseSeed(seed));
        }
        let mut noise = model.noise_sigma;
        if fine_slider(ui, &mut noise, 0.0..=0.5, "", "sensor noise σ [N·m]") {
            commands.push(Command::SetNoise(noise));
        }
        commands
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
    let name = super::estimator_panel::label_width(ui, text);
    let width = (ui.available_width() - name - 90.0).max(60.0);
    ui.spacing_mut().slider_width = width;
    let response = ui.add(
        // A typed value is passed on as typed: its command refuses it,
        // naming the valid range, if it lies outside.
        egui::Slider::new(value, range.clone())
            .clamping(egui::SliderClamping::Never)
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
