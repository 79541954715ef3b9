//! ROS message definitions (the `.msg` text that ROS 1 bags and ROS 2 MCAP
//! files store beside their messages) and a decoder driven by them: ROS 2
//! messages in CDR, ROS 1 messages in their own serialisation.
//!
//! Only what a recording stores is needed: no message package has to be
//! installed, and a custom type (e.g. a robot vendor's state message) is
//! decoded from its definition alone.

use std::collections::HashMap;
use std::sync::Arc;

/// Why a definition or a message could not be read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MsgError {
    /// A definition line is malformed.
    #[error("message definition of {message_type}, line {line}: {reason}: '{text}'")]
    Definition {
        /// The type being defined.
        message_type: String,
        /// Line (1-based) within that type's text.
        line: usize,
        /// The line.
        text: String,
        /// What is wrong.
        reason: String,
    },
    /// A field names a type the definition does not hold.
    #[error(
        "message definition of {message_type}: field '{field}' has type '{field_type}', which the definition does not define"
    )]
    UnknownType {
        /// The type holding the field.
        message_type: String,
        /// The field.
        field: String,
        /// Its type.
        field_type: String,
    },
    /// Types that contain themselves cannot be decoded.
    #[error("message definition of {message_type}: nested more than {MAX_DEPTH} deep (a type contains itself?)")]
    TooDeep {
        /// The root type.
        message_type: String,
    },
    /// A message ended before its definition did.
    #[error("{message_type} message: ends at byte {offset} while reading '{field}'")]
    Truncated {
        /// The root type.
        message_type: String,
        /// The field being read.
        field: String,
        /// Where the bytes ran out.
        offset: usize,
    },
    /// A message holds something its definition forbids.
    #[error("{message_type} message: field '{field}': {reason}")]
    Invalid {
        /// The root type.
        message_type: String,
        /// The field.
        field: String,
        /// What is wrong.
        reason: String,
    },
}

/// How deeply types may nest.
pub const MAX_DEPTH: usize = 32;

/// Which serialisation the messages use.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Encoding {
    /// ROS 2: CDR with its 4-byte encapsulation header (either byte order).
    Cdr,
    /// ROS 1: little-endian, unaligned, strings without terminator.
    Ros1,
}

/// A primitive type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Primitive {
    /// `bool`.
    Bool,
    /// `int8` (and ROS 1 `byte`).
    I8,
    /// `uint8`, `char` (ROS 1), `byte` (ROS 2).
    U8,
    /// `int16`.
    I16,
    /// `uint16`.
    U16,
    /// `int32`.
    I32,
    /// `uint32`.
    U32,
    /// `int64`.
    I64,
    /// `uint64`.
    U64,
    /// `float32`.
    F32,
    /// `float64`.
    F64,
    /// `string`.
    String,
    /// ROS 1 `time`: seconds and nanoseconds, both u32.
    Time,
    /// ROS 1 `duration`: seconds and nanoseconds, both i32.
    Duration,
}

impl Primitive {
    fn parse(name: &str, encoding: Encoding) -> Option<Self> {
        Some(match name {
            "bool" => Self::Bool,
            "int8" => Self::I8,
            "byte" if encoding == Encoding::Ros1 => Self::I8,
            "uint8" | "byte" | "char" => Self::U8,
            "int16" => Self::I16,
            "uint16" => Self::U16,
            "int32" => Self::I32,
            "uint32" => Self::U32,
            "int64" => Self::I64,
            "uint64" => Self::U64,
            "float32" => Self::F32,
            "float64" => Self::F64,
            "string" => Self::String,
            "time" if encoding == Encoding::Ros1 => Self::Time,
            "duration" if encoding == Encoding::Ros1 => Self::Duration,
            _ => return None,
        })
    }

    /// Bytes of one value (and its CDR alignment); strings vary.
    fn size(self) -> usize {
        match self {
            Self::Bool | Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 | Self::String => 4,
            Self::I64 | Self::U64 | Self::F64 | Self::Time | Self::Duration => 8,
        }
    }
}

/// What a field holds, one element of it.
#[derive(Debug, Clone, PartialEq, Eq)]
enum Element {
    Primitive(Primitive),
    /// Index into [`MessageDefinition::types`].
    Message(usize),
}

/// How many elements a field holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Count {
    One,
    Fixed(usize),
    Sequence,
}

