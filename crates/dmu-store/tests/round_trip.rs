//! A store holds exactly the scene it was made from: written from memory,
//! imported streaming from glTF (in one batch or many), quantized within its
//! stated bound, and with edits saved.

use std::path::Path;

use dmu_scene::{ChunkedMesh, ImportOptions, MeshId, Scene, StreamOptions, export_gltf};
use dmu_store::{Store, WriteOptions, save_edits};
use glam::{DAffine3, DVec3};

use dmu_testkit::{Data, with_data};

use crate::support::{assert_same_scene, small_plant, stored};

fn import_whole(path: &Path) -> Scene {
    dmu_scene::import_gltf(path, &ImportOptions::default())
        .unwrap()
        .0
}

fn import_store(glb: &Path, budget: u64) -> (tempfile::TempDir, Scene) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("imported.dmu");
    let options = dmu_store::ImportOptions {
        chunk_triangles: dmu_scene::DEFAULT_CHUNK_TRIANGLES,
        memory_budget_bytes: budget,
        write: WriteOptions::default(),
        progress: None,
        cad: &Default::default(),
    };
    let summary = dmu_store::import_gltf(glb, &out, &options).unwrap();
    let store = Store::open(&out).unwrap();
    assert_eq!(summary.store.file_bytes, store.info().file_bytes);
    assert_eq!(summary.triangles, store.skeleton().triangle_count());
    let scene = store.load_scene().unwrap();
    (dir, scene)
}

#[test]
fn written_store_loads_the_same_scene() {
    let scene = small_plant(60_000);
    let (_dir, path) = stored(&scene, WriteOptions::default());
    let store = Store::open(&path).unwrap();
    // The skeleton has everything but the geometry.
    assert!(
        store
            .skeleton()
            .meshes()
            .iter()
            .all(|m| !m.is_loaded() || m.triangles == 0)
    );
    assert_eq!(store.skeleton().triangle_count(), scene.triangle_count());
    assert_same_scene(&store.load_scene().unwrap(), &scene);
    // The tree from the skeleton is the tree from the scene.
    let from_skeleton = dmu_tree::Tree::build(store.skeleton(), Default::default());
    let from_scene = dmu_tree::Tree::build(&scene, Default::default());
    assert_eq!(from_skeleton.cell_count(), from_scene.cell_count());
    assert_eq!(from_skeleton.bounds(), from_scene.bounds());
}

#[test]
fn imported_store_equals_the_glb_scene() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("plant.glb");
    export_gltf(&small_plant(80_000), &glb).unwrap();
    let reference = import_whole(&glb);
    let (_d, scene) = import_store(&glb, 1 << 30);
    assert_same_scene(&scene, &reference);
}

#[test]
fn shared_models_import_into_stores_unchanged() {
    with_data(Data::Shared, |data| {
        for file in [
            "pcb/stickhub_board.glb",
            "pcb/video_board.glb",
            "bim/duplex.glb",
            "compressed/engine_quant.glb",
            "compressed/engine_meshopt.glb",
        ] {
            let glb = data.join(file);
            let reference = import_whole(&glb);
            let (_d, scene) = import_store(&glb, 256 << 20);
            assert_same_scene(&scene, &reference);
            eprintln!(
                "{file}: {} triangles through a store",
                scene.triangle_count()
            );
        }
    });
}

/// With a batch of one byte every mesh is decoded alone, from a fresh mapping:
/// the streamed meshes, loaded into the skeleton, are the whole import's.
#[test]
fn streaming_in_many_batches_equals_the_whole_import() {
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("plant.glb");
    export_gltf(&small_plant(40_000), &glb).unwrap();
    let reference = import_whole(&glb);
    let mut meshes: Vec<(MeshId, ChunkedMesh)> = Vec::new();
    let mut calls = 0;
    let progress = |done: usize, total: usize| assert!(done <= total);
    let options = StreamOptions {
        chunk_triangles: dmu_scene::DEFAULT_CHUNK_TRIANGLES,
        memory_budget_bytes: 0,
        min_batch_bytes: 1,
        progress: Some(&progress),
    };
    let streamed =
        dmu_scene::import_gltf_streaming::<dmu_scene::ImportError>(&glb, &options, &mut |id, m| {
            calls += 1;
            meshes.push((id, m));
            Ok(())
        })
        .unwrap();
    assert_eq!(streamed.batch_bytes, 1);
    let skeleton = streamed.structure.into_scene().unwrap();
    assert_eq!(calls, reference.meshes().len());
    assert_eq!(skeleton.triangle_count(), reference.triangle_count());
    for (id, mesh) in &meshes {
        let r = reference.mesh(*id);
        assert_eq!(mesh.positions, r.positions);
        assert_eq!(mesh.indices, r.indices);
        assert_eq!(skeleton.mesh(*id).chunks, r.chunks);
    }
    assert_eq!(skeleton.chunks(), reference.chunks());
}

