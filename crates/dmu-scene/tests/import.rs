//! glTF import: hard cases and bad input, each against a hand-written file.

use dmu_scene::{ImportError, ImportOptions, import_gltf_slice};
use glam::{DVec3, Vec3};
use proptest::prelude::*;
use serde_json::json;

use crate::support::{Doc, one_quad_doc};

fn f32_bytes(v: &[f32]) -> Vec<u8> {
    v.iter().flat_map(|x| x.to_le_bytes()).collect()
}

#[test]
fn nan_or_infinite_position_names_mesh_primitive_and_accessor() {
    for bad in [f32::NAN, f32::INFINITY, f32::NEG_INFINITY] {
        let mut d = Doc::new();
        let good = d.positions(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let broken = d.positions(&[[0.0; 3], [1.0, bad, 0.0], [0.0, 1.0, 0.0]]);
        let mesh = d.mesh(
            "bracket",
            vec![
                json!({ "attributes": { "POSITION": good } }),
                json!({ "attributes": { "POSITION": broken } }),
            ],
        );
        d.node(json!({ "mesh": mesh }), true);
        let err = d.import().expect_err("non-finite position must fail");
        assert!(
            matches!(err, ImportError::NonFinitePosition { mesh: 0, primitive: 1, accessor, vertex: 1, .. } if accessor == broken),
            "{err:?}"
        );
        let msg = err.to_string();
        for part in [
            "mesh 0",
            "\"bracket\"",
            "primitive 1",
            &format!("accessor {broken}"),
            "vertex 1",
        ] {
            assert!(msg.contains(part), "{msg:?} lacks {part:?}");
        }
    }
}

#[test]
fn index_out_of_range_is_an_error() {
    let mut d = Doc::new();
    let pos = d.positions(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let idx = d.indices(&[0, 1, 2, 0, 2, 3]);
    let mesh = d.mesh(
        "m",
        vec![json!({ "attributes": { "POSITION": pos }, "indices": idx })],
    );
    d.node(json!({ "mesh": mesh }), true);
    let err = d.import().expect_err("index 3 of 3 vertices");
    assert!(
        matches!(err, ImportError::IndexOutOfRange { index: 3, position: 5, vertex_count: 3, accessor, .. } if accessor == idx),
        "{err:?}"
    );
}

#[test]
fn reference_out_of_range_is_an_error_not_a_panic() {
    let cases = [
        json!({ "attributes": { "POSITION": 99 } }),
        json!({ "attributes": { "POSITION": 0 }, "indices": 42 }),
        json!({ "attributes": { "POSITION": 0 }, "material": 7 }),
    ];
    for prim in cases {
        let mut d = Doc::new();
        d.positions(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
        let mesh = d.mesh("m", vec![prim.clone()]);
        d.node(json!({ "mesh": mesh }), true);
        let err = d.import().expect_err("dangling reference");
        assert!(
            matches!(err, ImportError::Invalid { .. }),
            "{prim}: {err:?}"
        );
    }
    let mut d = one_quad_doc();
    d.node(json!({ "mesh": 5 }), true);
    assert!(matches!(d.import(), Err(ImportError::Invalid { .. })));
}

#[test]
fn accessor_overrunning_its_view_is_an_error() {
    let mut d = Doc::new();
    let pos = d.accessor(&f32_bytes(&[0.0; 9]), 5126, 4, "VEC3", json!({}));
    let mesh = d.mesh("m", vec![json!({ "attributes": { "POSITION": pos } })]);
    d.node(json!({ "mesh": mesh }), true);
    let err = d.import().expect_err("4 vertices in 36 bytes");
    assert!(
        err.to_string().contains(&format!("accessors[{pos}]")),
        "{err}"
    );
}

#[test]
fn empty_mesh_and_empty_primitive_import_with_zero_triangles() {
    let mut d = one_quad_doc();
    let empty = d.mesh("nothing", vec![]);
    d.node(json!({ "name": "empty part", "mesh": empty }), true);
    let pos = d.accessor(&[], 5126, 0, "VEC3", json!({}));
    let hollow = d.mesh("hollow", vec![json!({ "attributes": { "POSITION": pos } })]);
    d.node(json!({ "name": "hollow part", "mesh": hollow }), true);
    let (scene, _) = d.import().expect("imports");
    scene.validate().unwrap();
    assert_eq!(scene.parts().len(), 3);
    for name in ["empty part", "hollow part"] {
        let p = scene.find_part(name).unwrap();
        assert_eq!(scene.part_mesh(p).triangle_count(), 0);
        assert!(scene.part_world_bounds(p).is_empty());
    }
    assert_eq!(scene.triangle_count(), 2);
    assert!(!scene.world_bounds().is_empty());
}

#[test]
fn degenerate_triangles_are_kept_and_counted() {
    let mut d = Doc::new();
    let pos = d.positions(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [2.0, 0.0, 0.0]]);
    // A good triangle, a collinear one, and one with a repeated vertex.
    let idx = d.indices(&[0, 1, 2, 0, 1, 3, 2, 2, 1]);
    let mesh = d.mesh(
        "m",
        vec![json!({ "attributes": { "POSITION": pos }, "indices": idx })],
    );
    d.node(json!({ "mesh": mesh }), true);
    let (scene, report) = d.import().unwrap();
    assert_eq!(scene.triangle_count(), 3);
    assert_eq!(scene.degenerate_triangle_count(), 2);
    assert_eq!(report.primitives_with_computed_normals, 1);
    let mesh = &scene.meshes()[0];
    assert!(
        mesh.normals
            .iter()
            .all(|n| n.is_finite() && (n.length() - 1.0).abs() < 1e-6)
    );
}

#[test]
fn computed_normals_follow_the_winding() {
    let (scene, _) = one_quad_doc().import().unwrap();
    assert!(scene.meshes()[0].normals.iter().all(|&n| n == Vec3::Z));
}

#[test]
fn far_offset_keeps_hundredth_millimetre_precision() {
    // A part 1e7 mm from the origin with features 0.01 mm apart: the node transform
    // is read as f64 and the geometry stays local f32, so world positions are exact.
    let offset = [10_000_000.123_456, -12_345_678.987_654, 9_999_999.5];
    let local: Vec<[f32; 3]> = (0..50)
        .map(|i| [i as f32 * 0.01, 0.0, (i % 7) as f32 * 0.01])
        .collect();
    let mut d = Doc::new();
    let pos = d.positions(&local);
    let idx: Vec<u32> = (0..48).flat_map(|i| [i, i + 1, i + 2]).collect();
    let idx = d.indices(&idx);
    let mesh = d.mesh(
        "fine",
        vec![json!({ "attributes": { "POSITION": pos }, "indices": idx })],
    );
    let parent = d.node(json!({ "name": "site", "translation": [offset[0] - 1000.0, offset[1], offset[2]], "children": [] }), true);
    let child = d.node(
        json!({ "name": "fine part", "translation": [1000.0, 0.0, 0.0], "mesh": mesh }),
        false,
    );
    d.json["nodes"][parent]["children"] = json!([child]);
    let (scene, _) = d.import().unwrap();
    let part = scene.find_part("fine part").unwrap();
    let world = scene.part_world(part);
    let mesh = scene.part_mesh(part);
    assert_eq!(mesh.positions.len(), local.len());
    for &p in &mesh.positions {
        let w = world.transform_point3(p.as_dvec3());
        let err = (w - (DVec3::from(offset) + p.as_dvec3()))
            .abs()
            .max_element();
        assert!(err < 1e-4, "world error {err} mm at {w}");
    }
    // Two neighbours 0.01 mm apart stay 0.01 mm apart in world space.
    let w0 = world.transform_point3(DVec3::new(0.0, 0.0, 0.0));
    let w1 = world.transform_point3(DVec3::new(0.01f32 as f64, 0.0, 0.0));
    assert!(((w1 - w0).x - 0.01).abs() < 1e-6);
}

#[test]
fn strips_and_fans_become_triangle_lists() {
    let p = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 2.0, 0.0],
    ];
    for (mode, expected) in [
        (5, vec![[0, 1, 2], [2, 1, 3], [2, 3, 4]]),
        (6, vec![[0, 1, 2], [0, 2, 3], [0, 3, 4]]),
    ] {
        let mut d = Doc::new();
        let pos = d.positions(&p);
        let mesh = d.mesh(
            "m",
            vec![json!({ "attributes": { "POSITION": pos }, "mode": mode })],
        );
        d.node(json!({ "mesh": mesh }), true);
        let (scene, _) = d.import().unwrap();
        let m = &scene.meshes()[0];
        let got: Vec<[[f32; 3]; 3]> = m
            .indices
            .chunks(3)
            .map(|t| [0, 1, 2].map(|k| m.positions[t[k] as usize].to_array()))
            .collect();
        let want: Vec<[[f32; 3]; 3]> = expected.iter().map(|t| t.map(|i| p[i])).collect();
        assert_eq!(got, want, "mode {mode}");
    }
}

