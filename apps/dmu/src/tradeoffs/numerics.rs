//! Numerics: the f64 paths the program uses (world poses in f64, geometry
//! part-local in f32) against f32 world coordinates, at offsets from the
//! origin of 1 mm to 10^9 mm, each against an exact answer; and the store's
//! quantized positions against the f32 ones. The tests below fail when an
//! error passes its bound.

use std::hint::black_box;

use anyhow::Context as _;
use dmu_collide::{Checker, Report, Settings};
use dmu_geom::{Ray3d, Ray3f, RayTriTest3f};
use dmu_scene::{PartId, Scene};
use dmu_store::{Store, WriteOptions};
use dmu_tree::{Tree, TreeOptions};
use glam::{Affine3A, DAffine3, DQuat, DVec3, Quat, Vec3};

use super::{Bench, Knob, Point, timed};

/// Offsets from the origin, mm: 10^0 to 10^9.
pub fn offsets() -> impl Iterator<Item = f64> {
    (0..=9).map(|e| 10f64.powi(e))
}

/// Distance from the pick ray's origin to the face it hits, mm (not a
/// binary fraction, so rounding shows at every offset).
const PICK_DISTANCE: f64 = 100.3;
/// Side of the picked box, mm: large enough that f32 rounding at 10^9 mm
/// (64 mm steps) leaves it a box.
const PICK_SIDE: f64 = 1000.0;
/// The gap between the two boxes of the clearance case, mm.
const GAP: f64 = 0.3;
/// The clearance case's boxes' side, mm.
const SIDE: f64 = 4.0;

/// One box at `offset` on every axis, its tree, and a ray straight down onto
/// its top face from `PICK_DISTANCE` above.
fn pick_case(offset: f64) -> (Scene, Tree, Ray3d) {
    let mut scene = dmu_samples::grid(1, 10.0, PICK_SIDE as f32, 2048);
    let mut tree = Tree::build(&scene, TreeOptions::default());
    tree.move_part(
        &mut scene,
        PartId(0),
        DAffine3::from_translation(DVec3::splat(offset)),
    );
    let top = offset + PICK_SIDE / 2.0;
    let origin = DVec3::new(offset + 0.3, offset + 0.2, top + PICK_DISTANCE);
    (scene, tree, Ray3d::new(origin, DVec3::NEG_Z))
}

/// The f32 path of a pick: the part's vertices put into world coordinates
/// in f32 (what a renderer-style f32 world would hold) and hit by the ray in
/// f32. Returns the nearest distance.
fn pick_f32(scene: &Scene, ray: &Ray3d) -> Option<f32> {
    let part = PartId(0);
    let world = scene.part_world(part);
    let world =
        Affine3A::from_mat3_translation(world.matrix3.as_mat3(), world.translation.as_vec3());
    let ray = Ray3f {
        origin: ray.origin.as_vec3(),
        dir: ray.dir.as_vec3(),
    };
    let test = RayTriTest3f::new(&ray);
    let mesh = scene.part_mesh(part);
    let mut best: Option<f32> = None;
    for chunk in mesh.chunk_ids() {
        let c = scene.chunk(chunk);
        for t in c.triangles.clone() {
            let v = scene
                .triangle_local(c.mesh, chunk, t)
                .map(|v| world.transform_point3(v));
            if let Some(hit) = test.hit(v[0], v[1], v[2], 0.0, best.unwrap_or(f32::INFINITY)) {
                best = Some(hit.t);
            }
        }
    }
    best
}

/// Pick errors at `offset`: the f32 path's and the program's (f64), mm.
pub fn pick_errors(offset: f64) -> (f64, f64) {
    let (scene, tree, ray) = pick_case(offset);
    let f64_t = tree.pick(&scene, &ray).map_or(f64::INFINITY, |h| h.t);
    let f32_t = pick_f32(&scene, &ray).map_or(f64::INFINITY, f64::from);
    ((f32_t - PICK_DISTANCE).abs(), (f64_t - PICK_DISTANCE).abs())
}

/// Two boxes at `offset`, `GAP` apart along x.
fn clearance_case(offset: f64) -> (Scene, Tree) {
    let mut scene = dmu_samples::grid(2, 100.0, SIDE as f32, 2048);
    let mut tree = Tree::build(&scene, TreeOptions::default());
    let a = scene.find_part("box_0_0_0").expect("grid box");
    let b = scene.find_part("box_1_0_0").expect("grid box");
    let base = DVec3::splat(offset);
    // The other boxes of the grid wait a metre and more away.
    let others: Vec<PartId> = scene.part_ids().filter(|&p| p != a && p != b).collect();
    for (k, p) in others.into_iter().enumerate() {
        let away = base - DVec3::X * (1000.0 * (k + 1) as f64);
        tree.move_part(&mut scene, p, DAffine3::from_translation(away));
    }
    tree.move_part(&mut scene, a, DAffine3::from_translation(base));
    tree.move_part(
        &mut scene,
        b,
        DAffine3::from_translation(base + DVec3::X * (SIDE + GAP)),
    );
    (scene, tree)
}

