//! `plant`: placeholder until the generator lands.

use crate::scene::Scene;

/// Plant options.
#[derive(Clone, Debug)]
pub struct PlantOptions {
    /// Triangle target.
    pub triangles: u64,
    /// Seed.
    pub seed: u64,
}

/// Placeholder.
pub fn plant(_options: &PlantOptions) -> Scene {
    crate::samples::grid(2, 10.0, 4.0, 2048)
}