#[test]
fn points_and_lines_are_skipped_and_counted() {
    let mut d = one_quad_doc();
    let pos = d.positions(&[[0.0; 3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]);
    let prims = (0..4)
        .map(|mode| json!({ "attributes": { "POSITION": pos }, "mode": mode }))
        .collect();
    let mesh = d.mesh("wire", prims);
    d.node(json!({ "mesh": mesh }), true);
    let (scene, report) = d.import().unwrap();
    assert_eq!(scene.triangle_count(), 2);
    assert_eq!(
        (
            report.point_primitives_skipped,
            report.line_primitives_skipped
        ),
        (1, 3)
    );
}

#[test]
fn sparse_and_quantized_attributes_decode() {
    let mut d = Doc::new();
    // i16 normalized positions (KHR_mesh_quantization) scaled by the node.
    // Three elements of 3 × i16 (6 bytes), each padded to a stride of 8.
    let view_bytes: Vec<u8> = [[0i16, 0, 0, 0], [32767, 0, 0, 0], [0, -32767, 0, 0]]
        .iter()
        .flatten()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    let view = d.view(&view_bytes, Some(8));
    // Sparse: vertex 2 replaced by (0, 1, 0).
    let sparse_idx = d.view(&2u16.to_le_bytes(), None);
    let sparse_val = d.view(
        &[0i16, 32767, 0]
            .iter()
            .flat_map(|v| v.to_le_bytes())
            .collect::<Vec<_>>(),
        None,
    );
    let pos = d.json["accessors"].as_array().unwrap().len();
    d.json["accessors"].as_array_mut().unwrap().push(json!({
        "bufferView": view, "componentType": 5122, "normalized": true, "count": 3, "type": "VEC3",
        "sparse": { "count": 1, "indices": { "bufferView": sparse_idx, "componentType": 5123 }, "values": { "bufferView": sparse_val } }
    }));
    let mesh = d.mesh("q", vec![json!({ "attributes": { "POSITION": pos } })]);
    d.node(
        json!({ "mesh": mesh, "scale": [1000.0, 1000.0, 1000.0] }),
        true,
    );
    d.json["extensionsRequired"] = json!(["KHR_mesh_quantization"]);
    d.json["extensionsUsed"] = json!(["KHR_mesh_quantization"]);
    let (scene, _) = d.import().unwrap();
    let m = &scene.meshes()[0];
    let mut got: Vec<[f32; 3]> = m.positions.iter().map(|p| p.to_array()).collect();
    got.sort_by(|a, b| a.partial_cmp(b).unwrap());
    assert_eq!(got, vec![[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]]);
    assert_eq!(
        scene.tight_world_bounds().max,
        DVec3::new(1000.0, 1000.0, 0.0)
    );
    assert!(scene.world_bounds().contains(&scene.tight_world_bounds()));
}

#[test]
fn unsupported_required_extension_is_named() {
    let mut d = one_quad_doc();
    d.json["extensionsUsed"] = json!(["KHR_draco_mesh_compression"]);
    d.json["extensionsRequired"] = json!(["KHR_draco_mesh_compression"]);
    let err = d.import().expect_err("draco is not supported");
    assert!(
        matches!(&err, ImportError::UnsupportedExtension { name } if name == "KHR_draco_mesh_compression")
    );
    assert!(err.to_string().contains("KHR_draco_mesh_compression"));
    // Merely used (with a fallback in the file) is fine.
    d.json["extensionsRequired"] = json!([]);
    assert!(d.import().is_ok());
}

#[test]
fn node_cycles_and_shared_children_are_errors() {
    let mut d = one_quad_doc();
    d.json["nodes"][0]["children"] = json!([0]);
    assert!(d.import().unwrap_err().to_string().contains("cycle"));
    let mut d = one_quad_doc();
    d.node(json!({ "name": "a", "children": [0] }), true);
    assert!(
        d.import().is_err(),
        "node 0 reached from the scene and from node 1"
    );
}

#[test]
fn unnamed_nodes_get_stable_names_and_paths() {
    let mut d = one_quad_doc();
    d.json["nodes"][0].as_object_mut().unwrap().remove("name");
    let group = d.node(json!({ "children": [0] }), false);
    d.json["scenes"][0]["nodes"] = json!([group]);
    let (a, _) = d.import().unwrap();
    let (b, _) = d.import().unwrap();
    let p = dmu_scene::PartId(0);
    assert_eq!(a.part_name(p), "quad.0");
    assert_eq!(a.part_path(p), "node1/quad.0");
    assert_eq!(a.part_path(p), b.part_path(p));
}

#[test]
fn glb_container_and_corruptions() {
    let d = one_quad_doc();
    let glb = d.glb();
    let opts = ImportOptions::default();
    let (scene, _) = import_gltf_slice(&glb, None, "t", &opts).unwrap();
    assert_eq!(scene.triangle_count(), 2);
    for cut in [0, 3, 11, 12, 19, 40, glb.len() - 1] {
        assert!(
            import_gltf_slice(&glb[..cut], None, "t", &opts).is_err(),
            "truncated at {cut}"
        );
    }
    let mut bad_version = glb.clone();
    bad_version[4] = 1;
    assert!(
        import_gltf_slice(&bad_version, None, "t", &opts)
            .unwrap_err()
            .to_string()
            .contains("version 1")
    );
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]
    /// Any corruption of a valid file gives Ok or an error, never a panic.
    #[test]
    fn corrupted_files_never_panic(flips in prop::collection::vec((any::<usize>(), any::<u8>()), 1..8), glb in any::<bool>()) {
        let d = one_quad_doc();
        let mut bytes = if glb { d.glb() } else { d.bytes() };
        for (at, v) in flips {
            let n = bytes.len();
            bytes[at % n] = v;
        }
        let _ = import_gltf_slice(&bytes, None, "t", &ImportOptions::default());
    }
}

