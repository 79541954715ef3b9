//! 3-D rendering for the app: the camera and an offscreen wgpu renderer
//! (pipelines built once, plain vertex data per frame). f32 at this
//! boundary; no egui here.

pub mod camera;
pub mod renderer;
pub mod scene;
