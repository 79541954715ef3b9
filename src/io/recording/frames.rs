//! A recording's chosen topics as a session: a frame per torque message,
//! joint positions interpolated at its stamp, values mapped by joint name.

use std::collections::HashMap;
use std::path::Path;

use crate::io::rosmsg::Value;
use crate::io::session::{ContactTruth, Frame, FrameProblem, Session, Truth, frame_problem};

use super::scan::{Topics, scan};
use super::{
    Mapping, RecordingError, SECOND_TRUTH_POINT_TOPIC, SECOND_TRUTH_TOPIC, StampSource, TRUTH_POINT_TOPIC, TRUTH_TOPIC,
    TopicChoice, index_of,
};

/// Samples of one topic: stamps and values in a fixed joint order.
#[derive(Default)]
pub(crate) struct Samples {
    pub(crate) stamps_ns: Vec<i64>,
    pub(crate) values: Vec<f64>,
    pub(crate) width: usize,
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
    pub(crate) fn at(&self, stamp: i64) -> Option<Vec<f64>> {
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
pub(crate) struct JointOrder {
    pub(crate) names: Option<Vec<String>>,
    /// The last message's names and where each goes.
    pub(crate) cached: Option<(Vec<String>, Vec<usize>)>,
}

impl JointOrder {
    /// `values` in the order of `names` (set by the first message when
    /// unset); `message_names` `None` means already in that order.
    pub(crate) fn arrange(&mut self, message_names: Option<Vec<String>>, values: &[f64]) -> Result<Vec<f64>, String> {
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
pub fn read_session(
    path: &Path,
    bytes: &[u8],
    choice: &TopicChoice,
    progress: &dyn Fn(f64),
) -> Result<RecordingSession, RecordingError> {
    read_session_of(path, bytes, choice, progress, false)
}

/// [`read_session`] of the start of a recording cut anywhere (a preview
/// of a long one): the frames of the records before the cut.
pub fn read_session_start(path: &Path, bytes: &[u8], choice: &TopicChoice) -> Result<RecordingSession, RecordingError> {
    read_session_of(path, bytes, choice, &|_| {}, true)
}

// One pass over the file fills every topic's samples; the steps share
// their state, and split apart they would pass it all along.
#[allow(clippy::too_many_lines)]
fn read_session_of(
    path: &Path,
    bytes: &[u8],
    choice: &TopicChoice,
    progress: &dyn Fn(f64),
    cut_short: bool,
) -> Result<RecordingSession, RecordingError> {
    let index = index_of(path, bytes, cut_short)?;
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
    // The first true contact's wrench and point by stamp; then the second's.
    let mut truths: [HashMap<i64, (String, [f64; 3])>; 2] = [HashMap::new(), HashMap::new()];
    let mut truth_points: [HashMap<i64, [f64; 3]>; 2] = [HashMap::new(), HashMap::new()];
    let truth_topics = [
        (TRUTH_TOPIC, TRUTH_POINT_TOPIC),
        (SECOND_TRUTH_TOPIC, SECOND_TRUTH_POINT_TOPIC),
    ];
    let truth_stamps = truth_topics.map(|(wrench, point)| {
        index
            .topic(wrench)
            .zip(index.topic(point))
            .map(|(t, p)| (t.stamp_source(), p.stamp_source()))
    });
    let has_truth = truth_stamps[0].is_some();
    let mut topics = Topics::default();
    let mut seen = 0usize;

    scan(path, bytes, cut_short, &mut |message| {
        let i = topics.note(&message);
        let Some(info) = topics.list.get(i) else {
            return;
        };
        let topic = info.topic.as_str();
        let is_tau = topic == mapping.tau_topic;
        let is_q = topic == mapping.q_topic;
        // Which true contact (0 or 1) and whether its wrench (else its point).
        let truth_of = truth_topics
            .iter()
            .enumerate()
            .filter(|(k, _)| truth_stamps[*k].is_some())
            .find_map(|(k, (wrench, point))| (topic == *wrench || topic == *point).then_some((k, topic == *wrench)));
        let is_truth = has_truth && truth_of.is_some();
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
        if let Some((k, is_wrench)) = truth_of.filter(|_| is_truth) {
            let (Ok(value), Some(Some((wrench_stamps, point_stamps)))) = (decoded, truth_stamps.get(k)) else {
                return;
            };
            let stamps = if is_wrench { wrench_stamps } else { point_stamps };
            let Some(stamp) = stamps.stamp_ns(&value, message.log_ns) else {
                return;
            };
            if is_wrench {
                let link = match value.get("header.frame_id") {
                    Some(Value::Str(s)) => s.clone(),
                    _ => return,
                };
                if let (Some(force), Some(map)) = (xyz(&value, "wrench.force"), truths.get_mut(k)) {
                    map.insert(stamp, (link, force));
                }
            } else if let (Some(point), Some(map)) = (xyz(&value, "point"), truth_points.get_mut(k)) {
                map.insert(stamp, point);
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
                    match (truths[0].get(&stamp), truth_points[0].get(&stamp)) {
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
                // Both true contacts where a second is recorded with the first.
                let contact = |k: usize| -> Option<ContactTruth> {
                    let (link, force) = truths[k].get(&stamp)?;
                    Some(ContactTruth {
                        link: link.clone(),
                        point: *truth_points[k].get(&stamp)?,
                        force: *force,
                    })
                };
                let truth_all = match (contact(0), contact(1)) {
                    (Some(a), Some(b)) => vec![a, b],
                    _ => Vec::new(),
                };
                let frame = Frame {
                    t: seconds(stamp),
                    q: q_row,
                    tau: tau_row.to_vec(),
                    truth,
                    truth_all,
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
