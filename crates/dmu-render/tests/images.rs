//! Images against analytic and CPU references on the real driver.

use dmu_geom::glam::{DAffine3, DVec2, DVec3, DVec4};
use dmu_geom::{Plane, Ray3d};
use dmu_render::{Camera, Culling, RendererOptions, View};
use dmu_samples::grid;
use dmu_scene::Scene;
use dmu_testkit::{Gpu, image_path};
use dmu_tree::{Tree, TreeOptions};

use crate::support::{Rig, camera, differing};

/// Pixel position of a world point.
fn project(camera: &Camera, size: (u32, u32), p: DVec3) -> DVec2 {
    let aspect = f64::from(size.0) / f64::from(size.1);
    let clip = camera.projection(aspect) * camera.view_matrix() * DVec4::new(p.x, p.y, p.z, 1.0);
    let ndc = clip.truncate().truncate() / clip.w;
    DVec2::new(
        (ndc.x + 1.0) * 0.5 * f64::from(size.0),
        (1.0 - ndc.y) * 0.5 * f64::from(size.1),
    )
}

/// Convex hull, counter-clockwise in a y-down frame's sense of orientation.
fn hull(mut pts: Vec<DVec2>) -> Vec<DVec2> {
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    let cross = |o: DVec2, a: DVec2, b: DVec2| (a - o).perp_dot(b - o);
    let mut h: Vec<DVec2> = Vec::new();
    for pass in 0..2 {
        let start = h.len();
        let iter: Box<dyn Iterator<Item = &DVec2>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while h.len() >= start + 2 && cross(h[h.len() - 2], h[h.len() - 1], p) <= 0.0 {
                h.pop();
            }
            h.push(p);
        }
        h.pop();
    }
    h
}

fn inside(h: &[DVec2], p: DVec2) -> bool {
    (0..h.len()).all(|i| (h[(i + 1) % h.len()] - h[i]).perp_dot(p - h[i]) >= 0.0)
}

fn edge_distance(h: &[DVec2], p: DVec2) -> f64 {
    (0..h.len())
        .map(|i| {
            let (a, b) = (h[i], h[(i + 1) % h.len()]);
            let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
            (a + (b - a) * t - p).length()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The 3x3x3 grid, its tree, a 320x240 rig and a camera that sees every box.
fn grid_rig(gpu: &Gpu) -> (Scene, Tree, Rig, Camera) {
    let scene = grid(3, 10.0, 4.0, 2048);
    let tree = Tree::build(&scene, TreeOptions::default());
    let rig = Rig::new(gpu, &scene, &tree, (320, 240));
    let cam = camera(DVec3::new(-25.0, -35.0, 40.0), DVec3::splat(10.0), 0.5);
    (scene, tree, rig, cam)
}

/// Every box of a grid covers exactly the pixels inside the hull of its
/// projected corners, up to a 1-pixel border.
#[test]
fn grid_boxes_cover_their_projected_hulls() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree, mut rig, cam) = grid_rig(gpu);
        let size = rig.capture.size();
        let image = rig.shot(cam, Culling::None, &scene, &tree);
        image.save(image_path("grid_hulls.png")).unwrap();
        let hulls: Vec<Vec<DVec2>> = scene
            .part_ids()
            .map(|p| {
                let b = scene.part_world_bounds(p);
                hull(
                    b.corners()
                        .iter()
                        .map(|&c| project(&cam, size, c))
                        .collect(),
                )
            })
            .collect();
        // The camera sees no box in the top-left corner: that is the background.
        let background = *image.get_pixel(0, 0);
        let covered = |p: &image::Rgba<u8>| *p != background;
        let (mut expected_count, mut bad) = (0, Vec::new());
        for (x, y, px) in image.enumerate_pixels() {
            let centre = DVec2::new(f64::from(x) + 0.5, f64::from(y) + 0.5);
            let expected = hulls.iter().any(|h| inside(h, centre));
            expected_count += usize::from(expected);
            if expected != covered(px) {
                let near_edge = hulls.iter().any(|h| edge_distance(h, centre) <= 1.0);
                if !near_edge {
                    bad.push((x, y));
                }
            }
        }
        assert!(
            expected_count > 5000,
            "boxes cover only {expected_count} pixels"
        );
        assert!(
            bad.is_empty(),
            "{} pixels away from hull borders differ: {:?}",
            bad.len(),
            &bad[..bad.len().min(10)]
        );
    });
}

