//! Boxes and cylinders at known gaps, at the origin and 10^7 mm from it.

use dmu_collide::{Checker, Clash, ClashKind, Report, Settings};
use dmu_samples::Rng;
use dmu_scene::{PartId, Scene};
use dmu_tree::{Tree, TreeOptions};
use glam::{DAffine3, DQuat, DVec3, Vec3};

use crate::support::{
    Shape, box_mesh, brute_inside, cylinder_mesh, oracle, scene_of, tessellated_box_mesh,
    tolerance, world_triangles,
};

const GAPS: [f64; 4] = [0.0, 0.05, 1.0, 1000.0];
const FAR: DVec3 = DVec3::new(1e7, 1e7, 1e7);

/// Clashes of part 1 (moved) against the rest.
fn check(scene: &Scene, settings: &Settings) -> Vec<Clash> {
    let tree = Tree::build(scene, TreeOptions::default());
    let mut report = Report::default();
    Checker::new(scene).check(scene, &tree, &[PartId(1)], settings, &mut report);
    tree.validate_against(scene).unwrap();
    report.clashes
}

/// Places a pair laid out near the origin at `offset`, turned by `turn` about it.
fn placed(offset: DVec3, turn: DQuat, local: DAffine3) -> DAffine3 {
    DAffine3::from_rotation_translation(turn, offset) * local
}

/// The pair's one clash is `kind` at distance `gap` (relative 1e-6, or within
/// the contact tolerance for touching).
fn assert_gap(scene: &Scene, gap: f64, what: &str) {
    let tol = tolerance(scene, PartId(0), 1e-6).max(tolerance(scene, PartId(1), 1e-6));
    // A clearance above the gap: soft (or contact at 0).
    let clashes = check(scene, &Settings::with_clearance(2.0 * gap + 1.0));
    assert_eq!(clashes.len(), 1, "{what}: {clashes:?}");
    let c = clashes[0];
    // The moved part first.
    assert_eq!((c.a, c.b), (PartId(1), PartId(0)), "{what}");
    if gap == 0.0 {
        assert_eq!(c.kind, ClashKind::Contact, "{what}: {c:?}");
        assert!(
            c.distance <= tol,
            "{what}: {} > tolerance {tol}",
            c.distance
        );
    } else {
        assert_eq!(c.kind, ClashKind::Soft, "{what}: {c:?}");
        assert!(
            (c.distance - gap).abs() <= 1e-6 * gap,
            "{what}: distance {} for gap {gap} (error {:e})",
            c.distance,
            (c.distance - gap).abs() / gap
        );
    }
    // A clearance below the gap: clear, unless touching.
    let clashes = check(scene, &Settings::with_clearance(gap * 0.5));
    if gap == 0.0 {
        assert_eq!(clashes.len(), 1, "{what}");
        assert_eq!(clashes[0].kind, ClashKind::Contact, "{what}");
    } else {
        assert!(clashes.is_empty(), "{what}: {clashes:?}");
    }
}

fn turns() -> [DQuat; 2] {
    [
        DQuat::IDENTITY,
        DQuat::from_axis_angle(DVec3::new(1.0, 2.0, 3.0).normalize(), 0.7),
    ]
}

#[test]
fn boxes_face_to_face_at_known_gaps() {
    for offset in [DVec3::ZERO, FAR] {
        for turn in turns() {
            for gap in GAPS {
                // A 100 x 60 x 40 slab, a 40 mm cube above it, offset sideways so
                // only part of the faces overlap.
                let scene = scene_of(
                    &[
                        Shape::new(
                            "slab",
                            box_mesh(Vec3::new(50.0, 30.0, 20.0)),
                            placed(offset, turn, DAffine3::IDENTITY),
                        ),
                        Shape::new(
                            "cube",
                            box_mesh(Vec3::splat(20.0)),
                            placed(
                                offset,
                                turn,
                                DAffine3::from_translation(DVec3::new(35.0, -5.0, 40.0 + gap)),
                            ),
                        ),
                    ],
                    2048,
                );
                assert_gap(
                    &scene,
                    gap,
                    &format!("boxes gap {gap} at {offset} turned {turn}"),
                );
            }
        }
    }
}

/// Where the second part goes for a gap.
type Layout = fn(f64) -> DAffine3;

