//! The desktop app (eframe/egui): arrives with the app issue.
