//! The dialog that asks which topics of a recording make its frames.

use super::{ProprioscopeApp, egui};

/// The recordings' topics: the prompt shown, the choice made per
/// recording and the last one (tried first on the next recording).
#[derive(Debug, Default)]
pub struct TopicPrompts {
    /// A recording whose topics the user is asked to choose.
    pub prompt: Option<crate::batch::TopicPrompt>,
    pub(crate) choices: std::collections::HashMap<std::path::PathBuf, crate::io::recording::TopicChoice>,
    pub(crate) last: Option<crate::io::recording::TopicChoice>,
}

impl ProprioscopeApp {
    /// The topics dialog (see [`TopicPrompts::ui`]); a recording whose
    /// topics were chosen opens with them.
    pub(super) fn topic_prompt_ui(&mut self, ctx: &egui::Context) {
        if let Some(prompt) = self.topics.ui(ctx) {
            self.open_session(&prompt.path, prompt.robot);
        }
    }
}

impl TopicPrompts {
    /// The dialog that asks which topics of a recording make its frames
    /// (shown when the file leaves several choices). The recording to
    /// open once they are chosen (the choice remembered for it and tried
    /// first on the next); a cancelled prompt is dropped.
    pub(crate) fn ui(&mut self, ctx: &egui::Context) -> Option<crate::batch::TopicPrompt> {
        let prompt = self.prompt.as_mut()?;
        let mut decided = None;
        egui::Window::new("Recording topics")
            .collapsible(false)
            .resizable(false)
            .anchor(egui::Align2::CENTER_CENTER, [0.0, 0.0])
            .show(ctx, |ui| {
                ui.label(format!(
                    "Which topics make the frames of {}?",
                    prompt
                        .path
                        .file_name()
                        .map_or_else(String::new, |n| n.to_string_lossy().into_owned())
                ));
                ui.label(egui::RichText::new(&prompt.message).weak());
                ui.separator();
                let q = prompt.choice.q_topic.clone().unwrap_or_default();
                egui::ComboBox::from_label("joint positions (JointState)")
                    .selected_text(q)
                    .show_ui(ui, |ui| {
                        for topic in &prompt.position_topics {
                            ui.selectable_value(&mut prompt.choice.q_topic, Some(topic.clone()), topic);
                        }
                    });
                let tau = format!(
                    "{} {}",
                    prompt.choice.tau_topic.clone().unwrap_or_default(),
                    prompt.choice.tau_field.clone().unwrap_or_default()
                );
                egui::ComboBox::from_label("external torques (topic, field)")
                    .selected_text(tau)
                    .show_ui(ui, |ui| {
                        for (topic, field) in &prompt.torque_sources {
                            let selected = prompt.choice.tau_topic.as_ref() == Some(topic)
                                && prompt.choice.tau_field.as_ref() == Some(field);
                            if ui.selectable_label(selected, format!("{topic} {field}")).clicked() {
                                prompt.choice.tau_topic = Some(topic.clone());
                                prompt.choice.tau_field = Some(field.clone());
                            }
                        }
                    });
                ui.horizontal(|ui| {
                    if ui.button("Open").clicked() {
                        decided = Some(true);
                    }
                    if ui.button("Cancel").clicked() {
                        decided = Some(false);
                    }
                });
            });
        match decided {
            Some(true) => {
                let prompt = self.prompt.take()?;
                self.choices.insert(prompt.path.clone(), prompt.choice.clone());
                self.last = Some(prompt.choice.clone());
                Some(prompt)
            }
            Some(false) => {
                self.prompt = None;
                None
            }
            None => None,
        }
    }
}
