//! Robot recordings as sessions: ROS 2 MCAP files and ROS 1 bags.
//!
//! A recording holds topics, not frames. A frame is made for every
//! message of the torque topic: its time from the message's header stamp
//! (or a `…sec`/`…nanosec` field pair, or the log time), its torques from
//! the chosen float array mapped by joint name, and the joint positions
//! interpolated linearly at that stamp from a `JointState` topic. The
//! truth, when recorded, comes from `/contact/truth` (a `WrenchStamped`
//! whose `frame_id` names the link, force in the world frame) and
//! `/contact/truth_point` (a `PointStamped` in the world frame).
//!
//! `scan` walks a container's messages, `frames` turns the chosen topics
//! into a session.

mod frames;
mod scan;

use std::path::{Path, PathBuf};
use std::sync::Arc;

use crate::io::bag::BagError;
use crate::io::rosmsg::{MessageDefinition, Value};

pub use frames::{RecordingSession, read_session, read_session_start};
use scan::Topics;
pub(crate) use scan::scan;

/// The truth topics' names (the convention of our recordings).
pub const TRUTH_TOPIC: &str = "/contact/truth";
/// The truth point's topic.
pub const TRUTH_POINT_TOPIC: &str = "/contact/truth_point";
/// A second true contact's topic (where two press at once), as
/// [`TRUTH_TOPIC`].
pub const SECOND_TRUTH_TOPIC: &str = "/contact/truth_2";
/// The second true contact's point, as [`TRUTH_POINT_TOPIC`].
pub const SECOND_TRUTH_POINT_TOPIC: &str = "/contact/truth_point_2";

/// The first bytes of an MCAP file.
pub(crate) const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

/// Why a recording could not be read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file could not be read.
    #[error("{path}: cannot read the recording: {cause}")]
    Read {
        /// The file.
        path: PathBuf,
        /// The system's reason.
        cause: std::io::Error,
    },
    /// Neither MCAP nor a ROS 1 bag.
    #[error("{path}: not an MCAP file nor a ROS 1 bag (by its first bytes)")]
    Unknown {
        /// The file.
        path: PathBuf,
    },
    /// The MCAP container is malformed.
    #[error("{path}: MCAP: {reason}")]
    Mcap {
        /// The file.
        path: PathBuf,
        /// The reader's reason.
        reason: String,
    },
    /// The bag container is malformed.
    #[error("{path}: ROS 1 bag: {cause}")]
    Bag {
        /// The file.
        path: PathBuf,
        /// The reader's reason.
        cause: BagError,
    },
    /// The topic or field choice does not work for this file.
    #[error("{path}: {option}: {reason}")]
    Choice {
        /// The file.
        path: PathBuf,
        /// The option at fault (`--tau-topic`, …).
        option: String,
        /// What is wrong, with what the file offers.
        reason: String,
    },
    /// No frame could be made.
    #[error("{path}: no frame: {reason}")]
    Empty {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
}

/// Whether `path` names a recording (`.mcap` or `.bag`) by its extension.
#[must_use]
pub fn is_recording(path: &Path) -> bool {
    path.extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("mcap") || e.eq_ignore_ascii_case("bag"))
}

/// What a topic holds.
#[derive(Debug, Clone)]
pub struct TopicInfo {
    /// Its name.
    pub topic: String,
    /// Message type, `pkg/Type`.
    pub message_type: String,
    /// Messages on it.
    pub count: usize,
    /// First and last log time, ns.
    pub log_span_ns: (u64, u64),
    /// The decoder, or why there is none.
    pub definition: Result<Arc<MessageDefinition>, String>,
    /// Its first message, decoded (when it could be).
    pub first: Option<Value>,
}

impl TopicInfo {
    /// Messages per second over the log times (`None` for fewer than two).
    #[must_use]
    pub fn rate_hz(&self) -> Option<f64> {
        let (a, b) = self.log_span_ns;
        (self.count > 1 && b > a).then(|| (self.count - 1) as f64 / ((b - a) as f64 * 1e-9))
    }

    /// Whether messages carry joint names (a top-level `name` string array).
    #[must_use]
    pub fn has_names(&self) -> bool {
        self.first
            .as_ref()
            .and_then(|v| v.get("name"))
            .is_some_and(|v| v.as_strings().is_some())
    }

    /// Non-empty float arrays of the first message, with their lengths.
    #[must_use]
    pub fn float_arrays(&self) -> Vec<(String, usize)> {
        let Some(first) = &self.first else {
            return Vec::new();
        };
        first
            .float_array_paths()
            .into_iter()
            .filter_map(|p| {
                let n = first.get(&p).and_then(Value::as_floats).map_or(0, |v| v.len());
                (n > 0).then_some((p, n))
            })
            .collect()
    }

    /// Where its time comes from (`header.stamp`, a field pair, or the
    /// log time), judged on the first message.
    #[must_use]
    pub fn stamp_source(&self) -> StampSource {
        self.first.as_ref().map_or(StampSource::LogTime, StampSource::of)
    }
}

