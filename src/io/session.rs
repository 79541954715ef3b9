//! Recorded sessions in the interchange format (`contact-session`,
//! version 1): JSON, or CSV with the robot named elsewhere.

use std::path::{Path, PathBuf};

use rayon::prelude::*;
use serde::{Deserialize, Deserializer};

use crate::core::config::limits;
use crate::io::json_array;

mod live_line;
pub use live_line::{LiveLine, LiveReader, MAX_LIVE_LINE_BYTES};

/// The true contact of a frame, when known.
#[derive(Debug, Clone, PartialEq)]
pub enum Truth {
    /// Not recorded.
    Unknown,
    /// Known: nothing touches the robot.
    NoContact,
    /// Known contact.
    Contact {
        /// Link touched.
        link: String,
        /// Contact point, world frame, m.
        point: [f64; 3],
        /// Force applied to the robot, world frame, N.
        force: [f64; 3],
    },
}

impl Truth {
    /// Whether the frame is known to have a contact (`None`: not recorded).
    #[must_use]
    pub fn has_contact(&self) -> Option<bool> {
        match self {
            Self::Contact { .. } => Some(true),
            Self::NoContact => Some(false),
            Self::Unknown => None,
        }
    }
}

/// One frame of a session.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    /// Time, s.
    pub t: f64,
    /// Sensed joint positions, rad.
    pub q: Vec<f64>,
    /// Measured external torques, N·m.
    pub tau: Vec<f64>,
    /// The true contact.
    pub truth: Truth,
    /// Every true contact, where the session records them all (its
    /// `truth_all`: two probes pressing at once); empty where it does
    /// not, and `truth` is then the only one known.
    pub truth_all: Vec<ContactTruth>,
}

/// One true contact of a frame's `truth_all`.
#[derive(Debug, Clone, PartialEq, Deserialize, serde::Serialize)]
pub struct ContactTruth {
    /// Link touched.
    pub link: String,
    /// Contact point, world frame, m.
    pub point: [f64; 3],
    /// Force applied to the robot, world frame, N.
    pub force: [f64; 3],
}

impl Frame {
    /// Every contact known to press: `truth_all` where recorded, else
    /// `truth`'s (none where it is unknown or says no contact).
    #[must_use]
    pub fn true_contacts(&self) -> Vec<ContactTruth> {
        if !self.truth_all.is_empty() {
            return self.truth_all.clone();
        }
        match &self.truth {
            Truth::Contact { link, point, force } => vec![ContactTruth {
                link: link.clone(),
                point: *point,
                force: *force,
            }],
            Truth::Unknown | Truth::NoContact => Vec::new(),
        }
    }

    /// The frame as the JSON form writes it (`truth` absent when unknown,
    /// `null` without contact; `truth_all` where recorded).
    #[must_use]
    pub fn to_json(&self) -> serde_json::Value {
        let mut value = serde_json::json!({ "t": self.t, "q": self.q, "tau": self.tau });
        if !self.truth_all.is_empty() {
            value["truth_all"] = serde_json::json!(self.truth_all);
        }
        match &self.truth {
            Truth::Unknown => {}
            Truth::NoContact => value["truth"] = serde_json::Value::Null,
            Truth::Contact { link, point, force } => {
                value["truth"] = serde_json::json!({ "link": link, "point": point, "force": force });
            }
        }
        value
    }
}

/// A recorded session.
#[derive(Debug, Clone, PartialEq)]
pub struct Session {
    /// The file it came from.
    pub path: PathBuf,
    /// The robot as the file names it (URDF path relative to the file, or a
    /// built-in name); CSV files name none.
    pub robot: Option<String>,
    /// Sensed joint names in column order, when given.
    pub joints: Option<Vec<String>>,
    /// The frames, in file order.
    pub frames: Vec<Frame>,
}