#[derive(Debug, Clone, PartialEq, Eq)]
struct Field {
    name: Arc<str>,
    element: Element,
    count: Count,
}

#[derive(Debug, Clone, PartialEq, Eq)]
struct MessageType {
    name: String,
    fields: Vec<Field>,
}

/// A message type with every type it uses, ready to decode messages.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct MessageDefinition {
    encoding: Encoding,
    /// The root type is the first.
    types: Vec<MessageType>,
}

/// A decoded value.
#[derive(Debug, Clone, PartialEq)]
pub enum Value {
    /// `bool`.
    Bool(bool),
    /// Any signed integer.
    Int(i64),
    /// Any unsigned integer.
    UInt(u64),
    /// `float32` or `float64`.
    Float(f64),
    /// `string`.
    Str(String),
    /// An array of `float32` or `float64` (kept flat: the common case).
    Floats(Vec<f64>),
    /// Any other array.
    List(Vec<Value>),
    /// A message: its fields in definition order.
    Struct(Vec<(Arc<str>, Value)>),
}

impl Value {
    /// The field at a dotted path (`header.stamp.sec`).
    #[must_use]
    pub fn get(&self, path: &str) -> Option<&Value> {
        path.split('.').try_fold(self, |value, name| match value {
            Self::Struct(fields) => fields.iter().find(|(n, _)| &**n == name).map(|(_, v)| v),
            _ => None,
        })
    }

    /// As a float (any number).
    #[must_use]
    pub fn as_f64(&self) -> Option<f64> {
        match *self {
            Self::Float(x) => Some(x),
            Self::Int(i) => Some(i as f64),
            Self::UInt(u) => Some(u as f64),
            _ => None,
        }
    }

    /// As a signed integer (any integer that fits).
    #[must_use]
    pub fn as_i64(&self) -> Option<i64> {
        match *self {
            Self::Int(i) => Some(i),
            Self::UInt(u) => i64::try_from(u).ok(),
            _ => None,
        }
    }

    /// As an array of numbers.
    #[must_use]
    pub fn as_floats(&self) -> Option<Vec<f64>> {
        match self {
            Self::Floats(v) => Some(v.clone()),
            Self::List(items) => items.iter().map(Self::as_f64).collect(),
            _ => None,
        }
    }

    /// As an array of strings.
    #[must_use]
    pub fn as_strings(&self) -> Option<Vec<String>> {
        match self {
            Self::List(items) => items
                .iter()
                .map(|v| match v {
                    Self::Str(s) => Some(s.clone()),
                    _ => None,
                })
                .collect(),
            _ => None,
        }
    }

    /// Every field path under this value whose value is a float array
    /// (dotted; for choosing a torque field).
    #[must_use]
    pub fn float_array_paths(&self) -> Vec<String> {
        let mut paths = Vec::new();
        if let Self::Struct(fields) = self {
            for (name, value) in fields {
                match value {
                    Self::Floats(_) => paths.push(name.to_string()),
                    Self::Struct(_) => {
                        paths.extend(value.float_array_paths().into_iter().map(|p| format!("{name}.{p}")));
                    }
                    _ => {}
                }
            }
        }
        paths
    }
}

/// `pkg/msg/Type` and `pkg/Type` both become `pkg/Type`.
#[must_use]
pub fn normalize_type_name(name: &str) -> String {
    let name = name.trim();
    match name.split('/').collect::<Vec<_>>().as_slice() {
        [package, "msg", short] => format!("{package}/{short}"),
        _ => name.to_owned(),
    }
}

/// One field line before its type is resolved.
struct RawField {
    name: String,
    type_name: String,
    count: Count,
}

