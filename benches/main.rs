//! dmu's criterion benchmarks. CI compiles them (`cargo bench --no-run`); run
//! them by hand: `cargo bench -p dmu-benches`. `DMU_BENCH_TRIANGLES` sets the
//! plant size (default 10M, the size the foundation issue reports).

use std::hint::black_box;

use criterion::{BatchSize, Criterion, Throughput, criterion_group, criterion_main};
use dmu_collide::{Checker, Report, Settings};
use dmu_geom::Ray3d;
use dmu_samples::{PlantOptions, plant};
use dmu_scene::{ImportOptions, export_gltf, import_gltf};
use dmu_tree::{Tree, TreeOptions};
use glam::{DAffine3, DVec3};

fn plant_triangles() -> u64 {
    std::env::var("DMU_BENCH_TRIANGLES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(10_000_000)
}

/// Generation and glTF import throughput, in triangles per second.
fn scene_io(c: &mut Criterion) {
    let options = PlantOptions {
        triangles: plant_triangles(),
        ..PlantOptions::default()
    };
    let scene = plant(&options);
    let dir = tempfile::tempdir().expect("temp dir");
    let path = dir.path().join("plant.glb");
    export_gltf(&scene, &path).expect("export");

    let mut group = c.benchmark_group("scene_io");
    group.sample_size(10);
    group.throughput(Throughput::Elements(scene.triangle_count()));
    group.bench_function(format!("generate_plant_{}", options.triangles), |b| {
        b.iter(|| black_box(plant(&options)))
    });
    group.bench_function(format!("import_glb_plant_{}", options.triangles), |b| {
        b.iter(|| black_box(import_gltf(&path, &ImportOptions::default()).expect("import")))
    });
    group.bench_function(format!("export_glb_plant_{}", options.triangles), |b| {
        b.iter(|| export_gltf(&scene, &path).expect("export"))
    });
    group.finish();
}

/// Chunking cost per chunk size: the knob's time side (its effect on culling and
/// picking is measured with the tree and renderer).
fn chunking(c: &mut Criterion) {
    let scene = plant(&PlantOptions {
        triangles: 1_000_000,
        ..PlantOptions::default()
    });
    let big = scene
        .meshes()
        .iter()
        .max_by_key(|m| m.triangle_count())
        .expect("a mesh");
    let mut data = dmu_scene::MeshData {
        name: big.name.clone(),
        ..Default::default()
    };
    data.push_primitive(
        &big.positions,
        &big.normals,
        &remap_to_mesh(&scene, big),
        dmu_scene::MaterialId(0),
    );
    let mut group = c.benchmark_group("chunking");
    group.throughput(Throughput::Elements(u64::from(data.triangle_count())));
    for size in [256, 1024, 2048, 8192] {
        group.bench_function(format!("chunk_mesh_{size}"), |b| {
            b.iter(|| black_box(dmu_scene::chunk_mesh(&data, size)))
        });
    }
    group.finish();
}

/// A mesh's chunk-local indices as mesh-wide indices.
fn remap_to_mesh(scene: &dmu_scene::Scene, mesh: &dmu_scene::Mesh) -> Vec<u32> {
    mesh.chunk_ids()
        .flat_map(|c| {
            let chunk = scene.chunk(c);
            let base = chunk.vertices.start;
            mesh.indices[3 * chunk.triangles.start as usize..3 * chunk.triangles.end as usize]
                .iter()
                .map(move |&i| i + base)
        })
        .collect()
}

/// The cell tree on a 1M-triangle plant: build, a pick, a move of the largest
/// part (and back), a rebuild.
fn tree(c: &mut Criterion) {
    let mut scene = plant(&PlantOptions {
        triangles: 1_000_000,
        ..PlantOptions::default()
    });
    let options = TreeOptions::default();
    let mut group = c.benchmark_group("tree");
    group.bench_function("build_1M", |b| {
        b.iter(|| black_box(Tree::build(&scene, options)))
    });
    let mut tree = Tree::build(&scene, options);
    let bounds = scene.world_bounds();
    let ray = Ray3d::new(bounds.min, bounds.extent().normalize());
    group.bench_function("pick_diagonal_1M", |b| {
        b.iter(|| black_box(tree.pick(&scene, &ray)))
    });
    let part = scene
        .part_ids()
        .max_by_key(|&p| scene.part_mesh(p).triangle_count())
        .expect("a part");
    let home = scene.part_world(part);
    let away = DAffine3::from_translation(DVec3::new(1000.0, 0.0, 0.0)) * home;
    group.bench_function("move_largest_part_1m_and_back", |b| {
        b.iter(|| {
            tree.move_part(&mut scene, part, away);
            tree.move_part(&mut scene, part, home);
        })
    });
    // A drag step as the viewer makes it: 10 mm, the renderer's mirror of the
    // tree brought up to date, the part checked for collisions; back and forth.
    let mut mirror = dmu_render::Hierarchy::default();
    mirror.sync(&tree);
    let settings = Settings::with_clearance(5.0);
    let mut checker = Checker::new(&scene);
    let mut report = Report::default();
    let mut there = false;
    group.bench_function("drag_step_10mm_1M", |b| {
        b.iter(|| {
            there = !there;
            let offset = if there { 10.0 } else { 0.0 };
            let world = DAffine3::from_translation(DVec3::new(offset, 0.0, 0.0)) * home;
            tree.move_part(&mut scene, part, world);
            mirror.sync(&tree);
            checker.check(&scene, &tree, &[part], &settings, &mut report);
        })
    });
    tree.move_part(&mut scene, part, home);
    group.bench_function("rebuild_1M", |b| {
        b.iter_batched(
            || Tree::build(&scene, options),
            |mut t| t.rebuild(),
            BatchSize::LargeInput,
        )
    });
    group.finish();
}

/// Collision: one check of the largest part of a 1M-triangle plant against
/// everything near it (it rests on its floor, so contacts are examined), with
/// the tree and without it.
fn collide(c: &mut Criterion) {
    let scene = plant(&PlantOptions {
        triangles: 1_000_000,
        ..PlantOptions::default()
    });
    let tree = Tree::build(&scene, TreeOptions::default());
    let part = scene
        .part_ids()
        .max_by_key(|&p| scene.part_mesh(p).triangle_count())
        .expect("a part");
    let settings = Settings::with_clearance(5.0);
    let mut checker = Checker::new(&scene);
    let mut report = Report::default();
    let mut group = c.benchmark_group("collide");
    group.bench_function("check_largest_part_1M", |b| {
        b.iter(|| checker.check(&scene, &tree, &[part], &settings, &mut report))
    });
    group.bench_function("check_largest_part_1M_no_tree", |b| {
        b.iter(|| checker.check_without_tree(&scene, &[part], &settings, &mut report))
    });
    group.finish();
}

criterion_group!(benches, scene_io, chunking, tree, collide);
criterion_main!(benches);