/// Why a session could not be read.
#[derive(Debug, thiserror::Error)]
pub enum SessionError {
    /// The file could not be read.
    #[error("{path}: cannot read the session: {cause}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        cause: std::io::Error,
    },
    /// The file could not be written.
    #[error("{path}: cannot write the session: {cause}")]
    Write {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        cause: std::io::Error,
    },
    /// Malformed JSON or CSV.
    #[error("{path}:{line}: {message}")]
    Parse {
        /// The file.
        path: PathBuf,
        /// Line (1-based).
        line: usize,
        /// What is wrong.
        message: String,
    },
    /// A header field is wrong.
    #[error("{path}: field '{field}': {message}")]
    Header {
        /// The file.
        path: PathBuf,
        /// The field.
        field: String,
        /// What is wrong.
        message: String,
    },
    /// A frame is wrong.
    #[error("{path}: frame {frame} ({}): {field}: {message}", at_time(*.t))]
    Frame {
        /// The file.
        path: PathBuf,
        /// Frame index (0-based).
        frame: usize,
        /// Its time stamp.
        t: f64,
        /// The field (`tau[3]`, `q`, `t`).
        field: String,
        /// What is wrong.
        message: String,
    },
}

/// The file's header, its frames left as text: each frame is read on its
/// own, so that one that is not a frame keeps its place (and the check
/// names it) without a tree of JSON values built for every frame (that
/// tree took two thirds of the time to read a long recording).
#[derive(Deserialize)]
struct SessionFile<'a> {
    format: String,
    version: u32,
    robot: String,
    #[serde(default)]
    joints: Option<Vec<String>>,
    #[serde(borrow)]
    frames: Vec<&'a serde_json::value::RawValue>,
}

impl From<FrameFile> for Frame {
    fn from(f: FrameFile) -> Self {
        Self {
            t: f.t,
            q: f.q,
            tau: f.tau,
            truth: match f.truth {
                TruthField::Absent => Truth::Unknown,
                TruthField::Null => Truth::NoContact,
                TruthField::Contact(t) => Truth::Contact {
                    link: t.link,
                    point: t.point,
                    force: t.force,
                },
            },
            truth_all: f.truth_all.unwrap_or_default(),
        }
    }
}

/// A frame from its JSON text; `None` when the text is not JSON. A
/// value that is not a frame (a string, a wrong truth) keeps its place as
/// a frame with no values, so that the check names it.
fn frame_from_text(text: &str) -> Option<Frame> {
    match serde_json::from_str::<FrameFile>(text) {
        Ok(f) => Some(Frame::from(f)),
        // A wrong value can stop the parse before a syntax error does.
        Err(e) if e.is_data() && serde_json::from_str::<serde::de::IgnoredAny>(text).is_ok() => Some(not_a_frame()),
        Err(_) => None,
    }
}

/// A frame with no values, in the place of a value that is not a frame.
fn not_a_frame() -> Frame {
    Frame::from(FrameFile {
        t: f64::NAN,
        q: Vec::new(),
        tau: Vec::new(),
        truth: TruthField::Absent,
        truth_all: None,
    })
}

#[derive(Deserialize)]
struct FrameFile {
    #[serde(default = "not_a_number")]
    t: f64,
    // A missing array or a `null` value is read as missing values (NaN), so
    // that the frame is reported by [`Session::check`] with its number and
    // field rather than failing the whole file.
    #[serde(default, deserialize_with = "numbers_or_null")]
    q: Vec<f64>,
    #[serde(default, deserialize_with = "numbers_or_null")]
    tau: Vec<f64>,
    #[serde(default)]
    truth: TruthField,
    // Extra keys of a listed contact (a probe's number) are ignored.
    #[serde(default)]
    truth_all: Option<Vec<ContactTruth>>,
}

fn not_a_number() -> f64 {
    f64::NAN
}

fn numbers_or_null<'de, D: Deserializer<'de>>(d: D) -> Result<Vec<f64>, D::Error> {
    Ok(Vec::<Option<f64>>::deserialize(d)?
        .into_iter()
        .map(|v| v.unwrap_or(f64::NAN))
        .collect())
}