impl MessageDefinition {
    /// Parses the definition text stored with `type_name` (`.msg` text,
    /// then each dependency after a line of `=` and `MSG: pkg/Type`).
    pub fn parse(type_name: &str, text: &str, encoding: Encoding) -> Result<Self, MsgError> {
        let root = normalize_type_name(type_name);
        let mut blocks: Vec<(String, Vec<RawField>)> = Vec::new();
        let mut current = root.clone();
        let mut fields = Vec::new();
        let mut line_in_block = 0;
        for line in text.lines() {
            line_in_block += 1;
            let trimmed = line.trim();
            if trimmed.len() >= 3 && trimmed.chars().all(|c| c == '=') {
                blocks.push((std::mem::take(&mut current), std::mem::take(&mut fields)));
                line_in_block = 0;
                continue;
            }
            if let Some(name) = trimmed.strip_prefix("MSG:") {
                current = normalize_type_name(name);
                line_in_block = 0;
                continue;
            }
            if let Some(field) = parse_field_line(trimmed, &current, line_in_block)? {
                fields.push(field);
            }
        }
        blocks.push((current, fields));

        let names: Vec<String> = blocks.iter().map(|(n, _)| n.clone()).collect();
        let index: HashMap<&str, usize> = names.iter().enumerate().map(|(i, n)| (n.as_str(), i)).collect();
        let mut types = Vec::with_capacity(blocks.len());
        for (name, raw_fields) in &blocks {
            let package = name.split('/').next().unwrap_or_default();
            let mut fields = Vec::with_capacity(raw_fields.len());
            for raw in raw_fields {
                let element = if let Some(p) = Primitive::parse(&raw.type_name, encoding) {
                    Element::Primitive(p)
                } else {
                    let resolved =
                        resolve(&raw.type_name, package, &index, &names).ok_or_else(|| MsgError::UnknownType {
                            message_type: name.clone(),
                            field: raw.name.clone(),
                            field_type: raw.type_name.clone(),
                        })?;
                    Element::Message(resolved)
                };
                fields.push(Field {
                    name: Arc::from(raw.name.as_str()),
                    element,
                    count: raw.count,
                });
            }
            types.push(MessageType {
                name: name.clone(),
                fields,
            });
        }
        let definition = Self { encoding, types };
        definition.check_depth()?;
        Ok(definition)
    }

    /// The root type's name (`pkg/Type`).
    #[must_use]
    pub fn name(&self) -> &str {
        self.types.first().map_or("", |t| t.name.as_str())
    }

    fn check_depth(&self) -> Result<(), MsgError> {
        // Depth of each type by repeated relaxation; a cycle never settles.
        let mut depth = vec![0usize; self.types.len()];
        for _ in 0..=MAX_DEPTH {
            let mut changed = false;
            for (i, t) in self.types.iter().enumerate() {
                let d = t
                    .fields
                    .iter()
                    .filter_map(|f| match f.element {
                        Element::Message(j) => Some(depth.get(j).copied().unwrap_or(0) + 1),
                        Element::Primitive(_) => None,
                    })
                    .max()
                    .unwrap_or(0);
                if let Some(slot) = depth.get_mut(i)
                    && *slot != d
                {
                    *slot = d;
                    changed = true;
                }
            }
            if !changed {
                return Ok(());
            }
        }
        Err(MsgError::TooDeep {
            message_type: self.name().to_owned(),
        })
    }

    /// Decodes one message.
    pub fn decode(&self, bytes: &[u8]) -> Result<Value, MsgError> {
        let mut reader = Reader::new(self, bytes)?;
        reader.message(0)
    }
}

/// `Type` within `package`, `pkg/Type`, or ROS 1's `Header`.
fn resolve(type_name: &str, package: &str, index: &HashMap<&str, usize>, names: &[String]) -> Option<usize> {
    let normalized = normalize_type_name(type_name);
    if normalized.contains('/') {
        return index.get(normalized.as_str()).copied();
    }
    if let Some(&i) = index.get(format!("{package}/{normalized}").as_str()) {
        return Some(i);
    }
    if normalized == "Header"
        && let Some(&i) = index.get("std_msgs/Header")
    {
        return Some(i);
    }
    // Lenient: a unique type of that short name anywhere in the text.
    let mut matches = names
        .iter()
        .enumerate()
        .filter(|(_, n)| n.rsplit('/').next() == Some(normalized.as_str()));
    match (matches.next(), matches.next()) {
        (Some((i, _)), None) => Some(i),
        _ => None,
    }
}

