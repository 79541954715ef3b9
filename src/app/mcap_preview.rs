//! `proprioscope preview-mcap`: what an MCAP written by `estimate --out`
//! holds for Foxglove, drawn with the program's own renderer from the
//! file's messages alone (the arm's meshes, posed by the transforms, the
//! heatmap and the arrows at a time): a check that the file is complete
//! where no Foxglove can run.

use std::collections::HashMap;

use eframe::egui;
use foxglove::Decode as _;
use foxglove::messages::{FrameTransforms, Pose, SceneEntity, SceneUpdate};
use glam::{DAffine3, DQuat, DVec3, Vec3};

use crate::io::foxglove::{ARM_TOPIC, ARROWS_TOPIC, HEATMAP_TOPIC, TRANSFORMS_TOPIC};
use crate::render::camera::OrbitCamera;
use crate::render::renderer::{Frame, MeshVertex, Renderer};
use crate::render::scene::{arrow, grid_and_axes};

/// What the file shows at a time: the triangles and lines, their bounds,
/// and a caption of what was found.
pub struct McapScene {
    frame: Frame,
    bounds: Option<(Vec3, Vec3)>,
    caption: String,
}

fn pose_affine(pose: Option<&Pose>) -> DAffine3 {
    let Some(p) = pose else { return DAffine3::IDENTITY };
    let t = p.position.map_or(DVec3::ZERO, |v| DVec3::new(v.x, v.y, v.z));
    let r = p
        .orientation
        .map_or(DQuat::IDENTITY, |q| DQuat::from_xyzw(q.x, q.y, q.z, q.w).normalize());
    DAffine3::from_rotation_translation(r, t)
}

/// Every frame's pose in the fixed frame: each child from its parent,
/// chained to the frame that is no child (the root).
fn world_poses(parents: &HashMap<String, (String, DAffine3)>) -> HashMap<String, DAffine3> {
    let mut world: HashMap<String, DAffine3> = parents
        .values()
        .filter(|(parent, _)| !parents.contains_key(parent))
        .map(|(parent, _)| (parent.clone(), DAffine3::IDENTITY))
        .collect();
    // Chains are as long as the arm: one pass per link settles them all.
    for _ in 0..=parents.len() {
        for (child, (parent, local)) in parents {
            if let Some(p) = world.get(parent).copied() {
                world.insert(child.clone(), p * *local);
            }
        }
    }
    world
}

impl McapScene {
    /// What was found, as the preview's caption says it.
    #[must_use]
    pub fn caption(&self) -> &str {
        &self.caption
    }

    /// Triangles and line segments drawn.
    #[must_use]
    pub fn counts(&self) -> (usize, usize) {
        (self.frame.triangles.len() / 3, self.frame.lines.len() / 2)
    }

