//! Two-pass hierarchical-Z culling against the unculled reference and the
//! exact-visibility oracle: every frame exact, nothing visible missed, moved
//! parts followed, proxies drawn, and a frustum fallback where it cannot run.

use std::collections::BTreeSet;

use dmu_geom::glam::{DAffine3, DVec3};
use dmu_render::{Culling, View, count_differing, wgpu};
use dmu_scene::PartId;
use dmu_tree::EntryId;

use crate::culling::{small_plant, viewpoints};
use dmu_testkit::image_path;

use crate::support::{EveryOther, Rig, differing};

/// The newly visible are drawn in the frame that finds them: from its first
/// frame on, an `hzb` view draws the unculled image pixel for pixel and
/// every chunk instance owning a pixel, at every viewpoint; and from its
/// third it draws fewer triangles than frustum culling.
#[test]
fn every_hzb_frame_is_the_unculled_image_and_misses_nothing_visible() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        let size = (480, 270);
        let mut rig = Rig::new(gpu, &scene, &tree, size);
        for (i, cam) in viewpoints().into_iter().enumerate() {
            let none = rig.shot(cam, Culling::None, &scene, &tree);
            let mut view = View::new(cam, size, Culling::Hzb);
            for frame in 1..=3 {
                let stats = rig.frame(&mut view, &scene, &tree);
                assert_eq!(stats.culling, Culling::Hzb, "view {i}: hzb ran");
                let image = rig.image();
                if frame == 3 {
                    image
                        .save(image_path(&format!("plant_hzb_{i}.png")))
                        .unwrap();
                }
                let diff = differing(&none, &image);
                assert!(
                    diff.is_empty(),
                    "view {i} frame {frame}: {} pixels differ, first {:?}",
                    diff.len(),
                    diff.first()
                );
                let missing = rig.visible_but_not_drawn(&mut view, &scene, &tree);
                assert!(
                    missing.is_empty(),
                    "view {i} frame {frame}: visible but not drawn: {missing:?}"
                );
                if frame == 1 {
                    // Nothing was visible before: the first pass drew nothing,
                    // and against its empty pyramid every candidate is visible.
                    assert_eq!(stats.newly_visible, stats.chunks_drawn, "view {i}");
                } else {
                    assert_eq!(stats.newly_visible, 0, "view {i}: converged");
                }
                if frame == 3 {
                    // Frame 2's pyramid held the whole visible set: frame 3
                    // draws only what frame 2 found visible.
                    assert!(
                        stats.triangles_drawn < stats.triangles_in_frustum
                            && stats.culled_occlusion > 0,
                        "view {i}: nothing occluded: {stats:?}"
                    );
                }
            }
        }
    });
}

/// Along a walk with a part moved on the way, each frame equals the
/// unculled image: what comes into view and the moved part show at once.
/// The target's sides are odd, so the pyramid's first level takes the last
/// column and row of pixels alone (and its next level the last three
/// columns).
#[test]
fn a_moving_hzb_view_follows_the_camera_and_moved_parts_at_once() {
    dmu_testkit::with_gpu(|gpu| {
        let (mut scene, mut tree) = small_plant();
        let size = (481, 271);
        let mut rig = Rig::new(gpu, &scene, &tree, size);
        let start = viewpoints()[0];
        let mut view = View::new(start, size, Culling::Hzb);
        let mut reference = View::new(start, size, Culling::None);
        // The part owning the most pixels at the walk's start.
        let ids = rig.ids(&mut view, &scene, &tree);
        let moved = ids
            .visible_entries()
            .into_iter()
            .map(|e| tree.entries()[e.0 as usize].part)
            .max_by_key(|p: &PartId| tree.entries().iter().filter(|e| e.part == *p).count())
            .expect("a visible part");
        let mut newly = 0;
        for step in 0..12 {
            let mut cam = start;
            let forward = (start.target - start.eye).normalize();
            cam.eye += forward * (f64::from(step) * 1_500.0);
            cam.target += forward * (f64::from(step) * 1_500.0);
            if step == 6 {
                let world = scene.part_world(moved);
                let up = DAffine3::from_translation(DVec3::new(0.0, 0.0, 3_000.0));
                tree.move_part(&mut scene, moved, up * world);
            }
            view.camera = cam;
            reference.camera = cam;
            let stats = rig.frame(&mut view, &scene, &tree);
            newly += stats.newly_visible;
            let image = rig.image();
            rig.frame(&mut reference, &scene, &tree);
            let diff = differing(&rig.image(), &image);
            assert!(
                diff.is_empty(),
                "step {step}: {} pixels differ, first {:?}",
                diff.len(),
                diff.first()
            );
        }
        assert!(newly > 0, "the walk must bring chunks into view");
    });
}

