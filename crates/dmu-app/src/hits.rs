//! Pick hits as JSON, the same in `dmu pick` and the viewer, so that one can be
//! checked against the other.

use dmu_scene::Scene;
use dmu_tree::{Hit, HitReport};
use serde_json::Value;

/// `hit` of a ray whose direction is `ray_length` long: part name, id and
/// path, triangle, distance in world units, point and normal ([`HitReport`]).
pub fn hit_json(scene: &Scene, hit: &Hit, ray_length: f64) -> Value {
    serde_json::to_value(HitReport::new(scene, hit, ray_length)).expect("a hit report serializes")
}
