//! 3-D rendering for the app: camera math now; wgpu pipelines arrive with
//! the view. f32 at this boundary.

pub mod camera;