/// The chunk-id oracle agrees with exact CPU picking through pixel centres.
#[test]
fn id_oracle_agrees_with_cpu_pick() {
    dmu_testkit::with_gpu(|gpu| {
        let (samples, hits, _) = ids_agree_with_picks(gpu, &[]);
        assert!(
            hits > samples / 5,
            "only {hits} of {samples} rays hit the plant"
        );
    });
}

/// Under two section planes through the plant the GPU cuts exactly what the
/// CPU pick sees through: ids agree with picks of what the section keeps.
#[test]
fn sections_cut_the_image_as_the_pick_sees_through_them() {
    dmu_testkit::with_gpu(|gpu| {
        let o = DVec3::new(4_512_000.0, 5_342_750.0, 12_000.0);
        let (samples, hits, seen_through) = ids_agree_with_picks(
            gpu,
            &[
                Plane::from_point_normal(
                    o + DVec3::new(12_000.0, 0.0, 0.0),
                    DVec3::new(1.0, 0.2, 0.0),
                ),
                Plane::from_point_normal(o + DVec3::new(0.0, 0.0, 4_000.0), -DVec3::Z),
            ],
        );
        // The section must both cut and keep enough for the test to mean something.
        assert!(
            hits > samples / 40 && seen_through > samples / 10,
            "{hits} of {samples} rays hit the plant, {seen_through} through the cut"
        );
    });
}

/// Renders the ids of the 200k plant from inside it, cut by `section`, and
/// compares them with CPU picks (of what the section keeps) through a grid
/// of pixel centres. Returns the samples, the rays that hit, and those whose
/// nearest hit the section cut away.
fn ids_agree_with_picks(gpu: &Gpu, section: &[Plane]) -> (usize, usize, usize) {
    let scene = dmu_samples::plant(&dmu_samples::PlantOptions {
        triangles: 200_000,
        ..Default::default()
    });
    let tree = Tree::build(&scene, TreeOptions::default());
    let size = (480, 270);
    let mut rig = Rig::new(gpu, &scene, &tree, size);
    let o = DVec3::new(4_512_000.0, 5_342_750.0, 12_000.0);
    let cam = camera(
        o + DVec3::new(-8_000.0, 5_000.0, 6_000.0),
        o + DVec3::new(30_000.0, 25_000.0, 2_000.0),
        50.0,
    );
    let mut view = View::new(cam, size, Culling::None);
    view.set_section(section);
    let ids = rig.ids(&mut view, &scene, &tree);
    let t = (cam.fov_y_rad * 0.5).tan();
    let rot = DAffine3::from_mat4(cam.view_matrix()).matrix3.transpose();
    let (mut samples, mut hits, mut edge_only, mut seen_through) = (0, 0, 0, 0);
    for y in (2..size.1).step_by(6) {
        for x in (2..size.0).step_by(6) {
            let ndc = DVec2::new(
                (f64::from(x) + 0.5) / f64::from(size.0) * 2.0 - 1.0,
                1.0 - (f64::from(y) + 0.5) / f64::from(size.1) * 2.0,
            );
            let dir = rot * DVec3::new(ndc.x * t * view.aspect(), ndc.y * t, -1.0);
            let ray = Ray3d::new(cam.eye, dir);
            let pick = tree
                .pick_kept(&scene, &ray, section)
                .map(|h| (h.part, h.chunk));
            let whole = tree.pick(&scene, &ray).map(|h| (h.part, h.chunk));
            seen_through += usize::from(whole != pick);
            let id = ids.at(x, y).map(|e| {
                let entry = &tree.entries()[e.0 as usize];
                (entry.part, entry.chunk)
            });
            samples += 1;
            hits += usize::from(pick.is_some());
            if pick != id {
                // Only where the pixel centre grazes an edge may the two differ:
                // then a neighbour pixel shows what the ray hit.
                let neighbour = (-1i32..=1)
                    .flat_map(|dy| (-1i32..=1).map(move |dx| (dx, dy)))
                    .any(|(dx, dy)| {
                        let (nx, ny) = (x as i32 + dx, y as i32 + dy);
                        let e = ids.at(nx as u32, ny as u32).map(|e| {
                            let entry = &tree.entries()[e.0 as usize];
                            (entry.part, entry.chunk)
                        });
                        e == pick
                    });
                assert!(neighbour, "pixel ({x},{y}): GPU {id:?}, CPU pick {pick:?}");
                edge_only += 1;
            }
        }
    }
    assert!(
        edge_only * 50 < samples,
        "{edge_only} of {samples} samples differ at edges"
    );
    (samples, hits, seen_through)
}