/// A field line, or `None` for blank lines, comments and constants.
fn parse_field_line(line: &str, message_type: &str, number: usize) -> Result<Option<RawField>, MsgError> {
    let bad = |reason: &str| MsgError::Definition {
        message_type: message_type.to_owned(),
        line: number,
        text: line.to_owned(),
        reason: reason.to_owned(),
    };
    let code = line.split('#').next().unwrap_or_default().trim();
    if code.is_empty() {
        return Ok(None);
    }
    let mut parts = code.split_whitespace();
    let (Some(type_text), Some(rest)) = (parts.next(), parts.next()) else {
        return Err(bad("expected 'type name'"));
    };
    // Constants (`int8 A=1`, `string S = x`) hold no bytes in a message.
    if rest.contains('=') || code.split_whitespace().nth(2).is_some_and(|t| t.starts_with('=')) {
        return Ok(None);
    }
    let name = rest;
    if !name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
        return Err(bad("bad field name"));
    }
    let (base, count) = match type_text.find('[') {
        None => (type_text, Count::One),
        Some(open) => {
            let inside = type_text
                .get(open + 1..)
                .and_then(|s| s.strip_suffix(']'))
                .ok_or_else(|| bad("unclosed '['"))?;
            let count = if inside.is_empty() || inside.starts_with("<=") {
                Count::Sequence
            } else {
                let n: usize = inside.parse().map_err(|_| bad("bad array size"))?;
                if n > 1 << 20 {
                    return Err(bad("array size above 2^20"));
                }
                Count::Fixed(n)
            };
            (type_text.get(..open).unwrap_or_default(), count)
        }
    };
    // Bounded strings (`string<=10`) decode as strings.
    let base = base.split("<=").next().unwrap_or_default();
    if base.is_empty() {
        return Err(bad("empty type"));
    }
    if base == "wstring" {
        return Err(bad("wstring is not supported"));
    }
    Ok(Some(RawField {
        name: name.to_owned(),
        type_name: base.to_owned(),
        count,
    }))
}

struct Reader<'a> {
    definition: &'a MessageDefinition,
    bytes: &'a [u8],
    /// Where CDR alignment counts from.
    origin: usize,
    offset: usize,
    little_endian: bool,
    field: Arc<str>,
    depth: usize,
}

impl<'a> Reader<'a> {
    fn new(definition: &'a MessageDefinition, bytes: &'a [u8]) -> Result<Self, MsgError> {
        let mut reader = Self {
            definition,
            bytes,
            origin: 0,
            offset: 0,
            little_endian: true,
            field: Arc::from("(encapsulation header)"),
            depth: 0,
        };
        if definition.encoding == Encoding::Cdr {
            let header = reader.take(4)?;
            reader.little_endian = match header {
                [0, 1, _, _] => true,
                [0, 0, _, _] => false,
                _ => {
                    return Err(
                        reader.invalid(format!("encapsulation {header:02x?} is not plain CDR (00 00 or 00 01)"))
                    );
                }
            };
            reader.origin = 4;
        }
        Ok(reader)
    }

    fn invalid(&self, reason: String) -> MsgError {
        MsgError::Invalid {
            message_type: self.definition.name().to_owned(),
            field: self.field.to_string(),
            reason,
        }
    }