/// Where a message's time comes from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum StampSource {
    /// Seconds and nanoseconds fields (e.g. `header.stamp.sec` and
    /// `header.stamp.nanosec`).
    Fields {
        /// The seconds field.
        sec: String,
        /// The nanoseconds field.
        nanosec: String,
    },
    /// The time it was logged.
    LogTime,
}

impl StampSource {
    /// Judged on one message.
    #[must_use]
    pub fn of(message: &Value) -> Self {
        for prefix in ["header.stamp.", "stamp."] {
            let (sec, nanosec) = (format!("{prefix}sec"), format!("{prefix}nanosec"));
            if message.get(&sec).and_then(Value::as_i64).is_some()
                && message.get(&nanosec).and_then(Value::as_i64).is_some()
            {
                return Self::Fields { sec, nanosec };
            }
        }
        if let Value::Struct(fields) = message {
            for (name, value) in fields {
                let Some(prefix) = name.strip_suffix("sec") else {
                    continue;
                };
                if value.as_i64().is_none()
                    || prefix.ends_with("nano")
                    || prefix.ends_with("nano_")
                    || prefix.ends_with('n')
                {
                    continue;
                }
                for partner in ["nanosec", "nano_sec", "nsec"] {
                    let nanosec = format!("{prefix}{partner}");
                    if message.get(&nanosec).and_then(Value::as_i64).is_some() {
                        return Self::Fields {
                            sec: name.to_string(),
                            nanosec,
                        };
                    }
                }
            }
        }
        Self::LogTime
    }

    /// The time of `message`, ns (`log_ns` for [`StampSource::LogTime`]).
    #[must_use]
    pub fn stamp_ns(&self, message: &Value, log_ns: u64) -> Option<i64> {
        match self {
            Self::Fields { sec, nanosec } => {
                let s = message.get(sec).and_then(Value::as_i64)?;
                let n = message.get(nanosec).and_then(Value::as_i64)?;
                s.checked_mul(1_000_000_000)?.checked_add(n)
            }
            Self::LogTime => i64::try_from(log_ns).ok(),
        }
    }
}

impl std::fmt::Display for StampSource {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Fields { sec, nanosec } => match sec.strip_suffix(".sec") {
                Some(prefix) if nanosec.strip_suffix(".nanosec") == Some(prefix) => write!(f, "{prefix}"),
                _ => write!(f, "{sec} + {nanosec}"),
            },
            Self::LogTime => write!(f, "log time"),
        }
    }
}

/// The topics of a recording, by name.
#[derive(Debug, Clone)]
pub struct RecordingIndex {
    /// The file.
    pub path: PathBuf,
    /// `MCAP` or `ROS 1 bag`.
    pub container: &'static str,
    /// Every topic, sorted by name.
    pub topics: Vec<TopicInfo>,
}

/// Which topics and field make the frames; `None` lets the file decide
/// when it is unambiguous.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TopicChoice {
    /// `JointState` topic of the joint positions.
    pub q_topic: Option<String>,
    /// Topic of the external torques.
    pub tau_topic: Option<String>,
    /// Float array field of the torque topic (dotted path).
    pub tau_field: Option<String>,
}

/// The topics and field that make the frames.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Mapping {
    /// Joint positions' topic.
    pub q_topic: String,
    /// Torques' topic.
    pub tau_topic: String,
    /// Torques' field.
    pub tau_field: String,
}

impl std::fmt::Display for Mapping {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "--q-topic {} --tau-topic {} --tau-field {}",
            self.q_topic, self.tau_topic, self.tau_field
        )
    }
}

/// Reads the whole file (a recording is decoded from memory).
pub fn read_bytes(path: &Path) -> Result<Vec<u8>, RecordingError> {
    std::fs::read(path).map_err(|cause| RecordingError::Read {
        path: path.to_owned(),
        cause,
    })
}

/// Lists the topics of a recording held in `bytes`.
pub fn index(path: &Path, bytes: &[u8]) -> Result<RecordingIndex, RecordingError> {
    index_of(path, bytes, false)
}

/// [`index`]; with `cut_short`, of a file's start cut anywhere.
pub(crate) fn index_of(path: &Path, bytes: &[u8], cut_short: bool) -> Result<RecordingIndex, RecordingError> {
    let mut topics = Topics::default();
    let container = scan(path, bytes, cut_short, &mut |message| {
        let i = topics.note(&message);
        if let Some(t) = topics.list.get_mut(i) {
            t.count += 1;
            t.log_span_ns = (t.log_span_ns.0.min(message.log_ns), t.log_span_ns.1.max(message.log_ns));
        }
    })?;
    let mut list = topics.list;
    list.sort_by(|a, b| a.topic.cmp(&b.topic));
    Ok(RecordingIndex {
        path: path.to_owned(),
        container,
        topics: list,
    })
}

impl RecordingIndex {
    fn topic(&self, name: &str) -> Option<&TopicInfo> {
        self.topics.iter().find(|t| t.topic == name)
    }