/// Moving a part changes only the pixels it covered before or covers after.
#[test]
fn moving_a_part_changes_only_its_pixels() {
    dmu_testkit::with_gpu(|gpu| {
        let mut scene = grid(3, 10.0, 4.0, 2048);
        let mut tree = Tree::build(&scene, TreeOptions::default());
        let size = (320, 240);
        let mut rig = Rig::new(gpu, &scene, &tree, size);
        let cam = camera(DVec3::new(-25.0, -35.0, 40.0), DVec3::splat(10.0), 0.5);
        let mut view = View::new(cam, size, Culling::Frustum);
        rig.frame(&mut view, &scene, &tree);
        let before = rig.image();
        let ids_before = rig.ids(&mut view, &scene, &tree);
        let part = scene.find_part("box_1_1_2").unwrap();
        let moved = scene.part_world(part) * DAffine3::from_translation(DVec3::new(3.0, -6.0, 1.0));
        tree.move_part(&mut scene, part, moved);
        rig.frame(&mut view, &scene, &tree);
        let after = rig.image();
        let ids_after = rig.ids(&mut view, &scene, &tree);
        after.save(image_path("grid_moved.png")).unwrap();
        let of_part = |ids: &dmu_render::IdImage, x, y| {
            ids.at(x, y)
                .is_some_and(|e| tree.entries()[e.0 as usize].part == part)
        };
        let diff = differing(&before, &after);
        assert!(
            diff.len() > 100,
            "the move changed only {} pixels",
            diff.len()
        );
        for (x, y) in diff {
            assert!(
                of_part(&ids_before, x, y) || of_part(&ids_after, x, y),
                "pixel ({x},{y}) changed but the part is not there"
            );
        }
    });
}

/// Camera-relative f64 model-views: the same scene and camera shifted by 1e7
/// give the same image.
#[test]
fn image_is_stable_far_from_the_origin() {
    dmu_testkit::with_gpu(|gpu| {
        let near_scene = grid(3, 10.0, 4.0, 2048);
        let mut far_scene = near_scene.clone();
        let offset = DVec3::new(1.0e7, -2.0e7, 1.0e7);
        for p in far_scene.part_ids() {
            let w = far_scene.part_world(p);
            far_scene.set_part_world(p, DAffine3::from_translation(offset) * w);
        }
        let size = (320, 240);
        let cam = camera(DVec3::new(-25.0, -35.0, 40.0), DVec3::splat(10.0), 0.5);
        let far_cam = Camera {
            eye: cam.eye + offset,
            target: cam.target + offset,
            ..cam
        };
        let near_tree = Tree::build(&near_scene, TreeOptions::default());
        let far_tree = Tree::build(&far_scene, TreeOptions::default());
        let mut rig = Rig::new(gpu, &near_scene, &near_tree, size);
        let a = rig.shot(cam, Culling::Frustum, &near_scene, &near_tree);
        let mut far_rig = Rig::new(gpu, &far_scene, &far_tree, size);
        let b = far_rig.shot(far_cam, Culling::Frustum, &far_scene, &far_tree);
        b.save(image_path("grid_far.png")).unwrap();
        let diff = differing(&a, &b);
        assert!(
            diff.len() * 1000 < (size.0 * size.1) as usize,
            "{} pixels differ at 1e7",
            diff.len()
        );
    });
}