/// A frame's `truth` as written: absent, `null`, or a contact.
#[derive(Default)]
enum TruthField {
    #[default]
    Absent,
    Null,
    Contact(TruthFile),
}

impl<'de> Deserialize<'de> for TruthField {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        // Called only when the field is present.
        Ok(Option::<TruthFile>::deserialize(d)?.map_or(Self::Null, Self::Contact))
    }
}

#[derive(Deserialize)]
struct TruthFile {
    link: String,
    point: [f64; 3],
    force: [f64; 3],
}

impl Session {
    /// Reads a session file (`.csv` as CSV, anything else as JSON; a robot
    /// recording is read by [`Session::read`]). Frames are checked (see
    /// [`Session::check`]).
    pub fn read_file(path: &Path) -> Result<Self, SessionError> {
        let text = std::fs::read_to_string(path).map_err(|cause| SessionError::Read {
            path: path.to_owned(),
            cause,
        })?;
        let session = if is_csv(path) {
            Self::parse_csv(&text, path)?
        } else {
            Self::parse_json(&text, path)?
        };
        session.check()?;
        Ok(session)
    }

    /// The session of the start of a JSON text cut anywhere: the fields
    /// before its frames and the frames that end before the cut. `None`
    /// where that gives no frame, or one that fails the checks. (The
    /// fuzz target `session_json` checks that the frames of any cut of a
    /// session are its first frames.)
    #[must_use]
    pub fn parse_json_start(text: &str, path: &Path) -> Option<Self> {
        Self::from_split(json_array::split_array_field_start(text, "frames")?, path)?
            .ok()
            .filter(|session| !session.frames.is_empty() && session.check().is_ok())
    }

    /// The session of a text split at its frames, which are parsed in
    /// parallel; `None` where its fields around them or a frame are not
    /// JSON.
    fn from_split(split: json_array::Split<'_>, path: &Path) -> Option<Result<Self, SessionError>> {
        let file = serde_json::from_str::<SessionFile>(&split.rest).ok()?;
        let frames = split
            .elements
            .into_par_iter()
            .map(frame_from_text)
            .collect::<Option<Vec<Frame>>>()?;
        Some(Self::from_file(file, frames, path))
    }

    /// Parses the JSON form.
    pub fn parse_json(text: &str, path: &Path) -> Result<Self, SessionError> {
        // The frames found first and parsed in parallel; a text the split
        // does not take, or a frame that is not JSON, is parsed whole,
        // whose error names the line.
        json_array::split_array_field(text, "frames")
            .and_then(|split| Self::from_split(split, path))
            .unwrap_or_else(|| Self::parse_json_whole(text, path))
    }

    /// Parses the JSON form in one pass of `serde_json` (what
    /// [`Session::parse_json`] falls back on; the fuzz target checks
    /// that both read every text alike).
    pub fn parse_json_whole(text: &str, path: &Path) -> Result<Self, SessionError> {
        let file: SessionFile = serde_json::from_str(text).map_err(|e| {
            let mut message = e.to_string();
            if let Some(i) = message.rfind(" at line ") {
                message.truncate(i);
            }
            SessionError::Parse {
                path: path.to_owned(),
                line: e.line(),
                message,
            }
        })?;
        // Each frame's text is read on its own, so the frames are read in
        // parallel (in order); the whole text was JSON.
        let frames = file
            .frames
            .par_iter()
            .map(|raw| frame_from_text(raw.get()).unwrap_or_else(not_a_frame))
            .collect();
        Self::from_file(file, frames, path)
    }

