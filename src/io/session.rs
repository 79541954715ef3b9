//! Recorded sessions in the interchange format (`contact-session`,
//! version 1): JSON, or CSV with the robot named elsewhere.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Deserializer};

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
    #[error("{path}: frame {frame} (t = {t}): {field}: {message}")]
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

#[derive(Deserialize)]
struct SessionFile {
    format: String,
    version: u32,
    robot: String,
    #[serde(default)]
    joints: Option<Vec<String>>,
    frames: Vec<FrameFile>,
}

#[derive(Deserialize)]
struct FrameFile {
    t: f64,
    q: Vec<f64>,
    tau: Vec<f64>,
    #[serde(default)]
    truth: TruthField,
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
    /// Reads a session file: `.csv` as CSV, anything else as JSON. Frames
    /// are checked (see [`Session::check`]).
    pub fn read(path: &Path) -> Result<Self, SessionError> {
        let text = std::fs::read_to_string(path).map_err(|cause| SessionError::Read {
            path: path.to_owned(),
            cause,
        })?;
        let is_csv = path
            .extension()
            .and_then(|e| e.to_str())
            .is_some_and(|e| e.eq_ignore_ascii_case("csv"));
        let session = if is_csv {
            Self::parse_csv(&text, path)?
        } else {
            Self::parse_json(&text, path)?
        };
        session.check()?;
        Ok(session)
    }