/// Hidden parts vanish from the image and the oracle; selected parts are
/// highlighted and keep their pixels.
#[test]
fn hidden_and_selected_parts() {
    dmu_testkit::with_gpu(|gpu| {
        let mut scene = grid(3, 10.0, 4.0, 2048);
        let tree = Tree::build(&scene, TreeOptions::default());
        let size = (320, 240);
        let mut rig = Rig::new(gpu, &scene, &tree, size);
        let cam = camera(DVec3::new(-25.0, -35.0, 40.0), DVec3::splat(10.0), 0.5);
        let mut view = View::new(cam, size, Culling::Frustum);
        let part = scene.find_part("box_0_0_2").unwrap();
        let ids = rig.ids(&mut view, &scene, &tree);
        let of_part = |e: &dmu_tree::EntryId| tree.entries()[e.0 as usize].part == part;
        assert!(
            ids.visible_entries().iter().any(of_part),
            "the part is visible to begin with"
        );
        rig.frame(&mut view, &scene, &tree);
        let plain = rig.image();

        rig.renderer.set_selected(part, true);
        rig.frame(&mut view, &scene, &tree);
        let selected = rig.image();
        selected.save(image_path("grid_selected.png")).unwrap();
        let diff = differing(&plain, &selected);
        assert!(!diff.is_empty());
        assert!(
            diff.iter()
                .all(|&(x, y)| ids.at(x, y).as_ref().is_some_and(of_part))
        );
        rig.renderer.set_selected(part, false);

        scene.set_part_hidden(part, true);
        let stats = rig.frame(&mut view, &scene, &tree);
        assert!(stats.hidden > 0);
        let hidden_ids = rig.ids(&mut view, &scene, &tree);
        assert!(!hidden_ids.visible_entries().iter().any(of_part));
    });
}

/// A clashing part changes tint, to a colour other than the selection's, and
/// no other pixel changes; clearing the flag restores the image exactly.
#[test]
fn clashing_part_changes_tint_and_nothing_else() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree, mut rig, cam) = grid_rig(gpu);
        let size = rig.capture.size();
        let mut view = View::new(cam, size, Culling::Frustum);
        let part = scene.find_part("box_1_0_2").unwrap();
        let ids = rig.ids(&mut view, &scene, &tree);
        let of_part = |x: u32, y: u32| {
            ids.at(x, y)
                .is_some_and(|e| tree.entries()[e.0 as usize].part == part)
        };
        let part_pixels: Vec<(u32, u32)> = (0..size.1)
            .flat_map(|y| (0..size.0).map(move |x| (x, y)))
            .filter(|&(x, y)| of_part(x, y))
            .collect();
        assert!(part_pixels.len() > 200, "the part shows");
        rig.frame(&mut view, &scene, &tree);
        let plain = rig.image();

        rig.renderer.set_clashing(part, true);
        rig.frame(&mut view, &scene, &tree);
        let clashing = rig.image();
        clashing.save(image_path("grid_clashing.png")).unwrap();
        let diff = differing(&plain, &clashing);
        assert!(
            diff.iter().all(|&(x, y)| of_part(x, y)),
            "only the clashing part's pixels change"
        );
        assert!(
            diff.len() * 10 >= part_pixels.len() * 9,
            "{} of {} pixels of the part changed",
            diff.len(),
            part_pixels.len()
        );
        // The clash colour is red: red gains on green and blue wherever it changed.
        let redder = diff.iter().all(|&(x, y)| {
            let (p, c) = (plain.get_pixel(x, y).0, clashing.get_pixel(x, y).0);
            let red_share = |q: [u8; 4]| {
                f64::from(q[0]) / (1.0 + f64::from(q[0]) + f64::from(q[1]) + f64::from(q[2]))
            };
            red_share(c) > red_share(p)
        });
        assert!(redder, "clashing pixels turn red");

        // Selection wins over the clash tint, and looks different from it.
        rig.renderer.set_selected(part, true);
        rig.frame(&mut view, &scene, &tree);
        let selected = rig.image();
        let tint_diff = differing(&clashing, &selected);
        assert!(tint_diff.len() * 10 >= part_pixels.len() * 9);
        assert!(tint_diff.iter().all(|&(x, y)| of_part(x, y)));

        rig.renderer.set_selected(part, false);
        rig.renderer.set_clashing(part, false);
        rig.frame(&mut view, &scene, &tree);
        assert!(
            differing(&plain, &rig.image()).is_empty(),
            "flags clear exactly"
        );
    });
}

