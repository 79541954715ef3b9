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

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use super::bag::{self, BagError};
use super::inflate::{Compression, inflate};
use super::rosmsg::{Encoding, MessageDefinition, Value, normalize_type_name};
use super::session::{Frame, FrameProblem, Session, Truth, frame_problem};

/// The truth topics' names (the convention of our recordings).
pub const TRUTH_TOPIC: &str = "/contact/truth";
/// The truth point's topic.
pub const TRUTH_POINT_TOPIC: &str = "/contact/truth_point";

/// The first bytes of an MCAP file.
const MCAP_MAGIC: &[u8] = b"\x89MCAP0\r\n";

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

/// One message as the container gives it.
pub(crate) struct RawMessage<'a> {
    /// Channel or connection number.
    pub key: u32,
    /// Topic.
    pub topic: &'a str,
    /// Message type as stored.
    pub message_type: &'a str,
    /// Schema encoding and text.
    pub schema: Option<(&'a str, &'a [u8])>,
    /// `cdr` or `ros1`.
    pub message_encoding: &'a str,
    /// Log time, ns.
    pub log_ns: u64,
    /// The serialised message.
    pub data: &'a [u8],
}

/// Calls `visit` for every message of the file, in file order.
pub(crate) fn scan(
    path: &Path,
    bytes: &[u8],
    visit: &mut dyn FnMut(RawMessage<'_>),
) -> Result<&'static str, RecordingError> {
    if bytes.starts_with(MCAP_MAGIC) {
        McapScan::default().records(path, bytes.get(MCAP_MAGIC.len()..).unwrap_or_default(), false, visit)?;
        Ok("MCAP")
    } else if bytes.starts_with(bag::BAG_MAGIC) {
        bag::read_bag(bytes, &mut |connection, message| {
            visit(RawMessage {
                key: connection.id,
                topic: &connection.topic,
                message_type: &connection.message_type,
                schema: Some(("ros1msg", connection.definition.as_bytes())),
                message_encoding: "ros1",
                log_ns: message.time_ns,
                data: message.data,
            });
        })
        .map_err(|cause| RecordingError::Bag {
            path: path.to_owned(),
            cause,
        })?;
        Ok("ROS 1 bag")
    } else {
        Err(RecordingError::Unknown { path: path.to_owned() })
    }
}

/// A little-endian reader over one MCAP record's body, every length
/// checked against the bytes there are.
struct Fields<'a> {
    bytes: &'a [u8],
}

impl<'a> Fields<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let (head, rest) = (self.bytes.get(..n)?, self.bytes.get(n..)?);
        self.bytes = rest;
        Some(head)
    }

    fn u16(&mut self) -> Option<u16> {
        Some(u16::from_le_bytes(self.take(2)?.try_into().ok()?))
    }

    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }

    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }

    fn string(&mut self) -> Option<String> {
        let n = self.u32()? as usize;
        Some(String::from_utf8_lossy(self.take(n)?).into_owned())
    }

    /// A u32-length-prefixed byte array.
    fn bytes32(&mut self) -> Option<&'a [u8]> {
        let n = self.u32()? as usize;
        self.take(n)
    }
}

const OP_SCHEMA: u8 = 0x03;
const OP_CHANNEL: u8 = 0x04;
const OP_MESSAGE: u8 = 0x05;
const OP_CHUNK: u8 = 0x06;
const OP_DATA_END: u8 = 0x0F;

/// Schemas and channels of an MCAP file, as its records define them.
///
/// Our own reader of the container (the `mcap` crate writes our output):
/// the crate's reader 0.26 panicked on a record inside a chunk claiming
/// 2^64 − 1 bytes and allocated 4 GiB for a string claiming as much
/// (both found by fuzzing). Here every length is checked against the
/// bytes there are, chunks are decompressed within their declared size
/// and checked against their CRC, and a file cut short is read up to its
/// last whole record.
#[derive(Default)]
struct McapScan {
    /// By id: name, encoding, text.
    schemas: HashMap<u16, (String, String, Vec<u8>)>,
    /// By id: topic, message encoding, schema id.
    channels: HashMap<u16, (String, String, u16)>,
}

