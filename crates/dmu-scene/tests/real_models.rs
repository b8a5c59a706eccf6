//! Real models made by others (../shared/data and Debian's assimp-testmodels):
//! triangle and part counts as measured by an independent reader (pygltflib, in
//! ../shared/data/README.md), round trips through export, and broken files.

use std::collections::BTreeMap;
use std::path::Path;

use dmu_scene::{ImportError, ImportOptions, Scene, export_gltf, import_gltf};

use dmu_testkit::{Data, with_data};

fn import(path: &Path) -> Result<Scene, ImportError> {
    import_gltf(path, &ImportOptions::default()).map(|(s, _)| s)
}

/// Parts, names, paths, per-part triangle counts and colours, and transforms
/// (1e-9 relative) agree.
pub fn assert_same_scene(a: &Scene, b: &Scene) {
    assert_eq!(a.parts().len(), b.parts().len(), "part count");
    for p in a.part_ids() {
        assert_eq!(a.part_name(p), b.part_name(p));
        assert_eq!(a.part_path(p), b.part_path(p));
        assert_eq!(
            a.part_mesh(p).triangle_count(),
            b.part_mesh(p).triangle_count(),
            "triangles of {}",
            a.part_name(p)
        );
        let (wa, wb) = (
            a.part_world(p).to_cols_array(),
            b.part_world(p).to_cols_array(),
        );
        let scale = wa.iter().fold(1.0f64, |m, v| m.max(v.abs()));
        for (x, y) in wa.iter().zip(&wb) {
            assert!(
                (x - y).abs() <= 1e-9 * scale,
                "transform of {}: {wa:?} vs {wb:?}",
                a.part_name(p)
            );
        }
        assert_eq!(
            colours(a, p),
            colours(b, p),
            "colours of {}",
            a.part_name(p)
        );
    }
    assert_eq!(a.triangle_count(), b.triangle_count());
}

/// Triangles per base colour of a part.
fn colours(s: &Scene, p: dmu_scene::PartId) -> BTreeMap<[u32; 4], u64> {
    let mut m = BTreeMap::new();
    for c in s.part_mesh(p).chunk_ids() {
        let chunk = s.chunk(c);
        let colour = s.materials()[chunk.material.index()]
            .base_color
            .map(f32::to_bits);
        *m.entry(colour).or_default() += u64::from(chunk.triangle_count());
    }
    m
}

fn round_trip(scene: &Scene, ext: &str) -> Scene {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join(format!("out.{ext}"));
    export_gltf(scene, &path).unwrap();
    let back = import(&path).unwrap();
    back.validate().unwrap();
    back
}

