//! What Foxglove shows of the estimates: the arm moving, the posterior
//! painted on it, the contacts as arrows and the numbers to plot, in
//! Foxglove's own schemas (the `foxglove` crate's protobuf messages), for
//! an MCAP file (`super::mcap_out`) or the live WebSocket server
//! (`serve`). The messages are built here once and go out either way.
//!
//! Topics (beside `super::mcap_out`'s ROS 2 ones):
//! - `/proprioscope/transforms` (`foxglove.FrameTransforms`): every
//!   link's transform from its parent, every frame;
//! - `/proprioscope/arm` (`foxglove.SceneUpdate`): each link's mesh in its
//!   frame, once (and, live, every second for viewers that join late);
//! - `/robot_description` (`std_msgs/String`): the robot as URDF, once;
//! - `/proprioscope/heatmap` (`foxglove.SceneUpdate`): the posterior over
//!   the links in the app's colours, at most [`HEAT_HZ`] times a second
//!   and whenever a contact is called or released;
//! - `/proprioscope/arrows` (`foxglove.SceneUpdate`): the contacts (and a
//!   recording's truth) as the app's arrows, at most [`SCENE_HZ`] times a
//!   second and whenever a contact is called or released;
//! - `/proprioscope/numbers` (`proprioscope_msgs/FrameNumbers`, CDR):
//!   contact probability, force, verdict and the errors against the
//!   truth, every frame, for Foxglove's plots.

pub mod description;
pub mod layout;
pub mod painter;
pub mod readback;
pub mod scene;
pub mod serve;

use foxglove::Encode;
use glam::DVec3;

use super::cdr::Cdr;
use crate::core::estimate::estimator::Update;
use crate::core::estimate::summary::Verdict;

pub use painter::FoxglovePainter;
pub use scene::{ArmScene, Arrow, ArrowRole};

/// The most arrow updates (and credible sets) a second of the recording
/// gets; a contact called or released is always sent, and arrows that did
/// not move visibly are not sent again.
pub const SCENE_HZ: f64 = 30.0;

/// The most heatmaps a second of the recording gets, on the same terms: a
/// heatmap is the largest message (tens of kilobytes where the posterior
/// is wide), and at 15 a second the file of a 1 kHz recording stays
/// within twice its input (docs/validation.md, *Foxglove*).
pub const HEAT_HZ: f64 = 15.0;

/// The most transforms a second of the recording gets: every frame of a
/// recording at this rate or slower. A 1 kHz arm's transforms every
/// frame would be the largest part of the file, and Foxglove draws at
/// the screen's rate; `estimate --tf-hz 0` writes every frame.
pub const TRANSFORMS_HZ: f64 = 100.0;

/// Topic of the links' transforms.
pub const TRANSFORMS_TOPIC: &str = "/proprioscope/transforms";
/// Topic of the arm's meshes.
pub const ARM_TOPIC: &str = "/proprioscope/arm";
/// Topic of the URDF.
pub const DESCRIPTION_TOPIC: &str = "/robot_description";
/// Topic of the painted posterior.
pub const HEATMAP_TOPIC: &str = "/proprioscope/heatmap";
/// Topic of the arrows.
pub const ARROWS_TOPIC: &str = "/proprioscope/arrows";
/// Topic of the per-frame numbers.
pub const NUMBERS_TOPIC: &str = "/proprioscope/numbers";

/// A message on its way out: topic, schema, encoding and bytes.
#[derive(Debug, Clone, PartialEq)]
pub struct Outgoing {
    /// The topic.
    pub topic: &'static str,
    /// The schema's name (`foxglove.SceneUpdate`, `std_msgs/msg/String`).
    pub schema_name: String,
    /// How the schema is written (`protobuf`, `ros2msg`).
    pub schema_encoding: &'static str,
    /// The schema itself.
    pub schema_data: Vec<u8>,
    /// How the message is encoded (`protobuf`, `cdr`).
    pub message_encoding: &'static str,
    /// The message.
    pub data: Vec<u8>,
    /// Its time, ns on the recording's clock.
    pub stamp_ns: i64,
}

