//! ROS 1 bag files (format 2.0): connections and their messages, read in
//! one pass over the file (chunks uncompressed or lz4; bz2 is refused by
//! name).

use std::collections::BTreeMap;

use super::inflate::{Compression, inflate};

/// The first bytes of every bag of format 2.0.
pub const BAG_MAGIC: &[u8] = b"#ROSBAG V2.0\n";

/// Why a bag could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum BagError {
    /// Not a bag of format 2.0.
    #[error("not a ROS 1 bag of format 2.0 (it does not start with '#ROSBAG V2.0')")]
    NotABag,
    /// A record is malformed.
    #[error("record at byte {offset}: {reason}")]
    Record {
        /// Where the record starts (in its chunk for records inside one).
        offset: usize,
        /// What is wrong.
        reason: String,
    },
    /// A chunk's compression is not supported.
    #[error("chunk at byte {offset}: compression '{compression}' is not supported (none and lz4 are)")]
    Compression {
        /// Where the chunk starts.
        offset: usize,
        /// The compression named.
        compression: String,
    },
}

/// A connection: a topic with its type and definition.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Connection {
    /// The connection's number in the bag.
    pub id: u32,
    /// The topic.
    pub topic: String,
    /// The message type (`pkg/Type`).
    pub message_type: String,
    /// The full message definition text.
    pub definition: String,
}

/// One message: its connection, receive time (ns since the epoch) and
/// serialised bytes.
#[derive(Debug, Clone, Copy)]
pub struct BagMessage<'a> {
    /// Connection number.
    pub connection: u32,
    /// Record time, ns.
    pub time_ns: u64,
    /// The serialised message.
    pub data: &'a [u8],
}

const OP_MESSAGE: u8 = 0x02;
const OP_CHUNK: u8 = 0x05;
const OP_CONNECTION: u8 = 0x07;

/// A record: its header fields and data.
struct Record<'a> {
    fields: Vec<(&'a [u8], &'a [u8])>,
    data: &'a [u8],
}

impl<'a> Record<'a> {
    fn field(&self, name: &str) -> Option<&'a [u8]> {
        self.fields.iter().find(|(n, _)| *n == name.as_bytes()).map(|(_, v)| *v)
    }

    fn op(&self) -> Option<u8> {
        self.field("op").and_then(|v| v.first().copied())
    }
}

fn u32_at(bytes: &[u8], offset: usize) -> Option<u32> {
    let slice = bytes.get(offset..offset.checked_add(4)?)?;
    Some(u32::from_le_bytes([slice[0], slice[1], slice[2], slice[3]]))
}

/// `name=value` fields, each after its u32 length.
fn parse_fields(mut bytes: &[u8]) -> Option<Vec<(&[u8], &[u8])>> {
    let mut fields = Vec::new();
    while !bytes.is_empty() {
        let n = u32_at(bytes, 0)? as usize;
        let field = bytes.get(4..4usize.checked_add(n)?)?;
        let eq = field.iter().position(|&b| b == b'=')?;
        fields.push((field.get(..eq)?, field.get(eq + 1..)?));
        bytes = bytes.get(4 + n..)?;
    }
    Some(fields)
}

/// The records of `bytes` from `start`, each with its offset.
fn records(bytes: &[u8], start: usize) -> impl Iterator<Item = Result<(usize, Record<'_>), BagError>> {
    let mut offset = start;
    let mut failed = false;
    std::iter::from_fn(move || {
        if failed || offset >= bytes.len() {
            return None;
        }
        let at = offset;
        let record = (|| {
            let header_len = u32_at(bytes, at)? as usize;
            let header_end = at.checked_add(4)?.checked_add(header_len)?;
            let fields = parse_fields(bytes.get(at + 4..header_end)?)?;
            let data_len = u32_at(bytes, header_end)? as usize;
            let data_end = header_end.checked_add(4)?.checked_add(data_len)?;
            let data = bytes.get(header_end + 4..data_end)?;
            Some((data_end, Record { fields, data }))
        })();
        if let Some((end, record)) = record {
            offset = end;
            Some(Ok((at, record)))
        } else {
            failed = true;
            Some(Err(BagError::Record {
                offset: at,
                reason: "cut short or malformed (a length points past the end, or a header field has no '=')"
                    .to_owned(),
            }))
        }
    })
}