/// The f32 path of the gap: both facing faces put into world coordinates in
/// f32 and subtracted.
fn gap_f32(offset: f64) -> f32 {
    let half = (SIDE / 2.0) as f32;
    let a = offset as f32;
    let b = (offset + SIDE + GAP) as f32;
    (b - half) - (a + half)
}

/// Clearance errors at `offset`: the f32 path's and the program's, mm.
pub fn clearance_errors(offset: f64) -> (f64, f64) {
    let (scene, tree) = clearance_case(offset);
    let a = scene.find_part("box_0_0_0").expect("grid box");
    let mut checker = Checker::new(&scene);
    let mut report = Report::default();
    checker.check(
        &scene,
        &tree,
        &[a],
        &Settings::with_clearance(1.0),
        &mut report,
    );
    let d = report
        .clashes
        .iter()
        .map(|c| c.distance)
        .fold(f64::INFINITY, f64::min);
    ((f64::from(gap_f32(offset)) - GAP).abs(), (d - GAP).abs())
}

/// A part-local point, the pose's rotation, and the point placed at `offset`
/// by the f64 pose (the reference) and by an f32 one.
fn transformed(offset: f64) -> (DVec3, Vec3) {
    let local = Vec3::new(1.25, -0.75, 0.5);
    let q = DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7);
    let p64 = DAffine3::from_rotation_translation(q, DVec3::splat(offset))
        .transform_point3(local.as_dvec3());
    let p32 = Affine3A::from_rotation_translation(
        Quat::from_xyzw(q.x as f32, q.y as f32, q.z as f32, q.w as f32),
        DVec3::splat(offset).as_vec3(),
    )
    .transform_point3(local);
    (p64, p32)
}

/// The f32 transform's distance from the f64 one at `offset`, mm.
pub fn transform_error(offset: f64) -> f64 {
    let (p64, p32) = transformed(offset);
    p32.as_dvec3().distance(p64)
}

/// The median time of `reps` runs of `f`, ms.
fn per_call<T>(reps: usize, mut f: impl FnMut() -> T) -> f64 {
    dmu_geom::median(
        (0..reps.max(1))
            .map(|_| timed(|| black_box(f())).1)
            .collect::<Vec<_>>(),
    )
}

/// The largest distance between the positions of two scenes with the same
/// meshes, mm (part-local, as stored).
pub fn position_error(a: &Scene, b: &Scene) -> f64 {
    a.meshes()
        .iter()
        .zip(b.meshes())
        .flat_map(|(m, n)| m.positions.iter().zip(&n.positions))
        .map(|(p, q)| f64::from(p.distance(*q)))
        .fold(0.0, f64::max)
}

pub fn steps() -> u64 {
    4
}