#[test]
fn shared_models_import_with_their_published_counts_and_round_trip() {
    with_data(Data::Shared, |data| {
        let table: &[(&str, usize, u64)] = &[
            ("bim/steel_structure_mini_project.glb", 2_636, 241_016),
            ("bim/duplex.glb", 286, 27_740),
            ("bim/fzk_haus.glb", 107, 24_168),
            ("pcb/video_board_step_assembly.glb", 167, 382_729),
            ("pcb/video_board.glb", 166, 198_182),
            ("pcb/stickhub_board.glb", 37, 14_060),
            ("compressed/engine_quant.glb", 67, 110_342),
            ("compressed/engine_meshopt.glb", 67, 110_342),
        ];
        for &(file, parts, triangles) in table {
            let scene = import(&data.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
            scene.validate().unwrap();
            assert_eq!(
                (scene.parts().len(), scene.triangle_count()),
                (parts, triangles),
                "{file}"
            );
            let back = round_trip(&scene, "glb");
            assert_same_scene(&scene, &back);
            assert_eq!(
                back.meshes().len(),
                scene.meshes().len(),
                "{file}: instancing kept"
            );
        }
    });
}

#[test]
fn meshopt_compressed_equals_uncompressed() {
    with_data(Data::Shared, |data| {
        let quant = import(&data.join("compressed/engine_quant.glb")).unwrap();
        let meshopt = import(&data.join("compressed/engine_meshopt.glb")).unwrap();
        assert_same_scene(&quant, &meshopt);
        // gltfpack orders vertices differently in the two files: compare each mesh's
        // triangles as a sorted list, each in its lexicographically smallest rotation
        // (which keeps the winding, and is unique also for degenerate triangles with a
        // repeated corner, which the meshopt codec stores rotated).
        for (m, (a, b)) in quant.meshes().iter().zip(meshopt.meshes()).enumerate() {
            let (ta, tb) = (triangles(&quant, a), triangles(&meshopt, b));
            let differing = ta.iter().zip(&tb).filter(|(x, y)| x != y).count();
            assert!(
                ta.len() == tb.len() && differing == 0,
                "mesh {m}: {differing} of {} triangles differ",
                ta.len()
            );
        }
    });
}

fn triangles(scene: &Scene, mesh: &dmu_scene::Mesh) -> Vec<[[u32; 3]; 3]> {
    let mut out: Vec<[[u32; 3]; 3]> = mesh
        .chunk_ids()
        .flat_map(|c| {
            let chunk = scene.chunk(c);
            chunk.triangles.clone().map(move |t| {
                scene
                    .triangle_local(chunk.mesh, c, t)
                    .map(|p| p.to_array().map(f32::to_bits))
            })
        })
        .map(|t| {
            let rotations = [t, [t[1], t[2], t[0]], [t[2], t[0], t[1]]];
            rotations.into_iter().min().unwrap_or(t)
        })
        .collect();
    out.sort_unstable();
    out
}

#[test]
fn gltf_text_round_trip_with_embedded_buffer() {
    with_data(Data::Shared, |data| {
        let scene = import(&data.join("pcb/stickhub_board.glb")).unwrap();
        assert_same_scene(&scene, &round_trip(&scene, "gltf"));
    });
}

#[test]
fn debian_assimp_models() {
    with_data(Data::Assimp, |dir| {
        let engine = import(&dir.join("2CylinderEngine-glTF-Binary/2CylinderEngine.glb")).unwrap();
        assert_eq!(
            (engine.parts().len(), engine.triangle_count()),
            (67, 121_496)
        );
        assert_eq!(engine.materials().len(), 34);
        assert_same_scene(&engine, &round_trip(&engine, "glb"));

        match import(&dir.join("draco/2CylinderEngine.gltf")) {
            Err(ImportError::UnsupportedExtension { name }) => {
                assert_eq!(name, "KHR_draco_mesh_compression")
            }
            other => panic!("draco must be refused by name, got {other:?}"),
        }

        // Asset generator primitive modes: 00-03 and 07-10 are points and lines.
        for i in 0..16 {
            let path = dir.join(format!(
                "glTF-Asset-Generator/Mesh_PrimitiveMode/Mesh_PrimitiveMode_{i:02}.gltf"
            ));
            let (scene, report) = import_gltf(&path, &ImportOptions::default()).unwrap();
            let lines_or_points = matches!(i, 0..=3 | 7..=10);
            assert_eq!(
                scene.triangle_count(),
                if lines_or_points { 0 } else { 2 },
                "mode file {i:02}"
            );
            assert_eq!(
                report.point_primitives_skipped + report.line_primitives_skipped,
                usize::from(lines_or_points)
            );
        }

        for broken in [
            "IndexOutOfRange/IndexOutOfRange.gltf",
            "IndexOutOfRange/AllIndicesOutOfRange.gltf",
            "RecursiveNodes/RecursiveNodes.gltf",
            "BoxWithInfinites-glTF-Binary/BoxWithInfinites.glb",
            "wrongTypes/badNumber.gltf",
            "wrongTypes/badObject.gltf",
            "wrongTypes/badUint.gltf",
            "wrongTypes/badArray.gltf",
            "wrongTypes/badString.gltf",
        ] {
            let err = import(&dir.join(broken))
                .err()
                .unwrap_or_else(|| panic!("{broken} must fail"));
            assert!(!err.to_string().is_empty());
        }
        // Everything else in the folder: an answer, never a panic.
        for entry in walk(dir) {
            let _ = import(&entry);
        }
    });
}

fn walk(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).into_iter().flatten().flatten() {
        let p = e.path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else if p.extension().is_some_and(|x| x == "gltf" || x == "glb") {
            out.push(p);
        }
    }
    out.sort();
    out
}

/// The Khronos glTF-Validator suite: no input may panic, and every file the
/// validator finds no error in must import.
#[test]
fn gltf_validator_suite() {
    with_data(Data::Shared, |data| {
        let (mut clean, mut with_errors, mut refused, mut no_data) = (0, 0, 0, 0);
        let export_dir = tempfile::tempdir().unwrap();
        let mut exported = 0;
        for file in walk(&data.join("gltf-validator")) {
            let report_path = file.with_file_name(format!(
                "{}.report.json",
                file.file_name().unwrap().to_string_lossy()
            ));
            let report: serde_json::Value =
                serde_json::from_slice(&std::fs::read(&report_path).unwrap()).unwrap();
            let errors = report["issues"]["numErrors"].as_u64().unwrap();
            let result = import(&file);
            if let Ok(scene) = &result {
                // Whatever imports exports a glTF that imports again, the same.
                let out = export_dir.path().join("round.glb");
                export_gltf(scene, &out)
                    .unwrap_or_else(|e| panic!("{}: export failed: {e:#}", file.display()));
                let back = import(&out).unwrap_or_else(|e| {
                    panic!("{}: its export does not re-import: {e:#}", file.display())
                });
                assert_eq!(
                    back.triangle_count(),
                    scene.triangle_count(),
                    "{}",
                    file.display()
                );
                assert_eq!(
                    back.parts().len(),
                    scene.parts().len(),
                    "{}",
                    file.display()
                );
                exported += 1;
            }
            if errors == 0 {
                clean += 1;
                match &result {
                    Ok(_) => {}
                    // A .gltf whose buffer has no uri carries no data at all; the
                    // validator checks only its JSON. Refusing to invent geometry is right.
                    Err(e)
                        if e.to_string()
                            .contains("has no data (no uri, and no GLB BIN chunk)") =>
                    {
                        no_data += 1
                    }
                    Err(e) => panic!("{} has no validator error but failed: {e}", file.display()),
                }
            } else {
                with_errors += 1;
                refused += usize::from(result.is_err());
            }
        }
        eprintln!(
            "validator suite: {clean} clean files ({no_data} of them without buffer data, refused); {refused} of {with_errors} files with errors refused; {exported} exported and re-imported"
        );
        assert!(
            no_data <= 2,
            "{no_data} clean files lacked buffer data: more than the two known JSON-only cases"
        );
        assert!(
            clean > 100 && with_errors > 200,
            "suite looks incomplete: {clean} clean, {with_errors} with errors"
        );
    });
}