#[test]
fn cylinders_side_by_side_end_to_end_and_crossed_at_known_gaps() {
    const R: f64 = 25.0;
    const H: f64 = 100.0;
    let cylinder = || cylinder_mesh(R as f32, H as f32, 64);
    // Where the second cylinder goes for a gap: the rim edges at +x and -x face
    // each other; the caps face each other; an edge along z faces an edge along y.
    let layouts: [(&str, Layout); 3] = [
        ("side by side", |g| {
            DAffine3::from_translation(DVec3::new(2.0 * R + g, 0.0, 0.0))
        }),
        ("end to end", |g| {
            DAffine3::from_translation(DVec3::new(3.0, 4.0, H + g))
        }),
        ("crossed", |g| {
            DAffine3::from_translation(DVec3::new(2.0 * R + g, 0.0, 0.0))
                * DAffine3::from_rotation_x(std::f64::consts::FRAC_PI_2)
        }),
    ];
    for offset in [DVec3::ZERO, FAR] {
        for turn in turns() {
            for (name, layout) in layouts {
                for gap in GAPS {
                    let scene = scene_of(
                        &[
                            Shape::new("a", cylinder(), placed(offset, turn, DAffine3::IDENTITY)),
                            Shape::new("b", cylinder(), placed(offset, turn, layout(gap))),
                        ],
                        2048,
                    );
                    assert_gap(
                        &scene,
                        gap,
                        &format!("cylinders {name} gap {gap} at {offset}"),
                    );
                }
            }
        }
    }
}

/// Penetration by `depth` (negative gap) of the cube into the slab.
fn sunk(offset: DVec3, turn: DQuat, depth: f64, sideways: f64) -> Scene {
    scene_of(
        &[
            Shape::new(
                "slab",
                box_mesh(Vec3::new(50.0, 30.0, 20.0)),
                placed(offset, turn, DAffine3::IDENTITY),
            ),
            Shape::new(
                "cube",
                box_mesh(Vec3::splat(20.0)),
                placed(
                    offset,
                    turn,
                    DAffine3::from_translation(DVec3::new(sideways, -5.0, 40.0 - depth)),
                ),
            ),
        ],
        2048,
    )
}

#[test]
fn touching_is_contact_under_any_rigid_placement_and_penetration_is_hard() {
    let mut rng = Rng::new(7);
    for i in 0..60 {
        let offset = if i % 2 == 0 { DVec3::ZERO } else { FAR }
            + DVec3::new(
                rng.range(-1e3, 1e3),
                rng.range(-1e3, 1e3),
                rng.range(-1e3, 1e3),
            );
        let axis = DVec3::new(
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
            rng.range(-1.0, 1.0),
        );
        let turn = DQuat::from_axis_angle(axis.normalize_or(DVec3::Z), rng.range(-3.2, 3.2));
        let settings = Settings::with_clearance(1.0);
        let scene = sunk(offset, turn, 0.0, 12.5);
        let tol = tolerance(&scene, PartId(0), 1e-6);
        let kinds = |depth: f64, sideways: f64| {
            check(&sunk(offset, turn, depth, sideways), &settings)
                .iter()
                .map(|c| c.kind)
                .collect::<Vec<_>>()
        };
        // Resting on it: contact, every time (no hard/soft flicker from rounding).
        assert_eq!(kinds(0.0, 12.5), [ClashKind::Contact], "placement {i}");
        // Rounding-sized overlap or gap: still contact.
        assert_eq!(
            kinds(0.1 * tol, 12.5),
            [ClashKind::Contact],
            "placement {i}"
        );
        assert_eq!(
            kinds(-0.1 * tol, 12.5),
            [ClashKind::Contact],
            "placement {i}"
        );
        // Beyond the tolerance either way.
        assert_eq!(kinds(1e-3, 12.5), [ClashKind::Hard], "placement {i}");
        assert_eq!(kinds(-1e-3, 12.5), [ClashKind::Soft], "placement {i}");
        // Flush with the slab's side faces and sunk: the side faces coincide
        // facing the same way, so the solids overlap: hard, not contact.
        assert_eq!(kinds(1.0, 30.0), [ClashKind::Hard], "placement {i}");
        // Flush and resting: contact.
        assert_eq!(kinds(0.0, 30.0), [ClashKind::Contact], "placement {i}");
        // A twin slab on the same footprint: no face crosses another, the side
        // faces only coincide. Sunk it is hard (the same-facing rule), resting
        // it is contact.
        let twin = |depth: f64| {
            let h = Vec3::new(50.0, 30.0, 20.0);
            let scene = scene_of(
                &[
                    Shape::new(
                        "slab",
                        box_mesh(h),
                        placed(offset, turn, DAffine3::IDENTITY),
                    ),
                    Shape::new(
                        "twin",
                        box_mesh(h),
                        placed(
                            offset,
                            turn,
                            DAffine3::from_translation(DVec3::new(0.0, 0.0, 40.0 - depth)),
                        ),
                    ),
                ],
                2048,
            );
            check(&scene, &settings)
                .iter()
                .map(|c| c.kind)
                .collect::<Vec<_>>()
        };
        assert_eq!(twin(1.0), [ClashKind::Hard], "placement {i}");
        assert_eq!(twin(0.0), [ClashKind::Contact], "placement {i}");
    }
    assert!(
        tolerance(
            &sunk(DVec3::ZERO, DQuat::IDENTITY, 0.0, 0.0),
            PartId(0),
            1e-6
        ) < 2e-4
    );
}