    /// The scene of the MCAP `bytes` at `at_secs` after its first message.
    pub fn read(bytes: &[u8], at_secs: f64) -> Result<Self, String> {
        let stream = mcap::MessageStream::new(bytes).map_err(|e| e.to_string())?;
        let (mut start, mut arm, mut heat, mut arrows) = (None, None, None, None);
        let mut parents: HashMap<String, (String, DAffine3)> = HashMap::new();
        let mut transforms = 0usize;
        for message in stream {
            let message = message.map_err(|e| e.to_string())?;
            let t0 = *start.get_or_insert(message.log_time);
            let limit = t0.saturating_add((at_secs.max(0.0) * 1e9) as u64);
            let topic = message.channel.topic.as_str();
            if message.log_time > limit && topic != ARM_TOPIC {
                continue;
            }
            let data = message.data.as_ref();
            match topic {
                ARM_TOPIC => arm = Some(SceneUpdate::decode(data).map_err(|e| e.to_string())?),
                HEATMAP_TOPIC => heat = Some(SceneUpdate::decode(data).map_err(|e| e.to_string())?),
                ARROWS_TOPIC => arrows = Some(SceneUpdate::decode(data).map_err(|e| e.to_string())?),
                TRANSFORMS_TOPIC => {
                    transforms += 1;
                    for tf in FrameTransforms::decode(data).map_err(|e| e.to_string())?.transforms {
                        let pose = Pose {
                            position: tf.translation,
                            orientation: tf.rotation,
                        };
                        parents.insert(tf.child_frame_id, (tf.parent_frame_id, pose_affine(Some(&pose))));
                    }
                }
                _ => {}
            }
        }
        let arm = arm.ok_or_else(|| format!("no {ARM_TOPIC} in the file: not written by `estimate --out`?"))?;
        let world = world_poses(&parents);
        let mut scene = Self {
            frame: Frame::default(),
            bounds: None,
            caption: String::new(),
        };
        let drawn = |update: &Option<SceneUpdate>| update.as_ref().map_or(0, |u| u.entities.len());
        scene.caption = format!(
            "from the file alone at {at_secs:.3} s: {} link meshes, {} frames posed ({transforms} transform messages so far), {} heat entities, {} arrows",
            arm.entities.len(),
            world.len(),
            drawn(&heat),
            drawn(&arrows)
        );
        for entity in &arm.entities {
            scene.add_triangles(entity, &world);
        }
        for entity in heat.iter().flat_map(|u| &u.entities) {
            scene.add_triangles(entity, &world);
        }
        for entity in arrows.iter().flat_map(|u| &u.entities) {
            let frame = world.get(&entity.frame_id).copied().unwrap_or(DAffine3::IDENTITY);
            for a in &entity.arrows {
                let pose = frame * pose_affine(a.pose.as_ref());
                let direction = pose.transform_vector3(DVec3::X);
                let length = a.shaft_length + a.head_length;
                let tip = pose.translation + direction * length;
                let c = a.color.unwrap_or_default();
                arrow(
                    &mut scene.frame.lines,
                    tip,
                    direction,
                    length,
                    [c.r as f32, c.g as f32, c.b as f32, 1.0],
                );
            }
        }
        grid_and_axes(1.0, 0.1, &mut scene.frame.lines);
        Ok(scene)
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
                let (Some(a), Some(b), Some(c)) = (corner(tri[0]), corner(tri[1]), corner(tri[2])) else {
                    continue;
                };
                let normal = (b.0 - a.0).cross(c.0 - a.0).normalize_or_zero().as_vec3().to_array();
                for (p, colour) in [a, b, c] {
                    let v = p.as_vec3();
                    self.bounds = Some(self.bounds.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))));
                    self.frame.triangles.push(MeshVertex {
                        position: v.to_array(),
                        normal,
                        color: colour,
                    });
                }
            }
        }
    }
}

/// A window that shows one [`McapScene`].
struct Preview {
    scene: McapScene,
    renderer: Option<Renderer>,
    texture: Option<egui::TextureId>,
    camera: OrbitCamera,
    fitted: bool,
}

impl eframe::App for Preview {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        egui::CentralPanel::default().show(ui, |ui| {
            ui.label(&self.scene.caption);
            let rect = ui.available_rect_before_wrap();
            let size = [rect.width().max(1.0) as u32, rect.height().max(1.0) as u32];
            if !self.fitted
                && let Some((lo, hi)) = self.scene.bounds
            {
                self.camera.fit(lo, hi, rect.width() / rect.height().max(1.0));
                self.fitted = true;
            }
            let Some(state) = frame.wgpu_render_state() else {
                ui.label("no GPU renderer");
                return;
            };
            let renderer = self.renderer.get_or_insert_with(|| Renderer::new(&state.device, size));
            renderer.resize(&state.device, size);
            renderer.render(&state.device, &state.queue, &self.camera, &self.scene.frame);
            let mut egui_renderer = state.renderer.write();
            let id = *self.texture.get_or_insert_with(|| {
                egui_renderer.register_native_texture(&state.device, renderer.color_view(), wgpu::FilterMode::Linear)
            });
            let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
            ui.painter().image(id, rect, uv, egui::Color32::WHITE);
        });
    }
}

/// Renders what the MCAP `bytes` holds for Foxglove at `at_secs` after
/// its start, `size` pixels, headless.
pub fn render_mcap_headless(bytes: &[u8], at_secs: f64, size: [f32; 2]) -> Result<image::RgbaImage, String> {
    let scene = McapScene::read(bytes, at_secs)?;
    let mut harness = egui_kittest::Harness::builder()
        .with_size(egui::vec2(size[0], size[1]))
        .wgpu()
        .build_eframe(move |_| Preview {
            scene,
            renderer: None,
            texture: None,
            camera: OrbitCamera::default(),
            fitted: false,
        });
    harness.run_steps(3);
    harness.render()
}
