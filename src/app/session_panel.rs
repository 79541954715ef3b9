//! The session's summary in the side panel: skipped and failed frames,
//! the metrics against the truth, their export.

use std::path::Path;

use super::{ProprioscopeApp, egui};
use crate::core::eval::metrics::Metrics;

/// How one metric is written in the session panel.
type MetricText = fn(&Metrics) -> String;

/// The session panel's metrics, each a name and how it is written.
const METRIC_ROWS: [(&str, MetricText); 7] = [
    ("frames", |m: &Metrics| m.frames.to_string()),
    ("position median / p90 [mm]", |m: &Metrics| {
        format!("{:.1} / {:.1}", m.position_median_m * 1e3, m.position_p90_m * 1e3)
    }),
    ("force median / p90 [N]", |m: &Metrics| {
        format!("{:.2} / {:.2}", m.force_median_newtons, m.force_p90_newtons)
    }),
    ("link right", |m: &Metrics| format!("{:.0} %", m.link_accuracy * 100.0)),
    ("ε_r [mm], ε_F [N]", |m: &Metrics| {
        format!("{:.1}, {:.2}", m.eps_r_m * 1e3, m.eps_f_newtons)
    }),
    ("σ_r [mm]", |m: &Metrics| format!("{:.1}", m.sigma_r_m * 1e3)),
    ("90 % set holds the push", |m: &Metrics| {
        m.credible90_held
            .map_or_else(|| "–".to_owned(), |h| format!("{:.0} %", h * 100.0))
    }),
];

/// Metrics over all frames, and by the number of sensing joints.
pub(super) type SessionMetrics = (
    crate::core::eval::metrics::Metrics,
    Vec<(usize, crate::core::eval::metrics::Metrics)>,
);

impl ProprioscopeApp {
    /// The session's file, skipped frames, progress and metrics, with export.
    pub(super) fn session_summary_ui(&mut self, ui: &mut egui::Ui) {
        let Some(replay) = &self.model.replay else {
            return;
        };
        let session = replay.session.clone();
        ui.separator();
        ui.heading("Session");
        ui.label(format!(
            "{}: {} frames played, {} skipped",
            session
                .path
                .file_name()
                .map(|n| n.to_string_lossy())
                .unwrap_or_default(),
            session.frames.len(),
            session.problems.len()
        ));
        if !session.problems.is_empty() {
            egui::CollapsingHeader::new(format!("Skipped frames ({})", session.problems.len()))
                .default_open(true)
                .show(ui, |ui| {
                    for p in session.problems.iter().take(50) {
                        ui.colored_label(egui::Color32::LIGHT_RED, p.to_string());
                    }
                    if session.problems.len() > 50 {
                        ui.label(format!("… and {} more", session.problems.len() - 50));
                    }
                });
        }
        let failures = &self.session.failures;
        if !failures.is_empty() {
            egui::CollapsingHeader::new(format!("Frames not estimated ({})", failures.len()))
                .default_open(true)
                .show(ui, |ui| {
                    for (frame, why) in failures.iter().take(20) {
                        ui.colored_label(egui::Color32::LIGHT_RED, format!("frame {frame}: {why}"));
                    }
                    if failures.len() > 20 {
                        ui.label(format!("… and {} more", failures.len() - 20));
                    }
                });
        }
        let done = self.session_estimated() + failures.len();
        let total = session.frames.len();
        if done < total {
            ui.label(format!("metrics when every frame is estimated ({done} of {total})"));
            return;
        }
        let Some((all, by_joints)) = self.cached_session_metrics() else {
            ui.label("no frame has a known contact: no errors to report");
            return;
        };
        // The metrics of all frames as a table; by how many joints sense the
        // contact as lines that wrap (a column per group grew the side
        // panel past the window on sessions with contacts on every link).
        let rows = METRIC_ROWS;
        egui::Grid::new("session-metrics").striped(true).show(ui, |ui| {
            ui.label("frames with a contact");
            ui.strong("all");
            ui.end_row();
            for (name, value) in rows {
                ui.label(name);
                ui.label(value(&all));
                ui.end_row();
            }
        });
        if !by_joints.is_empty() {
            egui::CollapsingHeader::new("by the number of joints that sense the contact")
                .default_open(false)
                .show(ui, |ui| {
                    for (joints, m) in &by_joints {
                        ui.label(format!(
                            "{joints} joints: {} frames, position {:.1} / {:.1} mm, force {:.2} / {:.2} N, link right {:.0} %",
                            m.frames,
                            m.position_median_m * 1e3,
                            m.position_p90_m * 1e3,
                            m.force_median_newtons,
                            m.force_p90_newtons,
                            m.link_accuracy * 100.0
                        ));
                    }
                });
        }
        if ui.button("Export metrics as JSON…").clicked()
            && let Some(path) = self.picked(super::files::pick(|| {
                rfd::FileDialog::new().add_filter("JSON", &["json"]).save_file()
            }))
        {
            self.export_metrics(&path);
        }
    }

    /// The metrics of the frames estimated so far, computed again only
    /// when more are (a long session's take milliseconds).
    pub(super) fn cached_session_metrics(&mut self) -> Option<SessionMetrics> {
        let replay = self.model.replay.as_ref()?;
        let key = (self.session.generation, self.session_estimated());
        if self.session.metrics.as_ref().is_none_or(|(k, _)| *k != key) {
            let computed = crate::batch::session_metrics(&self.model.robot, &replay.session, &self.session.estimates);
            self.session.metrics = Some((key, computed));
        }
        self.session.metrics.as_ref().and_then(|(_, m)| m.clone())
    }

    /// Writes the session's metrics as JSON.
    pub fn export_metrics(&mut self, path: &Path) {
        let Some((all, by_joints)) = self.cached_session_metrics() else {
            self.error = Some("no metrics to export: no frame has a known contact and an estimate".to_owned());
            return;
        };
        let Some(replay) = &self.model.replay else {
            return;
        };
        let mut json = crate::batch::metrics_json(&all, &by_joints);
        json["session"] = serde_json::json!(replay.session.path.display().to_string());
        json["skipped_frames"] = serde_json::json!(replay.session.problems.len());
        let result = serde_json::to_string_pretty(&json)
            .map_err(|e| e.to_string())
            .and_then(|text| std::fs::write(path, text).map_err(|e| e.to_string()));
        self.error = result
            .err()
            .map(|e| format!("could not export to {}: {e}", path.display()));
    }
}
