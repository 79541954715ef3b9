//! Past parsing: any OBJ text that gives a mesh goes through the shell
//! pass, the BVH (a ray cast) and the surface sampling of a link, with
//! repeated, degenerate, huge and tiny faces alike: a surface or an
//! error, never a panic or a hang.
#![no_main]

use glam::DVec3;
use proprioscope::core::geometry::bvh::Bvh;
use proprioscope::core::geometry::shell::SmoothMesh;
use proprioscope::core::robot::builtin;
use proprioscope::core::surface::sampling::{Surface, SurfaceRequest};

libfuzzer_sys::fuzz_target!(|data: &[u8]| {
    let Ok(mesh) = proprioscope::io::mesh::read_obj(data, std::path::Path::new("fuzz.obj")) else {
        return;
    };
    let shell = SmoothMesh::new(&mesh);
    let bvh = Bvh::new(&shell.mesh);
    let _ = bvh.ray_cast(DVec3::new(0.01, 0.02, -10.0), DVec3::Z, f64::INFINITY);
    let _ = bvh.winding_number(DVec3::new(0.01, 0.02, 0.03));
    let Ok(robot) = builtin::one_link("fuzz", mesh) else {
        return;
    };
    let request = SurfaceRequest {
        links: vec![1],
        total_points: 64,
        seed: 0,
    };
    if let Ok(surface) = Surface::sample(&robot, &request) {
        assert!(surface.point_in_link.iter().all(|p| p.is_finite()));
        assert!(surface.inward_normal_in_link.iter().all(|n| n.is_finite()));
    }
});
