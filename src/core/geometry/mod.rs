//! Triangle meshes and what is computed on them: areas, shells and their
//! winding, primitives, the BVH, the smooth shell that a contact walks on.
//! Imports `numerics` only.

pub mod bvh;
pub mod mesh;
pub mod primitives;
pub mod shell;
