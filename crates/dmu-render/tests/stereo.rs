//! Stereo pairs: the enclosing frustum against the eyes' frusta, and each layer
//! of a stereo frame against a single-view render of that eye.

use std::collections::BTreeSet;

use dmu_geom::Aabb3d;
use dmu_geom::glam::DVec3;
use dmu_render::wgpu::Features;
use dmu_render::{
    Capture, Culling, FrameStats, RendererOptions, StereoCamera, StereoMode, StereoView, View,
    save_png,
};
use dmu_samples::grid;
use dmu_scene::Scene;
use dmu_testkit::{Adapter, Gpu, GpuTest, image_path};
use dmu_tree::{EntryId, Tree, TreeOptions};

use crate::culling::{small_plant, viewpoints};
use crate::support::{Rig, camera, differing};

/// A small deterministic generator (SplitMix64) for sample points and boxes.
struct Rng(u64);

impl Rng {
    fn unit(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn in_range(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * self.unit()
    }
}

/// The enclosing frustum never culls what an eye sees (boxes and points, far
/// from the origin), and beyond the distance where the eyes' frusta overlap it
/// is their union exactly.
#[test]
fn enclosing_frustum_contains_both_eyes() {
    let o = DVec3::new(4_512_000.0, 5_342_750.0, 12_000.0);
    let center = camera(o, o + DVec3::new(30_000.0, 20_000.0, -3_000.0), 50.0);
    let forward = (center.target - center.eye).normalize();
    let aspect = 16.0 / 9.0;
    let mut rng = Rng(7);
    for ipd in [65.0, 2_000.0] {
        let stereo = StereoCamera { center, ipd };
        let [left, right] = stereo.eyes();
        assert!(((right.eye - left.eye).length() - ipd).abs() < 1e-6);
        assert!((right.eye - left.eye).dot(forward).abs() < 1e-6);
        let (l, r) = (left.frustum(aspect), right.frustum(aspect));
        let enclosing = stereo.enclosing_frustum(aspect);
        // Where the eyes' frusta begin to overlap.
        let half_fov_x = ((center.fov_y_rad * 0.5).tan() * aspect).atan();
        let overlap = 0.5 * ipd / half_fov_x.tan();
        let (mut seen_boxes, mut seen_points, mut far_points) = (0, 0, 0);
        for _ in 0..20_000 {
            // Points around the eyes, denser near them.
            let p = center.eye
                + DVec3::new(
                    rng.in_range(-1.0, 1.0),
                    rng.in_range(-1.0, 1.0),
                    rng.in_range(-1.0, 1.0),
                ) * 60_000.0
                    * rng.unit().powi(3);
            let half = DVec3::new(rng.unit(), rng.unit(), rng.unit()) * rng.in_range(1.0, 3_000.0);
            let b = Aabb3d::new(p - half, p + half);
            if l.intersects_aabb(&b) || r.intersects_aabb(&b) {
                seen_boxes += 1;
                assert!(enclosing.intersects_aabb(&b), "ipd {ipd}: culled {b:?}");
            }
            let seen = l.contains_point(p) || r.contains_point(p);
            seen_points += usize::from(seen);
            if seen {
                assert!(enclosing.contains_point(p), "ipd {ipd}: culled {p}");
            }
            // Away from the planes, to stay clear of rounding on the boundary.
            let clear = [&l, &r, &enclosing]
                .iter()
                .all(|f| f.planes.iter().all(|pl| pl.signed_distance(p).abs() > 1e-6));
            if (p - center.eye).dot(forward) > overlap && clear {
                far_points += 1;
                assert_eq!(enclosing.contains_point(p), seen, "ipd {ipd}: {p}");
            }
        }
        assert!(
            seen_boxes > 1_000 && seen_points > 500 && far_points > 5_000,
            "ipd {ipd}: {seen_boxes} boxes, {seen_points} points seen, {far_points} far"
        );
    }
}

/// A rig whose renderer draws stereo pairs in `mode`, and a stereo capture
/// (multiview only where the device has it: see [`Gpu::supports`]).
fn stereo_rig(
    gpu: &Gpu,
    scene: &Scene,
    tree: &Tree,
    size: (u32, u32),
    mode: StereoMode,
) -> (Rig, Capture) {
    let options = RendererOptions {
        stereo: mode,
        ..Default::default()
    };
    let rig = Rig::with_options(gpu, scene, tree, size, options);
    let capture = Capture::stereo(&rig.device, size);
    (rig, capture)
}

/// One stereo frame.
fn stereo_frame(
    rig: &mut Rig,
    capture: &Capture,
    view: &mut StereoView,
    scene: &Scene,
    tree: &Tree,
) -> FrameStats {
    rig.renderer
        .render_stereo(view, scene, tree, scene, capture.stereo_target())
        .expect("render stereo")
}

/// Frames of `view` until occlusion culling converges, then enough more that
/// visible chunk instances are re-checked (one frame for the other modes); the
/// last frame's stats.
fn converge(
    rig: &mut Rig,
    capture: &Capture,
    view: &mut StereoView,
    scene: &Scene,
    tree: &Tree,
) -> FrameStats {
    let mut stats = stereo_frame(rig, capture, view, scene, tree);
    if view.view.culling != Culling::Occlusion {
        return stats;
    }
    while stats.frame == 1 || stats.newly_visible > 0 {
        assert!(stats.frame < 12, "no convergence in 12 frames");
        stats = stereo_frame(rig, capture, view, scene, tree);
    }
    let requery = u64::from(2 * view.view.options.requery_interval);
    let mut queries = 0;
    for _ in 0..requery {
        stats = stereo_frame(rig, capture, view, scene, tree);
        queries += stats.queries;
    }
    assert!(queries > 0, "no re-checks in {requery} frames");
    stats
}

/// Each culling mode's stereo layers against the unculled single-view images of
/// the two eyes; returns the occlusion-culled pair's view, stats and layers.
fn check_pair(
    rig: &mut Rig,
    capture: &Capture,
    camera: StereoCamera,
    scene: &Scene,
    tree: &Tree,
    what: &str,
) -> (StereoView, FrameStats, [image::RgbaImage; 2]) {
    let size = capture.size();
    let single = camera
        .eyes()
        .map(|eye| rig.shot(eye, Culling::None, scene, tree));
    assert!(
        !differing(&single[0], &single[1]).is_empty(),
        "{what}: the eyes see the same image"
    );
    let mut last = None;
    for culling in [Culling::None, Culling::Frustum, Culling::Occlusion] {
        let mut view = StereoView::new(camera, size, culling);
        view.view.options.adaptive = false;
        let stats = converge(rig, capture, &mut view, scene, tree);
        let layers = [0, 1].map(|layer| {
            capture
                .read_color_layer(&rig.device, &rig.queue, layer)
                .expect("read layer")
        });
        for (eye, (layer, reference)) in layers.iter().zip(&single).enumerate() {
            let diff = differing(reference, layer);
            assert!(
                diff.is_empty(),
                "{what}, {culling:?}, eye {eye}: {} pixels differ from the single view, first {:?}",
                diff.len(),
                diff.first()
            );
        }
        last = Some((view, stats, layers));
    }
    last.expect("three modes")
}

/// The chunk instances owning a pixel in either eye, from the single-view oracle.
fn visible_in_either_eye(
    rig: &mut Rig,
    camera: &StereoCamera,
    scene: &Scene,
    tree: &Tree,
) -> BTreeSet<EntryId> {
    let mut visible = BTreeSet::new();
    for eye in camera.eyes() {
        let mut view = View::new(eye, rig.capture.size(), Culling::None);
        visible.extend(rig.ids(&mut view, scene, tree).visible_entries());
    }
    visible
}

/// On the grid (nothing near the eyes), both layers of every culling mode
/// equal the single views of the eyes, pixel for pixel, drawn with multiview
/// and a layer at a time.
#[test]
fn stereo_layers_equal_single_views_on_the_grid() {
    dmu_testkit::with_gpu(|gpu| {
        let scene = grid(3, 10.0, 4.0, 2048);
        let tree = Tree::build(&scene, TreeOptions::default());
        let center = camera(DVec3::new(-25.0, -35.0, 40.0), DVec3::splat(10.0), 0.5);
        let stereo = StereoCamera { center, ipd: 3.0 };
        for mode in [StereoMode::Multiview, StereoMode::LayerPasses] {
            if mode == StereoMode::Multiview && !gpu.supports(Features::MULTIVIEW) {
                continue;
            }
            let (mut rig, capture) = stereo_rig(gpu, &scene, &tree, (320, 240), mode);
            assert_eq!(rig.renderer.stereo_mode(), mode);
            let what = format!("grid, {mode:?}");
            let (_, _, [left, right]) =
                check_pair(&mut rig, &capture, stereo, &scene, &tree, &what);
            if mode == StereoMode::Multiview {
                save_png(&left, &image_path("stereo_grid_left.png")).unwrap();
                save_png(&right, &image_path("stereo_grid_right.png")).unwrap();
            }
        }
    });
}

/// On the plant, from viewpoints inside it, both layers of every culling mode
/// equal the single views of the eyes; stereo occlusion culling culls, and
/// draws every chunk instance that owns a pixel in either eye.
#[test]
fn stereo_layers_equal_single_views_on_the_plant() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        let (mut rig, capture) = stereo_rig(gpu, &scene, &tree, (480, 270), StereoMode::Auto);
        eprintln!("stereo mode: {:?}", rig.renderer.stereo_mode());
        for (i, center) in viewpoints().into_iter().enumerate() {
            // Millimetres: a human interpupillary distance.
            let stereo = StereoCamera { center, ipd: 65.0 };
            let what = format!("plant view {i}");
            let (view, stats, [left, right]) =
                check_pair(&mut rig, &capture, stereo, &scene, &tree, &what);
            if i == 0 {
                save_png(&left, &image_path("stereo_left.png")).unwrap();
                save_png(&right, &image_path("stereo_right.png")).unwrap();
            }
            let drawn: BTreeSet<EntryId> = view.view.drawn_entries().collect();
            let exact = visible_in_either_eye(&mut rig, &stereo, &scene, &tree);
            let missing: Vec<_> = exact.difference(&drawn).collect();
            assert!(
                missing.is_empty(),
                "{what}: visible but not drawn: {missing:?}"
            );
            assert!(
                stats.triangles_drawn < stats.triangles_in_frustum,
                "{what}: nothing occluded: {stats:?}"
            );
            assert!(
                i == 3 || stats.culled_frustum > 0,
                "{what}: nothing culled by the frustum"
            );
        }
    });
}

