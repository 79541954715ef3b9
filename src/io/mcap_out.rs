//! Estimates out as ROS 2 MCAP, beside the input's own topics, so that
//! Foxglove, `RViz` (through rosbag2) or our own reader show them on the
//! robot.
//!
//! Topics written per frame (stamped with the frame's time):
//! - `/proprioscope/contact_probability` (`std_msgs/Float64`): every frame
//!   estimated over time (`--temporal filter|smooth`);
//! - `/proprioscope/contact` (`geometry_msgs/WrenchStamped`) and
//!   `/proprioscope/contact_point` (`geometry_msgs/PointStamped`): the
//!   most probable contact, only in frames with one, in the convention of
//!   the truth topics (`frame_id` of the wrench is the touched link, its
//!   force is in the world frame; the point is in the world frame);
//! - `/proprioscope/second_contact` and `/proprioscope/second_contact_point`
//!   (the same types): in frames where two contacts are called, the
//!   second (`/proprioscope/contact` then holds the first of the pair);
//! - `/proprioscope/region` (`sensor_msgs/PointCloud2`, world frame): the
//!   90 % credible set, fields `x y z` and `probability` (float32), empty
//!   in frames without contact; at the times of the Foxglove scene
//!   (`super::foxglove`'s arrows, at most 30 a second) where it is drawn.

use std::collections::{BTreeMap, HashMap};
use std::io::BufWriter;
use std::path::{Path, PathBuf};

use super::cdr::Cdr;
use super::foxglove::{ArmScene, FoxgloveFrame, Outgoing, frame_messages, opening};
use super::recording::{
    RecordingError, SECOND_TRUTH_POINT_TOPIC, SECOND_TRUTH_TOPIC, TRUTH_POINT_TOPIC, TRUTH_TOPIC, scan,
};
use super::session::{Frame, Truth};

/// Why the MCAP could not be written.
#[derive(Debug, thiserror::Error)]
pub enum McapOutError {
    /// The file could not be created or written.
    #[error("{path}: cannot write the MCAP: {reason}")]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        reason: String,
    },
    /// The input recording could not be copied.
    #[error(transparent)]
    Input(#[from] RecordingError),
}

/// One frame's estimate, as plain values.
#[derive(Debug, Clone, PartialEq)]
pub struct EstimateMessage {
    /// The frame's time, ns (the recording's clock).
    pub stamp_ns: i64,
    /// Probability that something touches the robot, when the estimate
    /// over time gives one.
    pub contact_probability: Option<f64>,
    /// The most probable contact, when the frame has one: link, point
    /// (world, m), force on the robot (world, N).
    pub contact: Option<(String, [f64; 3], [f64; 3])>,
    /// The second contact where two are called (`contact` is then the
    /// first of the pair), as `contact`.
    pub second_contact: Option<(String, [f64; 3], [f64; 3])>,
    /// The probable region: points (world, m) with their probability;
    /// `None`: not written for this frame (it follows the Foxglove scene's
    /// rate where there is one).
    pub region: Option<Vec<([f64; 3], f64)>>,
    /// What Foxglove shows of the frame, written where the writer has the
    /// arm's scene ([`EstimateWriter::add_foxglove`]).
    pub foxglove: Option<FoxgloveFrame>,
}

const HEADER_DEPS: &str = "================================================================================
MSG: std_msgs/Header
builtin_interfaces/Time stamp
string frame_id
================================================================================
MSG: builtin_interfaces/Time
int32 sec
uint32 nanosec
";

const VECTOR3: &str = "================================================================================
MSG: geometry_msgs/Vector3
float64 x
float64 y
float64 z
";

