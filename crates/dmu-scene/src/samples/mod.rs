//! Built-in sample models, generated in memory and deterministic by seed.

mod grid;
mod plant;
mod rng;
mod shapes;

pub use grid::grid;
pub use plant::{PlantOptions, plant};
pub use rng::Rng;
