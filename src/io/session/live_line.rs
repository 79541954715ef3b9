//! One line of a live stream at a time: a header or a frame in the
//! session format, checked as a session's frames are ([`LiveReader`]).

use super::{Frame, FrameFile, FrameProblem, frame_problem};

/// One line of a live stream (see [`LiveReader`]).
#[derive(Debug, Clone, PartialEq)]
pub enum LiveLine {
    /// The header: the robot as the source names it and the sensed joints'
    /// names in column order (either may be absent).
    Header {
        /// The robot.
        robot: Option<String>,
        /// Column names.
        joints: Vec<String>,
    },
    /// A frame that passed the checks.
    Frame(Frame),
    /// A line that is not a good header or frame: what is wrong.
    Bad(FrameProblem),
}

/// Longest line a live stream may send, bytes (a frame of a 100-joint
/// robot is a few kilobytes).
pub const MAX_LIVE_LINE_BYTES: usize = 1 << 20;

/// Reads a live stream: JSON lines in the session format, an optional
/// header object (`{"format": "contact-session", "version": 1, "robot":
/// …, "joints": […]}`) and one frame object per line. Each frame is
/// checked as a session's are (time going forwards, one value per joint,
/// all finite); a bad line is reported, never fatal.
#[derive(Debug, Clone, Default)]
pub struct LiveReader {
    width: Option<usize>,
    last_t: Option<f64>,
    lines: usize,
}

impl LiveReader {
    /// A reader expecting `width` values per frame (`None`: the first
    /// frame's count).
    #[must_use]
    pub fn new(width: Option<usize>) -> Self {
        Self {
            width,
            last_t: None,
            lines: 0,
        }
    }

    /// Starts over in time (a new connection may restart its clock).
    pub fn restart(&mut self) {
        self.last_t = None;
    }

    /// Reads one line (without its newline).
    pub fn line(&mut self, text: &str) -> LiveLine {
        let number = self.lines;
        self.lines += 1;
        let bad = |field: &str, message: String| {
            LiveLine::Bad(FrameProblem {
                frame: number,
                t: f64::NAN,
                field: field.to_owned(),
                message,
            })
        };
        if text.len() > MAX_LIVE_LINE_BYTES {
            return bad("line", format!("{} bytes, more than {MAX_LIVE_LINE_BYTES}", text.len()));
        }
        let value: serde_json::Value = match serde_json::from_str(text.trim()) {
            Ok(v) => v,
            Err(e) => return bad("line", format!("not JSON: {e}")),
        };
        if value.get("format").is_some() {
            if value.get("format").and_then(serde_json::Value::as_str) != Some("contact-session") {
                return bad("format", "is not \"contact-session\"".to_owned());
            }
            let joints: Vec<String> = value
                .get("joints")
                .and_then(|j| serde_json::from_value(j.clone()).ok())
                .unwrap_or_default();
            if !joints.is_empty() {
                self.width = Some(joints.len());
            }
            return LiveLine::Header {
                robot: value
                    .get("robot")
                    .and_then(serde_json::Value::as_str)
                    .map(str::to_owned),
                joints,
            };
        }
        let Ok(f) = serde_json::from_value::<FrameFile>(value) else {
            return bad("line", "is neither a header nor a frame".to_owned());
        };
        let frame = Frame::from(f);
        let width = self.width.or(Some(frame.q.len()));
        if let Some((field, message)) = frame_problem(&frame, width, self.last_t.unwrap_or(f64::NEG_INFINITY)) {
            return LiveLine::Bad(FrameProblem {
                frame: number,
                t: frame.t,
                field,
                message,
            });
        }
        self.width = width;
        self.last_t = Some(frame.t);
        LiveLine::Frame(frame)
    }
}