/// parry's own queries form the relative pose from f32 world poses: 10^7 mm
/// from the origin, where f32 steps by 1 mm, a 0.5 mm gap rounds away.
#[test]
fn an_f32_relative_pose_misreads_a_far_gap_which_the_f64_pose_keeps() {
    use parry3d::math::Pose;
    use parry3d::shape::TriMesh;
    let trimesh = |h: Vec3| {
        let (v, i) = box_mesh(h);
        TriMesh::new(v, i.chunks(3).map(|t| [t[0], t[1], t[2]]).collect()).unwrap()
    };
    let (slab, cube) = (
        trimesh(Vec3::new(50.0, 30.0, 20.0)),
        trimesh(Vec3::splat(20.0)),
    );
    let gap = 0.5;
    let parry_distance = |offset: DVec3| {
        let a = Pose::from_translation(offset.as_vec3());
        let b = Pose::from_translation((offset + DVec3::new(35.0, -5.0, 40.0 + gap)).as_vec3());
        parry3d::query::distance(&a, &slab, &b, &cube)
            .unwrap()
            .distance
    };
    // Near the origin parry reads the gap...
    assert!((parry_distance(DVec3::ZERO) - gap as f32).abs() < 1e-4);
    // ...far away the f32 poses put the cube on the slab.
    let far = parry_distance(FAR);
    assert!((far - gap as f32).abs() > 0.25, "parry read {far}");
    // Ours, from the same f32 geometry with f64 poses, reads 0.5.
    let scene = sunk(FAR, DQuat::IDENTITY, -gap, 35.0);
    let clashes = check(&scene, &Settings::with_clearance(1.0));
    assert_eq!(clashes[0].kind, ClashKind::Soft);
    assert!(
        (clashes[0].distance - gap).abs() < 1e-6 * gap,
        "{}",
        clashes[0].distance
    );
}

#[test]
fn a_part_inside_a_closed_part_is_hard_inside_an_open_one_is_not_seen() {
    for offset in [DVec3::ZERO, FAR] {
        let at = |p: DVec3| DAffine3::from_translation(offset + p);
        let inner = || box_mesh(Vec3::splat(5.0));
        let scene = scene_of(
            &[
                Shape::new("shell", box_mesh(Vec3::splat(100.0)), at(DVec3::ZERO)),
                Shape::new("inner", inner(), at(DVec3::new(10.0, 20.0, 30.0))),
            ],
            2048,
        );
        let clashes = check(&scene, &Settings::with_clearance(5.0));
        assert_eq!(clashes.len(), 1);
        assert_eq!(clashes[0].kind, ClashKind::Hard);
        assert_eq!(clashes[0].distance, 0.0);
        // The same shell without its top: a surface that contains nothing.
        let (v, mut i) = box_mesh(Vec3::splat(100.0));
        i.drain(6..12);
        let scene = scene_of(
            &[
                Shape::new("open", (v, i), at(DVec3::ZERO)),
                Shape::new("inner", inner(), at(DVec3::new(10.0, 20.0, 30.0))),
            ],
            2048,
        );
        assert!(check(&scene, &Settings::with_clearance(5.0)).is_empty());
        // Outside the closed shell: clear.
        let scene = scene_of(
            &[
                Shape::new("shell", box_mesh(Vec3::splat(100.0)), at(DVec3::ZERO)),
                Shape::new("inner", inner(), at(DVec3::new(300.0, 0.0, 0.0))),
            ],
            2048,
        );
        assert!(check(&scene, &Settings::with_clearance(5.0)).is_empty());
    }
}