    /// Parses the JSON form.
    pub fn parse_json(text: &str, path: &Path) -> Result<Self, SessionError> {
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
            frames: file
                .frames
                .into_iter()
                .map(|f| Frame {
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
                })
                .collect(),
        })
    }

    /// Parses the CSV form: `t,q1..qn,tau1..taun[,link,px,py,pz,fx,fy,fz]`.
    /// An empty `link` in a file with truth columns means no contact.
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
        let has_truth = columns.len() == 1 + 2 * n + 7;
        let mut expected: Vec<String> = vec!["t".to_owned()];
        expected.extend((1..=n).map(|i| format!("q{i}")));
        expected.extend((1..=n).map(|i| format!("tau{i}")));
        if has_truth {
            expected.extend(truth_columns.iter().map(|s| (*s).to_owned()));
        }
        if n == 0 || columns != expected {
            return Err(parse(
                1,
                format!("header '{header}' is not 't,q1..qn,tau1..taun[,link,px,py,pz,fx,fy,fz]'"),
            ));
        }
        let mut frames = Vec::new();
        for (i, line) in lines {
            let cells: Vec<&str> = line.split(',').map(str::trim).collect();
            if cells.len() != columns.len() {
                return Err(parse(
                    i + 1,
                    format!("{} values, the header has {}", cells.len(), columns.len()),
                ));
            }
            let number = |k: usize| {
                cells[k].parse::<f64>().map_err(|_| {
                    parse(
                        i + 1,
                        format!("column '{}': '{}' is not a number", columns[k], cells[k]),
                    )
                })
            };
            let values = (0..=2 * n).map(number).collect::<Result<Vec<f64>, _>>()?;
            let truth = if !has_truth {
                Truth::Unknown
            } else if cells[1 + 2 * n].is_empty() {
                Truth::NoContact
            } else {
                let v = (2 * n + 2..columns.len())
                    .map(number)
                    .collect::<Result<Vec<f64>, _>>()?;
                Truth::Contact {
                    link: cells[1 + 2 * n].to_owned(),
                    point: [v[0], v[1], v[2]],
                    force: [v[3], v[4], v[5]],
                }
            };
            frames.push(Frame {
                t: values[0],
                q: values[1..=n].to_vec(),
                tau: values[n + 1..].to_vec(),
                truth,
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
    /// number of `joints` when given), and times that do not go backwards.
    pub fn check(&self) -> Result<(), SessionError> {
        let width = self
            .joints
            .as_ref()
            .map(Vec::len)
            .or_else(|| self.frames.first().map(|f| f.q.len()));
        let mut last_t = f64::NEG_INFINITY;
        for (i, f) in self.frames.iter().enumerate() {
            let bad = |field: String, message: String| SessionError::Frame {
                path: self.path.clone(),
                frame: i,
                t: f.t,
                field,
                message,
            };
            if !f.t.is_finite() {
                return Err(bad("t".to_owned(), "is not finite".to_owned()));
            }
            if f.t < last_t {
                return Err(bad("t".to_owned(), format!("goes backwards from {last_t}")));
            }
            last_t = f.t;
            for (name, values) in [("q", &f.q), ("tau", &f.tau)] {
                if let Some(w) = width
                    && values.len() != w
                {
                    return Err(bad(
                        name.to_owned(),
                        format!("{} values, expected {w} (one per joint)", values.len()),
                    ));
                }
                if let Some(j) = values.iter().position(|v| !v.is_finite()) {
                    return Err(bad(format!("{name}[{j}]"), format!("{} is not finite", values[j])));
                }
            }
            if let Truth::Contact { point, force, .. } = &f.truth
                && point.iter().chain(force).any(|v| !v.is_finite())
            {
                return Err(bad("truth".to_owned(), "point or force is not finite".to_owned()));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const JSON: &str = r#"{"format": "contact-session", "version": 1, "robot": "lwr4plus", "extra": 1,
      "frames": [
        {"t": 0.0, "q": [0, 0], "tau": [0.1, 0.2], "truth": {"link": "l", "point": [1, 2, 3], "force": [4, 5, 6]}},
        {"t": 0.5, "q": [0, 0], "tau": [0.0, 0.0], "truth": null},
        {"t": 1.0, "q": [0, 0], "tau": [0.0, 0.0]}
      ]}"#;

    #[test]
    fn json_truth_can_be_a_contact_null_or_absent() {
        let s = Session::parse_json(JSON, Path::new("s.json")).unwrap();
        s.check().unwrap();
        assert_eq!(s.frames.len(), 3);
        assert!(matches!(s.frames[0].truth, Truth::Contact { .. }));
        assert_eq!(s.frames[1].truth, Truth::NoContact);
        assert_eq!(s.frames[2].truth, Truth::Unknown);
    }

    #[test]
    fn csv_reads_the_same_frames() {
        let csv = "t,q1,q2,tau1,tau2,link,px,py,pz,fx,fy,fz\n0.0,0,0,0.1,0.2,l,1,2,3,4,5,6\n0.5,0,0,0,0,,,,,,,\n";
        let s = Session::parse_csv(csv, Path::new("s.csv")).unwrap();
        let j = Session::parse_json(JSON, Path::new("s.json")).unwrap();
        assert_eq!(s.frames[..2], j.frames[..2]);
    }

    #[test]
    fn bad_frames_are_named() {
        let text = JSON.replace(r#""t": 0.5"#, r#""t": -0.5"#);
        let e = Session::parse_json(&text, Path::new("s.json"))
            .unwrap()
            .check()
            .unwrap_err()
            .to_string();
        assert!(e.contains("frame 1") && e.contains("backwards"), "{e}");
        let text = JSON.replace(r#""tau": [0.0, 0.0], "truth": null"#, r#""tau": [0.0], "truth": null"#);
        let e = Session::parse_json(&text, Path::new("s.json"))
            .unwrap()
            .check()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("frame 1") && e.contains("tau") && e.contains("expected 2"),
            "{e}"
        );
        let csv = "t,q1,q2,tau1,tau2\n0.0,0,0,0.1,nan\n";
        let e = Session::parse_csv(csv, Path::new("s.csv"))
            .unwrap()
            .check()
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("frame 0") && e.contains("tau[1]") && e.contains("NaN"),
            "{e}"
        );
        let e = Session::parse_csv("t,q1,tau2\n", Path::new("h.csv"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("h.csv:1") && e.contains("header"), "{e}");
    }
}