    /// The session of a parsed file's header and frames.
    fn from_file(file: SessionFile, frames: Vec<Frame>, path: &Path) -> Result<Self, SessionError> {
        let header = |field: &str, message: String| SessionError::Header {
            path: path.to_owned(),
            field: field.to_owned(),
            message,
        };
        if file.format != "contact-session" {
            return Err(header(
                "format",
                format!("'{}' is not \"contact-session\"", file.format),
            ));
        }
        if file.version != 1 {
            return Err(header(
                "version",
                format!("{} is not supported (this program reads version 1)", file.version),
            ));
        }
        Ok(Self {
            path: path.to_owned(),
            robot: Some(file.robot),
            joints: file.joints,
            frames,
        })
    }

    /// Parses the CSV form:
    /// `t,q1..qn,tau1..taun[,link,px,py,pz,fx,fy,fz[,link2,px2,py2,pz2,fx2,fy2,fz2]]`.
    /// An empty `link` in a file with truth columns means no contact; a
    /// second contact's columns, where its `link2` is given, make the
    /// frame's `truth_all` both contacts.
    pub fn parse_csv(text: &str, path: &Path) -> Result<Self, SessionError> {
        let parse = |line: usize, message: String| SessionError::Parse {
            path: path.to_owned(),
            line,
            message,
        };
        let mut lines = text.lines().enumerate().filter(|(_, l)| !l.trim().is_empty());
        let Some((_, header)) = lines.next() else {
            return Err(parse(1, "empty file: expected a header t,q1,...,tau1,...".to_owned()));
        };
        let columns: Vec<&str> = header.split(',').map(str::trim).collect();
        let n = columns.iter().filter(|c| c.starts_with('q')).count();
        let truth_columns = ["link", "px", "py", "pz", "fx", "fy", "fz"];
        let has_second = columns.len() == 1 + 2 * n + 14;
        let has_truth = has_second || columns.len() == 1 + 2 * n + 7;
        let mut expected: Vec<String> = vec!["t".to_owned()];
        expected.extend((1..=n).map(|i| format!("q{i}")));
        expected.extend((1..=n).map(|i| format!("tau{i}")));
        if has_truth {
            expected.extend(truth_columns.iter().map(|s| (*s).to_owned()));
        }
        if has_second {
            expected.extend(truth_columns.iter().map(|s| format!("{s}2")));
        }
        if n == 0 || columns != expected {
            return Err(parse(
                1,
                format!(
                    "header '{header}' is not 't,q1..qn,tau1..taun[,link,px,py,pz,fx,fy,fz[,link2,px2,py2,pz2,fx2,fy2,fz2]]'"
                ),
            ));
        }
        let truth_width = columns.len() - (1 + 2 * n);
        // A row with a value that is not a number, or with too few or too
        // many values, stays a frame (NaN where unreadable, its values
        // counted as given) so that the check names it by frame and field.
        let number = |cell: Option<&&str>| cell.and_then(|c| c.parse::<f64>().ok()).unwrap_or(f64::NAN);
        let mut frames = Vec::new();
        for (_, line) in lines {
            let cells: Vec<&str> = line.split(',').map(str::trim).collect();
            let t = number(cells.first());
            let q: Vec<f64> = (1..=n).map(|k| number(cells.get(k))).collect();
            let values_given = cells.len().saturating_sub(1 + n);
            let tau_given = if cells.len() == columns.len() {
                n
            } else if has_truth {
                values_given.saturating_sub(truth_width)
            } else {
                values_given
            };
            let tau: Vec<f64> = (n + 1..n + 1 + tau_given).map(|k| number(cells.get(k))).collect();
            // The contact whose `link` column is `at`, if one is given.
            let contact_at = |at: usize| -> Option<ContactTruth> {
                let link = cells.get(at).filter(|c| !c.is_empty())?;
                let v: [f64; 6] = std::array::from_fn(|k| number(cells.get(at + 1 + k)));
                Some(ContactTruth {
                    link: (*link).to_owned(),
                    point: [v[0], v[1], v[2]],
                    force: [v[3], v[4], v[5]],
                })
            };
            let complete = has_truth && cells.len() == columns.len();
            let first = complete.then(|| contact_at(1 + 2 * n)).flatten();
            let second = (complete && has_second).then(|| contact_at(1 + 2 * n + 7)).flatten();
            let truth = match (&first, complete) {
                (_, false) => Truth::Unknown,
                (None, true) => Truth::NoContact,
                (Some(c), true) => Truth::Contact {
                    link: c.link.clone(),
                    point: c.point,
                    force: c.force,
                },
            };
            let truth_all = match (first, second) {
                (Some(a), Some(b)) => vec![a, b],
                _ => Vec::new(),
            };
            frames.push(Frame {
                t,
                q,
                tau,
                truth,
                truth_all,
            });
        }
        Ok(Self {
            path: path.to_owned(),
            robot: None,
            joints: None,
            frames,
        })
    }