/// Issue 18: a small cube deep inside a closed hollow box of many chunks, whose
/// chunk boxes are all far from the cube, is a hard clash when the cube moves
/// (it is swallowed) and when the box moves (it swallows), at the origin and
/// 10^7 mm from it; outside, or in the box without its top, it is clear.
#[test]
fn issue_18_a_part_deep_inside_a_closed_part_of_many_chunks_is_hard() {
    for offset in [DVec3::ZERO, FAR] {
        let at = |p: DVec3| DAffine3::from_translation(offset + p);
        // Half size 1000, each face 5 x 5 squares: 300 triangles, 6 a chunk.
        let (v, i) = tessellated_box_mesh(Vec3::splat(1000.0), 5);
        let mut open = i.clone();
        open.drain(..6 * 25); // the +x face: open, it contains nothing
        for (shell, closed) in [((v.clone(), i), true), ((v.clone(), open), false)] {
            let mut scene = scene_of(
                &[
                    Shape::new("hall", shell, at(DVec3::ZERO)),
                    Shape::new(
                        "pump",
                        box_mesh(Vec3::splat(5.0)),
                        at(DVec3::new(10.0, -20.0, 30.0)),
                    ),
                ],
                6,
            );
            let (hall, pump) = (PartId(0), PartId(1));
            assert!(scene.part_mesh(hall).chunks.len() >= if closed { 50 } else { 42 });
            // The cube's first vertex is inside by brute-force ray parity (the
            // oracle; the open hall too, but an open surface holds nothing),
            // and no chunk box of the hall is near the cube.
            let first = scene
                .part_world(pump)
                .transform_point3(scene.part_mesh(pump).positions[0].as_dvec3());
            assert!(brute_inside(first, &world_triangles(&scene, hall)));
            let pump_box = scene.part_world_bounds(pump).inflated(5.0);
            assert!(
                scene
                    .part_mesh(hall)
                    .chunk_ids()
                    .all(|c| !scene.chunk_world_bounds(hall, c).overlaps(&pump_box))
            );
            let mut tree = Tree::build(
                &scene,
                TreeOptions {
                    cell_triangles: 12,
                    ..TreeOptions::default()
                },
            );
            let mut checker = Checker::new(&scene);
            let mut report = Report::default();
            let settings = Settings::with_clearance(5.0);
            // Moved about inside: found at every step, by either part.
            for step in 0..=20 {
                let dx = 10.0 * f64::from(step);
                tree.move_part(&mut scene, pump, at(DVec3::new(10.0 + dx, -20.0, 30.0)));
                for moved in [pump, hall] {
                    checker.check(&scene, &tree, &[moved], &settings, &mut report);
                    let kinds: Vec<_> = report
                        .clashes
                        .iter()
                        .map(|c| (c.a, c.b, c.kind, c.distance))
                        .collect();
                    let (a, b) = if moved == pump {
                        (pump, hall)
                    } else {
                        (hall, pump)
                    };
                    let want = if closed {
                        vec![(a, b, ClashKind::Hard, 0.0)]
                    } else {
                        vec![]
                    };
                    assert_eq!(
                        kinds, want,
                        "offset {offset}, closed {closed}, step {step}, moved {moved:?}"
                    );
                    let mut flat = Report::default();
                    checker.check_without_tree(&scene, &[moved], &settings, &mut flat);
                    assert_eq!(flat.clashes, report.clashes);
                }
            }
            // Out of the hall: clear, whichever moves.
            tree.move_part(&mut scene, pump, at(DVec3::new(3000.0, 0.0, 0.0)));
            for moved in [pump, hall] {
                checker.check(&scene, &tree, &[moved], &settings, &mut report);
                assert!(report.clashes.is_empty(), "{:?}", report.clashes);
            }
        }
    }
}

