//! `plant`: placeholder until the generator lands (same API).

use crate::scene::Scene;

/// Plant options.
#[derive(Clone, Debug)]
pub struct PlantOptions {
    /// Triangle target.
    pub triangles: u64,
    /// Seed.
    pub seed: u64,
    /// World offset in millimetres.
    pub origin: glam::DVec3,
    /// Maximum triangles per chunk.
    pub chunk_triangles: u32,
}

impl Default for PlantOptions {
    fn default() -> Self {
        Self {
            triangles: 1_000_000,
            seed: 1,
            origin: glam::DVec3::new(4_512_000.0, 5_341_000.0, 12_000.0),
            chunk_triangles: 2048,
        }
    }
}

/// Placeholder.
pub fn plant(options: &PlantOptions) -> Scene {
    crate::samples::grid(2, 10.0, 4.0, options.chunk_triangles)
}
