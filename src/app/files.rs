//! File dialogs, and what the app says where none can be shown (on Linux
//! the dialogs come from a desktop portal, which a bare window manager or
//! a remote session may lack: the dialog call then returns at once).

use std::path::PathBuf;
use std::time::{Duration, Instant};

/// Files' part: the path typed under Scenes → Open path, the package
/// folders, the recorder, and whether the user chose the robot.
#[derive(Default)]
pub struct Files {
    /// The path typed under Scenes → Open path.
    pub(crate) path_input: String,
    /// The interactive mode being recorded.
    pub(crate) recording: Option<super::recorder::Recording>,
    /// Folders for `package://` URIs when opening URDFs and sessions.
    pub package_paths: Vec<std::path::PathBuf>,
    /// The robot was chosen by the user (a scene, URDF or name), not the
    /// default one: sessions that name no robot are shown on it.
    pub robot_chosen: bool,
}

/// What a file dialog gave.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Picked {
    /// A path.
    Path(PathBuf),
    /// The user closed the dialog.
    Cancelled,
    /// No dialog appeared: it returned nothing faster than a person can.
    Unavailable,
}

/// A dialog that returns nothing within this time was never shown.
const FASTEST_CANCEL: Duration = Duration::from_millis(250);

/// What the app shows when no dialog can be shown.
pub const NO_DIALOG: &str = "no file dialog could be shown (on Linux it needs a desktop portal, \
     e.g. xdg-desktop-portal-gtk): type the path under Scenes > Open path, or give it on the \
     command line: proprioscope view FILE";

/// Runs a dialog and tells a cancel from a dialog that never appeared.
pub fn pick(dialog: impl FnOnce() -> Option<PathBuf>) -> Picked {
    let started = Instant::now();
    match dialog() {
        Some(path) => Picked::Path(path),
        None if started.elapsed() < FASTEST_CANCEL => Picked::Unavailable,
        None => Picked::Cancelled,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_dialog_that_returns_nothing_at_once_was_not_shown() {
        assert_eq!(pick(|| None), Picked::Unavailable);
        assert_eq!(pick(|| Some(PathBuf::from("a.json"))), Picked::Path("a.json".into()));
        let slow = pick(|| {
            std::thread::sleep(FASTEST_CANCEL + Duration::from_millis(20));
            None
        });
        assert_eq!(slow, Picked::Cancelled);
    }
}
