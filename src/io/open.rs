//! Any file a session comes from: a session file (JSON, CSV) or a robot
//! recording (ROS 2 MCAP, ROS 1 bag), opened by its name. The session
//! format and the recordings' readers do not know each other; this is
//! where they meet.

use std::path::Path;

use super::recording::{self, RecordingError, TopicChoice, is_recording};
use super::session::{FrameProblem, Session, SessionError, is_csv};

/// Why a session could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum OpenError {
    /// A session file could not be read.
    #[error(transparent)]
    Session(#[from] SessionError),
    /// A robot recording (MCAP, ROS 1 bag) could not be read.
    #[error(transparent)]
    Recording(#[from] RecordingError),
}

impl Session {
    /// Reads a session: `.csv` as CSV, `.mcap` and `.bag` as a robot
    /// recording (the topics it implies; a torque message that makes no
    /// frame is an error here), anything else as JSON. Frames are checked
    /// (see [`Session::check`]).
    pub fn read(path: &Path) -> Result<Self, OpenError> {
        if !is_recording(path) {
            return Ok(Self::read_file(path)?);
        }
        let (session, problems) = Self::open(path, &TopicChoice::default(), &|_| {})?;
        if let Some(problem) = problems.into_iter().next() {
            return Err(problem.into_error(path).into());
        }
        Ok(session)
    }

    /// Reads a session and skips its bad frames instead of failing: the
    /// session without them, and one report per skipped frame (numbered as
    /// in the file). A file cut short while being recorded is read up to
    /// its last complete frame.
    pub fn read_skipping_bad_frames(path: &Path) -> Result<(Self, Vec<FrameProblem>), OpenError> {
        Self::read_skipping_bad_frames_with_progress(path, &|_| {})
    }

    /// [`Session::read_skipping_bad_frames`], telling `progress` how far it
    /// is (0 to 1).
    pub fn read_skipping_bad_frames_with_progress(
        path: &Path,
        progress: &dyn Fn(f64),
    ) -> Result<(Self, Vec<FrameProblem>), OpenError> {
        Self::open(path, &TopicChoice::default(), progress)
    }

    /// A session file, or a robot recording (`.mcap`, `.bag`) read with
    /// `choice`, skipping bad frames (see
    /// [`Session::read_skipping_bad_frames`]).
    pub fn open(
        path: &Path,
        choice: &TopicChoice,
        progress: &dyn Fn(f64),
    ) -> Result<(Self, Vec<FrameProblem>), OpenError> {
        if is_recording(path) {
            let bytes = recording::read_bytes(path)?;
            progress(0.1);
            let read = recording::read_session(path, &bytes, choice, &|f| progress(0.1 + 0.9 * f))?;
            return Ok((read.session, read.problems));
        }
        Ok(Self::read_file_skipping_bad_frames(path, progress)?)
    }
}

impl Session {
    /// The first frames of a file longer than `max_bytes`, read from its
    /// first `max_bytes` (a preview while the whole file is read): a JSON
    /// session's ([`Session::parse_json_start`]), or a recording's
    /// ([`recording::read_session_start`], with `choice`). `None` where
    /// the file is shorter, is CSV, or its start gives no frame: the whole
    /// read says why.
    #[must_use]
    pub fn open_start(path: &Path, choice: &TopicChoice, max_bytes: usize) -> Option<(Self, Vec<FrameProblem>)> {
        if is_csv(path) {
            return None;
        }
        let bytes = read_start(path, max_bytes)?;
        if !is_recording(path) {
            // The cut may fall inside a character.
            let text = match std::str::from_utf8(&bytes) {
                Ok(text) => text,
                Err(e) => std::str::from_utf8(bytes.get(..e.valid_up_to())?).ok()?,
            };
            return Self::parse_json_start(text, path).map(|session| (session, Vec::new()));
        }
        let read = recording::read_session_start(path, &bytes, choice).ok()?;
        (!read.session.frames.is_empty()).then_some((read.session, read.problems))
    }
}

/// The first `max_bytes` of a file longer than that.
fn read_start(path: &Path, max_bytes: usize) -> Option<Vec<u8>> {
    use std::io::Read;
    let mut bytes = Vec::new();
    std::fs::File::open(path)
        .ok()?
        .take(max_bytes as u64 + 1)
        .read_to_end(&mut bytes)
        .ok()?;
    (bytes.len() > max_bytes).then(|| {
        bytes.truncate(max_bytes);
        bytes
    })
}

/// Whether the file at `path` names no robot (CSV sessions and robot
/// recordings): the robot must come from elsewhere.
#[must_use]
pub fn names_no_robot(path: &Path) -> bool {
    is_csv(path) || is_recording(path)
}
