//! Record parsing (errors name their line), writing (read back unchanged) and
//! replay on the grid.

use dmu_collide::{
    Checker, ClashKind, RecordError, RecordedMove, Settings, Step, SweepMode, parse_record, replay,
    write_record,
};
use dmu_samples::{Rng, grid};
use dmu_scene::PartId;
use dmu_tree::{Tree, TreeOptions};
use glam::{DAffine3, DQuat, DVec3};

fn line(t: f64, part: &str, x: f64) -> String {
    format!(
        r#"{{"t": {t}, "part": "{part}", "translation": [{x}, 0, 0], "rotation": [0, 0, 0, 1]}}"#
    )
}

#[test]
fn lines_group_by_time_and_name_parts_by_name_or_id() {
    let scene = grid(2, 10.0, 4.0, 2048);
    let text = [
        line(0.0, "box_0_0_0", 1.0),
        line(0.0, "#1", 11.0),
        String::new(),
        line(0.5, "box_0_0_0", 2.0),
        r#"{"t": 1, "part": "box_0_0_0", "translation": [3, 4, 5], "rotation": [0, 0, 0.7071068, 0.7071068]}"#.into(),
    ]
    .join("\n");
    let steps = parse_record(&text, &scene).unwrap();
    assert_eq!(steps.len(), 3);
    assert_eq!((steps[0].t, steps[0].moves.len()), (0.0, 2));
    assert_eq!(steps[0].moves[1].part, dmu_scene::PartId(1));
    assert_eq!(steps[1].moves[0].line, 4);
    let last = steps[2].moves[0];
    assert_eq!(last.line, 5);
    assert_eq!(last.world.translation, DVec3::new(3.0, 4.0, 5.0));
    let (_, rotation, _) = last.world.to_scale_rotation_translation();
    assert!(rotation.angle_between(DQuat::from_rotation_z(std::f64::consts::FRAC_PI_2)) < 1e-6);
}