/// The schemas this module writes: name and `ros2msg` text.
fn schema_text(name: &str) -> String {
    match name {
        "std_msgs/msg/Float64" => "float64 data\n".to_owned(),
        "geometry_msgs/msg/PointStamped" => format!(
            "std_msgs/Header header\ngeometry_msgs/Point point\n{HEADER_DEPS}================================================================================\nMSG: geometry_msgs/Point\nfloat64 x\nfloat64 y\nfloat64 z\n"
        ),
        "geometry_msgs/msg/WrenchStamped" => format!(
            "std_msgs/Header header\ngeometry_msgs/Wrench wrench\n{HEADER_DEPS}================================================================================\nMSG: geometry_msgs/Wrench\nVector3 force\nVector3 torque\n{VECTOR3}"
        ),
        "sensor_msgs/msg/JointState" => format!(
            "std_msgs/Header header\nstring[] name\nfloat64[] position\nfloat64[] velocity\nfloat64[] effort\n{HEADER_DEPS}"
        ),
        "sensor_msgs/msg/PointCloud2" => format!(
            "std_msgs/Header header\nuint32 height\nuint32 width\nsensor_msgs/PointField[] fields\nbool is_bigendian\nuint32 point_step\nuint32 row_step\nuint8[] data\nbool is_dense\n{HEADER_DEPS}================================================================================\nMSG: sensor_msgs/PointField\nuint8 INT8=1\nuint8 UINT8=2\nuint8 INT16=3\nuint8 UINT16=4\nuint8 INT32=5\nuint8 UINT32=6\nuint8 FLOAT32=7\nuint8 FLOAT64=8\nstring name\nuint32 offset\nuint8 datatype\nuint32 count\n"
        ),
        _ => String::new(),
    }
}

/// Writes estimates (and what they came from) to an MCAP file.
pub struct EstimateWriter {
    path: PathBuf,
    writer: mcap::Writer<BufWriter<std::fs::File>>,
    world_frame: String,
    /// Our channels by topic.
    channels: HashMap<&'static str, u16>,
    /// The Foxglove messages' channels by topic.
    foxglove_channels: HashMap<&'static str, u16>,
    /// The arm's scene, where the estimates are drawn for Foxglove.
    scene: Option<ArmScene>,
    sequence: u32,
}

const OUT_TOPICS: [(&str, &str); 6] = [
    ("/proprioscope/contact_probability", "std_msgs/msg/Float64"),
    ("/proprioscope/contact", "geometry_msgs/msg/WrenchStamped"),
    ("/proprioscope/contact_point", "geometry_msgs/msg/PointStamped"),
    ("/proprioscope/second_contact", "geometry_msgs/msg/WrenchStamped"),
    ("/proprioscope/second_contact_point", "geometry_msgs/msg/PointStamped"),
    ("/proprioscope/region", "sensor_msgs/msg/PointCloud2"),
];

impl EstimateWriter {
    /// Creates the file; `world_frame` names the robot's root link.
    pub fn create(path: &Path, world_frame: &str) -> Result<Self, McapOutError> {
        let fail = |reason: String| McapOutError::Write {
            path: path.to_owned(),
            reason,
        };
        let file = std::fs::File::create(path).map_err(|e| fail(e.to_string()))?;
        // Chunks of 4 MiB rather than 768 KiB: the heatmaps repeat their
        // points and colours, and larger chunks let the compression find
        // them (4 % smaller on a 1 kHz minute: docs/decisions.md, *Foxglove*).
        let options = mcap::WriteOptions::new()
            .chunk_size(Some(4 << 20))
            .profile("ros2")
            .library(concat!("proprioscope/", env!("CARGO_PKG_VERSION")));
        let writer = options.create(BufWriter::new(file)).map_err(|e| fail(e.to_string()))?;
        let mut out = Self {
            path: path.to_owned(),
            writer,
            world_frame: world_frame.to_owned(),
            channels: HashMap::new(),
            foxglove_channels: HashMap::new(),
            scene: None,
            sequence: 0,
        };
        for (topic, schema) in OUT_TOPICS {
            let id = out.channel(topic, schema)?;
            out.channels.insert(topic, id);
        }
        Ok(out)
    }

    fn fail(&self, e: impl std::fmt::Display) -> McapOutError {
        McapOutError::Write {
            path: self.path.clone(),
            reason: e.to_string(),
        }
    }

    fn channel(&mut self, topic: &str, schema: &str) -> Result<u16, McapOutError> {
        let schema_id = self
            .writer
            .add_schema(schema, "ros2msg", schema_text(schema).as_bytes())
            .map_err(|e| self.fail(e))?;
        self.writer
            .add_channel(schema_id, topic, "cdr", &BTreeMap::new())
            .map_err(|e| self.fail(e))
    }

