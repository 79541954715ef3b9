//! `proprioscope preview-mcap`: what an MCAP written by `estimate --out`
//! holds for Foxglove, drawn with the program's own renderer from the
//! file's messages alone (the arm's meshes, posed by the transforms, the
//! heatmap and the arrows at a time): a check that the file is complete
//! where no Foxglove can run.

use eframe::egui;
use glam::Vec3;

use crate::io::foxglove::readback::Snapshot;
use crate::render::camera::OrbitCamera;
use crate::render::renderer::{Frame, MeshVertex, Renderer};
use crate::render::scene::{arrow, grid_and_axes};

/// What the file shows at a time, as the renderer draws it, and a caption
/// of what was found.
pub struct McapScene {
    frame: Frame,
    bounds: Option<(Vec3, Vec3)>,
    caption: String,
}

impl McapScene {
    /// The scene of the MCAP `bytes` at `at_secs` after its first message.
    pub fn read(bytes: &[u8], at_secs: f64) -> Result<Self, String> {
        let snapshot = Snapshot::read(bytes, at_secs).map_err(|e| e.to_string())?;
        let mut scene = Self {
            frame: Frame::default(),
            bounds: None,
            caption: format!(
                "from the file alone at {at_secs:.3} s: {} link meshes, {} frames posed ({} transform messages so far), {} heat entities, {} arrows",
                snapshot.link_meshes,
                snapshot.frames_posed,
                snapshot.transform_messages,
                snapshot.heat_entities,
                snapshot.arrows.len()
            ),
        };
        for triangle in &snapshot.triangles {
            let [a, b, c] = triangle.map(|(p, _)| p);
            let normal = (b - a).cross(c - a).normalize_or_zero().as_vec3().to_array();
            for (p, colour) in triangle {
                let v = p.as_vec3();
                scene.bounds = Some(scene.bounds.map_or((v, v), |(lo, hi)| (lo.min(v), hi.max(v))));
                scene.frame.triangles.push(MeshVertex {
                    position: v.to_array(),
                    normal,
                    color: *colour,
                });
            }
        }
        for a in &snapshot.arrows {
            arrow(&mut scene.frame.lines, a.tip, a.direction, a.length_m, a.colour);
        }
        grid_and_axes(1.0, 0.1, &mut scene.frame.lines);
        Ok(scene)
    }

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