    /// Every frame has finite values, `q` and `tau` of one length (the
    /// number of `joints` when given), and times that do not go backwards;
    /// the first frame that does not is the error.
    pub fn check(&self) -> Result<(), SessionError> {
        match self.problems().into_iter().next() {
            Some(problem) => Err(problem.into_error(&self.path)),
            None => Ok(()),
        }
    }

    /// Every frame that breaks the rules of [`Session::check`], one report
    /// each (a frame's time is compared with the last good frame's).
    #[must_use]
    pub fn problems(&self) -> Vec<FrameProblem> {
        let width = self.joints.as_ref().map(Vec::len).or_else(|| {
            // Without names, the width most frames have.
            let mut counts: std::collections::BTreeMap<usize, usize> = std::collections::BTreeMap::new();
            for f in &self.frames {
                *counts.entry(f.q.len()).or_default() += 1;
            }
            counts
                .into_iter()
                .max_by_key(|&(width, count)| (count, width))
                .map(|(w, _)| w)
        });
        let mut last_t = f64::NEG_INFINITY;
        let mut out = Vec::new();
        for (i, f) in self.frames.iter().enumerate() {
            let problem = frame_problem(f, width, last_t);
            match problem {
                Some((field, message)) => out.push(FrameProblem {
                    frame: i,
                    t: f.t,
                    field,
                    message,
                }),
                None => last_t = f.t,
            }
        }
        out
    }

    /// Drops the frames that break the rules and returns their reports;
    /// the other frames keep their order.
    pub fn remove_bad_frames(&mut self) -> Vec<FrameProblem> {
        let problems = self.problems();
        let mut bad = problems.iter().map(|p| p.frame).peekable();
        let mut index = 0;
        self.frames.retain(|_| {
            let keep = bad.next_if_eq(&index).is_none();
            index += 1;
            keep
        });
        problems
    }

    /// A session file (JSON, CSV) skipping bad frames (see
    /// [`Session::read_skipping_bad_frames`]), telling `progress` how far
    /// it is (0 to 1: reading the file to 0.3, then parsing and checking it).
    pub fn read_file_skipping_bad_frames(
        path: &Path,
        progress: &dyn Fn(f64),
    ) -> Result<(Self, Vec<FrameProblem>), SessionError> {
        use std::io::Read as _;
        let read_error = |cause| SessionError::Read {
            path: path.to_owned(),
            cause,
        };
        let mut file = std::fs::File::open(path).map_err(read_error)?;
        let total = file.metadata().map_or(0, |m| m.len()).max(1);
        let mut bytes = Vec::with_capacity(usize::try_from(total).unwrap_or(0));
        let mut chunk = vec![0u8; 1 << 20];
        loop {
            let n = file.read(&mut chunk).map_err(read_error)?;
            if n == 0 {
                break;
            }
            bytes.extend_from_slice(chunk.get(..n).unwrap_or_default());
            progress(0.3 * bytes.len() as f64 / total as f64);
        }
        let text = String::from_utf8(bytes)
            .map_err(|e| read_error(std::io::Error::new(std::io::ErrorKind::InvalidData, e)))?;
        progress(0.3);
        let result = Self::parse_skipping_bad_frames(&text, path);
        progress(1.0);
        result
    }