/// With proxies, `hzb` tests and draws them as any candidate, and a proxy
/// the first pass draws cluster by cluster: its frames show what frustum
/// culling with the same proxies shows, with fewer triangles inside the
/// plant, some proxies drawn only in part.
#[test]
fn hzb_draws_proxies_and_matches_the_frustum_image() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        let size = (480, 270);
        let mut rig = Rig::with_proxies(gpu, &scene, &tree, size);
        let pixels = f64::from(size.0 * size.1);
        let (mut drew_proxies, mut culled, mut clusters) = (false, false, 0);
        for (i, cam) in viewpoints().into_iter().enumerate() {
            let mut frustum = View::new(cam, size, Culling::Frustum);
            frustum.options.lod_error_px = 1.0;
            let f = rig.frame(&mut frustum, &scene, &tree);
            let reference = rig.image();
            let mut hzb = View::new(cam, size, Culling::Hzb);
            hzb.options.lod_error_px = 1.0;
            rig.frame(&mut hzb, &scene, &tree);
            rig.frame(&mut hzb, &scene, &tree);
            let last = rig.frame(&mut hzb, &scene, &tree);
            let (any, surface) = count_differing(reference.as_raw(), rig.image().as_raw());
            println!(
                "view {i}: hzb {} proxies ({} clusters left out) {} triangles; frustum {} proxies {} triangles; {any} differ, {surface} another surface",
                last.proxies_drawn,
                last.culled_clusters,
                last.triangles_drawn,
                f.proxies_drawn,
                f.triangles_drawn
            );
            assert!(last.triangles_drawn <= f.triangles_drawn, "view {i}");
            // Depth ties between touching pieces may resolve differently.
            assert!(surface as f64 <= 0.001 * pixels, "view {i}: {surface}");
            drew_proxies |= last.proxies_drawn > 0;
            culled |= last.triangles_drawn < f.triangles_drawn;
            clusters += last.culled_clusters;
        }
        assert!(drew_proxies, "hzb drew proxies somewhere");
        assert!(culled, "hzb culled something");
        assert!(clusters > 0, "hzb left out clusters of some proxy");
    });
}

/// Flying into the plant with proxies and back out: each `hzb` frame draws
/// what the frame before found visible before it traverses the tree, less
/// the proxies that no longer fit and what a proxy now stands for. Every
/// frame shows what frustum culling with the same
/// proxies shows (but for depth ties), and no chunk instance owning a pixel
/// goes undrawn two frames running.
#[test]
fn hzb_flying_in_with_proxies_keeps_the_frustum_image_and_is_never_two_frames_late() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        let size = (480, 270);
        let mut rig = Rig::with_proxies(gpu, &scene, &tree, size);
        let start = viewpoints()[3];
        let mut hzb = View::new(start, size, Culling::Hzb);
        hzb.options.lod_error_px = 1.0;
        let mut frustum = View::new(start, size, Culling::Frustum);
        frustum.options.lod_error_px = 1.0;
        let mut proxy_counts = BTreeSet::new();
        let mut late: BTreeSet<EntryId> = BTreeSet::new();
        for step in (0..16).chain((0..16).rev()) {
            let mut cam = start;
            cam.eye += (start.target - start.eye) * (f64::from(step) / 20.0);
            hzb.camera = cam;
            frustum.camera = cam;
            rig.frame(&mut frustum, &scene, &tree);
            let reference = rig.image();
            let stats = rig.frame(&mut hzb, &scene, &tree);
            let (_, surface) = count_differing(reference.as_raw(), rig.image().as_raw());
            // Both draw in canonical order, and along this flight nothing ties:
            // a proxy drawn once too often showed as 7 to 292 pixels here.
            assert_eq!(surface, 0, "step {step}: another surface");
            proxy_counts.insert(stats.proxies_drawn);
            let drawn: BTreeSet<EntryId> = hzb.drawn_entries().collect();
            let mut exact_view = View::new(cam, size, Culling::Frustum);
            let missing: BTreeSet<EntryId> = rig
                .ids(&mut exact_view, &scene, &tree)
                .visible_entries()
                .difference(&drawn)
                .copied()
                .collect();
            let twice: Vec<_> = missing.intersection(&late).collect();
            assert!(twice.is_empty(), "step {step}: two frames late: {twice:?}");
            late = missing;
        }
        assert!(
            proxy_counts.len() > 2,
            "the flight must change the proxies drawn: {proxy_counts:?}"
        );
    });
}