/// Whether the renderer's probe accepts multiview on `gpu`, and how many
/// pixels multiview gets wrong where the near plane cuts boxes (both eyes in
/// one place, so any difference between the layers is the driver's).
fn multiview_on_near_clipped_boxes(gpu: &Gpu) -> (bool, usize) {
    let scene = grid(3, 10.0, 4.0, 2048);
    let tree = Tree::build(&scene, TreeOptions::default());
    let size = (320, 240);
    let (auto, _) = stereo_rig(gpu, &scene, &tree, size, StereoMode::Auto);
    let (mut rig, capture) = stereo_rig(gpu, &scene, &tree, size, StereoMode::Multiview);
    let accepted = auto.renderer.stereo_mode() == StereoMode::Multiview;
    let center = camera(DVec3::new(-25.0, -35.0, 40.0), DVec3::splat(10.0), 45.0);
    let single = rig.shot(center, Culling::None, &scene, &tree);
    let mut view = StereoView::new(StereoCamera { center, ipd: 0.0 }, size, Culling::None);
    stereo_frame(&mut rig, &capture, &mut view, &scene, &tree);
    let wrong: usize = (0..2)
        .map(|layer| {
            let image = capture
                .read_color_layer(&rig.device, &rig.queue, layer)
                .expect("read layer");
            differing(&single, &image).len()
        })
        .sum();
    eprintln!("multiview accepted: {accepted}; {wrong} pixels wrong with multiview");
    (accepted, wrong)
}

