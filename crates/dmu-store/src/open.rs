//! Opening a model file as a [`Scene`], whatever it is: a store or glTF.

use std::io::Read as _;
use std::path::Path;

use dmu_scene::{ImportOptions, ImportReport, Scene};

use crate::cad::{CadOptions, convert, is_cad};
use crate::{Store, StoreError, format::MAGIC};

/// Opens a `.dmu` store (all geometry loaded), a `.glb`/`.gltf` file, or a
/// STEP or IFC file (through the converter, [`crate::cad`], with `cad`'s
/// settings) as a scene: the one opening path of the command line, the viewer
/// and the Python module. A file that starts with a store's magic is read as
/// the store it is, whatever its name says (a store renamed `.glb` is not
/// reported as malformed JSON). A store keeps its own chunks; `options`
/// applies to glTF, STEP and IFC. Any other extension is refused with
/// [`StoreError::UnknownInputFormat`].
pub fn open_scene(
    path: &Path,
    options: &ImportOptions<'_>,
    cad: &CadOptions,
) -> Result<(Scene, ImportReport), StoreError> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_ascii_lowercase());
    if ext.as_deref() == Some("dmu") || starts_with_magic(path) {
        let scene = Store::open(path)?.load_scene()?;
        return Ok((scene, ImportReport::default()));
    }
    if is_cad(path) {
        let converted = convert(path, &std::env::temp_dir(), cad, options.progress)?;
        let (scene, mut report) = import(&converted.glb, path, options)?;
        report.failed_products = converted.failed;
        return Ok((scene, report));
    }
    if !matches!(ext.as_deref(), Some("glb" | "gltf")) {
        return Err(StoreError::UnknownInputFormat {
            path: path.to_owned(),
        });
    }
    import(path, path, options)
}

/// The glTF file `glb` imported, its errors naming `source` (the file the
/// user gave).
fn import(
    glb: &Path,
    source: &Path,
    options: &ImportOptions<'_>,
) -> Result<(Scene, ImportReport), StoreError> {
    dmu_scene::import_gltf(glb, options).map_err(|e| StoreError::Import {
        path: source.to_owned(),
        source: e,
    })
}

/// Whether the file starts with a store's magic.
fn starts_with_magic(path: &Path) -> bool {
    let mut magic = [0; MAGIC.len()];
    dmu_scene::open_regular_file(path).is_ok_and(|mut f| f.read_exact(&mut magic).is_ok())
        && magic == MAGIC
}
