//! Shared test helpers: small models, stores in temporary folders, and scene
//! comparison.

use std::path::PathBuf;

use dmu_samples::{PlantOptions, plant};
use dmu_scene::Scene;
use dmu_store::{WriteOptions, write_scene};

/// A small plant (about `triangles`), far from the origin as real plants are.
pub fn small_plant(triangles: u64) -> Scene {
    plant(&PlantOptions {
        triangles,
        ..PlantOptions::default()
    })
}

/// `scene` written as a store in a fresh temporary folder.
pub fn stored(scene: &Scene, options: WriteOptions) -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("model.dmu");
    write_scene(scene, &path, options).unwrap();
    (dir, path)
}

/// Structure, names, transforms (exactly), colours, visibility and geometry agree.
pub fn assert_same_scene(a: &Scene, b: &Scene) {
    assert_eq!(a.parts().len(), b.parts().len(), "part count");
    assert_eq!(a.triangle_count(), b.triangle_count(), "triangles");
    for p in a.part_ids() {
        assert_eq!(a.part_path(p), b.part_path(p));
        assert_eq!(
            a.part_world(p),
            b.part_world(p),
            "transform of {}",
            a.part_name(p)
        );
        assert_eq!(a.part(p).hidden, b.part(p).hidden);
        assert_eq!(
            a.part_mesh(p).triangle_count(),
            b.part_mesh(p).triangle_count()
        );
    }
    assert_eq!(a.materials(), b.materials(), "materials and colours");
    assert_eq!(a.chunks(), b.chunks(), "chunk tables and boxes");
    assert_eq!(a.meshes(), b.meshes(), "geometry");
}

/// `../shared/data` from the workspace root, or `None` after [`skip`] when
/// absent, as in a user's clone.
pub fn shared_data(test: &str) -> Option<PathBuf> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/data");
    if dir.is_dir() {
        Some(dir)
    } else {
        skip(
            test,
            "../shared/data is absent (it exists beside the project checkout in CI)",
        );
        None
    }
}

/// Ends a test whose prerequisite is missing: under `CI=true` (where the
/// prerequisites are installed) it fails with `reason`; elsewhere it prints
/// `SKIPPED <test>: <reason>` and the test returns.
pub fn skip(test: &str, reason: &str) {
    if std::env::var("CI").as_deref() == Ok("true") {
        panic!("{test}: {reason} (CI=true: a missing prerequisite is a failure)");
    }
    eprintln!("SKIPPED {test}: {reason}");
}