    fn take(&mut self, n: usize) -> Result<&'a [u8], MsgError> {
        let end = self.offset.checked_add(n);
        match end.and_then(|end| self.bytes.get(self.offset..end)) {
            Some(slice) => {
                self.offset += n;
                Ok(slice)
            }
            None => Err(MsgError::Truncated {
                message_type: self.definition.name().to_owned(),
                field: self.field.to_string(),
                offset: self.bytes.len(),
            }),
        }
    }

    fn align(&mut self, size: usize) -> Result<(), MsgError> {
        if self.definition.encoding == Encoding::Cdr && size > 1 {
            let misalignment = (self.offset - self.origin) % size;
            if misalignment != 0 {
                self.take(size - misalignment)?;
            }
        }
        Ok(())
    }

    fn array<const N: usize>(&mut self) -> Result<[u8; N], MsgError> {
        let slice = self.take(N)?;
        let mut out = [0u8; N];
        out.copy_from_slice(slice);
        if !self.little_endian {
            out.reverse();
        }
        Ok(out)
    }

    fn u32(&mut self) -> Result<u32, MsgError> {
        self.align(4)?;
        Ok(u32::from_le_bytes(self.array()?))
    }

    /// A sequence length, bounded by the bytes left so that a corrupt
    /// length cannot ask for gigabytes.
    fn length(&mut self, element_bytes: usize) -> Result<usize, MsgError> {
        let n = self.u32()? as usize;
        let left = self.bytes.len().saturating_sub(self.offset);
        if n.saturating_mul(element_bytes.max(1)) > left {
            return Err(self.invalid(format!("length {n} exceeds the {left} bytes left")));
        }
        Ok(n)
    }

    fn primitive(&mut self, p: Primitive) -> Result<Value, MsgError> {
        if p != Primitive::String {
            self.align(match p {
                Primitive::Time | Primitive::Duration => 4,
                _ => p.size(),
            })?;
        }
        Ok(match p {
            Primitive::Bool => Value::Bool(self.array::<1>()?[0] != 0),
            Primitive::I8 => Value::Int(i64::from(i8::from_le_bytes(self.array()?))),
            Primitive::U8 => Value::UInt(u64::from(self.array::<1>()?[0])),
            Primitive::I16 => Value::Int(i64::from(i16::from_le_bytes(self.array()?))),
            Primitive::U16 => Value::UInt(u64::from(u16::from_le_bytes(self.array()?))),
            Primitive::I32 => Value::Int(i64::from(i32::from_le_bytes(self.array()?))),
            Primitive::U32 => Value::UInt(u64::from(u32::from_le_bytes(self.array()?))),
            Primitive::I64 => Value::Int(i64::from_le_bytes(self.array()?)),
            Primitive::U64 => Value::UInt(u64::from_le_bytes(self.array()?)),
            Primitive::F32 => Value::Float(f64::from(f32::from_le_bytes(self.array()?))),
            Primitive::F64 => Value::Float(f64::from_le_bytes(self.array()?)),
            Primitive::Time => {
                let secs = u32::from_le_bytes(self.array()?);
                let nsecs = u32::from_le_bytes(self.array()?);
                Value::Struct(vec![
                    (Arc::from("sec"), Value::UInt(u64::from(secs))),
                    (Arc::from("nanosec"), Value::UInt(u64::from(nsecs))),
                ])
            }
            Primitive::Duration => {
                let secs = i32::from_le_bytes(self.array()?);
                let nsecs = i32::from_le_bytes(self.array()?);
                Value::Struct(vec![
                    (Arc::from("sec"), Value::Int(i64::from(secs))),
                    (Arc::from("nanosec"), Value::Int(i64::from(nsecs))),
                ])
            }
            Primitive::String => {
                let n = self.length(1)?;
                let bytes = self.take(n)?;
                // CDR counts and stores a terminating NUL; ROS 1 neither.
                let text = match self.definition.encoding {
                    Encoding::Cdr => bytes.strip_suffix(&[0]).unwrap_or(bytes),
                    Encoding::Ros1 => bytes,
                };
                Value::Str(String::from_utf8_lossy(text).into_owned())
            }
        })
    }

    fn element(&mut self, element: &Element) -> Result<Value, MsgError> {
        match element {
            Element::Primitive(p) => self.primitive(*p),
            Element::Message(i) => self.message(*i),
        }
    }

    fn message(&mut self, type_index: usize) -> Result<Value, MsgError> {
        let definition = self.definition;
        let Some(message_type) = definition.types.get(type_index) else {
            return Err(self.invalid(format!("no type {type_index}")));
        };
        self.depth += 1;
        if self.depth > MAX_DEPTH {
            return Err(MsgError::TooDeep {
                message_type: definition.name().to_owned(),
            });
        }
        let mut values = Vec::with_capacity(message_type.fields.len());
        for field in &message_type.fields {
            self.field = Arc::clone(&field.name);
            let n = match field.count {
                Count::One => {
                    let value = self.element(&field.element)?;
                    values.push((Arc::clone(&field.name), value));
                    continue;
                }
                Count::Fixed(n) => n,
                Count::Sequence => {
                    let element_bytes = match field.element {
                        Element::Primitive(p) => p.size(),
                        Element::Message(_) => 0,
                    };
                    self.length(element_bytes)?
                }
            };
            let value = match field.element {
                Element::Primitive(p @ (Primitive::F32 | Primitive::F64)) => {
                    let mut floats = Vec::with_capacity(n.min(1 << 16));
                    for _ in 0..n {
                        if let Value::Float(x) = self.primitive(p)? {
                            floats.push(x);
                        }
                    }
                    Value::Floats(floats)
                }
                ref element => {
                    let mut items = Vec::with_capacity(n.min(1 << 16));
                    for _ in 0..n {
                        items.push(self.element(element)?);
                    }
                    Value::List(items)
                }
            };
            values.push((Arc::clone(&field.name), value));
        }
        self.depth -= 1;
        Ok(Value::Struct(values))
    }
}

#[cfg(test)]
#[path = "rosmsg_tests.rs"]
mod tests;