    fn write(&mut self, channel: u16, stamp_ns: i64, data: &[u8]) -> Result<(), McapOutError> {
        let time = u64::try_from(stamp_ns).unwrap_or(0);
        self.sequence = self.sequence.wrapping_add(1);
        let header = mcap::records::MessageHeader {
            channel_id: channel,
            sequence: self.sequence,
            log_time: time,
            publish_time: time,
        };
        self.writer
            .write_to_known_channel(&header, data)
            .map_err(|e| self.fail(e))
    }

    /// Copies every message of a recording (its topics, types and times).
    pub fn copy_recording(&mut self, source: &Path, bytes: &[u8]) -> Result<(), McapOutError> {
        let mut ids: HashMap<u32, u16> = HashMap::new();
        let mut failure = None;
        scan(source, bytes, false, &mut |message| {
            if failure.is_some() {
                return;
            }
            let id = if let Some(&id) = ids.get(&message.key) {
                id
            } else {
                {
                    let (encoding, text) = message.schema.unwrap_or(("", &[]));
                    let added = self
                        .writer
                        .add_schema(message.message_type, encoding, text)
                        .and_then(|schema| {
                            self.writer
                                .add_channel(schema, message.topic, message.message_encoding, &BTreeMap::new())
                        });
                    match added {
                        Ok(id) => {
                            ids.insert(message.key, id);
                            id
                        }
                        Err(e) => {
                            failure = Some(self.fail(e));
                            return;
                        }
                    }
                }
            };
            let header = mcap::records::MessageHeader {
                channel_id: id,
                sequence: 0,
                log_time: message.log_ns,
                publish_time: message.log_ns,
            };
            if let Err(e) = self.writer.write_to_known_channel(&header, message.data) {
                failure = Some(self.fail(e));
            }
        })?;
        failure.map_or(Ok(()), Err)
    }

    /// Writes a session's frames as a recording would hold them:
    /// `/joint_states` (positions, and the external torques as effort) and
    /// the truth topics, at `origin_ns` + each frame's time.
    pub fn write_frames(&mut self, joints: &[String], frames: &[Frame], origin_ns: i64) -> Result<(), McapOutError> {
        self.write_joint_states("/joint_states", joints, frames, origin_ns)?;
        let truth = self.channel(TRUTH_TOPIC, "geometry_msgs/msg/WrenchStamped")?;
        let truth_point = self.channel(TRUTH_POINT_TOPIC, "geometry_msgs/msg/PointStamped")?;
        // A second true contact's topics only where one is recorded.
        let second = if frames.iter().any(|f| f.truth_all.len() >= 2) {
            Some((
                self.channel(SECOND_TRUTH_TOPIC, "geometry_msgs/msg/WrenchStamped")?,
                self.channel(SECOND_TRUTH_POINT_TOPIC, "geometry_msgs/msg/PointStamped")?,
            ))
        } else {
            None
        };
        for frame in frames {
            let stamp = origin_ns.saturating_add((frame.t * 1e9).round() as i64);
            // The first contact is `truth` (else `truth_all`'s first), the
            // second the other of `truth_all`.
            let first = match (&frame.truth, frame.truth_all.first()) {
                (Truth::Contact { link, point, force }, _) => Some((link.as_str(), *point, *force)),
                (_, Some(c)) => Some((c.link.as_str(), c.point, c.force)),
                _ => None,
            };
            let second_contact = (frame.truth_all.len() >= 2)
                .then(|| {
                    frame
                        .truth_all
                        .iter()
                        .map(|c| (c.link.as_str(), c.point, c.force))
                        .find(|c| Some(*c) != first)
                })
                .flatten();
            for ((wrench_id, point_id), contact) in [
                ((truth, truth_point), first),
                (second.unwrap_or((truth, truth_point)), second_contact),
            ] {
                let Some((link, point, force)) = contact else { continue };
                let mut w = Cdr::new();
                w.header(stamp, link).xyz(force).xyz([0.0; 3]);
                self.write(wrench_id, stamp, &w.0)?;
                let mut p = Cdr::new();
                p.header(stamp, &self.world_frame).xyz(point);
                self.write(point_id, stamp, &p.0)?;
            }
        }
        Ok(())
    }

