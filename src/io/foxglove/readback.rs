//! An MCAP's Foxglove messages read back into what they draw at a time:
//! the arm's meshes posed by the transforms, the heatmap and the arrows,
//! in the fixed frame (the transforms' root). `preview-mcap` draws it; a
//! fuzz target feeds it any bytes.

use std::collections::{HashMap, HashSet};
use std::path::Path;

use foxglove::messages::{FrameTransforms, Pose, SceneEntity, SceneUpdate};
use glam::{DAffine3, DQuat, DVec3};

use super::{ARM_TOPIC, ARROWS_TOPIC, HEATMAP_TOPIC, TRANSFORMS_TOPIC};
use crate::io::recording::scan;

/// Why the file could not be read back.
#[derive(Debug, thiserror::Error)]
pub enum ReadbackError {
    /// Not an MCAP, or a broken one.
    #[error("{reason}")]
    Mcap {
        /// What the reader said.
        reason: String,
    },
    /// A message of ours that does not decode.
    #[error("topic {topic}: a message does not decode as Foxglove's schema: {reason}")]
    Decode {
        /// The topic.
        topic: String,
        /// What the decoder said.
        reason: String,
    },
    /// No arm: not written by `estimate --out`.
    #[error("no {ARM_TOPIC} in the file: not written by `estimate --out`?")]
    NoArm,
}

/// A triangle's corners (fixed frame, m) with their colours (RGBA, [0, 1]).
pub type Triangle = [(DVec3, [f32; 4]); 3];

/// An arrow as drawn: its tip (fixed frame, m), its direction, length and
/// colour.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArrowDrawn {
    /// Where it ends.
    pub tip: DVec3,
    /// Unit direction, tail to tip.
    pub direction: DVec3,
    /// Length, m.
    pub length_m: f64,
    /// RGBA.
    pub colour: [f32; 4],
}

/// What the file shows at a time.
#[derive(Debug, Clone, Default)]
pub struct Snapshot {
    /// The arm's and the heatmap's triangles.
    pub triangles: Vec<Triangle>,
    /// The arrows.
    pub arrows: Vec<ArrowDrawn>,
    /// Entities of the arm (one a link mesh).
    pub link_meshes: usize,
    /// Frames posed in the fixed frame.
    pub frames_posed: usize,
    /// Transform messages up to the time.
    pub transform_messages: usize,
    /// Heatmap entities at the time.
    pub heat_entities: usize,
}

fn pose_affine(pose: Option<&Pose>) -> DAffine3 {
    let Some(p) = pose else { return DAffine3::IDENTITY };
    let t = p.position.map_or(DVec3::ZERO, |v| DVec3::new(v.x, v.y, v.z));
    let r = p
        .orientation
        .map(|q| DQuat::from_xyzw(q.x, q.y, q.z, q.w))
        .filter(|q| q.is_finite() && q.length() > 1e-12)
        .map_or(DQuat::IDENTITY, DQuat::normalize);
    DAffine3::from_rotation_translation(r, t)
}

/// Every frame's pose in the fixed frame: each child from its parent,
/// chained to a frame that is no child (identity). A frame on a cycle is
/// left out. Each frame is resolved once.
fn world_poses(parents: &HashMap<String, (String, DAffine3)>) -> HashMap<String, DAffine3> {
    let mut world: HashMap<String, DAffine3> = HashMap::new();
    // Frames found to hang from a cycle: never walked again.
    let mut cut: HashSet<&str> = HashSet::new();
    for start in parents.keys() {
        // Up from `start` to a frame already posed, a root, or a cycle.
        let (mut path, mut on_path) = (Vec::new(), HashSet::new());
        let mut at = start.as_str();
        let base = loop {
            if let Some(p) = world.get(at) {
                break Some(*p);
            }
            let Some((parent, _)) = parents.get(at) else {
                world.insert(at.to_owned(), DAffine3::IDENTITY);
                break Some(DAffine3::IDENTITY);
            };
            if cut.contains(at) || !on_path.insert(at) {
                break None;
            }
            path.push(at);
            at = parent.as_str();
        };
        let Some(mut pose) = base else {
            cut.extend(path);
            continue;
        };
        for frame in path.into_iter().rev() {
            if let Some((_, local)) = parents.get(frame) {
                pose *= *local;
                world.insert(frame.to_owned(), pose);
            }
        }
    }
    world
}

fn decode<T: foxglove::Decode>(topic: &str, data: &[u8]) -> Result<T, ReadbackError> {
    T::decode(data).map_err(|e| ReadbackError::Decode {
        topic: topic.to_owned(),
        reason: e.to_string(),
    })
}