fn connection(record: &Record<'_>, offset: usize) -> Result<Connection, BagError> {
    let bad = |reason: &str| BagError::Record {
        offset,
        reason: reason.to_owned(),
    };
    let id = record
        .field("conn")
        .and_then(|v| u32_at(v, 0))
        .ok_or_else(|| bad("connection without a 'conn' number"))?;
    let header = parse_fields(record.data).ok_or_else(|| bad("malformed connection header"))?;
    let text = |name: &str| {
        header
            .iter()
            .find(|(n, _)| *n == name.as_bytes())
            .map(|(_, v)| String::from_utf8_lossy(v).into_owned())
    };
    let topic = text("topic")
        .or_else(|| record.field("topic").map(|v| String::from_utf8_lossy(v).into_owned()))
        .ok_or_else(|| bad("connection without a topic"))?;
    Ok(Connection {
        id,
        topic,
        message_type: text("type").ok_or_else(|| bad("connection without a type"))?,
        definition: text("message_definition").unwrap_or_default(),
    })
}

/// Reads every connection and message of a bag, calling `visit` for each
/// message in file order with its connection. Connections are
/// returned by number.
pub fn read_bag(
    bytes: &[u8],
    visit: &mut dyn FnMut(&Connection, BagMessage<'_>),
) -> Result<BTreeMap<u32, Connection>, BagError> {
    read_bag_with(bytes, visit, false)
}

/// [`read_bag`] of the start of a bag cut anywhere (a preview of a long
/// one): the records before the one the cut falls in.
///
/// # Errors
/// As [`read_bag`], for the records before the cut.
pub fn read_bag_start(
    bytes: &[u8],
    visit: &mut dyn FnMut(&Connection, BagMessage<'_>),
) -> Result<BTreeMap<u32, Connection>, BagError> {
    read_bag_with(bytes, visit, true)
}

fn read_bag_with(
    bytes: &[u8],
    visit: &mut dyn FnMut(&Connection, BagMessage<'_>),
    cut_short: bool,
) -> Result<BTreeMap<u32, Connection>, BagError> {
    if !bytes.starts_with(BAG_MAGIC) {
        return Err(BagError::NotABag);
    }
    let start = BAG_MAGIC.len();
    let mut connections = BTreeMap::new();
    for item in records(bytes, start) {
        let (offset, record) = match item {
            Ok(item) => item,
            // The record the cut falls in, and what follows, are not there.
            Err(_) if cut_short => break,
            Err(e) => return Err(e),
        };
        match record.op() {
            Some(OP_CHUNK) => {
                let compression = record.field("compression").unwrap_or(b"none");
                let size = record.field("size").and_then(|v| u32_at(v, 0)).unwrap_or(0);
                let inflated;
                let data = match compression {
                    b"none" => record.data,
                    b"lz4" => {
                        inflated = inflate(Compression::Lz4, record.data, u64::from(size))
                            .map_err(|reason| BagError::Record { offset, reason })?;
                        &inflated
                    }
                    other => {
                        return Err(BagError::Compression {
                            offset,
                            compression: String::from_utf8_lossy(other).into_owned(),
                        });
                    }
                };
                for inner in records(data, 0) {
                    let (inner_offset, inner) = inner.map_err(|e| match e {
                        BagError::Record { offset: o, reason } => BagError::Record {
                            offset,
                            reason: format!("in the chunk, at byte {o}: {reason}"),
                        },
                        other => other,
                    })?;
                    match inner.op() {
                        Some(OP_CONNECTION) => {
                            let c = connection(&inner, inner_offset)?;
                            connections.entry(c.id).or_insert(c);
                        }
                        Some(OP_MESSAGE) => {
                            let id = inner.field("conn").and_then(|v| u32_at(v, 0));
                            let time = inner.field("time").and_then(|v| Some((u32_at(v, 0)?, u32_at(v, 4)?)));
                            let (Some(id), Some((secs, nsecs))) = (id, time) else {
                                return Err(BagError::Record {
                                    offset,
                                    reason: format!(
                                        "message at byte {inner_offset} of the chunk lacks 'conn' or 'time'"
                                    ),
                                });
                            };
                            let Some(c) = connections.get(&id) else {
                                return Err(BagError::Record {
                                    offset,
                                    reason: format!(
                                        "message at byte {inner_offset} of the chunk names connection {id}, not yet defined"
                                    ),
                                });
                            };
                            visit(
                                c,
                                BagMessage {
                                    connection: id,
                                    time_ns: u64::from(secs) * 1_000_000_000 + u64::from(nsecs),
                                    data: inner.data,
                                },
                            );
                        }
                        _ => {}
                    }
                }
            }
            Some(OP_CONNECTION) => {
                let c = connection(&record, offset)?;
                connections.entry(c.id).or_insert(c);
            }
            _ => {}
        }
    }
    Ok(connections)
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;

    fn field(name: &str, value: &[u8]) -> Vec<u8> {
        let mut f = Vec::new();
        f.extend(((name.len() + 1 + value.len()) as u32).to_le_bytes());
        f.extend(name.as_bytes());
        f.push(b'=');
        f.extend(value);
        f
    }

    fn record(fields: &[Vec<u8>], data: &[u8]) -> Vec<u8> {
        let header: Vec<u8> = fields.concat();
        let mut r = Vec::new();
        r.extend((header.len() as u32).to_le_bytes());
        r.extend(header);
        r.extend((data.len() as u32).to_le_bytes());
        r.extend(data);
        r
    }

    /// A bag with one uncompressed chunk: a connection on `/x` of type
    /// `std_msgs/Float64` and the given messages (time ns, f64 value).
    pub(crate) fn tiny_bag(values: &[(u64, f64)]) -> Vec<u8> {
        let conn_header = [
            field("topic", b"/x"),
            field("type", b"std_msgs/Float64"),
            field("md5sum", b"fdb28210bfa9d7c91146260178d9a584"),
            field("message_definition", b"float64 data\n"),
        ]
        .concat();
        let mut chunk = record(
            &[
                field("op", &[OP_CONNECTION]),
                field("conn", &0u32.to_le_bytes()),
                field("topic", b"/x"),
            ],
            &conn_header,
        );
        for (t, v) in values {
            let secs = (t / 1_000_000_000) as u32;
            let nsecs = (t % 1_000_000_000) as u32;
            let time = [secs.to_le_bytes(), nsecs.to_le_bytes()].concat();
            chunk.extend(record(
                &[
                    field("op", &[OP_MESSAGE]),
                    field("conn", &0u32.to_le_bytes()),
                    field("time", &time),
                ],
                &v.to_le_bytes(),
            ));
        }
        let mut bag = BAG_MAGIC.to_vec();
        bag.extend(record(
            &[field("op", &[0x03]), field("conn_count", &1u32.to_le_bytes())],
            &[b' '; 16],
        ));
        bag.extend(record(
            &[
                field("op", &[OP_CHUNK]),
                field("compression", b"none"),
                field("size", &(chunk.len() as u32).to_le_bytes()),
            ],
            &chunk,
        ));
        bag
    }

    #[test]
    fn reads_a_hand_made_bag_and_rejects_its_prefixes() {
        let bag = tiny_bag(&[(1_500_000_000, 2.5), (2_000_000_001, -1.0)]);
        let mut seen = Vec::new();
        let connections = read_bag(&bag, &mut |c, m| {
            seen.push((c.topic.clone(), m.time_ns, m.data.to_vec()));
        })
        .unwrap();
        assert_eq!(connections.len(), 1);
        assert_eq!(connections[&0].message_type, "std_msgs/Float64");
        assert_eq!(connections[&0].definition, "float64 data\n");
        assert_eq!(seen.len(), 2);
        assert_eq!(seen[1].1, 2_000_000_001);
        assert_eq!(seen[0].2, 2.5f64.to_le_bytes().to_vec());
        // A cut inside a record is an error; between records (after the
        // bag header) it is a shorter bag.
        let header_end = BAG_MAGIC.len() + 4 + u32_at(&bag, BAG_MAGIC.len()).unwrap() as usize + 4 + 16;
        for n in BAG_MAGIC.len() + 1..bag.len() {
            let result = read_bag(&bag[..n], &mut |_, _| {});
            assert_eq!(result.is_ok(), n == header_end, "a prefix of {n} bytes");
        }
        assert_eq!(read_bag(b"#ROSBAG V1.2\n", &mut |_, _| {}), Err(BagError::NotABag));
        // Read as a start, a prefix gives the records before its cut: the
        // chunk's two messages once it is whole.
        for n in BAG_MAGIC.len() + 1..=bag.len() {
            let mut count = 0;
            read_bag_start(&bag[..n], &mut |_, _| count += 1).unwrap();
            assert_eq!(count, if n == bag.len() { 2 } else { 0 }, "a prefix of {n} bytes");
        }
    }
}