pub fn run(bench: &Bench<'_>) -> anyhow::Result<Vec<Knob>> {
    let reps = bench.scale.numerics_reps;
    let knob = |name: &str, reference: &str, time: &str, error: &str, points| {
        Knob {
        section: "numerics",
        name: name.to_owned(),
        unit: "mm".to_owned(),
        note: "offset from the origin; the error is the f32 path's (world coordinates in f32), the f64 path's is in the table".to_owned(),
        reference: reference.to_owned(),
        time: time.to_owned(),
        error_unit: error.to_owned(),
        exact_setting: None,
        log_x: true,
        log_error: true,
        points,
    }
    };
    let mut knobs = Vec::new();
    let points = offsets()
        .map(|o| {
            let (scene, tree, ray) = pick_case(o);
            let (e32, e64) = pick_errors(o);
            Point::new(o, per_call(reps, || tree.pick(&scene, &ray)), e32, "mm")
                .extra("f64 error, mm", e64)
                .extra("f32 ms", per_call(reps, || pick_f32(&scene, &ray)))
        })
        .collect();
    knobs.push(knob(
        "pick distance",
        &format!("the exact distance, {PICK_DISTANCE} mm"),
        "pick (f64)",
        "mm",
        points,
    ));
    bench.progress.inc(1);
    let points = offsets()
        .map(|o| {
            let (scene, tree) = clearance_case(o);
            let a = scene.find_part("box_0_0_0").expect("grid box");
            let mut checker = Checker::new(&scene);
            let mut report = Report::default();
            let settings = Settings::with_clearance(1.0);
            let (e32, e64) = clearance_errors(o);
            Point::new(
                o,
                per_call(reps.div_ceil(10), || {
                    checker.check(&scene, &tree, &[a], &settings, &mut report);
                }),
                e32,
                "mm",
            )
            .extra("f64 error, mm", e64)
        })
        .collect();
    knobs.push(knob(
        "clearance",
        &format!("the exact gap, {GAP} mm"),
        "clearance check (f64)",
        "mm",
        points,
    ));
    bench.progress.inc(1);
    let points = offsets()
        .map(|o| {
            let e = transform_error(o);
            Point::new(o, per_call(reps, || transformed(o).0), e, "mm")
                .extra("f32 and f64 ms", per_call(reps, || transformed(o)))
        })
        .collect();
    knobs.push(knob(
        "transform",
        "the f64 transform",
        "f64 transform",
        "mm",
        points,
    ));
    bench.progress.inc(1);
    let mut points = Vec::new();
    for quantize in [false, true] {
        let file = bench.scratch.join(format!("quantized-{quantize}.dmu"));
        let summary = dmu_store::write_scene(bench.scene, &file, WriteOptions { quantize })
            .with_context(|| format!("writing {}", file.display()))?;
        let (loaded, ms) = timed(|| Store::open(&file).and_then(|s| s.load_scene()));
        let loaded = loaded.with_context(|| format!("loading {}", file.display()))?;
        points.push(
            Point::new(
                f64::from(u8::from(quantize)),
                ms,
                position_error(bench.scene, &loaded),
                "mm, largest",
            )
            .label(if quantize { "u16" } else { "f32" })
            .extra("file MB", summary.file_bytes as f64 / 1e6),
        );
    }
    knobs.push(Knob {
        section: "numerics",
        name: "store quantization".to_owned(),
        unit: String::new(),
        note: "positions stored as f32, or as u16 within each chunk's box".to_owned(),
        reference: "the model's f32 positions".to_owned(),
        time: "open and load".to_owned(),
        error_unit: "mm, largest".to_owned(),
        exact_setting: Some(0.0),
        log_x: false,
        log_error: false,
        points,
    });
    bench.progress.inc(1);
    Ok(knobs)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// One unit in the last place of `x` in f64 and in f32.
    fn ulp64(x: f64) -> f64 {
        x.abs().max(f64::MIN_POSITIVE) * f64::EPSILON
    }
    fn ulp32(x: f64) -> f64 {
        x.abs().max(1.0) * f64::from(f32::EPSILON)
    }

    /// The program's f64 paths stay within a few f64 ulps of the offset at
    /// every offset up to 10^9 mm; the f32 paths within a few f32 ulps (the
    /// foil is what it claims to be), and at 10^7 mm already off by more
    /// than a tenth of a millimetre.
    #[test]
    fn f64_paths_stay_exact_to_1e9_mm_and_f32_paths_do_not() {
        for o in offsets() {
            let (p32, p64) = pick_errors(o);
            assert!(p64 <= 1e-9 + 8.0 * ulp64(o), "pick at {o}: f64 error {p64}");
            assert!(p32 <= 1e-4 + 8.0 * ulp32(o), "pick at {o}: f32 error {p32}");
            let (c32, c64) = clearance_errors(o);
            assert!(
                c64 <= 1e-9 + 8.0 * ulp64(o),
                "clearance at {o}: f64 error {c64}"
            );
            assert!(
                c32 <= 1e-6 + 4.0 * ulp32(o),
                "clearance at {o}: f32 error {c32}"
            );
            let t32 = transform_error(o);
            assert!(
                t32 <= 1e-5 + 4.0 * ulp32(o),
                "transform at {o}: f32 error {t32}"
            );
        }
        assert!(pick_errors(1e7).0 > 0.1 || clearance_errors(1e7).0 > 0.1);
    }

    /// Quantized positions stay within half a step of the 16-bit grid over
    /// their chunk's box (1/131070 of its extent on each axis, as documented,
    /// up to f32 rounding), and unquantized ones are exact.
    #[test]
    fn store_quantization_stays_within_its_bound() {
        let scene = dmu_samples::plant(&dmu_samples::PlantOptions {
            triangles: 20_000,
            ..Default::default()
        });
        let dir = tempfile::tempdir().unwrap();
        for quantize in [false, true] {
            let file = dir.path().join("q.dmu");
            dmu_store::write_scene(&scene, &file, WriteOptions { quantize }).unwrap();
            let loaded = Store::open(&file).unwrap().load_scene().unwrap();
            for (m, n) in scene.meshes().iter().zip(loaded.meshes()) {
                for c in m.chunk_ids() {
                    let chunk = scene.chunk(c);
                    // Half a step of the 16-bit grid, plus the f32 rounding of
                    // the quantizer's arithmetic (a point a hair below a half
                    // step can round up): a few ulps of the box's coordinates.
                    let b = chunk.bounds;
                    let ulps = b.min.abs().max(b.max.abs()) * (4.0 * f32::EPSILON);
                    let bound = b.extent() / 131_070.0 + ulps;
                    let range = chunk.vertices.start as usize..chunk.vertices.end as usize;
                    for (p, q) in m.positions[range.clone()].iter().zip(&n.positions[range]) {
                        let d = (*p - *q).abs();
                        if quantize {
                            assert!(d.cmple(bound).all(), "chunk {c:?}: {p} became {q}");
                        } else {
                            assert_eq!(p, q);
                        }
                    }
                }
            }
        }
    }
}