#[test]
fn quantized_positions_stay_within_the_stated_bound() {
    let scene = small_plant(30_000);
    let (_dir, path) = stored(&scene, WriteOptions { quantize: true });
    let (_dir2, plain) = stored(&scene, WriteOptions::default());
    let store = Store::open(&path).unwrap();
    assert!(
        store.info().geometry_file_bytes < Store::open(&plain).unwrap().info().geometry_file_bytes
    );
    let loaded = store.load_scene().unwrap();
    let mut worst = 0.0f64;
    for (m, mesh) in scene.meshes().iter().enumerate() {
        let q = &loaded.meshes()[m];
        assert_eq!(q.indices, mesh.indices, "indices are exact");
        for c in mesh.chunk_ids() {
            let chunk = scene.chunk(c);
            let extent = f64::from((chunk.bounds.max - chunk.bounds.min).max_element());
            for v in chunk.vertices.start as usize..chunk.vertices.end as usize {
                let d = f64::from((q.positions[v] - mesh.positions[v]).abs().max_element());
                // Half a grid step, plus f32 rounding of the blend of the box's ends.
                let ends = chunk.bounds.min.abs().max(chunk.bounds.max.abs());
                let rounding = 4.0 * f64::from(f32::EPSILON) * f64::from(ends.max_element());
                assert!(
                    d <= extent / 131_070.0 + rounding,
                    "vertex {v}: {d} of {extent}"
                );
                worst = worst.max(d / extent);
                let dot = q.normals[v].dot(mesh.normals[v]);
                assert!(dot > 0.9995, "normal {v} turned by acos({dot})");
            }
        }
    }
    eprintln!("quantized: worst error {worst:e} of the chunk extent");
}

#[test]
fn saved_edits_reopen_with_the_new_transforms() {
    let mut scene = small_plant(20_000);
    let (_dir, path) = stored(&scene, WriteOptions::default());
    let store = Store::open(&path).unwrap();
    let mut edited = store.skeleton().clone();
    for p in edited.part_ids().step_by(7).collect::<Vec<_>>() {
        let moved =
            DAffine3::from_translation(DVec3::new(100.0, -0.01, 2.5)) * edited.part_world(p);
        edited.set_part_world(p, moved);
        scene.set_part_world(p, moved);
    }
    let hide = edited.part_ids().nth(3).unwrap();
    edited.set_part_hidden(hide, true);
    scene.set_part_hidden(hide, true);
    save_edits(&store, &edited).unwrap();
    // The open store still reads the file it opened; a new open sees the save.
    assert!(!store.load_scene().unwrap().part(hide).hidden);
    let reopened = Store::open(&path).unwrap();
    assert_same_scene(&reopened.load_scene().unwrap(), &scene);
}

#[test]
fn saving_a_different_model_is_refused() {
    let (_dir, path) = stored(&small_plant(20_000), WriteOptions::default());
    let store = Store::open(&path).unwrap();
    let other = small_plant(30_000);
    let err = save_edits(&store, &other).unwrap_err().to_string();
    assert!(
        err.contains("does not match") && err.contains("model.dmu"),
        "{err}"
    );
    // Nothing was written.
    let again = Store::open(&path).unwrap();
    assert_eq!(
        again.skeleton().parts().len(),
        store.skeleton().parts().len()
    );
}

#[test]
fn a_taken_skeleton_loads_mesh_by_mesh_and_picks_as_the_whole_scene() {
    let scene = small_plant(60_000);
    let (_dir, path) = stored(&scene, WriteOptions::default());
    let mut store = Store::open(&path).unwrap();
    let mut skeleton = store.take_skeleton();
    // The store keeps its chunk tables only.
    assert!(store.skeleton().parts().is_empty());
    assert_eq!(store.skeleton().chunks(), scene.chunks());
    assert_eq!(skeleton.parts().len(), scene.parts().len());
    let tree = dmu_tree::Tree::build(&skeleton, Default::default());
    let full_tree = dmu_tree::Tree::build(&scene, Default::default());
    // Rays from above the plant's box down through it, a grid of them: the
    // pick on the skeleton loads the meshes the ray meets before its hit
    // until none is left, and must then equal the whole scene's pick.
    let b = scene.world_bounds();
    let mut loads = 0;
    for i in 0..12 {
        for j in 0..12 {
            let x = b.min.x + (b.max.x - b.min.x) * (f64::from(i) + 0.5) / 12.0;
            let y = b.min.y + (b.max.y - b.min.y) * (f64::from(j) + 0.37) / 12.0;
            let ray = dmu_geom::Ray3d::new(
                DVec3::new(x, y, b.max.z + 1000.0),
                DVec3::new(0.1, -0.05, -1.0),
            );
            let hit = loop {
                let (hit, unloaded) = tree.pick_loaded(&skeleton, &ray, &[]);
                let Some(&first) = unloaded.first() else {
                    break hit;
                };
                let mesh = skeleton.part(tree.entries()[first.0 as usize].part).mesh;
                let chunks = store.mesh_geometry(mesh).unwrap();
                let borrowed: Vec<_> = chunks.iter().map(|c| c.geometry()).collect();
                skeleton.load_mesh_geometry(mesh, &borrowed).unwrap();
                assert_eq!(skeleton.mesh(mesh), scene.mesh(mesh));
                loads += 1;
            };
            assert_eq!(hit, full_tree.pick(&scene, &ray), "ray {i}, {j}");
        }
    }
    assert!(loads > 0);
    // Unloading keeps the chunk table; a wrong chunk count is refused.
    let m = MeshId::from_index(0);
    skeleton.unload_mesh_geometry(m);
    assert!(!skeleton.mesh(m).is_loaded() || skeleton.mesh(m).triangles == 0);
    assert!(skeleton.load_mesh_geometry(m, &[]).is_err() || scene.mesh(m).chunks.is_empty());
}