impl Snapshot {
    /// What the MCAP `bytes` shows `at_secs` after its first message.
    pub fn read(bytes: &[u8], at_secs: f64) -> Result<Self, ReadbackError> {
        let (mut start, mut arm, mut heat, mut arrows) = (None, None, None, None);
        let mut parents: HashMap<String, (String, DAffine3)> = HashMap::new();
        let mut out = Self::default();
        let offset_ns = if at_secs.is_finite() {
            (at_secs.max(0.0) * 1e9) as u64
        } else {
            0
        };
        let mut failure = None;
        // Our own reader of the container: every length checked against
        // the bytes there are (the `mcap` crate's reader allocates what a
        // chunk claims).
        scan(Path::new("MCAP"), bytes, false, &mut |message| {
            if failure.is_some() {
                return;
            }
            let t0 = *start.get_or_insert(message.log_ns);
            let topic = message.topic;
            if message.log_ns > t0.saturating_add(offset_ns) && topic != ARM_TOPIC {
                return;
            }
            let data = message.data;
            let decoded = match topic {
                ARM_TOPIC => decode::<SceneUpdate>(topic, data).map(|u| arm = Some(u)),
                HEATMAP_TOPIC => decode::<SceneUpdate>(topic, data).map(|u| heat = Some(u)),
                ARROWS_TOPIC => decode::<SceneUpdate>(topic, data).map(|u| arrows = Some(u)),
                TRANSFORMS_TOPIC => decode::<FrameTransforms>(topic, data).map(|tfs| {
                    out.transform_messages += 1;
                    for tf in tfs.transforms {
                        let pose = Pose {
                            position: tf.translation,
                            orientation: tf.rotation,
                        };
                        parents.insert(tf.child_frame_id, (tf.parent_frame_id, pose_affine(Some(&pose))));
                    }
                }),
                _ => Ok(()),
            };
            if let Err(e) = decoded {
                failure = Some(e);
            }
        })
        .map_err(|e| ReadbackError::Mcap { reason: e.to_string() })?;
        if let Some(e) = failure {
            return Err(e);
        }
        let arm = arm.ok_or(ReadbackError::NoArm)?;
        let world = world_poses(&parents);
        out.frames_posed = world.len();
        out.link_meshes = arm.entities.len();
        out.heat_entities = heat.as_ref().map_or(0, |u| u.entities.len());
        for entity in arm.entities.iter().chain(heat.iter().flat_map(|u| &u.entities)) {
            out.add_triangles(entity, &world);
        }
        for entity in arrows.iter().flat_map(|u| &u.entities) {
            let frame = world.get(&entity.frame_id).copied().unwrap_or(DAffine3::IDENTITY);
            for a in &entity.arrows {
                let pose = frame * pose_affine(a.pose.as_ref());
                let Some(direction) = pose.transform_vector3(DVec3::X).try_normalize() else {
                    continue;
                };
                let length_m = a.shaft_length + a.head_length;
                let c = a.color.unwrap_or_default();
                out.arrows.push(ArrowDrawn {
                    tip: pose.translation + direction * length_m,
                    direction,
                    length_m,
                    colour: [c.r as f32, c.g as f32, c.b as f32, 1.0],
                });
            }
        }
        Ok(out)
    }

    fn add_triangles(&mut self, entity: &SceneEntity, world: &HashMap<String, DAffine3>) {
        let Some(frame) = world.get(&entity.frame_id).copied() else {
            return;
        };
        for t in &entity.triangles {
            let pose = frame * pose_affine(t.pose.as_ref());
            let corner = |i: usize| -> Option<(DVec3, [f32; 4])> {
                let p = t.points.get(i)?;
                let c = t.colors.get(i).or(t.color.as_ref())?;
                Some((
                    pose.transform_point3(DVec3::new(p.x, p.y, p.z)),
                    [c.r as f32, c.g as f32, c.b as f32, c.a as f32],
                ))
            };
            let order: Vec<usize> = if t.indices.is_empty() {
                (0..t.points.len()).collect()
            } else {
                t.indices.iter().map(|&i| i as usize).collect()
            };
            for tri in order.chunks_exact(3) {
                if let [Some(a), Some(b), Some(c)] = [tri[0], tri[1], tri[2]].map(corner) {
                    self.triangles.push([a, b, c]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_chain_of_frames_composes_and_a_cycle_is_left_out() {
        let step = DAffine3::from_translation(DVec3::X);
        let mut parents = HashMap::new();
        parents.insert("a".to_owned(), ("root".to_owned(), step));
        parents.insert("b".to_owned(), ("a".to_owned(), step));
        parents.insert("c".to_owned(), ("b".to_owned(), step));
        parents.insert("x".to_owned(), ("y".to_owned(), step));
        parents.insert("y".to_owned(), ("x".to_owned(), step));
        let world = world_poses(&parents);
        assert_eq!(world["c"].translation, DVec3::new(3.0, 0.0, 0.0));
        assert_eq!(world["root"], DAffine3::IDENTITY);
        assert!(!world.contains_key("x") && !world.contains_key("y"));
    }

    /// Found by fuzzing: a chunk claiming 3.6 GB uncompressed made the
    /// `mcap` crate's reader allocate that much; our reader refuses it.
    #[test]
    fn a_chunk_claiming_gigabytes_is_an_error_not_an_allocation() {
        let mut file = crate::io::recording::MCAP_MAGIC.to_vec();
        let record = |op: u8, body: &[u8]| {
            let mut r = vec![op];
            r.extend((body.len() as u64).to_le_bytes());
            r.extend(body);
            r
        };
        file.extend(record(0x01, &[0; 8]));
        let compressed = [0x28, 0xb5, 0x2f, 0xfd, 0, 0, 0, 0];
        let mut chunk = Vec::new();
        chunk.extend(0u64.to_le_bytes());
        chunk.extend(0u64.to_le_bytes());
        chunk.extend(3_659_655_580u64.to_le_bytes());
        chunk.extend(0u32.to_le_bytes());
        chunk.extend(4u32.to_le_bytes());
        chunk.extend(b"zstd");
        chunk.extend((compressed.len() as u64).to_le_bytes());
        chunk.extend(compressed);
        file.extend(record(0x06, &chunk));
        let result = Snapshot::read(&file, 0.0);
        assert!(matches!(result, Err(ReadbackError::Mcap { .. })), "{result:?}");
    }

    #[test]
    fn bytes_that_are_no_mcap_are_an_error() {
        assert!(matches!(
            Snapshot::read(b"not an mcap", 0.0),
            Err(ReadbackError::Mcap { .. })
        ));
    }
}
