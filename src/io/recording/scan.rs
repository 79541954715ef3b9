//! The messages of an MCAP file or a ROS 1 bag, in file order, and the
//! topics they make.

use std::collections::HashMap;
use std::path::Path;
use std::sync::Arc;

use crate::io::bag::{self};
use crate::io::inflate::{Compression, inflate};
use crate::io::rosmsg::{Encoding, MessageDefinition, normalize_type_name};

use super::{MCAP_MAGIC, RecordingError, TopicInfo};

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

/// Calls `visit` for every message of the file, in file order; with
/// `cut_short`, of a file's start cut anywhere (an MCAP is always read so:
/// a recorder killed leaves such a file).
pub(crate) fn scan(
    path: &Path,
    bytes: &[u8],
    cut_short: bool,
    visit: &mut dyn FnMut(RawMessage<'_>),
) -> Result<&'static str, RecordingError> {
    if bytes.starts_with(MCAP_MAGIC) {
        McapScan::default().records(path, bytes.get(MCAP_MAGIC.len()..).unwrap_or_default(), false, visit)?;
        Ok("MCAP")
    } else if bytes.starts_with(bag::BAG_MAGIC) {
        let read = if cut_short { bag::read_bag_start } else { bag::read_bag };
        read(bytes, &mut |connection, message| {
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
pub(crate) struct Topics {
    pub(crate) list: Vec<TopicInfo>,
    by_name: HashMap<String, usize>,
    by_key: HashMap<u32, usize>,
}

impl Topics {
    /// The topic of `message`, added (with its first message decoded)
    /// when new.
    pub(crate) fn note(&mut self, message: &RawMessage<'_>) -> usize {
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