/// The probe that picks multiview or layer passes predicts the driver: where
/// it accepts multiview, boxes cut by the near plane come out right in both
/// layers; where it rejects it, multiview really does get them wrong.
#[test]
fn multiview_probe_predicts_the_driver() {
    GpuTest::new().features(Features::MULTIVIEW).run(|gpu| {
        let (accepted, wrong) = multiview_on_near_clipped_boxes(gpu);
        assert_eq!(accepted, wrong == 0, "{wrong} pixels wrong");
    });
}

/// Multiview draws boxes cut by the near plane into both layers as single
/// views draw them, but on the driver declared to get them wrong.
#[test]
fn multiview_draws_near_clipped_boxes_right() {
    GpuTest::new()
        .features(Features::MULTIVIEW)
        .fails_on(
            Adapter::lavapipe("Mesa 22.3"),
            "Mesa 22.3's lavapipe draws near-clipped triangles of view 1 into layer 0",
        )
        .run(|gpu| {
            let (_, wrong) = multiview_on_near_clipped_boxes(gpu);
            assert_eq!(wrong, 0, "pixels wrong with multiview");
        });
}

/// Culling once for the pair draws what the union of the eyes' own frustum
/// culling draws, plus at most what lies in the wedge neither eye sees.
#[test]
fn stereo_frustum_culling_covers_both_eyes() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        let size = (320, 180);
        let (mut rig, capture) = stereo_rig(gpu, &scene, &tree, size, StereoMode::Auto);
        for center in viewpoints() {
            let stereo = StereoCamera { center, ipd: 65.0 };
            let mut pair = StereoView::new(stereo, size, Culling::Frustum);
            stereo_frame(&mut rig, &capture, &mut pair, &scene, &tree);
            let drawn: BTreeSet<EntryId> = pair.view.drawn_entries().collect();
            let mut either = BTreeSet::new();
            for eye in stereo.eyes() {
                let mut view = View::new(eye, size, Culling::Frustum);
                rig.frame(&mut view, &scene, &tree);
                either.extend(view.drawn_entries());
            }
            assert!(
                either.is_subset(&drawn),
                "the pair culled what an eye draws"
            );
            // The blind wedge is 65 mm wide at the eyes: it adds next to nothing.
            assert!(
                drawn.len() <= either.len() + either.len() / 100,
                "pair draws {}, the eyes {}",
                drawn.len(),
                either.len()
            );
        }
    });
}