impl McapScan {
    /// The records of `bytes` (after the magic, or a chunk's content).
    fn records(
        &mut self,
        path: &Path,
        mut bytes: &[u8],
        in_chunk: bool,
        visit: &mut dyn FnMut(RawMessage<'_>),
    ) -> Result<(), RecordingError> {
        let fail = |reason: String| RecordingError::Mcap {
            path: path.to_owned(),
            reason,
        };
        while bytes.len() >= 9 {
            let mut head = Fields { bytes };
            let (Some(op), Some(len)) = (head.take(1).and_then(|b| b.first().copied()), head.u64()) else {
                break;
            };
            let Some(body) = usize::try_from(len).ok().and_then(|n| head.take(n)) else {
                if in_chunk {
                    return Err(fail(format!(
                        "a record in a chunk claims {len} bytes, more than the chunk holds"
                    )));
                }
                // A file cut short (a recorder killed): what came before is used.
                break;
            };
            bytes = head.bytes;
            match op {
                OP_DATA_END => break,
                OP_CHUNK if in_chunk => return Err(fail("a chunk inside a chunk".to_owned())),
                _ => self.record(path, op, body, visit)?,
            }
        }
        Ok(())
    }

    fn record(
        &mut self,
        path: &Path,
        op: u8,
        body: &[u8],
        visit: &mut dyn FnMut(RawMessage<'_>),
    ) -> Result<(), RecordingError> {
        let fail = |what: &str| RecordingError::Mcap {
            path: path.to_owned(),
            reason: what.to_owned(),
        };
        let mut f = Fields { bytes: body };
        match op {
            OP_SCHEMA => {
                let (Some(id), Some(name), Some(encoding), Some(data)) = (f.u16(), f.string(), f.string(), f.bytes32())
                else {
                    return Err(fail("a schema record is malformed"));
                };
                self.schemas.insert(id, (name, encoding, data.to_vec()));
            }
            OP_CHANNEL => {
                let (Some(id), Some(schema_id), Some(topic), Some(encoding)) =
                    (f.u16(), f.u16(), f.string(), f.string())
                else {
                    return Err(fail("a channel record is malformed"));
                };
                self.channels.insert(id, (topic, encoding, schema_id));
            }
            OP_MESSAGE => {
                let (Some(channel_id), Some(sequence), Some(log_ns), Some(_publish)) =
                    (f.u16(), f.u32(), f.u64(), f.u64())
                else {
                    return Err(fail("a message record is malformed"));
                };
                let Some((topic, message_encoding, schema_id)) = self.channels.get(&channel_id) else {
                    return Err(fail(&format!(
                        "message {sequence} on channel {channel_id}, which no channel record defines"
                    )));
                };
                let schema = self.schemas.get(schema_id);
                visit(RawMessage {
                    key: u32::from(channel_id),
                    topic,
                    message_type: schema.map_or("", |s| s.0.as_str()),
                    schema: schema.map(|s| (s.1.as_str(), s.2.as_slice())),
                    message_encoding,
                    log_ns,
                    data: f.bytes,
                });
            }
            OP_CHUNK => {
                let (Some(_start), Some(_end), Some(size), Some(crc), Some(compression), Some(records_len)) =
                    (f.u64(), f.u64(), f.u64(), f.u32(), f.string(), f.u64())
                else {
                    return Err(fail("a chunk record is malformed"));
                };
                let Some(data) = usize::try_from(records_len).ok().and_then(|n| f.take(n)) else {
                    return Err(fail("a chunk claims more bytes than it holds"));
                };
                let inflated: std::borrow::Cow<'_, [u8]> = match compression.as_str() {
                    "" => data.into(),
                    "zstd" => inflate(Compression::Zstd, data, size).map_err(|e| fail(&e))?.into(),
                    "lz4" => inflate(Compression::Lz4, data, size).map_err(|e| fail(&e))?.into(),
                    other => {
                        return Err(fail(&format!(
                            "chunk compression '{other}' is not supported (zstd, lz4, none)"
                        )));
                    }
                };
                if compression.is_empty() && inflated.len() as u64 != size {
                    return Err(fail("an uncompressed chunk's size does not match its header"));
                }
                if crc != 0 && crc32fast::hash(&inflated) != crc {
                    return Err(fail("a chunk's CRC does not match its content"));
                }
                self.records(path, &inflated, true, visit)?;
            }
            // Header, footer, indexes, statistics, metadata, attachments:
            // nothing a session needs.
            _ => {}
        }
        Ok(())
    }
}

/// The decoder of a channel's messages, or why there is none.
fn definition_of(message: &RawMessage<'_>) -> Result<Arc<MessageDefinition>, String> {
    let encoding = match message.message_encoding {
        "cdr" => Encoding::Cdr,
        "ros1" => Encoding::Ros1,
        other => return Err(format!("message encoding '{other}' is not a ROS one (cdr, ros1)")),
    };
    let Some((schema_encoding, text)) = message.schema else {
        return Err("no schema".to_owned());
    };
    if !matches!(schema_encoding, "ros2msg" | "ros1msg") {
        return Err(format!(
            "schema encoding '{schema_encoding}' is not a message definition"
        ));
    }
    let text = std::str::from_utf8(text).map_err(|e| format!("schema text is not UTF-8: {e}"))?;
    MessageDefinition::parse(message.message_type, text, encoding)
        .map(Arc::new)
        .map_err(|e| e.to_string())
}

/// Topics by container key (channel or connection number).
#[derive(Default)]
struct Topics {
    list: Vec<TopicInfo>,
    by_name: HashMap<String, usize>,
    by_key: HashMap<u32, usize>,
}

impl Topics {
    /// The topic of `message`, added (with its first message decoded)
    /// when new.
    fn note(&mut self, message: &RawMessage<'_>) -> usize {
        if let Some(&i) = self.by_key.get(&message.key) {
            return i;
        }
        let i = if let Some(&i) = self.by_name.get(message.topic) {
            i
        } else {
            let definition = definition_of(message);
            let first = definition.as_ref().ok().and_then(|d| d.decode(message.data).ok());
            self.list.push(TopicInfo {
                topic: message.topic.to_owned(),
                message_type: normalize_type_name(message.message_type),
                count: 0,
                log_span_ns: (message.log_ns, message.log_ns),
                definition,
                first,
            });
            self.by_name.insert(message.topic.to_owned(), self.list.len() - 1);
            self.list.len() - 1
        };
        self.by_key.insert(message.key, i);
        i
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
    let mut topics = Topics::default();
    let container = scan(path, bytes, &mut |message| {
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
            if topic.topic == TRUTH_TOPIC || topic.topic == TRUTH_POINT_TOPIC {
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

/// Samples of one topic: stamps and values in a fixed joint order.
#[derive(Default)]
struct Samples {
    stamps_ns: Vec<i64>,
    values: Vec<f64>,
    width: usize,
}

impl Samples {
    /// Sorted by stamp (stable: equal stamps keep file order).
    fn sorted(self) -> Self {
        let mut order: Vec<usize> = (0..self.stamps_ns.len()).collect();
        order.sort_by_key(|&i| self.stamps_ns.get(i).copied().unwrap_or(0));
        let mut stamps_ns = Vec::with_capacity(order.len());
        let mut values = Vec::with_capacity(self.values.len());
        for i in order {
            if let (Some(&s), Some(row)) = (
                self.stamps_ns.get(i),
                self.values.get(i * self.width..(i + 1) * self.width),
            ) {
                stamps_ns.push(s);
                values.extend_from_slice(row);
            }
        }
        Self {
            stamps_ns,
            values,
            width: self.width,
        }
    }

    fn row(&self, i: usize) -> Option<&[f64]> {
        self.values.get(i * self.width..(i + 1) * self.width)
    }

    /// The values at `stamp`, linear between the samples around it
    /// (exact at a sample's own stamp).
    fn at(&self, stamp: i64) -> Option<Vec<f64>> {
        let after = self.stamps_ns.partition_point(|&s| s <= stamp);
        let before = after.checked_sub(1)?;
        let s0 = *self.stamps_ns.get(before)?;
        let row0 = self.row(before)?;
        if s0 == stamp {
            return Some(row0.to_vec());
        }
        let s1 = *self.stamps_ns.get(after)?;
        let row1 = self.row(after)?;
        let w = (stamp - s0) as f64 / (s1 - s0) as f64;
        Some(row0.iter().zip(row1).map(|(a, b)| a + (b - a) * w).collect())
    }
}

/// Maps each message's named values into one joint order.
struct JointOrder {
    names: Option<Vec<String>>,
    /// The last message's names and where each goes.
    cached: Option<(Vec<String>, Vec<usize>)>,
}

impl JointOrder {
    /// `values` in the order of `names` (set by the first message when
    /// unset); `message_names` `None` means already in that order.
    fn arrange(&mut self, message_names: Option<Vec<String>>, values: &[f64]) -> Result<Vec<f64>, String> {
        let Some(message_names) = message_names else {
            return match &self.names {
                Some(n) if n.len() != values.len() => Err(format!(
                    "{} values for {} joints (the array has no names)",
                    values.len(),
                    n.len()
                )),
                _ => Ok(values.to_vec()),
            };
        };
        if message_names.len() != values.len() {
            return Err(format!("{} names but {} values", message_names.len(), values.len()));
        }
        if let Some(name) = repeated_name(&message_names) {
            // Two values for one joint would leave another joint's at 0.
            return Err(format!("the message names joint '{name}' twice"));
        }
        let names = self.names.get_or_insert_with(|| message_names.clone());
        if let Some((cached_names, slots)) = &self.cached
            && *cached_names == message_names
        {
            return Ok(permute(values, slots, names.len()));
        }
        let mut slots = Vec::with_capacity(message_names.len());
        for name in &message_names {
            let slot = names
                .iter()
                .position(|n| n == name)
                .ok_or_else(|| format!("joint '{name}' is not among {}", names.join(", ")))?;
            slots.push(slot);
        }
        if message_names.len() != names.len() {
            return Err(format!(
                "{} joints named, {} expected ({})",
                message_names.len(),
                names.len(),
                names.join(", ")
            ));
        }
        let out = permute(values, &slots, names.len());
        self.cached = Some((message_names, slots));
        Ok(out)
    }
}

/// The first name that `names` gives twice.
fn repeated_name(names: &[String]) -> Option<&str> {
    let mut seen = std::collections::HashSet::with_capacity(names.len());
    names.iter().find(|n| !seen.insert(n.as_str())).map(String::as_str)
}

fn permute(values: &[f64], slots: &[usize], n: usize) -> Vec<f64> {
    let mut out = vec![0.0; n];
    for (&v, &slot) in values.iter().zip(slots) {
        if let Some(o) = out.get_mut(slot) {
            *o = v;
        }
    }
    out
}

fn xyz(value: &Value, path: &str) -> Option<[f64; 3]> {
    let get = |axis: &str| value.get(&format!("{path}.{axis}")).and_then(Value::as_f64);
    Some([get("x")?, get("y")?, get("z")?])
}

/// What a recording gave: the session, the frames it skipped (numbered as
/// torque messages in stamp order) and the mapping used.
pub struct RecordingSession {
    /// The frames.
    pub session: Session,
    /// Torque messages that made no frame, and why.
    pub problems: Vec<FrameProblem>,
    /// The topics and field used.
    pub mapping: Mapping,
    /// Where the times came from.
    pub stamps: StampSource,
    /// Other messages skipped (joint states), one line per topic.
    pub notes: Vec<String>,
    /// The clock reading of `t = 0` (the first torque message's stamp), ns.
    pub origin_ns: i64,
}

/// Reads a recording's frames (see the module's doc). `progress` goes
/// from 0 to 1.
// One pass over the file fills every topic's samples; the steps share
// their state, and split apart they would pass it all along.
#[allow(clippy::too_many_lines)]
pub fn read_session(
    path: &Path,
    bytes: &[u8],
    choice: &TopicChoice,
    progress: &dyn Fn(f64),
) -> Result<RecordingSession, RecordingError> {
    let index = index(path, bytes)?;
    progress(0.3);
    let mapping = index.mapping(choice)?;
    let (Some(tau_info), Some(q_info)) = (index.topic(&mapping.tau_topic), index.topic(&mapping.q_topic)) else {
        return Err(index.choice_error("--tau-topic", "topic vanished".to_owned()));
    };
    let total = tau_info.count + q_info.count;
    let tau_stamps = tau_info.stamp_source();
    let q_stamps = q_info.stamp_source();
    let tau_named = tau_info.has_names();

    let mut q_order = JointOrder {
        names: None,
        cached: None,
    };
    // Torques without names take the joint order of the position topic.
    if !tau_named
        && let Some(names) = q_info
            .first
            .as_ref()
            .and_then(|v| v.get("name"))
            .and_then(Value::as_strings)
    {
        q_order.names = Some(names);
    }
    let mut tau_order = JointOrder {
        names: q_order.names.clone(),
        cached: None,
    };
    let mut q = Samples::default();
    let mut tau = Samples::default();
    let mut tau_problems: Vec<(Option<i64>, String)> = Vec::new();
    let mut q_problems = 0usize;
    let mut first_q_problem = None;
    let mut truths: HashMap<i64, (String, [f64; 3])> = HashMap::new();
    let mut truth_points: HashMap<i64, [f64; 3]> = HashMap::new();
    let truth_stamps = index
        .topic(TRUTH_TOPIC)
        .zip(index.topic(TRUTH_POINT_TOPIC))
        .map(|(t, p)| (t.stamp_source(), p.stamp_source()));
    let has_truth = truth_stamps.is_some();
    let mut topics = Topics::default();
    let mut seen = 0usize;

    scan(path, bytes, &mut |message| {
        let i = topics.note(&message);
        let Some(info) = topics.list.get(i) else {
            return;
        };
        let topic = info.topic.as_str();
        let is_tau = topic == mapping.tau_topic;
        let is_q = topic == mapping.q_topic;
        let is_truth = has_truth && (topic == TRUTH_TOPIC || topic == TRUTH_POINT_TOPIC);
        if !(is_tau || is_q || is_truth) {
            return;
        }
        let Ok(definition) = &info.definition else {
            return;
        };
        let decoded = definition.decode(message.data).map_err(|e| e.to_string());
        seen += 1;
        if seen.is_multiple_of(4096) {
            progress(0.3 + 0.6 * seen as f64 / total.max(1) as f64);
        }
        if is_truth {
            let (Ok(value), Some((wrench_stamps, point_stamps))) = (decoded, &truth_stamps) else {
                return;
            };
            let stamps = if topic == TRUTH_TOPIC {
                wrench_stamps
            } else {
                point_stamps
            };
            let Some(stamp) = stamps.stamp_ns(&value, message.log_ns) else {
                return;
            };
            if topic == TRUTH_TOPIC {
                let link = match value.get("header.frame_id") {
                    Some(Value::Str(s)) => s.clone(),
                    _ => return,
                };
                if let Some(force) = xyz(&value, "wrench.force") {
                    truths.insert(stamp, (link, force));
                }
            } else if let Some(point) = xyz(&value, "point") {
                truth_points.insert(stamp, point);
            }
            return;
        }
        // One topic may give both (a JointState with effort): decoded once.
        let (for_q, for_tau) = match (is_q, is_tau) {
            (true, true) => (Some(decoded.clone()), Some(decoded)),
            (true, false) => (Some(decoded), None),
            _ => (None, Some(decoded)),
        };
        if let Some(decoded) = for_q {
            let arranged = decoded.and_then(|value| {
                let stamp = q_stamps.stamp_ns(&value, message.log_ns).ok_or("no time stamp")?;
                let names = value.get("name").and_then(Value::as_strings);
                let positions = value.get("position").and_then(Value::as_floats).ok_or("no position")?;
                Ok((stamp, q_order.arrange(names, &positions)?))
            });
            match arranged {
                Ok((stamp, row)) if q.width == 0 || row.len() == q.width => {
                    q.width = row.len();
                    q.stamps_ns.push(stamp);
                    q.values.extend(row);
                }
                Ok(_) => {
                    q_problems += 1;
                    first_q_problem.get_or_insert_with(|| "a different number of joints".to_owned());
                }
                Err(e) => {
                    q_problems += 1;
                    first_q_problem.get_or_insert(e);
                }
            }
        }
        if let Some(decoded) = for_tau {
            let mut stamp = None;
            let arranged = decoded.and_then(|value| {
                stamp = tau_stamps.stamp_ns(&value, message.log_ns);
                let s = stamp.ok_or("no time stamp")?;
                let names = if tau_named {
                    value.get("name").and_then(Value::as_strings)
                } else {
                    None
                };
                let values = value
                    .get(&mapping.tau_field)
                    .and_then(Value::as_floats)
                    .ok_or_else(|| format!("no float array '{}'", mapping.tau_field))?;
                Ok((s, tau_order.arrange(names, &values)?))
            });
            match arranged {
                Ok((s, row)) if tau.width == 0 || row.len() == tau.width => {
                    tau.width = row.len();
                    tau.stamps_ns.push(s);
                    tau.values.extend(row);
                }
                Ok((s, row)) => tau_problems.push((Some(s), format!("{} values, {} expected", row.len(), tau.width))),
                Err(e) => tau_problems.push((stamp, e)),
            }
        }
    })?;
    progress(0.9);

    let joints = tau_order.names.clone().or_else(|| q_order.names.clone());
    let (q, tau) = (q.sorted(), tau.sorted());
    let Some(&origin) = tau.stamps_ns.first() else {
        return Err(RecordingError::Empty {
            path: path.to_owned(),
            reason: match tau_problems.first() {
                Some((_, e)) => format!("no usable message on {}: {e}", mapping.tau_topic),
                None => format!("no message on {}", mapping.tau_topic),
            },
        });
    };
    if q.stamps_ns.is_empty() {
        return Err(RecordingError::Empty {
            path: path.to_owned(),
            reason: format!(
                "no usable joint positions on {}{}",
                mapping.q_topic,
                first_q_problem.map(|e| format!(": {e}")).unwrap_or_default()
            ),
        });
    }
    // Where each torque joint's position sits in the position topic's order
    // (`None`: the same order).
    let q_slots: Option<Vec<Option<usize>>> = match (&q_order.names, &joints) {
        (Some(qn), Some(tn)) if qn != tn => Some(tn.iter().map(|name| qn.iter().position(|n| n == name)).collect()),
        _ => None,
    };
    let positions_in_tau_order = |stamp: i64| -> Result<Vec<f64>, String> {
        let row = q.at(stamp).ok_or_else(|| {
            let (a, b) = (
                q.stamps_ns.first().copied().unwrap_or(0),
                q.stamps_ns.last().copied().unwrap_or(0),
            );
            format!(
                "no joint positions around this stamp ({} covers {:.6} s to {:.6} s)",
                mapping.q_topic,
                (a - origin) as f64 * 1e-9,
                (b - origin) as f64 * 1e-9
            )
        })?;
        let Some(slots) = &q_slots else {
            return Ok(row);
        };
        slots
            .iter()
            .zip(joints.iter().flatten())
            .map(|(slot, name)| {
                slot.and_then(|k| row.get(k).copied())
                    .ok_or_else(|| format!("joint '{name}' has no position on {}", mapping.q_topic))
            })
            .collect()
    };

    let seconds = |stamp: i64| (stamp - origin) as f64 / 1e9;
    let mut frames = Vec::with_capacity(tau.stamps_ns.len());
    let mut problems = Vec::new();
    for (k, &stamp) in tau.stamps_ns.iter().enumerate() {
        let Some(tau_row) = tau.row(k) else { continue };
        match positions_in_tau_order(stamp) {
            Ok(q_row) => {
                let truth = if has_truth {
                    match (truths.get(&stamp), truth_points.get(&stamp)) {
                        (Some((link, force)), Some(point)) => Truth::Contact {
                            link: link.clone(),
                            point: *point,
                            force: *force,
                        },
                        (None, None) => Truth::NoContact,
                        _ => Truth::Unknown,
                    }
                } else {
                    Truth::Unknown
                };
                let frame = Frame {
                    t: seconds(stamp),
                    q: q_row,
                    tau: tau_row.to_vec(),
                    truth,
                };
                // The rules of every session: finite values, one per joint.
                match frame_problem(&frame, Some(tau.width), f64::NEG_INFINITY) {
                    None => frames.push(frame),
                    Some((field, message)) => problems.push(FrameProblem {
                        frame: k,
                        t: frame.t,
                        field,
                        message,
                    }),
                }
            }
            Err(message) => problems.push(FrameProblem {
                frame: k,
                t: seconds(stamp),
                field: mapping.tau_topic.clone(),
                message,
            }),
        }
    }
    // Torque messages that could not be read at all come after, numbered
    // past the readable ones.
    let readable = tau.stamps_ns.len();
    for (j, (stamp, message)) in tau_problems.into_iter().enumerate() {
        problems.push(FrameProblem {
            frame: readable + j,
            t: stamp.map_or(f64::NAN, seconds),
            field: mapping.tau_topic.clone(),
            message,
        });
    }
    let mut notes = Vec::new();
    if q_problems > 0 {
        notes.push(format!(
            "{}: {q_problems} messages skipped (first: {})",
            mapping.q_topic,
            first_q_problem.unwrap_or_default()
        ));
    }
    progress(1.0);
    Ok(RecordingSession {
        session: Session {
            path: path.to_owned(),
            robot: None,
            joints,
            frames,
        },
        problems,
        mapping,
        stamps: tau_stamps,
        notes,
        origin_ns: origin,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bag_messages_become_topics() {
        let bag = super::bag::tests::tiny_bag(&[(1_000_000_000, 1.0), (1_100_000_000, 2.0), (1_200_000_000, 3.0)]);
        let index = index(Path::new("x.bag"), &bag).unwrap();
        assert_eq!(index.container, "ROS 1 bag");
        let [topic] = index.topics.as_slice() else { panic!() };
        assert_eq!(topic.topic, "/x");
        assert_eq!(topic.message_type, "std_msgs/Float64");
        assert_eq!(topic.count, 3);
        assert!((topic.rate_hz().unwrap() - 10.0).abs() < 1e-9);
        assert_eq!(
            topic.first.as_ref().and_then(|v| v.get("data")).and_then(Value::as_f64),
            Some(1.0)
        );
        assert_eq!(topic.stamp_source(), StampSource::LogTime);
        // Nothing to make frames of.
        assert!(matches!(
            index.mapping(&TopicChoice::default()),
            Err(RecordingError::Choice { .. })
        ));
    }

    /// Found by the fuzzer: a record inside a chunk claiming 2^64 - 1
    /// bytes made the `mcap` crate's chunk reader overflow (a panic).
    #[test]
    fn a_chunk_record_claiming_exabytes_is_an_error() {
        let mut file = MCAP_MAGIC.to_vec();
        let record = |op: u8, body: &[u8]| {
            let mut r = vec![op];
            r.extend((body.len() as u64).to_le_bytes());
            r.extend(body);
            r
        };
        // Header: profile "", library "".
        file.extend(record(0x01, &[0; 8]));
        let mut inner = vec![0xff];
        inner.extend(u64::MAX.to_le_bytes());
        let mut chunk = Vec::new();
        chunk.extend(0u64.to_le_bytes());
        chunk.extend(0u64.to_le_bytes());
        chunk.extend((inner.len() as u64).to_le_bytes());
        chunk.extend(0u32.to_le_bytes());
        chunk.extend(0u32.to_le_bytes()); // compression "": none
        chunk.extend((inner.len() as u64).to_le_bytes());
        chunk.extend(&inner);
        file.extend(record(0x06, &chunk));
        let result = index(Path::new("x.mcap"), &file);
        assert!(
            matches!(result, Err(RecordingError::Mcap { .. })),
            "{:?}",
            result.map(|i| i.topics.len())
        );
    }

    #[test]
    fn interpolation_is_exact_at_samples_and_linear_between() {
        let s = Samples {
            stamps_ns: vec![0, 10, 20],
            values: vec![0.0, 1.0, 1.0, 3.0, 2.0, 5.0],
            width: 2,
        };
        assert_eq!(s.at(10), Some(vec![1.0, 3.0]));
        assert_eq!(s.at(15), Some(vec![1.5, 4.0]));
        assert_eq!(s.at(20), Some(vec![2.0, 5.0]));
        assert_eq!(s.at(21), None);
        assert_eq!(s.at(-1), None);
    }

    #[test]
    fn joints_are_mapped_by_name() {
        let mut order = JointOrder {
            names: Some(vec!["a".into(), "b".into(), "c".into()]),
            cached: None,
        };
        let names = |n: &[&str]| Some(n.iter().map(|s| (*s).to_owned()).collect());
        assert_eq!(
            order.arrange(names(&["c", "a", "b"]), &[3.0, 1.0, 2.0]),
            Ok(vec![1.0, 2.0, 3.0])
        );
        assert_eq!(
            order.arrange(names(&["c", "a", "b"]), &[6.0, 4.0, 5.0]),
            Ok(vec![4.0, 5.0, 6.0])
        );
        assert!(order.arrange(names(&["c", "a", "x"]), &[0.0; 3]).is_err());
        assert!(order.arrange(names(&["c", "a"]), &[0.0; 2]).is_err());
        assert!(order.arrange(None, &[0.0; 2]).is_err());
        assert_eq!(order.arrange(None, &[7.0, 8.0, 9.0]), Ok(vec![7.0, 8.0, 9.0]));
    }

    #[test]
    fn a_message_that_names_a_joint_twice_is_refused_naming_it() {
        let names = |n: &[&str]| Some(n.iter().map(|s| (*s).to_owned()).collect());
        // As the first message (which sets the order) and after it.
        let mut fresh = JointOrder {
            names: None,
            cached: None,
        };
        let e = fresh.arrange(names(&["a", "b", "a"]), &[1.0, 2.0, 3.0]).unwrap_err();
        assert!(e.contains("'a' twice"), "{e}");
        let mut order = JointOrder {
            names: Some(vec!["a".into(), "b".into(), "c".into()]),
            cached: None,
        };
        let e = order.arrange(names(&["a", "c", "a"]), &[1.0, 2.0, 3.0]).unwrap_err();
        assert!(e.contains("'a' twice"), "{e}");
    }

    #[test]
    fn stamps_come_from_headers_or_field_pairs() {
        let s =
            |fields: Vec<(&str, Value)>| Value::Struct(fields.into_iter().map(|(n, v)| (Arc::from(n), v)).collect());
        let header = s(vec![(
            "header",
            s(vec![(
                "stamp",
                s(vec![("sec", Value::Int(2)), ("nanosec", Value::UInt(5))]),
            )]),
        )]);
        assert_eq!(StampSource::of(&header).stamp_ns(&header, 0), Some(2_000_000_005));
        let fri = s(vec![
            ("sample_time", Value::Float(0.005)),
            ("time_stamp_sec", Value::UInt(3)),
            ("time_stamp_nano_sec", Value::UInt(7)),
        ]);
        assert_eq!(
            StampSource::of(&fri),
            StampSource::Fields {
                sec: "time_stamp_sec".into(),
                nanosec: "time_stamp_nano_sec".into()
            }
        );
        assert_eq!(StampSource::of(&fri).stamp_ns(&fri, 0), Some(3_000_000_007));
        let bare = s(vec![("data", Value::Float(1.0))]);
        assert_eq!(StampSource::of(&bare).stamp_ns(&bare, 42), Some(42));
    }
}