#[test]
fn errors_name_the_line_and_what_is_wrong() {
    let scene = grid(2, 10.0, 4.0, 2048);
    let ok = line(0.0, "box_0_0_0", 1.0);
    let cases: [(String, &str); 9] = [
        ("{\"t\": 0, ".into(), "line 2: EOF while parsing"),
        (r#"{"t": 0, "part": "box_0_0_0", "translation": [1, 2], "rotation": [0, 0, 0, 1]}"#.into(), "line 2: invalid length 2"),
        (r#"{"t": 0, "part": "box_0_0_0", "rotation": [0, 0, 0, 1]}"#.into(), "line 2: missing field `translation`"),
        (r#"{"t": 0, "part": "box_0_0_0", "translate": [0, 0, 0], "translation": [0, 0, 0], "rotation": [0, 0, 0, 1]}"#.into(), "line 2: unknown field `translate`"),
        (r#"{"t": 0, "part": "box_0_0_0", "translation": [0, 0, 0], "rotation": [0, 0, 0, 2]}"#.into(), "line 2: rotation [0, 0, 0, 2] is not a unit quaternion"),
        (r#"{"t": "now", "part": "box_0_0_0", "translation": [0, 0, 0], "rotation": [0, 0, 0, 1]}"#.into(), "line 2: invalid type: string \"now\""),
        (line(0.0, "pump_7", 0.0), "line 2: unknown part \"pump_7\""),
        (line(0.0, "box_0_0_0", 5.0), "line 2: part \"box_0_0_0\" already moves at t = 0"),
        (line(-1.0, "box_0_0_0", 5.0), "line 2: t = -1 comes after t = 0"),
    ];
    for (bad, want) in cases {
        let err = parse_record(&format!("{ok}\n{bad}\n{ok}"), &scene).unwrap_err();
        let message = err.to_string();
        assert!(
            message.starts_with(want),
            "{message:?} should start with {want:?}"
        );
        let line = match err {
            RecordError::Malformed { line, .. }
            | RecordError::UnknownPart { line, .. }
            | RecordError::DuplicatePart { line, .. }
            | RecordError::OutOfOrder { line, .. } => line,
            other => panic!("{other}"),
        };
        assert_eq!(line, 2);
    }
    assert!(parse_record("", &scene).unwrap().is_empty());
}

#[test]
fn replay_moves_through_the_tree_and_reports_each_step() {
    let mut scene = grid(2, 10.0, 4.0, 2048);
    let mut tree = Tree::build(&scene, TreeOptions::default());
    let mut checker = Checker::new(&scene);
    // box_0_0_0 (side 4) slides towards box_1_0_0 (faces at x = 8..12).
    let text = [
        line(0.0, "box_0_0_0", 0.0),
        line(1.0, "box_0_0_0", 3.0),
        line(2.0, "box_0_0_0", 6.0),
        line(3.0, "box_0_0_0", 7.0),
    ]
    .join("\n");
    let steps = parse_record(&text, &scene).unwrap();
    let mut seen = Vec::new();
    let summary = replay(
        &mut scene,
        &mut tree,
        &mut checker,
        &steps,
        &Settings::with_clearance(5.0),
        SweepMode::Off,
        |o| {
            seen.push((
                o.index,
                o.step.t,
                o.report
                    .clashes
                    .iter()
                    .map(|c| (c.kind, c.distance))
                    .collect::<Vec<_>>(),
            ));
        },
    );
    tree.validate_against(&scene).unwrap();
    assert_eq!(summary.steps, 4);
    assert_eq!(summary.clashes, 3);
    assert!(summary.part_pairs_tested >= 3 && summary.chunk_pairs_tested >= 3);
    // Gaps 6 (clear: clearance 5 is strict), 3 (soft), 0 (contact), -1 (hard).
    assert_eq!(seen[0], (0, 0.0, vec![]));
    assert_eq!(seen[1].2, vec![(ClashKind::Soft, 3.0)]);
    assert_eq!(seen[2].2, vec![(ClashKind::Contact, 0.0)]);
    assert_eq!(seen[3].2, vec![(ClashKind::Hard, 0.0)]);
}

/// Whether `a` is `b` to within a few ulps: serde_json (without its
/// `float_roundtrip` feature) may read a shortest-form number an ulp off.
fn ulps_close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 4.0 * f64::EPSILON * b.abs()
}

/// Random steps (increasing times, one to three distinct parts each, random
/// poses) written and read back are the same steps, line numbers included
/// (numbers to within a few ulps).
#[test]
fn written_steps_read_back_unchanged() {
    let scene = grid(3, 10.0, 4.0, 2048);
    let parts = scene.parts().len() as u64;
    let mut rng = Rng::new(12);
    let mut steps: Vec<Step> = Vec::new();
    let mut line = 0;
    let mut t = 0.0;
    for _ in 0..50 {
        t += rng.range(1e-6, 2.0);
        let mut moves: Vec<RecordedMove> = Vec::new();
        for _ in 0..1 + rng.below(3) {
            let part = PartId(rng.below(parts) as u32);
            if moves.iter().any(|m| m.part == part) {
                continue;
            }
            let axis = DVec3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 1.0).normalize();
            let rotation = DQuat::from_axis_angle(axis, rng.range(-3.0, 3.0));
            let translation = DVec3::new(rng.range(-1e6, 1e6), rng.range(-50.0, 50.0), 0.125);
            line += 1;
            moves.push(RecordedMove {
                line,
                part,
                world: DAffine3::from_rotation_translation(rotation, translation),
            });
        }
        steps.push(Step { t, moves });
    }
    let mut out = Vec::new();
    write_record(&mut out, &scene, &steps).unwrap();
    let text = String::from_utf8(out).unwrap();
    assert_eq!(text.lines().count(), line);
    let read = parse_record(&text, &scene).unwrap();
    assert_eq!(read.len(), steps.len());
    for (got, want) in read.iter().zip(&steps) {
        assert!(ulps_close(got.t, want.t), "t {} read as {}", want.t, got.t);
        assert_eq!(got.moves.len(), want.moves.len());
        for (g, w) in got.moves.iter().zip(&want.moves) {
            assert_eq!((g.line, g.part), (w.line, w.part));
            let (gt, wt) = (g.world.translation, w.world.translation);
            assert!(
                (0..3).all(|i| ulps_close(gt[i], wt[i])),
                "line {}: translation {wt} read back as {gt}",
                w.line
            );
            assert!(
                g.world.matrix3.abs_diff_eq(w.world.matrix3, 1e-12),
                "line {}: {:?} read back as {:?}",
                w.line,
                w.world.matrix3,
                g.world.matrix3
            );
        }
    }
}