/// A Foxglove schema message as outgoing bytes.
fn encoded<T: Encode>(topic: &'static str, message: &T, stamp_ns: i64) -> Outgoing {
    let schema = T::get_schema();
    let mut data = Vec::with_capacity(message.encoded_len().unwrap_or(256));
    // Encoding into a growing Vec cannot run out of room.
    let _ = message.encode(&mut data);
    Outgoing {
        topic,
        schema_name: schema.as_ref().map_or_else(String::new, |s| s.name.clone()),
        schema_encoding: "protobuf",
        schema_data: schema.map(|s| s.data.into_owned()).unwrap_or_default(),
        message_encoding: "protobuf",
        data,
        stamp_ns,
    }
}

/// `std_msgs/String` as a ROS 2 message.
fn ros_string(topic: &'static str, text: &str, stamp_ns: i64) -> Outgoing {
    let mut m = Cdr::new();
    m.string(text);
    Outgoing {
        topic,
        schema_name: "std_msgs/msg/String".to_owned(),
        schema_encoding: "ros2msg",
        schema_data: b"string data\n".to_vec(),
        message_encoding: "cdr",
        data: m.0,
        stamp_ns,
    }
}

/// The schema of [`FrameNumbers`] (`ros2msg`).
pub const NUMBERS_SCHEMA: &str = "# One frame's estimate as numbers; NaN where there is none.
float64 contact_probability
float64 force_newtons
uint8 verdict
float64 position_error_m
float64 force_error_newtons
";

/// One frame's numbers for plots.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameNumbers {
    /// Probability that something touches the arm (the estimate over time's,
    /// else 1 for a contact called and 0 for none).
    pub contact_probability: f64,
    /// The most probable contact's force, N (0 without one).
    pub force_newtons: f64,
    /// 0 no contact, 1 contact, 2 poorly explained.
    pub verdict: u8,
    /// Distance from the true contact, m (NaN without both).
    pub position_error_m: f64,
    /// Force error against the truth, N (NaN without both).
    pub force_error_newtons: f64,
}

impl FrameNumbers {
    /// No estimate: every number NaN, the verdict "no contact".
    pub const NONE: Self = Self {
        contact_probability: f64::NAN,
        force_newtons: f64::NAN,
        verdict: 0,
        position_error_m: f64::NAN,
        force_error_newtons: f64::NAN,
    };

    /// A frame's numbers from its estimate and, where known, the true
    /// contact's point and force (world, m and N).
    #[must_use]
    pub fn of(update: &Update, truth: Option<(DVec3, DVec3)>) -> Self {
        let s = &update.summary;
        let contact = s.verdict != Verdict::NoContact;
        let (position_error_m, force_error_newtons) = match (contact, truth) {
            (true, Some((point, force))) => (s.map.point_world.distance(point), s.map.force_world.distance(force)),
            _ => (f64::NAN, f64::NAN),
        };
        Self {
            contact_probability: s.contact_probability.unwrap_or(if contact { 1.0 } else { 0.0 }),
            force_newtons: if contact { s.map.force_newtons } else { 0.0 },
            verdict: match s.verdict {
                Verdict::NoContact => 0,
                Verdict::Contact => 1,
                Verdict::PoorFit => 2,
            },
            position_error_m,
            force_error_newtons,
        }
    }

    fn outgoing(&self, stamp_ns: i64) -> Outgoing {
        let mut m = Cdr::new();
        m.f64(self.contact_probability)
            .f64(self.force_newtons)
            .u8(self.verdict)
            .f64(self.position_error_m)
            .f64(self.force_error_newtons);
        Outgoing {
            topic: NUMBERS_TOPIC,
            schema_name: "proprioscope_msgs/msg/FrameNumbers".to_owned(),
            schema_encoding: "ros2msg",
            schema_data: NUMBERS_SCHEMA.as_bytes().to_vec(),
            message_encoding: "cdr",
            data: m.0,
            stamp_ns,
        }
    }
}

/// When a part of the stream is next due: at most so many times a second
/// of the recording, or at once when forced (a change of verdict).
#[derive(Debug, Clone, Default)]
pub struct Clock {
    interval_ns: i64,
    last: Option<i64>,
}

