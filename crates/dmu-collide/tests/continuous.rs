//! The continuous check: tunnelling, rotations, two moving parts.

use dmu_collide::{
    Checker, Motion, RecordedMove, Report, Settings, Step, SweepDecision, SweepMode, replay,
};
use dmu_scene::{PartId, Scene};
use dmu_tree::{Tree, TreeOptions};
use glam::{DAffine3, DVec3, Vec3};

use crate::support::{Shape, box_mesh, scene_of};

const FAR: DVec3 = DVec3::new(1e7, -1e7, 1e7);

fn at(offset: DVec3, p: DVec3) -> DAffine3 {
    DAffine3::from_translation(offset + p)
}

/// A 1 mm plate (200 x 200) at z = 0 and a 20 mm cube above it at z = 50.
fn plate_and_cube(offset: DVec3) -> Scene {
    scene_of(
        &[
            Shape::new(
                "plate",
                box_mesh(Vec3::new(100.0, 100.0, 0.5)),
                at(offset, DVec3::ZERO),
            ),
            Shape::new(
                "cube",
                box_mesh(Vec3::splat(10.0)),
                at(offset, DVec3::new(0.0, 0.0, 50.0)),
            ),
        ],
        2048,
    )
}

fn sweep(scene: &Scene, motions: &[Motion], settings: &Settings) -> Report {
    let tree = Tree::build(scene, TreeOptions::default());
    let mut report = Report::default();
    Checker::new(scene).sweep(scene, &tree, motions, settings, &mut report);
    report
}

#[test]
fn a_thin_plate_crossed_in_one_step_is_found_only_when_continuous() {
    for offset in [DVec3::ZERO, FAR] {
        let mut scene = plate_and_cube(offset);
        let cube = PartId(1);
        let steps = [Step {
            t: 1.0,
            moves: vec![RecordedMove {
                line: 1,
                part: cube,
                world: at(offset, DVec3::new(0.0, 0.0, -50.0)),
            }],
        }];
        let settings = Settings::with_clearance(5.0);
        let run = |scene: &mut Scene, mode: SweepMode| {
            let mut tree = Tree::build(scene, TreeOptions::default());
            let mut checker = Checker::new(scene);
            let mut seen = Vec::new();
            let mut because = Vec::new();
            let summary = replay(
                scene,
                &mut tree,
                &mut checker,
                &steps,
                &settings,
                mode,
                |o| {
                    seen.push(o.report.clone());
                    because.extend_from_slice(o.swept_because);
                },
            );
            (summary, seen, because)
        };
        // Discrete: the cube ends 39.5 mm below the plate, beyond the clearance.
        let (summary, seen, because) = run(&mut scene.clone(), SweepMode::Off);
        assert_eq!((summary.steps, summary.clashes, summary.impacts), (1, 0, 0));
        assert!(seen[0].is_clear() && because.is_empty());
        // Auto: the cube fell 100 mm, more than its 20 mm: swept, and said why.
        let (summary, _, because) = run(&mut scene.clone(), SweepMode::Auto);
        assert_eq!((summary.clashes, summary.impacts), (0, 1));
        let expected = SweepDecision {
            part: cube,
            moved: 100.0,
            thickness: 20.0,
        };
        assert_eq!(because.len(), 1);
        assert_eq!(because[0].part, expected.part);
        assert!(
            (because[0].moved - expected.moved).abs() < 1e-9,
            "{because:?}"
        );
        assert!((because[0].thickness - expected.thickness).abs() < 1e-9);
        assert_eq!(
            because[0].describe(&scene),
            "part cube moved 100 model units, more than its thickness 20: continuous (swept) check"
        );
        // Always: it met the plate 39.5 mm into its 100 mm fall.
        let (summary, seen, because) = run(&mut scene, SweepMode::Always);
        assert_eq!((summary.clashes, summary.impacts), (0, 1));
        assert!(because.is_empty(), "swept always, not by choice");
        let impact = seen[0].impacts[0];
        assert_eq!((impact.a, impact.b), (cube, PartId(0)));
        assert!((impact.toi - 0.395).abs() < 1e-6, "toi {}", impact.toi);
        assert!(
            (impact.point.z - (offset.z + 0.5)).abs() < 1e-3,
            "{}",
            impact.point
        );
    }
}