    /// Writes frames as `sensor_msgs/JointState` messages on `topic`
    /// (positions, and the torques as effort) at `origin_ns` + each
    /// frame's time.
    pub fn write_joint_states(
        &mut self,
        topic: &str,
        joints: &[String],
        frames: &[Frame],
        origin_ns: i64,
    ) -> Result<(), McapOutError> {
        let states = self.channel(topic, "sensor_msgs/msg/JointState")?;
        for frame in frames {
            let stamp = origin_ns.saturating_add((frame.t * 1e9).round() as i64);
            let mut m = Cdr::new();
            m.header(stamp, "");
            m.u32(joints.len() as u32);
            for name in joints {
                m.string(name);
            }
            m.floats(&frame.q).floats(&[]).floats(&frame.tau);
            self.write(states, stamp, &m.0)?;
        }
        Ok(())
    }

    /// Writes one frame's estimate.
    pub fn write_estimate(&mut self, e: &EstimateMessage) -> Result<(), McapOutError> {
        let id = |topic: &str| self.channels.get(topic).copied().unwrap_or(0);
        let (probability, contact, point, region) = (
            id("/proprioscope/contact_probability"),
            id("/proprioscope/contact"),
            id("/proprioscope/contact_point"),
            id("/proprioscope/region"),
        );
        let second = (
            id("/proprioscope/second_contact"),
            id("/proprioscope/second_contact_point"),
        );
        if let Some(p) = e.contact_probability {
            let mut m = Cdr::new();
            m.f64(p);
            self.write(probability, e.stamp_ns, &m.0)?;
        }
        let world = self.world_frame.clone();
        for ((contact, point), c) in [((contact, point), &e.contact), (second, &e.second_contact)] {
            let Some((link, p, f)) = c else { continue };
            let mut w = Cdr::new();
            w.header(e.stamp_ns, link).xyz(*f).xyz([0.0; 3]);
            self.write(contact, e.stamp_ns, &w.0)?;
            let mut q = Cdr::new();
            q.header(e.stamp_ns, &world).xyz(*p);
            self.write(point, e.stamp_ns, &q.0)?;
        }
        if let Some(points) = &e.region {
            let mut c = Cdr::new();
            c.header(e.stamp_ns, &world).u32(1).u32(points.len() as u32);
            c.u32(4);
            for (k, name) in ["x", "y", "z", "probability"].iter().enumerate() {
                // FLOAT32 = 7, one each.
                c.string(name).u32(4 * k as u32).u8(7).u32(1);
            }
            c.u8(0).u32(16).u32(16 * points.len() as u32);
            c.u32(16 * points.len() as u32);
            for (p, probability) in points {
                for v in [p[0], p[1], p[2], *probability] {
                    c.0.extend((v as f32).to_le_bytes());
                }
            }
            c.u8(1);
            self.write(region, e.stamp_ns, &c.0)?;
        }
        if let (Some(scene), Some(frame)) = (&self.scene, &e.foxglove) {
            let messages = frame_messages(scene, frame);
            self.write_outgoing(&messages)?;
        }
        Ok(())
    }

    /// From now on, draws each estimate for Foxglove on `scene`'s arm
    /// (`super::foxglove`): its meshes and URDF are written at `stamp_ns`.
    pub fn add_foxglove(&mut self, scene: ArmScene, stamp_ns: i64) -> Result<(), McapOutError> {
        self.write_outgoing(&opening(&scene, stamp_ns))?;
        self.scene = Some(scene);
        Ok(())
    }

    /// Writes Foxglove's messages (`super::foxglove`), each topic's channel
    /// made with its schema the first time it comes.
    pub fn write_outgoing(&mut self, messages: &[Outgoing]) -> Result<(), McapOutError> {
        for m in messages {
            let channel = if let Some(&id) = self.foxglove_channels.get(m.topic) {
                id
            } else {
                let schema = self
                    .writer
                    .add_schema(&m.schema_name, m.schema_encoding, &m.schema_data)
                    .map_err(|e| self.fail(e))?;
                let id = self
                    .writer
                    .add_channel(schema, m.topic, m.message_encoding, &BTreeMap::new())
                    .map_err(|e| self.fail(e))?;
                self.foxglove_channels.insert(m.topic, id);
                id
            };
            self.write(channel, m.stamp_ns, &m.data)?;
        }
        Ok(())
    }

