//! The numerical core: pure maths on `glam` f64 types in SI units, no I/O
//! and no UI, in rooms by concern. Each room imports only the rooms
//! listed before it here (ARCHITECTURE.md draws the floors).

pub mod numerics;

pub mod geometry;

pub mod robot;

pub mod surface;

pub mod estimate;

pub mod over_time;

pub mod config;

pub mod eval;

pub mod paint;
