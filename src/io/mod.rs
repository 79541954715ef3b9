//! Loading and saving: URDF, meshes, scenes.