impl Clock {
    /// At most `hz` times a second (0 or less: every time).
    #[must_use]
    pub fn every(hz: f64) -> Self {
        Self {
            interval_ns: if hz > 0.0 { (1e9 / hz).round() as i64 } else { 0 },
            last: None,
        }
    }

    /// Whether a frame at `stamp_ns` gets this part (`force`: whatever the
    /// rate); if so it is counted as sent. A clock that goes back (a new
    /// stream) starts over.
    pub fn due(&mut self, stamp_ns: i64, force: bool) -> bool {
        let due = match self.last {
            None => true,
            Some(t) => force || stamp_ns < t || stamp_ns.saturating_sub(t) >= self.interval_ns,
        };
        if due {
            self.last = Some(stamp_ns);
        }
        due
    }
}

/// How many heatmap bytes a second of the recording may take on average,
/// and in one burst: a posterior that is wide paints the whole arm (half
/// a megabyte a heatmap), and without a budget a press's onset, sent at
/// every change of verdict, would be most of the file.
pub const HEAT_BUDGET: (f64, f64) = (64.0 * 1024.0, 1024.0 * 1024.0);

/// About how many bytes a heatmap of `painted_vertices` takes (a point, a
/// colour and two triangles' indices each).
#[must_use]
pub fn heat_bytes(painted_vertices: usize) -> f64 {
    90.0 * painted_vertices as f64
}

/// A budget of bytes a second of the recording, with a burst allowance:
/// a message is sent when the budget holds its size.
#[derive(Debug, Clone)]
pub struct ByteBudget {
    per_second: f64,
    burst: f64,
    level: f64,
    last_ns: Option<i64>,
}

impl ByteBudget {
    /// `per_second` bytes a second, at most `burst` saved up (full at
    /// the start).
    #[must_use]
    pub fn new((per_second, burst): (f64, f64)) -> Self {
        Self {
            per_second,
            burst,
            level: burst,
            last_ns: None,
        }
    }

    /// Whether `bytes` may be sent at `stamp_ns`; if so they are spent.
    pub fn take(&mut self, stamp_ns: i64, bytes: f64) -> bool {
        let elapsed_s = self
            .last_ns
            .map_or(0.0, |t| stamp_ns.saturating_sub(t).max(0) as f64 * 1e-9);
        self.last_ns = Some(stamp_ns);
        self.level = (self.level + elapsed_s * self.per_second).min(self.burst);
        if bytes <= self.level {
            self.level -= bytes;
            true
        } else {
            false
        }
    }
}

/// Paint per link: each painted vertex and its colour ([`painted`]).
pub type Paint = Vec<Vec<(u32, [f32; 4])>>;

/// What Foxglove is sent of one frame.
#[derive(Debug, Clone, PartialEq)]
pub struct FoxgloveFrame {
    /// The frame's time, ns on the recording's clock.
    pub stamp_ns: i64,
    /// Joint positions in the robot's joint order, when the transforms are
    /// due ([`TRANSFORMS_HZ`]).
    pub joint_positions: Option<Vec<f64>>,
    /// The numbers to plot.
    pub numbers: FrameNumbers,
    /// The heatmap, when it is due ([`HEAT_HZ`]): per link, its painted
    /// mesh vertices with their colours ([`painted`]).
    pub heat: Option<Paint>,
    /// The arrows, when they are due ([`SCENE_HZ`]).
    pub arrows: Option<Vec<Arrow>>,
}

/// How far from the arm's grey a vertex's colour must be, in some channel,
/// to be sent as painted: five steps of an 8-bit channel. The log scale
/// fades into the grey, so nearly every vertex is a trace off it; those
/// within this are drawn grey by the arm beneath.
pub const PAINT_VISIBLE: f32 = 5.0 / 255.0;

/// A colour as an 8-bit screen shows it (each channel to the nearest
/// k/255): what the app's view displays, and a few values that repeat
/// from one heatmap to the next, so that the file's compression finds
/// them.
#[must_use]
pub fn as_8_bit(c: [f32; 4]) -> [f32; 4] {
    c.map(|x| (x.clamp(0.0, 1.0) * 255.0).round() / 255.0)
}

