//! Loading a large arm mesh: the shell pass, the BVH and the surface
//! sampling on a 200,000-triangle sphere, distinct, with every face given
//! twice (as CAD exports sometimes do), and a small mesh with one face
//! repeated 100,000 times. Each must take seconds at most.

// Benchmarks may unwrap: a panic aborts the run with its message.
#![allow(clippy::unwrap_used, missing_docs)]

use std::time::Duration;

use criterion::{Criterion, criterion_group, criterion_main};
use glam::DVec3;
use proprioscope::core::geometry::bvh::Bvh;
use proprioscope::core::geometry::mesh::TriMesh;
use proprioscope::core::geometry::primitives;
use proprioscope::core::geometry::shell::SmoothMesh;
use proprioscope::core::robot::builtin;
use proprioscope::core::robot::model::Robot;
use proprioscope::core::surface::sampling::{Surface, SurfaceRequest};

/// A one-joint arm whose moving link is `mesh`.
fn arm(mesh: TriMesh) -> Robot {
    builtin::one_link("bench", mesh).unwrap()
}

/// Every triangle of `mesh` twice.
fn doubled(mesh: &TriMesh) -> TriMesh {
    let mut out = mesh.clone();
    out.triangles.extend_from_within(..);
    out
}

fn meshes(c: &mut Criterion) {
    // 448 segments: 199,808 triangles.
    let sphere = primitives::sphere(0.06, 448);
    let mut box_with_repeats = primitives::cuboid(DVec3::new(0.1, 0.1, 0.3));
    let first = box_with_repeats.triangles[0];
    box_with_repeats.triangles.extend(std::iter::repeat_n(first, 100_000));
    let cases = [
        (format!("{} distinct triangles", sphere.triangles.len()), sphere.clone()),
        (
            format!("{} triangles, each given twice", sphere.triangles.len()),
            doubled(&sphere),
        ),
        (
            "a box with one face repeated 100,000 times".to_owned(),
            box_with_repeats,
        ),
    ];
    let mut group = c.benchmark_group("mesh");
    group.sample_size(10).measurement_time(Duration::from_secs(10));
    for (label, mesh) in &cases {
        group.bench_function(format!("{label}: shells and normals"), |b| {
            b.iter(|| SmoothMesh::new(mesh));
        });
        let cleaned = SmoothMesh::new(mesh).mesh;
        group.bench_function(format!("{label}: BVH of the cleaned mesh"), |b| {
            b.iter(|| Bvh::new(&cleaned));
        });
        let robot = arm(mesh.clone());
        let request = SurfaceRequest {
            links: vec![1],
            total_points: 500,
            seed: 0,
        };
        group.bench_function(format!("{label}: 500 surface samples (all of it)"), |b| {
            b.iter(|| Surface::sample(&robot, &request).unwrap());
        });
    }
    group.finish();
}

criterion_group!(benches, meshes);
criterion_main!(benches);