#[test]
fn a_turning_bar_hits_a_post_between_two_clear_poses() {
    for offset in [DVec3::ZERO, FAR] {
        // A 200 mm bar along x turning a quarter turn about z; a post at 45°, 60 mm out.
        let scene = scene_of(
            &[
                Shape::new(
                    "post",
                    box_mesh(Vec3::splat(5.0)),
                    at(offset, DVec3::new(42.4, 42.4, 0.0)),
                ),
                Shape::new(
                    "bar",
                    box_mesh(Vec3::new(100.0, 5.0, 5.0)),
                    at(offset, DVec3::ZERO),
                ),
            ],
            2048,
        );
        let from = at(offset, DVec3::ZERO);
        let to = from * DAffine3::from_rotation_z(std::f64::consts::FRAC_PI_2);
        let settings = Settings::default();
        // Clear at both ends.
        for pose in [from, to] {
            let mut s = scene.clone();
            s.set_part_world(PartId(1), pose);
            let tree = Tree::build(&s, TreeOptions::default());
            let mut report = Report::default();
            Checker::new(&s).check(&s, &tree, &[PartId(1)], &settings, &mut report);
            assert!(report.is_clear(), "{report:?}");
        }
        let report = sweep(
            &scene,
            &[Motion {
                part: PartId(1),
                from,
                to,
            }],
            &settings,
        );
        assert_eq!(report.impacts.len(), 1, "{report:?}");
        let toi = report.impacts[0].toi;
        // The bar's leading face (y = 5 in its frame) first reaches a post
        // corner at polar (r, φ) when it has turned φ - asin(5 / r).
        let angle = [(37.4, 37.4), (47.4, 37.4), (37.4, 47.4), (47.4, 47.4)]
            .map(|(x, y): (f64, f64)| y.atan2(x) - (5.0 / x.hypot(y)).asin())
            .into_iter()
            .fold(f64::INFINITY, f64::min);
        let expected = angle / std::f64::consts::FRAC_PI_2;
        assert!(
            (toi - expected).abs() < 1e-5,
            "toi {toi}, expected {expected}"
        );
    }
}

#[test]
fn two_parts_moving_at_each_other_and_parts_touching_at_the_start() {
    let scene = scene_of(
        &[
            Shape::new(
                "left",
                box_mesh(Vec3::splat(10.0)),
                at(FAR, DVec3::new(-100.0, 0.0, 0.0)),
            ),
            Shape::new(
                "right",
                box_mesh(Vec3::splat(10.0)),
                at(FAR, DVec3::new(100.0, 0.0, 0.0)),
            ),
        ],
        2048,
    );
    let motions = [
        Motion {
            part: PartId(0),
            from: at(FAR, DVec3::new(-100.0, 0.0, 0.0)),
            to: at(FAR, DVec3::ZERO),
        },
        Motion {
            part: PartId(1),
            from: at(FAR, DVec3::new(100.0, 0.0, 0.0)),
            to: at(FAR, DVec3::ZERO),
        },
    ];
    let report = sweep(&scene, &motions, &Settings::default());
    assert_eq!(report.impacts.len(), 1);
    // The gap of 180 closes at 200 per step.
    assert!(
        (report.impacts[0].toi - 0.9).abs() < 1e-6,
        "{:?}",
        report.impacts
    );
    // Resting on the plate and sliding along it: an impact at once.
    let scene = plate_and_cube(FAR);
    let from = at(FAR, DVec3::new(0.0, 0.0, 10.5));
    let slide = Motion {
        part: PartId(1),
        from,
        to: at(FAR, DVec3::new(50.0, 0.0, 10.5)),
    };
    let report = sweep(&scene, &[slide], &Settings::default());
    assert_eq!(report.impacts.len(), 1);
    assert_eq!(report.impacts[0].toi, 0.0);
    // Lifting off it, 1 mm above and rising: nothing.
    let lift = Motion {
        part: PartId(1),
        from: at(FAR, DVec3::new(0.0, 0.0, 11.5)),
        to: at(FAR, DVec3::new(0.0, 0.0, 60.0)),
    };
    assert!(
        sweep(&scene, &[lift], &Settings::default())
            .impacts
            .is_empty()
    );
}