/// Each part's properties by its path.
fn properties_by_path(scene: &Scene) -> Vec<(String, Vec<(String, String)>)> {
    scene
        .part_ids()
        .map(|p| {
            let props = scene
                .node_properties(scene.part(p).node)
                .map(|(k, v)| (k.to_owned(), v.to_owned()))
                .collect();
            (scene.part_path(p), props)
        })
        .collect()
}

#[test]
fn properties_survive_the_store_its_saves_rewrites_and_a_streamed_import() {
    use dmu_store::StoreError;
    let mut scene = small_plant(20_000);
    let mut nodes: Vec<_> = scene
        .part_ids()
        .step_by(5)
        .map(|p| (scene.part(p).node, p))
        .collect();
    nodes.sort();
    let mut props = dmu_scene::Properties::default();
    for (node, p) in nodes {
        props.push(node, "GlobalId", &format!("guid-{}", p.0));
        props.push(node, "IfcClass", "IfcPipeSegment");
    }
    scene.set_properties(props.clone()).unwrap();
    let (dir, path) = stored(&scene, WriteOptions::default());
    let store = Store::open(&path).unwrap();
    assert_eq!(store.skeleton().properties(), &props);
    assert_eq!(store.load_scene().unwrap().properties(), &props);
    // Saved edits, then a far-field rewrite, copy them.
    let mut edited = store.skeleton().clone();
    let p = edited.part_ids().next().unwrap();
    edited.set_part_world(
        p,
        DAffine3::from_translation(DVec3::X) * edited.part_world(p),
    );
    save_edits(&store, &edited).unwrap();
    let store = Store::open(&path).unwrap();
    assert_eq!(store.skeleton().properties(), &props);
    dmu_store::write_far_fields(&store, b"index", [Ok::<_, StoreError>(Some(vec![1, 2]))])
        .unwrap()
        .commit()
        .unwrap();
    let store = Store::open(&path).unwrap();
    assert_eq!(store.far_field_cells(), 1);
    assert_eq!(store.skeleton().properties(), &props);
    // Through glTF extras and the streaming import, part by part.
    let glb = dir.path().join("plant.glb");
    export_gltf(&scene, &glb).unwrap();
    let (_d, imported) = import_store(&glb, 1 << 30);
    assert_eq!(properties_by_path(&imported), properties_by_path(&scene));
    // A store without properties has no properties segment.
    let kinds = |b: &[u8]| {
        crate::support::toc(b)
            .iter()
            .filter(|e| e.kind == 7)
            .count()
    };
    assert_eq!(kinds(&std::fs::read(&path).unwrap()), 1);
    let (_bare_dir, bare) = stored(&small_plant(20_000), WriteOptions::default());
    assert_eq!(kinds(&std::fs::read(bare).unwrap()), 0);
}

#[test]
fn a_crafted_properties_segment_is_an_error_naming_it() {
    use xxhash_rust::xxh3::xxh3_64;
    let mut scene = small_plant(20_000);
    let mut props = dmu_scene::Properties::default();
    props.push(scene.part(dmu_scene::PartId(0)).node, "GlobalId", "g");
    scene.set_properties(props).unwrap();
    let (dir, path) = stored(&scene, WriteOptions::default());
    let bytes = std::fs::read(&path).unwrap();
    let e = crate::support::entry(&bytes, 7, 0);
    // The row's node (after the three counts) made one past the last node,
    // the segment's checksum made right: only the contents' check sees it.
    let mut out = bytes.clone();
    let at = e.offset as usize + 24;
    out[at..at + 4].copy_from_slice(&(scene.nodes().len() as u32).to_le_bytes());
    let sum = xxh3_64(&out[e.padded()]);
    let out = crate::support::with_toc(&out, |entries| {
        for x in entries.iter_mut().filter(|x| x.kind == 7) {
            x.checksum = sum;
        }
    });
    let crafted = dir.path().join("crafted.dmu");
    std::fs::write(&crafted, out).unwrap();
    let err = Store::open(&crafted).unwrap_err().to_string();
    assert!(
        err.contains("crafted.dmu") && err.contains("properties") && err.contains("node"),
        "{err}"
    );
}
