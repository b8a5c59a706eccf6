//! Opening a model file as a [`Scene`], whatever it is: a store or glTF.

use std::io::Read as _;
use std::path::Path;

use dmu_scene::{ImportOptions, ImportReport, Scene};

use crate::{Store, StoreError, format::MAGIC};

/// Opens a `.dmu` store (all geometry loaded) or a `.glb`/`.gltf` file as a
/// scene: the one opening path of the command line, the viewer and the Python
/// module. A file that starts with a store's magic is read as the store it is,
/// whatever its name says (a store renamed `.glb` is not reported as malformed
/// JSON). A store keeps its own chunks; `options` applies to glTF only.
/// Any other extension is refused with [`StoreError::UnknownInputFormat`].
pub fn open_scene(
    path: &Path,
    options: &ImportOptions<'_>,
) -> Result<(Scene, ImportReport), StoreError> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if ext.as_deref() == Some("dmu") || starts_with_magic(path) {
        let scene = Store::open(path)?.load_scene()?;
        return Ok((scene, ImportReport::default()));
    }
    if !matches!(ext.as_deref(), Some("glb" | "gltf")) {
        return Err(StoreError::UnknownInputFormat {
            path: path.to_owned(),
        });
    }
    dmu_scene::import_gltf(path, options).map_err(|source| StoreError::Import {
        path: path.to_owned(),
        source,
    })
}

/// Whether the file starts with a store's magic.
fn starts_with_magic(path: &Path) -> bool {
    let mut magic = [0; MAGIC.len()];
    dmu_scene::open_regular_file(path).is_ok_and(|mut f| f.read_exact(&mut magic).is_ok())
        && magic == MAGIC
}