/// A pair sharing an off-centre field of view (`View::fov`, as a headset's
/// eye, here with non-square pixels) is culled once against a frustum
/// enclosing both eyes' frusta: each layer equals the single view of that
/// eye with the same field of view, unculled, and the pair draws everything
/// either eye's own frustum culling draws.
#[test]
fn stereo_with_an_off_centre_fov_equals_single_views() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        let size = (320, 240);
        let (mut rig, capture) = stereo_rig(gpu, &scene, &tree, size, StereoMode::Auto);
        let fov = dmu_geom::Fov {
            left: -0.80,
            right: 0.62,
            down: -0.78,
            up: 0.70,
        };
        for (i, center) in viewpoints().into_iter().enumerate() {
            let stereo = StereoCamera { center, ipd: 65.0 };
            let mut either = BTreeSet::new();
            let single = stereo.eyes().map(|eye| {
                let mut culled = View::new(eye, size, Culling::Frustum);
                culled.fov = Some(fov);
                rig.frame(&mut culled, &scene, &tree);
                either.extend(culled.drawn_entries());
                let mut view = View::new(eye, size, Culling::None);
                view.fov = Some(fov);
                rig.frame(&mut view, &scene, &tree);
                rig.image()
            });
            let mut pair = StereoView::new(stereo, size, Culling::Frustum);
            pair.view.fov = Some(fov);
            stereo_frame(&mut rig, &capture, &mut pair, &scene, &tree);
            let drawn: BTreeSet<EntryId> = pair.view.drawn_entries().collect();
            assert!(
                either.is_subset(&drawn),
                "view {i}: the pair culled what an eye draws"
            );
            for (eye, reference) in single.iter().enumerate() {
                let layer = capture
                    .read_color_layer(&rig.device, &rig.queue, eye as u32)
                    .expect("read layer");
                let diff = differing(reference, &layer);
                assert!(
                    diff.is_empty(),
                    "view {i}, eye {eye}: {} pixels differ, first {:?}",
                    diff.len(),
                    diff.first()
                );
            }
        }
    });
}