/// A section plane through the middle column of the grid: the column wholly
/// on its far side is culled (not drawn, counted), triangles drawn fall, the
/// cut boxes show their inside in the section colour, and only they do.
#[test]
fn a_section_culls_what_it_cuts_away_and_caps_what_it_cuts() {
    dmu_testkit::with_gpu(|gpu| {
        let (scene, tree, mut rig, cam) = grid_rig(gpu);
        let size = rig.capture.size();
        let mut view = View::new(cam, size, Culling::Frustum);
        let whole = rig.frame(&mut view, &scene, &tree);
        view.set_section(&[Plane::from_point_normal(
            DVec3::new(10.0, 0.0, 0.0),
            DVec3::X,
        )]);
        let cut = rig.frame(&mut view, &scene, &tree);
        let image = rig.image();
        image.save(image_path("grid_section.png")).unwrap();
        // Column x = 0 (boxes at -2..2) is wholly cut away: 9 boxes of 12 triangles.
        assert_eq!(cut.culled_section, 9, "{cut:?}");
        assert_eq!(whole.triangles_drawn - cut.triangles_drawn, 9 * 12);
        let ids = rig.ids(&mut view, &scene, &tree);
        let column = |x: u32, y: u32| {
            ids.at(x, y).map(|e| {
                let part = tree.entries()[e.0 as usize].part;
                scene.part_name(part).as_bytes()[4] - b'0'
            })
        };
        let cap = RendererOptions::default().section_cap.map(srgb_byte);
        let (mut caps, mut column0) = (0, 0);
        for (x, y, px) in image.enumerate_pixels() {
            let is_cap = (0..3).all(|c| px[c].abs_diff(cap[c]) <= 1);
            if is_cap {
                caps += 1;
                assert_eq!(
                    column(x, y),
                    Some(1),
                    "cap colour at ({x},{y}) off the cut column"
                );
            }
            column0 += usize::from(column(x, y) == Some(0));
        }
        assert_eq!(column0, 0, "the cut-away column shows");
        assert!(caps > 300, "only {caps} pixels show the cut faces");
    });
}

/// A linear colour channel as an sRGB byte.
fn srgb_byte(linear: f32) -> u8 {
    let s = if linear <= 0.003_130_8 {
        linear * 12.92
    } else {
        1.055 * linear.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0).round() as u8
}

/// A unit box around the origin whose six faces have six colours, as one
/// mesh: counter-clockwise outward faces, or inward (`inside_out`), without
/// the +z face (`open`).
fn coloured_box(
    b: &mut dmu_scene::SceneBuilder,
    colours: &[dmu_scene::MaterialId; 6],
    inside_out: bool,
    open: bool,
) -> dmu_scene::MeshId {
    use dmu_geom::glam::Vec3;
    let mut mesh = dmu_scene::MeshData {
        name: "box".into(),
        ..Default::default()
    };
    for (face, &material) in colours.iter().enumerate() {
        let (axis, positive) = (face / 2, face % 2 == 1);
        if open && axis == 2 && positive {
            continue;
        }
        let mut n = Vec3::ZERO;
        n[axis] = if positive { 1.0 } else { -1.0 };
        // Tangents ordered so that (u x v) points along n.
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let (u, v) = if positive { (u, v) } else { (v, u) };
        let corner = |a: f32, c: f32| {
            let mut p = n;
            p[u] = a;
            p[v] = c;
            p
        };
        let quad = [
            corner(-1.0, -1.0),
            corner(1.0, -1.0),
            corner(1.0, 1.0),
            corner(-1.0, 1.0),
        ];
        let triangles = if inside_out {
            [0, 2, 1, 0, 3, 2]
        } else {
            [0, 1, 2, 0, 2, 3]
        };
        mesh.push_primitive(&quad, &[n; 4], &triangles, material);
    }
    b.add_mesh(&mesh)
}