/// Issue 18: a tessellated block resting on a tessellated floor, where the
/// narrow phase holds a pair at distance 0 early and then tests the other
/// touching pairs for penetration only, equals the brute force over every
/// triangle pair: resting (contact), sunk by
/// a fraction of the tolerance (contact) and by more than it (hard), lifted
/// (soft), turned about the vertical, tilted, at the origin and 10^7 mm away.
#[test]
fn issue_18_resting_faces_tested_for_penetration_only_equal_brute_force() {
    let floor = tessellated_box_mesh(Vec3::new(400.0, 300.0, 10.0), 6);
    let block = tessellated_box_mesh(Vec3::new(60.0, 40.0, 30.0), 4);
    let mut kinds = std::collections::BTreeSet::new();
    let mut rng = Rng::new(18);
    for offset in [DVec3::ZERO, FAR] {
        for i in 0..24 {
            let tolerance = 1e-6 * 1000.0; // the floor's scale (extent ~1000) sets it
            let z = 40.0 + [0.0, 0.0, -0.3 * tolerance, -3.0 * tolerance, 0.5][i % 5];
            let turn = DQuat::from_rotation_z(rng.range(-3.2, 3.2));
            let tilt = if i % 6 == 5 {
                DQuat::from_rotation_x(0.01)
            } else {
                DQuat::IDENTITY
            };
            let at = DVec3::new(rng.range(-300.0, 300.0), rng.range(-200.0, 200.0), z);
            let scene = scene_of(
                &[
                    Shape::new("floor", floor.clone(), DAffine3::from_translation(offset)),
                    Shape::new(
                        "block",
                        block.clone(),
                        DAffine3::from_rotation_translation(tilt * turn, offset + at),
                    ),
                ],
                64,
            );
            let settings = Settings::with_clearance(1.0);
            let got: Vec<_> = check(&scene, &settings)
                .iter()
                .map(|c| (c.a, c.b, c.kind, c.distance))
                .collect();
            let want: Vec<_> = oracle(&scene, &[PartId(1)], &settings, &[true, true])
                .iter()
                .map(|e| (e.a, e.b, e.kind, e.distance))
                .collect();
            assert_eq!(got.len(), want.len(), "case {i}: {got:?} vs {want:?}");
            for (g, w) in got.iter().zip(&want) {
                assert_eq!(
                    (g.0, g.1, g.2),
                    (w.0, w.1, w.2),
                    "case {i}: {got:?} vs {want:?}"
                );
                assert!((g.3 - w.3).abs() <= 1e-9, "case {i}: {got:?} vs {want:?}");
                kinds.insert(g.2);
            }
        }
    }
    assert_eq!(kinds.len(), 3, "{kinds:?}");
}

#[test]
fn mirrored_and_scaled_parts_measure_world_distances() {
    // The cube mirrored in x and scaled by 2 (half size 10 -> 20): same gap.
    for offset in [DVec3::ZERO, FAR] {
        let cube = DAffine3::from_translation(offset + DVec3::new(35.0, -5.0, 40.0 + 0.05))
            * DAffine3::from_scale(DVec3::new(-2.0, 2.0, 2.0));
        let scene = scene_of(
            &[
                Shape::new(
                    "slab",
                    box_mesh(Vec3::new(50.0, 30.0, 20.0)),
                    DAffine3::from_translation(offset),
                ),
                Shape::new("cube", box_mesh(Vec3::splat(10.0)), cube),
            ],
            2048,
        );
        assert_gap(&scene, 0.05, "mirrored, scaled");
        // Sunk 1 mm: still hard (mirroring must not turn faces inside out).
        let cube = DAffine3::from_translation(offset + DVec3::new(50.0 - 20.0, 30.0 - 20.0, 39.0))
            * DAffine3::from_scale(DVec3::new(-2.0, 2.0, 2.0));
        let scene = scene_of(
            &[
                Shape::new(
                    "slab",
                    box_mesh(Vec3::new(50.0, 30.0, 20.0)),
                    DAffine3::from_translation(offset),
                ),
                Shape::new("cube", box_mesh(Vec3::splat(10.0)), cube),
            ],
            2048,
        );
        let clashes = check(&scene, &Settings::default());
        assert_eq!(clashes.len(), 1);
        assert_eq!(clashes[0].kind, ClashKind::Hard);
    }
}
