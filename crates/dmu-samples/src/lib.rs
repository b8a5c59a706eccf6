//! dmu's built-in sample models, generated in memory and deterministic by seed:
//! the procedural process plant (the default model of the `dmu` tools) and a
//! grid of boxes for tests.
//!
//! Design choices:
//! - A generator is a function from options to a [`dmu_scene::Scene`], built
//!   with the public `SceneBuilder` and chunked with `dmu_scene::chunk_mesh` as
//!   an import is, so sample models take the same paths as real files.
//! - The plant's size is set by a triangle budget, so benchmarks scale one
//!   number.
//!
//! Conventions: as in `dmu-scene`; the plant is in millimetres, far from the
//! origin as real plants are.
//!
//! ```
//! let scene = dmu_samples::grid(2, 10.0, 4.0, dmu_scene::DEFAULT_CHUNK_TRIANGLES);
//! assert_eq!(scene.parts().len(), 8);
//! assert_eq!(scene.triangle_count(), 8 * 12);
//! scene.validate().unwrap();
//! ```

mod grid;
mod plant;
mod rng;
mod shapes;

pub use grid::grid;
pub use plant::{PlantOptions, plant};
pub use rng::Rng;