/// Back faces are culled where that hides nothing, and only there. Four
/// boxes with a colour per face: solid; the same mesh mirrored (its windings
/// flip); an inside-out box; an open box (no top). Seen from above, culling
/// on and off give the same image but for a few silhouette pixels (where a
/// back face won a depth tie): culling a mirrored, inside-out or open box's
/// back faces would show its far faces' colours instead, or nothing. From
/// inside the solid box, culling shows what lies beyond it, where drawing
/// back faces shows its inside.
#[test]
fn back_faces_are_culled_only_on_solids_that_do_not_mirror() {
    dmu_testkit::with_gpu(|gpu| {
        let mut b = dmu_scene::SceneBuilder::new("boxes", 2048);
        let colours = [
            [0.8, 0.1, 0.1, 1.0],
            [0.1, 0.8, 0.1, 1.0],
            [0.1, 0.1, 0.8, 1.0],
            [0.8, 0.8, 0.1, 1.0],
            [0.1, 0.8, 0.8, 1.0],
            [0.8, 0.1, 0.8, 1.0],
        ]
        .map(|c| b.add_material("face", c));
        let solid = coloured_box(&mut b, &colours, false, false);
        let inside_out = coloured_box(&mut b, &colours, true, false);
        let open = coloured_box(&mut b, &colours, false, true);
        let mirror = DAffine3::from_scale(DVec3::new(-1.0, 1.0, 1.0));
        for (k, (mesh, placed)) in [
            (solid, DAffine3::IDENTITY),
            (solid, mirror),
            (inside_out, DAffine3::IDENTITY),
            (open, DAffine3::IDENTITY),
        ]
        .into_iter()
        .enumerate()
        {
            let at = DAffine3::from_translation(DVec3::new(4.0 * k as f64, 0.0, 0.0)) * placed;
            let node = b.add_node(dmu_scene::SceneBuilder::ROOT, format!("box{k}"), at);
            b.add_part(node, mesh);
        }
        let scene = b.finish();
        let solid_meshes: Vec<bool> = scene.meshes().iter().map(|m| m.solid).collect();
        assert_eq!(solid_meshes, [true, false, false]);
        let tree = Tree::build(&scene, TreeOptions::default());
        let size = (320, 240);
        let rig = |cull_back_faces| {
            let options = RendererOptions {
                cull_back_faces,
                ..Default::default()
            };
            Rig::with_options(gpu, &scene, &tree, size, options)
        };
        let (mut culling, mut drawing) = (rig(true), rig(false));
        let above = camera(DVec3::new(0.0, -6.0, 6.0), DVec3::new(6.0, 0.0, 0.0), 0.1);
        let culled = culling.shot(above, Culling::Frustum, &scene, &tree);
        let drawn = drawing.shot(above, Culling::Frustum, &scene, &tree);
        culled.save(image_path("back_faces_culled.png")).unwrap();
        drawn.save(image_path("back_faces_drawn.png")).unwrap();
        let background = drawn.pixels().filter(|&&p| p == drawn[(0, 0)]).count();
        let covered = drawn.pixels().count() - background;
        assert!(
            covered > 8_000,
            "the boxes fill much of the view: {covered} pixels"
        );
        let differ = differing(&culled, &drawn);
        assert!(
            differ.len() <= 20,
            "{} of {covered} pixels differ: {:?}",
            differ.len(),
            &differ[..differ.len().min(10)]
        );

        // From inside the solid box, looking at the others.
        let inside = camera(DVec3::new(0.0, -0.5, 0.0), DVec3::new(8.0, 0.0, 0.0), 0.1);
        let part_pixels = |rig: &mut Rig| {
            let mut view = View::new(inside, size, Culling::Frustum);
            let ids = rig.ids(&mut view, &scene, &tree);
            let mut per_part = [0usize; 4];
            for e in ids.ids.iter().filter_map(|&v| v.checked_sub(1)) {
                per_part[tree.entries()[e as usize].part.index()] += 1;
            }
            per_part
        };
        let (seen_culling, seen_drawing) = (part_pixels(&mut culling), part_pixels(&mut drawing));
        let pixels = (size.0 * size.1) as usize;
        assert_eq!(seen_drawing, [pixels, 0, 0, 0], "its inside fills the view");
        assert_eq!(seen_culling[0], 0, "{seen_culling:?}");
        assert!(
            seen_culling[1] > 1000,
            "the mirrored box beyond: {seen_culling:?}"
        );
    });
}
