//! Pick hits as JSON, the same in `dmu pick` and the viewer, so that one can be
//! checked against the other.

use dmu_scene::Scene;
use dmu_tree::Hit;
use serde_json::{Value, json};

/// `hit` of a ray whose direction is `ray_length` long: part name, id and
/// path, triangle, distance in world units, point and normal.
pub fn hit_json(scene: &Scene, hit: &Hit, ray_length: f64) -> Value {
    json!({
        "hit": true,
        "part": scene.part_name(hit.part),
        "part_id": hit.part.0,
        "path": scene.part_path(hit.part),
        "triangle": hit.triangle,
        "distance": hit.t * ray_length,
        "point": hit.point.to_array(),
        "normal": hit.normal.to_array(),
    })
}