    fn choice_error(&self, option: &str, reason: String) -> RecordingError {
        RecordingError::Choice {
            path: self.path.clone(),
            option: option.to_owned(),
            reason,
        }
    }

    /// Float arrays that may be the external torques: topic, field, and
    /// how likely (2: named *external*; 1: an effort or torque).
    #[must_use]
    pub fn torque_candidates(&self) -> Vec<(String, String, u8)> {
        let mut candidates = Vec::new();
        for topic in &self.topics {
            if [
                TRUTH_TOPIC,
                TRUTH_POINT_TOPIC,
                SECOND_TRUTH_TOPIC,
                SECOND_TRUTH_POINT_TOPIC,
            ]
            .contains(&topic.topic.as_str())
            {
                continue;
            }
            for (field, _) in topic.float_arrays() {
                let last = field.rsplit('.').next().unwrap_or_default().to_ascii_lowercase();
                if !(last == "effort" || last.contains("torque")) {
                    continue;
                }
                let external = topic.topic.to_ascii_lowercase().contains("external") || last.contains("external");
                candidates.push((topic.topic.clone(), field, if external { 2 } else { 1 }));
            }
        }
        candidates
    }

    /// Topics with joint names and positions (`JointState`-like).
    #[must_use]
    pub fn position_topics(&self) -> Vec<&str> {
        self.topics
            .iter()
            .filter(|t| t.has_names() && t.float_arrays().iter().any(|(f, _)| f == "position"))
            .map(|t| t.topic.as_str())
            .collect()
    }

    /// The mapping `choice` asks for, completed where the file leaves one
    /// possibility (or one clearly best: a torque topic or field named
    /// *external* over a measured effort; `/joint_states` over other
    /// position topics).
    pub fn mapping(&self, choice: &TopicChoice) -> Result<Mapping, RecordingError> {
        let mut candidates = self.torque_candidates();
        if let Some(topic) = &choice.tau_topic {
            let Some(info) = self.topic(topic) else {
                return Err(self.choice_error("--tau-topic", format!("no topic '{topic}' (see `proprioscope topics`)")));
            };
            candidates.retain(|(t, _, _)| t == topic);
            if let Some(field) = &choice.tau_field {
                let arrays = info.float_arrays();
                if !arrays.iter().any(|(f, _)| f == field) {
                    let names: Vec<&str> = arrays.iter().map(|(f, _)| f.as_str()).collect();
                    return Err(self.choice_error(
                        "--tau-field",
                        format!(
                            "'{topic}' has no non-empty float array '{field}' (it has: {})",
                            names.join(", ")
                        ),
                    ));
                }
                candidates = vec![(topic.clone(), field.clone(), 2)];
            }
        } else if let Some(field) = &choice.tau_field {
            candidates = self
                .topics
                .iter()
                .filter(|t| t.float_arrays().iter().any(|(f, _)| f == field))
                .map(|t| (t.topic.clone(), field.clone(), 1))
                .collect();
        }
        let best = candidates.iter().map(|c| c.2).max().unwrap_or(0);
        candidates.retain(|c| c.2 == best);
        let (tau_topic, tau_field) = match candidates.as_slice() {
            [(t, f, _)] => (t.clone(), f.clone()),
            [] if choice.tau_field.is_some() => {
                let field = choice.tau_field.clone().unwrap_or_default();
                return Err(self.choice_error(
                    "--tau-field",
                    format!("no topic has a non-empty float array '{field}' (see `proprioscope topics`)"),
                ));
            }
            [] => {
                return Err(self.choice_error(
                    "--tau-topic",
                    "no torque: no topic has a non-empty float array named effort or …torque… (name one with --tau-topic and --tau-field)".to_owned(),
                ));
            }
            many => {
                let listed: Vec<String> = many.iter().map(|(t, f, _)| format!("{t} {f}")).collect();
                return Err(self.choice_error(
                    "--tau-topic",
                    format!(
                        "several torque sources, choose one with --tau-topic and --tau-field: {}",
                        listed.join("; ")
                    ),
                ));
            }
        };
        let positions = self.position_topics();
        let q_topic = match &choice.q_topic {
            Some(q) if positions.contains(&q.as_str()) => q.clone(),
            Some(q) => {
                return Err(self.choice_error(
                    "--q-topic",
                    format!(
                        "'{q}' is not a topic with joint names and positions (these are: {})",
                        positions.join(", ")
                    ),
                ));
            }
            None if positions.contains(&tau_topic.as_str()) => tau_topic.clone(),
            None => match positions.as_slice() {
                [one] => (*one).to_owned(),
                [] => return Err(self.choice_error("--q-topic", "no topic has joint names and positions".to_owned())),
                many if many.contains(&"/joint_states") => "/joint_states".to_owned(),
                many => {
                    return Err(self.choice_error(
                        "--q-topic",
                        format!("several joint position topics, choose one: {}", many.join(", ")),
                    ));
                }
            },
        };
        Ok(Mapping {
            q_topic,
            tau_topic,
            tau_field,
        })
    }
}

#[cfg(test)]
#[path = "tests.rs"]
mod tests;
