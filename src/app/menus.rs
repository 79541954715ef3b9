//! The menu bar: Scenes, Session, View, Robot, and the last error.

use super::{ProprioscopeApp, egui, files, shipped_scenes};

impl ProprioscopeApp {
    pub(super) fn menu_ui(&mut self, ui: &mut egui::Ui) {
        egui::MenuBar::new().ui(ui, |ui| {
            ui.menu_button("Scenes", |ui| {
                if ui.button("Open scene or URDF…").clicked() {
                    ui.close();
                    if let Some(path) = self.picked(files::pick(|| {
                        rfd::FileDialog::new()
                            .add_filter("scene or URDF", &["json", "urdf"])
                            .pick_file()
                    })) {
                        self.open(&path.display().to_string());
                    }
                }
                if ui
                    .button("Add package folder…")
                    .on_hover_text("a folder where package:// mesh URIs of URDFs are looked up")
                    .clicked()
                {
                    ui.close();
                    if let Some(folder) = self.picked(files::pick(|| rfd::FileDialog::new().pick_folder())) {
                        self.files.package_paths.push(folder);
                    }
                }
                if ui.button("Save scene…").clicked() {
                    ui.close();
                    if let Some(path) = self.picked(files::pick(|| {
                        rfd::FileDialog::new().add_filter("scene", &["json"]).save_file()
                    })) {
                        self.save(&path);
                    }
                }
                ui.horizontal(|ui| {
                    ui.add(
                        egui::TextEdit::singleline(&mut self.files.path_input)
                            .hint_text("path of a scene, URDF, session or recording")
                            .desired_width(220.0),
                    );
                    if ui.button("Open path").clicked() {
                        ui.close();
                        let path = self.files.path_input.trim().to_owned();
                        if !path.is_empty() {
                            self.open(&path);
                        }
                    }
                });
                ui.separator();
                for path in shipped_scenes() {
                    let name = path
                        .file_stem()
                        .map(|s| s.to_string_lossy().into_owned())
                        .unwrap_or_default();
                    if ui.button(name).clicked() {
                        ui.close();
                        self.open(&path.display().to_string());
                    }
                }
            });
            self.session_menu_ui(ui);
            ui.menu_button("View", |ui| {
                ui.checkbox(&mut self.panels.robot, "Robot panel");
                ui.checkbox(&mut self.panels.estimator, "Estimator panel");
                if ui.button("Fit the robot in view (R)").clicked() {
                    ui.close();
                    self.view.fit_pending = true;
                }
            });
            ui.menu_button("Robot", |ui| {
                for name in crate::core::robot::builtin::BUILTIN_NAMES {
                    if ui.button(name).clicked() {
                        ui.close();
                        self.open(name);
                    }
                }
            });
            if let Some(error) = &self.error {
                ui.colored_label(egui::Color32::LIGHT_RED, error);
            }
            if let Some(refused) = &self.model.refused {
                ui.colored_label(egui::Color32::LIGHT_RED, format!("not applied: {refused}"));
            }
        });
    }

    /// The Session menu.
    pub(super) fn session_menu_ui(&mut self, ui: &mut egui::Ui) {
        ui.menu_button("Session", |ui| {
            if ui.button("Open session…").clicked() {
                ui.close();
                if let Some(path) = self.picked(super::files::pick(|| {
                    rfd::FileDialog::new()
                        .add_filter("session or recording", &["json", "csv", "mcap", "bag"])
                        .pick_file()
                })) {
                    self.open_session(&path, None);
                }
            }
            ui.horizontal(|ui| {
                ui.add(egui::TextEdit::singleline(&mut self.live.address_input).desired_width(160.0));
                if self.live.view.is_none() && ui.button("Listen live").on_hover_text("frames as JSON lines over TCP (host:port) or UDP (udp://host:port), e.g. from `proprioscope stream`").clicked() {
                    ui.close();
                    let address = self.live.address_input.clone();
                    self.start_live(&address);
                }
            });
            if self.model.replay.is_some() && ui.button("Close session").clicked() {
                ui.close();
                self.close_session();
            }
            ui.separator();
            if self.files.recording.is_some() {
                if ui.button("Stop recording").clicked() {
                    ui.close();
                    self.stop_recording();
                }
            } else if ui.button("Record…").clicked() {
                ui.close();
                if let Some(path) = self.picked(super::files::pick(|| {
                    rfd::FileDialog::new()
                        .add_filter("session", &["json"])
                        .set_file_name("recording.session.json")
                        .save_file()
                })) {
                    self.start_recording(&path);
                }
            }
        });
        if let Some(frames) = self.recorded_frames() {
            ui.colored_label(egui::Color32::from_rgb(230, 70, 70), format!("REC {frames} frames"));
        }
        if let Some(loader) = &self.session.loader {
            // While a preview is shown, the bar says how much of it there is.
            let shown = self
                .model
                .replay
                .as_ref()
                .filter(|_| self.session.previewing)
                .and_then(|r| Some(r.session.frames.last()?.t - r.session.frames.first()?.t))
                .map(|secs| format!(", its first {secs:.1} s shown"))
                .unwrap_or_default();
            ui.add(egui::Spinner::new());
            ui.add(
                egui::ProgressBar::new(loader.progress() as f32)
                    .desired_width(360.0)
                    .text(format!(
                        "loading {}{shown} ({:.0} s)",
                        loader.path.file_name().map(|n| n.to_string_lossy()).unwrap_or_default(),
                        loader.started.elapsed().as_secs_f64()
                    )),
            );
            // The bar moves while nothing else asks for a frame.
            ui.ctx().request_repaint_after(std::time::Duration::from_millis(100));
        }
    }
}