/// Per link, the vertices whose colour is visibly off the arm's grey
/// ([`PAINT_VISIBLE`]), with it as 8 bits show it ([`as_8_bit`];
/// `colours[link][vertex]`): what a heatmap message needs, the part of the
/// arm where the posterior has mass.
#[must_use]
pub fn painted(colours: &[Vec<[f32; 4]>]) -> Paint {
    let grey = crate::core::paint::colours::ROBOT_GREY;
    colours
        .iter()
        .map(|link| {
            link.iter()
                .enumerate()
                .filter(|(_, c)| c.iter().zip(&grey).any(|(a, b)| (a - b).abs() > PAINT_VISIBLE))
                .map(|(v, c)| (v as u32, as_8_bit(*c)))
                .collect()
        })
        .collect()
}

/// The messages that start a stream: the arm's meshes and its URDF.
#[must_use]
pub fn opening(scene: &ArmScene, stamp_ns: i64) -> Vec<Outgoing> {
    vec![
        encoded(ARM_TOPIC, &scene.arm(stamp_ns), stamp_ns),
        ros_string(DESCRIPTION_TOPIC, &description::urdf_text(scene.robot()), stamp_ns),
    ]
}

/// One frame's messages: its transforms and numbers, and the scene when due.
#[must_use]
pub fn frame_messages(scene: &ArmScene, frame: &FoxgloveFrame) -> Vec<Outgoing> {
    let t = frame.stamp_ns;
    let mut out = vec![frame.numbers.outgoing(t)];
    if let Some(q) = &frame.joint_positions {
        out.push(encoded(TRANSFORMS_TOPIC, &scene.transforms(q, t), t));
    }
    if let Some(paint) = &frame.heat {
        out.push(encoded(HEATMAP_TOPIC, &scene.heat(paint, t), t));
    }
    if let Some(arrows) = &frame.arrows {
        out.push(encoded(ARROWS_TOPIC, &scene.arrows(arrows, t), t));
    }
    out
}

#[cfg(test)]
#[allow(clippy::float_cmp)] // the bytes written are the numbers given
mod tests {
    use super::*;

    #[test]
    fn a_clock_keeps_its_rate_and_every_forced_time() {
        let mut clock = Clock::every(SCENE_HZ);
        let ms = 1_000_000;
        let sent: Vec<i64> = (0..200).filter(|&k| clock.due(k * ms, k == 150)).collect();
        // Every 34 ms (30 Hz rounds up to whole frames), and at frame 150.
        assert_eq!(&sent[..3], &[0, 34, 68]);
        assert!(sent.contains(&150));
        assert!(sent.len() <= 200 / 33 + 2);
        let mut every = Clock::every(0.0);
        assert!((0..10).all(|k| every.due(k, false)));
    }

    #[test]
    fn the_byte_budget_refills_with_the_recording_s_time() {
        let mut budget = ByteBudget::new((1000.0, 2000.0));
        assert!(budget.take(0, 1500.0));
        assert!(!budget.take(0, 1000.0));
        // Half a second later, 500 + 500 bytes are there.
        assert!(budget.take(500_000_000, 1000.0));
        assert!(!budget.take(500_000_000, 1.0));
        // Never more than the burst.
        assert!(!budget.take(100_000_000_000, 2001.0));
        assert!(budget.take(100_000_000_000, 2000.0));
    }

    #[test]
    fn numbers_are_little_endian_cdr_in_the_schema_s_order() {
        let n = FrameNumbers {
            contact_probability: 0.25,
            force_newtons: 12.0,
            verdict: 1,
            position_error_m: f64::NAN,
            force_error_newtons: 1.5,
        };
        let o = n.outgoing(7);
        let f = |at: usize| f64::from_le_bytes(o.data[at..at + 8].try_into().unwrap());
        assert_eq!(&o.data[..4], &[0, 1, 0, 0]);
        assert_eq!((f(4), f(12), o.data[20]), (0.25, 12.0, 1));
        // The next float64 is aligned to 8 bytes after the 4-byte header.
        assert!(f(28).is_nan());
        assert_eq!(f(36), 1.5);
    }
}