    /// [`Session::read_skipping_bad_frames`] of a file's text (`path`
    /// names it in errors and says whether it is CSV).
    pub fn parse_skipping_bad_frames(text: &str, path: &Path) -> Result<(Self, Vec<FrameProblem>), SessionError> {
        let mut session = if is_csv(path) {
            Self::parse_csv(text, path)?
        } else {
            match Self::parse_json(text, path) {
                Err(e) => match close_cut_recording(text) {
                    Some(closed) => Self::parse_json(&closed, path)?,
                    None => return Err(e),
                },
                ok => ok?,
            }
        };
        let problems = session.remove_bad_frames();
        Ok((session, problems))
    }
}

/// The file's frame number of each of the `kept` frames left after
/// skipping those in `problems`.
#[must_use]
pub fn kept_frame_numbers(kept: usize, problems: &[FrameProblem]) -> Vec<usize> {
    let bad: std::collections::BTreeSet<usize> = problems.iter().map(|p| p.frame).collect();
    (0..kept + problems.len()).filter(|i| !bad.contains(i)).collect()
}

/// Whether `path` names a CSV file (the form that names no robot).
#[must_use]
pub fn is_csv(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("csv"))
}

/// What is wrong with one frame, if anything.
pub(crate) fn frame_problem(f: &Frame, width: Option<usize>, last_t: f64) -> Option<(String, String)> {
    if !f.t.is_finite() {
        return Some(("t".to_owned(), "is missing or not finite".to_owned()));
    }
    if f.t < last_t {
        return Some(("t".to_owned(), format!("goes backwards from {last_t}")));
    }
    for (name, values) in [("q", &f.q), ("tau", &f.tau)] {
        if let Some(w) = width
            && values.len() != w
        {
            return Some((
                name.to_owned(),
                format!("{} values, expected {w} (one per joint)", values.len()),
            ));
        }
        if let Some((j, v)) = values.iter().enumerate().find(|(_, v)| !v.is_finite()) {
            return Some((format!("{name}[{j}]"), format!("{v} is missing or not finite")));
        }
        let range = if name == "q" {
            &limits::JOINT_POSITION
        } else {
            &limits::TORQUE
        };
        if let Some((j, e)) = values
            .iter()
            .enumerate()
            .find_map(|(j, &v)| Some((j, range.check(v).err()?)))
        {
            return Some((format!("{name}[{j}]"), e.to_string()));
        }
    }
    if let Truth::Contact { point, force, .. } = &f.truth {
        if point.iter().chain(force).any(|v| !v.is_finite()) {
            return Some(("truth".to_owned(), "point or force is not finite".to_owned()));
        }
        // Beyond these the errors against them overflow (they printed inf).
        if point.iter().any(|v| v.abs() > MAX_TRUTH_POINT_M) || force.iter().any(|v| v.abs() > MAX_TRUTH_FORCE_N) {
            return Some((
                "truth".to_owned(),
                format!("point {point:?} or force {force:?} beyond {MAX_TRUTH_POINT_M} m or {MAX_TRUTH_FORCE_N} N"),
            ));
        }
    }
    None
}

/// The farthest a true contact point may be from the base, m.
pub const MAX_TRUTH_POINT_M: f64 = limits::COORDINATE.max;

/// The largest component of a true contact force, N.
pub const MAX_TRUTH_FORCE_N: f64 = limits::FORCE_COMPONENT.max;

/// A recording cut short (the program was killed while writing it): its
/// header and every complete frame line, closed. `None` when the text is
/// not such a recording.
fn close_cut_recording(text: &str) -> Option<String> {
    // The recorder writes the header on the first line and one frame per
    // line after it; only the last line can be incomplete.
    let lines: Vec<&str> = text.lines().collect();
    let first = lines.first()?;
    if !first.trim_end().ends_with("\"frames\":[") {
        return None;
    }
    // Only the last line can be incomplete (and a blank one after it): a
    // bounded number of tries, not one parse of the file per line.
    for keep in (lines.len().saturating_sub(2).max(1)..=lines.len()).rev() {
        let Some(kept) = lines.get(..keep) else {
            continue;
        };
        let candidate = format!("{}\n]}}\n", kept.join("\n"));
        if serde_json::from_str::<serde_json::Value>(&candidate).is_ok() {
            return Some(candidate);
        }
    }
    None
}