    /// Writes the summary and closes the file.
    pub fn finish(mut self) -> Result<(), McapOutError> {
        self.writer.finish().map_err(|e| self.fail(e))?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::recording::{self, TopicChoice};
    use crate::io::rosmsg::Value;
    use crate::io::session::ContactTruth;

    #[test]
    fn estimates_and_frames_read_back_with_our_reader() {
        let dir = std::env::temp_dir().join(format!("proprioscope-mcap-out-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("est.mcap");
        let joints = vec!["j1".to_owned(), "j2".to_owned()];
        let frames: Vec<Frame> = (0..5)
            .map(|k| Frame {
                t: 0.005 * f64::from(k),
                q: vec![0.1 * f64::from(k), -0.2],
                tau: vec![1.0, f64::from(k)],
                truth: if k % 2 == 0 {
                    Truth::Contact {
                        link: "l2".into(),
                        point: [0.1, 0.2, 0.3],
                        force: [0.0, -5.0, 1.0],
                    }
                } else {
                    Truth::NoContact
                },
                // Frame 2 has a second true contact.
                truth_all: if k == 2 {
                    vec![
                        ContactTruth {
                            link: "l2".into(),
                            point: [0.1, 0.2, 0.3],
                            force: [0.0, -5.0, 1.0],
                        },
                        ContactTruth {
                            link: "l3".into(),
                            point: [0.4, 0.5, 0.6],
                            force: [1.0, 0.0, 2.0],
                        },
                    ]
                } else {
                    Vec::new()
                },
            })
            .collect();
        let origin = 1_760_000_000_000_000_000;
        let mut out = EstimateWriter::create(&path, "base").unwrap();
        out.write_frames(&joints, &frames, origin).unwrap();
        for (k, f) in frames.iter().enumerate() {
            out.write_estimate(&EstimateMessage {
                stamp_ns: origin + (f.t * 1e9).round() as i64,
                contact_probability: Some(0.25 * k as f64),
                contact: (k == 2).then(|| ("l2".to_owned(), [0.1, 0.2, 0.3], [0.0, -4.0, 0.0])),
                second_contact: (k == 2).then(|| ("l3".to_owned(), [0.4, 0.2, 0.3], [0.0, 0.0, 5.0])),
                region: Some(vec![([0.1, 0.2, 0.3], 0.5), ([0.0, 0.0, 1.0], 0.25)]),
                foxglove: None,
            })
            .unwrap();
        }
        out.finish().unwrap();

        let bytes = std::fs::read(&path).unwrap();
        let read = recording::read_session(&path, &bytes, &TopicChoice::default(), &|_| {}).unwrap();
        assert_eq!(read.session.frames, frames);
        assert_eq!(read.session.joints, Some(joints));
        let index = recording::index(&path, &bytes).unwrap();
        let topic = |name: &str| index.topics.iter().find(|t| t.topic == name).unwrap();
        assert_eq!(topic("/proprioscope/contact_probability").count, 5);
        assert_eq!(topic("/proprioscope/contact").count, 1);
        let first = topic("/proprioscope/contact").first.clone().unwrap();
        assert_eq!(first.get("header.frame_id"), Some(&Value::Str("l2".into())));
        assert_eq!(first.get("wrench.force.y").and_then(Value::as_f64), Some(-4.0));
        assert_eq!(topic("/proprioscope/second_contact").count, 1);
        let second = topic("/proprioscope/second_contact").first.clone().unwrap();
        assert_eq!(second.get("header.frame_id"), Some(&Value::Str("l3".into())));
        assert_eq!(second.get("wrench.force.z").and_then(Value::as_f64), Some(5.0));
        let point = topic("/proprioscope/second_contact_point").first.clone().unwrap();
        assert_eq!(point.get("point.x").and_then(Value::as_f64), Some(0.4));
        let cloud = topic("/proprioscope/region").first.clone().unwrap();
        assert_eq!(cloud.get("width").and_then(Value::as_i64), Some(2));
        assert_eq!(cloud.get("point_step").and_then(Value::as_i64), Some(16));
        let Some(Value::List(data)) = cloud.get("data") else {
            panic!()
        };
        let bytes: Vec<u8> = data.iter().map(|v| v.as_i64().unwrap() as u8).collect();
        let f = |i: usize| f32::from_le_bytes(bytes[4 * i..4 * i + 4].try_into().unwrap());
        assert_eq!((f(2), f(3), f(6), f(7)), (0.3, 0.5, 1.0, 0.25));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