/// Issue 18's CI run: a fuzzed glTF whose accessor has no bufferView and a
/// count of 4e9 asked for 48 GB of zeros and aborted. It is an error naming
/// the accessor; a small zero-filled accessor still imports.
#[test]
fn issue_18_a_huge_accessor_without_a_buffer_view_is_refused() {
    let gltf = |count: u64| {
        format!(
            r#"{{"asset": {{"version": "2.0"}}, "scene": 0, "scenes": [{{"nodes": [0]}}],
            "accessors": [{{"componentType": 5126, "count": {count}, "type": "VEC3",
                "min": [0, 0, 0], "max": [0, 0, 0]}}],
            "meshes": [{{"primitives": [{{"attributes": {{"POSITION": 0}}}}]}}],
            "nodes": [{{"mesh": 0}}]}}"#
        )
    };
    let err = import_gltf_slice(
        gltf(4_000_000_000).as_bytes(),
        None,
        "t",
        &ImportOptions::default(),
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("accessors[0]") && err.contains("without a bufferView"),
        "{err}"
    );
    assert!(import_gltf_slice(gltf(3).as_bytes(), None, "t", &ImportOptions::default()).is_ok());
}

#[test]
fn node_extras_become_properties_that_export_keeps() {
    let mut d = one_quad_doc();
    d.json["nodes"][0]["extras"] = json!({
        "GlobalId": "2O2Fr$t4X7Zf8NOew3FLOH",
        "IfcClass": "IfcWallStandardCase",
        "SourceFile": "walls.ifc",
        "storey": 3,
        "fire_rated": true,
        "nested": { "a": 1 },
        "list": [1, 2],
        "none": null,
        "long": "x".repeat(dmu_scene::properties::MAX_VALUE_BYTES + 1),
    });
    let storey = d.node(
        json!({ "name": "Level 1", "children": [0], "extras": { "GlobalId": "0Storey" } }),
        false,
    );
    let odd = d.node(json!({ "name": "odd", "extras": "not an object" }), false);
    let crowded: serde_json::Map<String, serde_json::Value> =
        (0..100).map(|i| (format!("k{i:03}"), json!(i))).collect();
    let many = d.node(json!({ "name": "many", "extras": crowded }), false);
    d.json["scenes"][0]["nodes"] = json!([storey, odd, many]);
    let (scene, report) = d.import().unwrap();
    // The nested, the list, the null and the long value; the string; 36 past 64.
    assert_eq!(report.properties_dropped, 4 + 1 + 36);
    let wall = dmu_scene::PartId(0);
    let props = |s: &dmu_scene::Scene, n: dmu_scene::NodeId| {
        let mut v: Vec<(String, String)> = s
            .node_properties(n)
            .map(|(k, v)| (k.to_owned(), v.to_owned()))
            .collect();
        v.sort();
        v
    };
    let node = scene.part(wall).node;
    assert_eq!(
        props(&scene, node),
        [
            ("GlobalId", "2O2Fr$t4X7Zf8NOew3FLOH"),
            ("IfcClass", "IfcWallStandardCase"),
            ("SourceFile", "walls.ifc"),
            ("fire_rated", "true"),
            ("storey", "3"),
        ]
        .map(|(k, v)| (k.to_owned(), v.to_owned()))
    );
    let level = scene.node(node).parent.unwrap();
    assert_eq!(
        props(&scene, level),
        [("GlobalId".into(), "0Storey".into())]
    );
    let many_node = dmu_scene::NodeId(scene.nodes().len() as u32 - 1);
    assert_eq!(scene.node_name(many_node), "many");
    assert_eq!(scene.node_properties(many_node).count(), 64);
    // Found by GlobalId and by class, ignoring case; a storey has no part.
    assert_eq!(scene.find_part("2O2Fr$t4X7Zf8NOew3FLOH").unwrap(), wall);
    assert_eq!(scene.search_parts("ifcwall"), [wall]);
    assert_eq!(scene.search_parts("2o2fr$T4"), [wall]);
    assert!(scene.search_parts("0Storey").is_empty());
    assert!(scene.find_part("0Storey").is_err());
    // Only the GlobalId names a part; the source file, on every part of a
    // file, is left out of searches.
    assert!(scene.find_part("true").is_err());
    assert!(scene.find_part("IfcWallStandardCase").is_err());
    assert!(scene.search_parts("walls.ifc").is_empty());
    // Exported as extras and read back the same.
    let dir = tempfile::tempdir().unwrap();
    let glb = dir.path().join("walls.glb");
    dmu_scene::export_gltf(&scene, &glb).unwrap();
    let (again, report) =
        dmu_scene::import_gltf(&glb, &dmu_scene::ImportOptions::default()).unwrap();
    assert_eq!(report.properties_dropped, 0);
    assert_eq!(again.properties(), scene.properties());
}
