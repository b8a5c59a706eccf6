//! The streaming import (the JSON read as a stream into flat arrays, never a
//! document) against the whole-document import: the same scene's structure for
//! generated plants, the real models and every glTF-Validator case; and memory
//! for structure that grows with the node count by a small constant.

use std::path::{Path, PathBuf};

use dmu_scene::{
    ImportError, ImportOptions, StreamOptions, Streamed, Structure, export_gltf,
    import_gltf_streaming,
};

use dmu_testkit::{Data, with_data};

use crate::support::small_plant;

fn streamed(path: &Path) -> Result<Streamed, ImportError> {
    let options = StreamOptions {
        chunk_triangles: dmu_scene::DEFAULT_CHUNK_TRIANGLES,
        memory_budget_bytes: 0,
        min_batch_bytes: 1 << 20,
        progress: None,
    };
    import_gltf_streaming::<ImportError>(path, &options, &mut |_, _| Ok(()))
}

fn whole(path: &Path) -> Result<Structure, ImportError> {
    dmu_scene::import_gltf(path, &ImportOptions::default()).map(|(s, _)| Structure::of(&s))
}

/// The structure streamed from `path` is the whole import's, array for array:
/// nodes (parents, f64 transforms bit for bit), names, parts, chunk tables and
/// boxes, materials.
fn assert_same_structure(path: &Path) -> Structure {
    let reference = whole(path).unwrap();
    let streamed = streamed(path).unwrap().structure;
    assert_eq!(
        streamed.nodes.len(),
        reference.nodes.len(),
        "{path:?} nodes"
    );
    assert_eq!(
        streamed.node_names, reference.node_names,
        "{path:?} node names"
    );
    assert_eq!(streamed.parts, reference.parts, "{path:?} parts");
    assert_eq!(streamed.chunks, reference.chunks, "{path:?} chunks");
    assert_eq!(streamed, reference, "{path:?}");
    streamed
}

#[test]
fn a_streamed_plant_has_the_whole_imports_structure() {
    let dir = tempfile::tempdir().unwrap();
    let scene = small_plant(30_000);
    // Binary, and JSON with the buffer inside it as a data URI.
    for name in ["plant.glb", "plant.gltf"] {
        let path = dir.path().join(name);
        export_gltf(&scene, &path).unwrap();
        let s = assert_same_structure(&path);
        assert_eq!(s.parts.len(), scene.parts().len());
        assert_eq!(s.triangle_count(), scene.triangle_count());
    }
}

#[test]
fn real_models_stream_to_the_whole_imports_structure() {
    with_data(Data::Shared, |data| {
        for file in [
            "bim/steel_structure_mini_project.glb",
            "bim/duplex.glb",
            "bim/fzk_haus.glb",
            "pcb/video_board_step_assembly.glb",
            "pcb/video_board.glb",
            "pcb/stickhub_board.glb",
            "compressed/engine_quant.glb",
            "compressed/engine_meshopt.glb",
        ] {
            let s = assert_same_structure(&data.join(file));
            eprintln!(
                "{file}: {} nodes, {} parts, {} chunks, the same streamed",
                s.nodes.len(),
                s.parts.len(),
                s.chunks.len()
            );
        }
    });
}

fn gltf_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            gltf_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "gltf" || e == "glb") {
            out.push(path);
        }
    }
}

/// Every case of the Khronos glTF-Validator suite: the two imports agree (the
/// same structure, or both refuse the file), and nothing panics.
#[test]
fn validator_cases_stream_as_the_whole_import_reads_them() {
    with_data(Data::Shared, |data| {
        let mut files = Vec::new();
        gltf_files(&data.join("gltf-validator"), &mut files);
        files.sort();
        assert!(files.len() > 300, "{} validator cases", files.len());
        let (mut same, mut refused) = (0, 0);
        for path in &files {
            match (whole(path), streamed(path)) {
                (Ok(reference), Ok(s)) => {
                    assert_eq!(s.structure, reference, "{path:?}");
                    same += 1;
                }
                (Err(_), Err(_)) => refused += 1,
                (w, s) => panic!(
                    "{path:?}: the whole import gives {:?}, the streaming one {:?}",
                    w.err().map(|e| e.to_string()),
                    s.err().map(|e| e.to_string())
                ),
            }
        }
        eprintln!("{same} cases import the same structure, {refused} are refused by both");
    });
}

/// What the streaming import holds for the structure (its flat arrays,
/// counted from their capacities) grows linearly with the nodes and chunks,
/// by a small constant: at most 400 bytes a node, 100 a chunk and 3 a name
/// byte (the file's nodes, the structure made from them, and the arrays'
/// growth slack), over plants from 300 to 5,000 nodes; the figures are printed.
#[test]
fn structure_memory_grows_linearly_with_nodes_and_chunks() {
    let dir = tempfile::tempdir().unwrap();
    let mut sizes = Vec::new();
    for triangles in [20_000, 160_000, 1_280_000] {
        let path = dir.path().join(format!("plant{triangles}.glb"));
        export_gltf(&small_plant(triangles), &path).unwrap();
        let s = streamed(&path).unwrap();
        let st = &s.structure;
        let (nodes, chunks) = (st.nodes.len() as u64, st.chunks.len() as u64);
        let names = (st.node_names.bytes.len() + st.mesh_names.bytes.len()) as u64;
        let peak = s.structure_peak_bytes;
        eprintln!(
            "{triangles} triangles: {nodes} nodes, {} parts, {chunks} chunks, {names} name bytes: peak {peak} B, {:.0} B a node and chunk",
            st.parts.len(),
            peak as f64 / (nodes + chunks) as f64
        );
        assert!(
            peak <= 400 * nodes + 100 * chunks + 3 * names + (64 << 10),
            "{triangles}: {peak} bytes"
        );
        sizes.push((nodes + chunks, peak));
    }
    // Linear: k times the nodes and chunks cost at most 1.5 k times the bytes
    // (the arrays grow by doubling).
    let ((u0, p0), (u2, p2)) = (sizes[0], sizes[2]);
    assert!(u2 > 8 * u0, "the plants grow: {sizes:?}");
    assert!(
        (p2 as f64 / p0 as f64) < 1.5 * (u2 as f64 / u0 as f64),
        "{sizes:?}"
    );
}