/// A depth target a shader cannot read: the frame is culled by frustum
/// instead, says so, and is still the unculled image.
#[test]
fn hzb_falls_back_to_frustum_where_depth_cannot_be_read() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        let size = (320, 180);
        let mut rig = Rig::new(gpu, &scene, &tree, size);
        let depth = rig.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("depth without texture binding"),
            size: wgpu::Extent3d {
                width: size.0,
                height: size.1,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: dmu_render::DEPTH_FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT,
            view_formats: &[],
        });
        let depth_view = depth.create_view(&Default::default());
        let cam = viewpoints()[1];
        let none = rig.shot(cam, Culling::None, &scene, &tree);
        let mut view = View::new(cam, size, Culling::Hzb);
        let target = dmu_render::FrameTarget {
            color: rig.capture.frame_target().color,
            depth: &depth_view,
        };
        let stats = rig
            .renderer
            .render(&mut view, &scene, &tree, &scene, target)
            .expect("render");
        assert_eq!(stats.culling, Culling::Frustum);
        assert!(differing(&none, &rig.image()).is_empty());
    });
}

/// `auto` times hzb, chc and frustum in turn (four frames each), then runs
/// the one its own figures say is fastest (a mode keeps at least four
/// frames), reports what each took, and its frames stay exact.
#[test]
fn auto_times_each_mode_then_keeps_the_fastest() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        let size = (480, 270);
        let mut rig = Rig::new(gpu, &scene, &tree, size);
        let cam = viewpoints()[0];
        let none = rig.shot(cam, Culling::None, &scene, &tree);
        let mut view = View::new(cam, size, Culling::Auto);
        let frames: Vec<_> = (0..20)
            .map(|_| rig.frame(&mut view, &scene, &tree))
            .collect();
        let used: Vec<Culling> = frames.iter().map(|s| s.auto.unwrap().ran).collect();
        assert_eq!(&used[..4], &[Culling::Hzb; 4], "{used:?}");
        assert_eq!(&used[4..8], &[Culling::Occlusion; 4], "{used:?}");
        assert_eq!(&used[8..12], &[Culling::Frustum; 4], "{used:?}");
        // A mode runs at least four frames once switched to (its times count
        // from its third); after that a frame runs the fastest by the times
        // the frame before reported.
        let mut run = 0;
        for (k, pair) in frames.windows(2).enumerate().skip(11) {
            let a = pair[0].auto.expect("auto reports its times");
            assert!(
                a.hzb_ms > 0.0 && a.chc_ms > 0.0 && a.frustum_ms > 0.0,
                "{a:?}"
            );
            let fastest = [
                (a.hzb_ms, Culling::Hzb),
                (a.chc_ms, Culling::Occlusion),
                (a.frustum_ms, Culling::Frustum),
            ]
            .into_iter()
            .min_by(|x, y| x.0.total_cmp(&y.0))
            .unwrap()
            .1;
            run = if k == 11 || a.ran != used[k - 1] {
                1
            } else {
                run + 1
            };
            let ran = pair[1].auto.unwrap().ran;
            if ran != a.ran || run >= 4 {
                assert_eq!(ran, fastest, "frame {}: {a:?} after {run} frames", k + 2);
            } else {
                assert_eq!(ran, a.ran, "frame {}: a mode runs four frames", k + 2);
            }
        }
        let last = frames.last().unwrap();
        if last.auto.unwrap().ran != Culling::Occlusion {
            // hzb and frustum frames are exact every frame.
            assert!(differing(&none, &rig.image()).is_empty());
        }
    });
}

/// Geometry that arrives late (a source holding only every other chunk,
/// then all): a candidate without geometry counts as visible, stays among
/// the drawn (wanted) entries without being counted as drawn, and once
/// everything is resident the frames equal the unculled image.
#[test]
fn hzb_keeps_chunks_without_geometry_wanted() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree) = small_plant();
        let size = (480, 270);
        let mut rig = Rig::new(gpu, &scene, &tree, size);
        let cam = viewpoints()[0];
        let none = rig.shot(cam, Culling::None, &scene, &tree);
        rig.evict_odd_chunks(&scene);
        let mut view = View::new(cam, size, Culling::Hzb);
        let partial = EveryOther(&scene);
        for _ in 0..3 {
            let stats = rig
                .renderer
                .render(
                    &mut view,
                    &scene,
                    &tree,
                    &partial,
                    rig.capture.frame_target(),
                )
                .expect("render with half the geometry");
            assert!(
                stats.not_resident > 0,
                "the test must withhold wanted chunks"
            );
            let wanted: Vec<EntryId> = view.drawn_entries().collect();
            let withheld = wanted
                .iter()
                .filter(|e| tree.entries()[e.0 as usize].chunk.index() % 2 == 1)
                .count() as u64;
            assert!(withheld > 0, "withheld chunks stay wanted");
            assert_eq!(
                stats.chunks_drawn + withheld,
                wanted.len() as u64,
                "drawn counts only what was drawn: {stats:?}"
            );
        }
        for _ in 0..2 {
            rig.frame(&mut view, &scene, &tree);
        }
        let diff = differing(&none, &rig.image());
        assert!(
            diff.is_empty(),
            "{} pixels differ once resident",
            diff.len()
        );
    });
}