/// Writes a session while it happens, in the JSON form: the header on the
/// first line, then one frame a line, each flushed to the operating system
/// as it is written, so that a program killed mid-session loses no frame
/// it has written (its file reads back with
/// [`Session::read_skipping_bad_frames`]). [`Recorder::finish`] closes the
/// JSON.
#[derive(Debug)]
pub struct Recorder {
    out: std::io::BufWriter<std::fs::File>,
    path: PathBuf,
    frames: usize,
}

impl Recorder {
    /// Creates (or truncates) `path` and writes the header: the robot as a
    /// session names it and the sensed joints' names in column order.
    pub fn create(path: &Path, robot: &str, joints: &[String]) -> Result<Self, SessionError> {
        let write_error = |cause| SessionError::Write {
            path: path.to_owned(),
            cause,
        };
        let file = std::fs::File::create(path).map_err(write_error)?;
        let mut recorder = Self {
            out: std::io::BufWriter::new(file),
            path: path.to_owned(),
            frames: 0,
        };
        let header = serde_json::json!({
            "format": "contact-session",
            "version": 1,
            "robot": robot,
            "joints": joints,
            "recorded_by": "proprioscope",
        });
        // The header object without its closing brace, then the frames.
        let text = header.to_string();
        let open = text.strip_suffix('}').unwrap_or(&text);
        recorder.write_line(&format!("{open},\"frames\":["))?;
        Ok(recorder)
    }

    /// Appends a frame and hands it to the operating system.
    pub fn write(&mut self, frame: &Frame) -> Result<(), SessionError> {
        let value = frame.to_json();
        let separator = if self.frames == 0 { "" } else { "," };
        self.write_line(&format!("{separator}{value}"))?;
        self.frames += 1;
        Ok(())
    }

    /// Frames written so far.
    #[must_use]
    pub fn frames(&self) -> usize {
        self.frames
    }

    /// The file being written.
    #[must_use]
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Closes the JSON; returns the number of frames.
    pub fn finish(mut self) -> Result<usize, SessionError> {
        self.write_line("]}")?;
        Ok(self.frames)
    }

    fn write_line(&mut self, line: &str) -> Result<(), SessionError> {
        use std::io::Write as _;
        writeln!(self.out, "{line}")
            .and_then(|()| self.out.flush())
            .map_err(|cause| SessionError::Write {
                path: self.path.clone(),
                cause,
            })
    }
}

/// A frame that breaks the rules of the format.
#[derive(Debug, Clone, PartialEq)]
pub struct FrameProblem {
    /// Frame number in the file (0-based).
    pub frame: usize,
    /// Its time stamp (NaN when unreadable).
    pub t: f64,
    /// The field (`t`, `q`, `tau[3]`, `truth`).
    pub field: String,
    /// What is wrong.
    pub message: String,
}

impl FrameProblem {
    /// As an error of the file at `path`.
    #[must_use]
    pub fn into_error(self, path: &Path) -> SessionError {
        SessionError::Frame {
            path: path.to_owned(),
            frame: self.frame,
            t: self.t,
            field: self.field,
            message: self.message,
        }
    }
}

impl std::fmt::Display for FrameProblem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "frame {} ({}): {}: {}",
            self.frame,
            at_time(self.t),
            self.field,
            self.message
        )
    }
}

/// `t = 1.5` for a frame's time, or what stands in for a time it lacks.
fn at_time(t: f64) -> String {
    if t.is_finite() {
        format!("t = {t}")
    } else {
        "no time".to_owned()
    }
}

#[cfg(test)]
#[path = "session_tests.rs"]
mod tests;
