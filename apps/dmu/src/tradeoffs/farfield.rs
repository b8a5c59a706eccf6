//! Far-field knobs (MMR's textured depth meshes, `dmu_render::FarField`): a
//! few viewpoint cells along the rendering section's camera path, each
//! captured at every setting, and the path's frames inside the cell drawn
//! with its far field beyond the cull box, compared pixel for pixel with the
//! full-geometry image of the same frame.
//!
//! Design choices:
//! - **The cells of `dmu farfield build`**: the grid of cubes of
//!   `dmu_app::farfield` (1/24 of the model's largest extent, that
//!   command's default cell), each cull box found by `cull_box`'s bisection
//!   on a budget of a tenth of the model's triangles, so the near field is
//!   the same fraction of the model at any size.
//! - **Every knob starts at "none"** (setting 0): the same frames without a
//!   far field, frustum culling with every chunk whole, which is how the
//!   reference images are drawn, so its error is 0 and its time is what a far
//!   field must beat.
//! - **Each setting measured once**: one capture per cell and options, and
//!   one measurement per thing drawn, shared by every knob that has it (the
//!   default options are a point of each knob), so the knobs agree where they
//!   meet.
//! - **Baselines from the same captures**: the near field alone (nothing
//!   beyond the cull box), and the flat impostor: the cull box's six faces
//!   textured with the captures (12 triangles; the far-field shader's lookup
//!   is projective, so each face shows its capture as a flat picture).
//! - **A far field's upload is not a frame's cost**: each cell's timed frames
//!   follow one that is not timed, which puts the far field on the GPU.

use std::sync::Arc;

use anyhow::Context as _;
use dmu_app::farfield::{cell_box, cells_along, cull_box};
use dmu_geom::Aabb3d;
use dmu_render::{
    Camera, Capture, Culling, FarField, FarFieldOptions, Renderer, RendererOptions, View,
    count_differing, headless_device,
};
use dmu_scene::Scene;
use dmu_tree::{Tree, TreeOptions};

use super::report::number;
use super::{Bench, Knob, Point};

/// Cells across the model's largest extent (`dmu farfield build`'s default).
const CELLS_ACROSS: f64 = 24.0;
/// A cull box holds at most this share of the model's triangles.
const NEAR_SHARE: f64 = 0.1;
/// Path frames drawn in each cell.
const FRAMES_PER_CELL: usize = 4;
const RESOLUTIONS_QUICK: &[u32] = &[128, 512];
const RESOLUTIONS_FULL: &[u32] = &[128, 256, 512, 1024];
const MESH_ERRORS_QUICK: &[f64] = &[1.0, 8.0];
const MESH_ERRORS_FULL: &[f64] = &[0.5, 1.0, 2.0, 4.0, 8.0];

const ERROR_UNIT: &str = "% of pixels showing another surface";

/// What a setting draws beyond the cull box (the chunk instances touching
/// it are drawn as geometry in all but `None`).
#[derive(Clone, Copy, Debug, PartialEq)]
enum Far {
    /// No far field: every chunk instance in the frustum (the reference).
    None,
    /// Nothing: the near field of these options' captures alone.
    NearOnly(FarFieldOptions),
    /// The captures on the cull box's faces (flat impostors).
    BoxFaces(FarFieldOptions),
    /// The captures' depth meshes.
    Meshes(FarFieldOptions),
}

impl Far {
    /// The options of the captures it draws from (none for `None`).
    fn options(self) -> Option<FarFieldOptions> {
        match self {
            Far::None => None,
            Far::NearOnly(o) | Far::BoxFaces(o) | Far::Meshes(o) => Some(o),
        }
    }
}

/// A knob's point: its setting, its label where it is a category, and what
/// it draws.
type Setting = (f64, Option<&'static str>, Far);

const NONE: Setting = (0.0, Some("none"), Far::None);

/// A knob to sweep.
struct Plan {
    name: &'static str,
    unit: &'static str,
    note: String,
    settings: Vec<Setting>,
}

/// The capture options the other knobs hold while one is swept (the same
/// in both runs, so the knobs measured in both agree): `dmu farfield
/// build`'s defaults.
fn base() -> FarFieldOptions {
    FarFieldOptions::default()
}

/// The knobs and their settings.
fn plan(quick: bool) -> Vec<Plan> {
    let base = base();
    let (resolutions, errors) = if quick {
        (RESOLUTIONS_QUICK, MESH_ERRORS_QUICK)
    } else {
        (RESOLUTIONS_FULL, MESH_ERRORS_FULL)
    };
    let held = format!(
        "{} px faces, mesh error {} px, skins",
        base.resolution,
        number(base.mesh_error_px)
    );
    let with_none = |rest: Vec<Setting>| std::iter::once(NONE).chain(rest).collect();
    vec![
        Plan {
            name: "far field",
            unit: "",
            note: format!(
                "what is drawn beyond each cell's cull box: none is no far field (every chunk \
                 instance in the frustum); the others draw the chunk instances touching the box \
                 and beyond it nothing, the six captures on the box's faces (flat impostors, 12 \
                 triangles; built in the captures' time alone), or their depth meshes ({held})"
            ),
            settings: with_none(vec![
                (1.0, Some("near field only"), Far::NearOnly(base)),
                (2.0, Some("cull box faces"), Far::BoxFaces(base)),
                (3.0, Some("depth meshes"), Far::Meshes(base)),
            ]),
        },
        Plan {
            name: "far field resolution",
            unit: "px",
            note: format!(
                "pixels per face side of the six captures (mesh error {} px, skins); none (0) is \
                 no far field",
                number(base.mesh_error_px)
            ),
            settings: with_none(
                resolutions
                    .iter()
                    .map(|&resolution| {
                        let options = FarFieldOptions { resolution, ..base };
                        (f64::from(resolution), None, Far::Meshes(options))
                    })
                    .collect(),
            ),
        },
        Plan {
            name: "far field mesh error",
            unit: "px",
            note: format!(
                "the depth meshes' simplification bound, pixels of a capture, of image position \
                 and of parallax at the cell's corner ({} px faces, skins); none (0) is no far \
                 field",
                base.resolution
            ),
            settings: with_none(
                errors
                    .iter()
                    .map(|&mesh_error_px| {
                        let options = FarFieldOptions {
                            mesh_error_px,
                            ..base
                        };
                        (mesh_error_px, None, Far::Meshes(options))
                    })
                    .collect(),
            ),
        },
        Plan {
            name: "far field skins",
            unit: "",
            note: format!(
                "the depth meshes' triangles across depth discontinuities dropped (holes) or \
                 kept (skins: silhouettes stretched off the cell's centre); {} px faces, mesh \
                 error {} px; none is no far field",
                base.resolution,
                number(base.mesh_error_px)
            ),
            settings: with_none(vec![
                (
                    1.0,
                    Some("holes"),
                    Far::Meshes(FarFieldOptions {
                        skins: false,
                        ..base
                    }),
                ),
                (2.0, Some("skins"), Far::Meshes(base)),
            ]),
        },
    ]
}

/// What the knobs draw, each once.
fn distinct(plans: &[Plan]) -> Vec<Far> {
    let mut out: Vec<Far> = Vec::new();
    for &(_, _, far) in plans.iter().flat_map(|p| &p.settings) {
        if !out.contains(&far) {
            out.push(far);
        }
    }
    out
}

/// Steps of the progress bar this section takes: one per thing drawn.
pub fn steps(quick: bool) -> u64 {
    distinct(&plan(quick)).len() as u64
}

/// `n` of `items`, evenly spread (all of them when there are fewer).
fn spread<T: Copy>(items: &[T], n: usize) -> Vec<T> {
    let n = n.min(items.len());
    (0..n)
        .map(|i| items[(2 * i + 1) * items.len() / (2 * n)])
        .collect()
}

/// A viewpoint cell, its cull box, its frames and their reference images.
struct Cell {
    cell: Aabb3d,
    near_box: Aabb3d,
    cameras: Vec<Camera>,
    reference: Vec<Vec<u8>>,
}

/// `count` cells the rendering section's path crosses (evenly spread along
/// it), each with a few of the path's frames inside it, made denser so that
/// every cell holds several.
fn cells(tree: &Tree, count: usize, cell_size: f64, budget: u64) -> Vec<Cell> {
    let path = super::render::path(tree, 2 * FRAMES_PER_CELL * CELLS_ACROSS as usize);
    let crossed = cells_along(tree, cell_size, path.iter().map(|c| c.eye));
    spread(&crossed, count)
        .into_iter()
        .map(|g| {
            let cell = cell_box(tree, cell_size, g);
            let inside: Vec<Camera> = path
                .iter()
                .filter(|c| cell.contains_point(c.eye))
                .copied()
                .collect();
            Cell {
                cell,
                near_box: cull_box(tree, &cell, budget),
                cameras: spread(&inside, FRAMES_PER_CELL),
                reference: Vec::new(),
            }
        })
        .collect()
}

/// `field`'s captures on its cull box's six faces, 12 triangles: the flat
/// impostor. Far-field face `f` looks along +X, -X, +Y, -Y, +Z, -Z
/// (dmu-render's order, checked on the captured vertices), so its quad is
/// the box's side across axis `f / 2`; the cull box is a cube around the
/// centre, so each side lies within its face's capture.
fn box_faces(field: &FarField) -> FarField {
    debug_assert!(
        field.vertices.iter().all(|v| {
            let f = v[3] as usize;
            (if f.is_multiple_of(2) {
                v[f / 2]
            } else {
                -v[f / 2]
            }) > 0.0
        }),
        "far-field faces are not in the order +X, -X, +Y, -Y, +Z, -Z"
    );
    let lo = (field.near_box.min - field.center).as_vec3().to_array();
    let hi = (field.near_box.max - field.center).as_vec3().to_array();
    let mut vertices = Vec::with_capacity(24);
    let mut indices = Vec::with_capacity(36);
    let mut face_starts = [0; 7];
    for f in 0..6 {
        let axis = f / 2;
        let (u, v) = ((axis + 1) % 3, (axis + 2) % 3);
        let first = vertices.len() as u32;
        for (a, b) in [
            (lo[u], lo[v]),
            (hi[u], lo[v]),
            (lo[u], hi[v]),
            (hi[u], hi[v]),
        ] {
            let mut p = [0.0, 0.0, 0.0, f as f32];
            p[axis] = if f.is_multiple_of(2) {
                hi[axis]
            } else {
                lo[axis]
            };
            (p[u], p[v]) = (a, b);
            vertices.push(p);
        }
        indices.extend([0, 1, 2, 1, 3, 2].map(|i| first + i));
        face_starts[f + 1] = indices.len() as u32;
    }
    FarField {
        vertices,
        indices,
        face_starts,
        ..field.clone()
    }
}

/// `field` without its meshes: the near field alone.
fn near_only(field: &FarField) -> FarField {
    FarField {
        vertices: Vec::new(),
        indices: Vec::new(),
        face_starts: [0; 7],
        ..field.clone()
    }
}

/// A cell's far field as captured with some options.
#[derive(Clone)]
struct Captured {
    field: Arc<FarField>,
    /// Drawing and reading the six faces back, ms.
    capture_ms: f64,
    /// That and meshing, ms.
    build_ms: f64,
    /// [`FarField::encode`]'s length.
    bytes: usize,
}

/// The sweep's GPU, model, cells and what it has captured.
struct Sweep<'a> {
    scene: &'a Scene,
    tree: &'a Tree,
    device: dmu_render::wgpu::Device,
    queue: dmu_render::wgpu::Queue,
    renderer: Renderer,
    capture: Capture,
    size: (u32, u32),
    cells: Vec<Cell>,
    /// Per options, each cell's capture.
    captured: Vec<(FarFieldOptions, Vec<Captured>)>,
}

/// Sums over a setting's cells and frames.
#[derive(Default)]
struct Tally {
    ms: Vec<f64>,
    any: u64,
    surface: u64,
    chunk_triangles: u64,
    far_triangles: u64,
    build_ms: f64,
    bytes: f64,
}

impl Sweep<'_> {
    /// `cell`'s capture with `options`, every cell's captured on first use.
    fn far_field(&mut self, options: FarFieldOptions, cell: usize) -> anyhow::Result<Captured> {
        if let Some((_, c)) = self.captured.iter().find(|(o, _)| *o == options) {
            return Ok(c[cell].clone());
        }
        let mut out = Vec::with_capacity(self.cells.len());
        for c in &self.cells {
            let (field, build) = self
                .renderer
                .capture_far_field(
                    self.scene,
                    self.tree,
                    self.scene,
                    dmu_render::FarFieldRegion {
                        cell: c.cell,
                        near_box: c.near_box,
                        excluded: &Default::default(),
                    },
                    &options,
                )
                .context("capturing a far field")?;
            out.push(Captured {
                bytes: field.encode().len(),
                capture_ms: build.capture_ms,
                build_ms: field.build_ms,
                field: Arc::new(field),
            });
        }
        let c = out[cell].clone();
        self.captured.push((options, out));
        Ok(c)
    }

    /// Draws each cell's frames with its far field as `far` says; the point
    /// (setting 0, to be set by the knob).
    fn measure(&mut self, far: Far) -> anyhow::Result<Point> {
        let mut tally = Tally::default();
        for cell in 0..self.cells.len() {
            // The far field drawn, its build time and its bytes.
            let (field, build_ms, bytes) = match far {
                Far::None => (None, 0.0, 0),
                Far::NearOnly(o) => {
                    let c = self.far_field(o, cell)?;
                    (Some(Arc::new(near_only(&c.field))), 0.0, 0)
                }
                Far::BoxFaces(o) => {
                    let c = self.far_field(o, cell)?;
                    let faces = box_faces(&c.field);
                    let bytes = faces.encode().len();
                    (Some(Arc::new(faces)), c.capture_ms, bytes)
                }
                Far::Meshes(o) => {
                    let c = self.far_field(o, cell)?;
                    (Some(c.field), c.build_ms, c.bytes)
                }
            };
            tally.build_ms += build_ms;
            tally.bytes += bytes as f64;
            self.frames(cell, field, &mut tally)?;
        }
        let cells = self.cells.len() as f64;
        let frames = tally.ms.len() as f64;
        let share =
            |pixels: u64| 100.0 * pixels as f64 / (frames * f64::from(self.size.0 * self.size.1));
        Ok(Point::new(
            0.0,
            dmu_geom::median(tally.ms),
            share(tally.surface),
            ERROR_UNIT,
        )
        .extra("% of pixels differing at all", share(tally.any))
        .extra("build per cell, ms", tally.build_ms / cells)
        .extra("bytes per cell", tally.bytes / cells)
        .extra(
            "chunk triangles a frame",
            tally.chunk_triangles as f64 / frames,
        )
        .extra(
            "far-field triangles a frame",
            tally.far_triangles as f64 / frames,
        ))
    }

    /// Draws `cell`'s frames with `field` and adds them to `tally`.
    fn frames(
        &mut self,
        cell: usize,
        field: Option<Arc<FarField>>,
        tally: &mut Tally,
    ) -> anyhow::Result<()> {
        let c = &self.cells[cell];
        let mut view = View::new(c.cameras[0], self.size, Culling::Frustum);
        let drawn = field.is_some();
        view.far_field = field;
        // Not timed: it puts the far field on the GPU.
        self.renderer.render(
            &mut view,
            self.scene,
            self.tree,
            self.scene,
            self.capture.frame_target(),
        )?;
        for (&camera, reference) in c.cameras.iter().zip(&c.reference) {
            view.camera = camera;
            let stats = self.renderer.render(
                &mut view,
                self.scene,
                self.tree,
                self.scene,
                self.capture.frame_target(),
            )?;
            anyhow::ensure!(
                stats.far_field == drawn,
                "a frame in cell {:?} drew a far field: {} (expected {drawn})",
                c.cell,
                stats.far_field
            );
            let image = self.capture.read_color(&self.device, &self.queue)?;
            let (any, surface) = count_differing(reference, image.as_raw());
            tally.ms.push(stats.cpu_ms);
            tally.any += any;
            tally.surface += surface;
            tally.chunk_triangles += stats.triangles_drawn;
            tally.far_triangles += stats.far_field_triangles;
        }
        Ok(())
    }
}

/// The far-field knobs, in the rendering section of the report.
pub fn run(bench: &Bench<'_>) -> anyhow::Result<Vec<Knob>> {
    let scene: &Scene = bench.scene;
    let tree = Tree::build(scene, TreeOptions::default());
    let (device, queue, _) = headless_device().context("opening a GPU device")?;
    let size = bench.scale.render_size;
    // Simplified chunk levels, as `dmu farfield build` captures with.
    let mut renderer = Renderer::new(
        &device,
        &queue,
        scene,
        &tree,
        RendererOptions {
            lod_levels: true,
            ..Default::default()
        },
    );
    renderer.enable_far_fields(scene, &tree);
    let model_triangles: u64 = tree.entries().iter().map(|e| u64::from(e.triangles)).sum();
    let budget = (model_triangles as f64 * NEAR_SHARE) as u64;
    let cell_size = tree.bounds().extent().max_element() / CELLS_ACROSS;
    let mut sweep = Sweep {
        scene,
        tree: &tree,
        capture: Capture::new(&device, size),
        cells: cells(&tree, bench.scale.far_field_cells, cell_size, budget),
        device,
        queue,
        renderer,
        size,
        captured: Vec::new(),
    };
    anyhow::ensure!(!sweep.cells.is_empty(), "the path crosses no cell");
    // The references: each frame without a far field, every chunk whole.
    for c in &mut sweep.cells {
        let mut view = View::new(c.cameras[0], size, Culling::Frustum);
        for &camera in &c.cameras {
            view.camera = camera;
            sweep
                .renderer
                .render(&mut view, scene, &tree, scene, sweep.capture.frame_target())?;
            let image = sweep.capture.read_color(&sweep.device, &sweep.queue)?;
            c.reference.push(image.into_raw());
        }
    }
    let plans = plan(bench.scale.quick);
    let fars = distinct(&plans);
    let mut measured = Vec::new();
    for (i, &far) in fars.iter().enumerate() {
        measured.push((far, sweep.measure(far)?));
        bench.progress.inc(1);
        // Captures no later setting draws from are let go (the full run's
        // would hold hundreds of MB of textures).
        sweep
            .captured
            .retain(|(o, _)| fars[i + 1..].iter().any(|f| f.options() == Some(*o)));
    }
    let frames: usize = sweep.cells.iter().map(|c| c.cameras.len()).sum();
    let setup = format!(
        "; {} cells of {} model units along the rendering path, cull boxes of at most {} \
         triangles ({} % of the model), {frames} frames in all",
        sweep.cells.len(),
        number(cell_size),
        budget,
        number(NEAR_SHARE * 100.0),
    );
    Ok(plans
        .into_iter()
        .map(|p| Knob {
            section: "rendering",
            name: p.name.to_owned(),
            unit: p.unit.to_owned(),
            note: p.note + &setup,
            reference: "frustum culling, every chunk drawn whole, no far field".to_owned(),
            time: "median frame time".to_owned(),
            error_unit: ERROR_UNIT.to_owned(),
            exact_setting: Some(0.0),
            log_x: false,
            log_error: false,
            points: p
                .settings
                .iter()
                .map(|&(setting, label, far)| {
                    let (_, point) = measured
                        .iter()
                        .find(|(f, _)| *f == far)
                        .expect("every setting measured");
                    let point = Point {
                        setting,
                        ..point.clone()
                    };
                    match label {
                        Some(l) => point.label(l),
                        None => point,
                    }
                })
                .collect(),
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every knob has the reference at 0, and the default options are a
    /// point of every knob (so the knobs meet at one measurement).
    #[test]
    fn each_knob_starts_at_none_and_meets_the_others_at_the_defaults() {
        for quick in [true, false] {
            let base = base();
            for p in plan(quick) {
                assert_eq!(p.settings[0], NONE, "{}", p.name);
                assert!(
                    p.settings.iter().any(|s| s.2 == Far::Meshes(base)),
                    "{}",
                    p.name
                );
            }
        }
        // none, near field only, cull box faces, the base meshes, 128 px, 8 px,
        // holes.
        assert_eq!(steps(true), 7);
    }

    #[test]
    fn spread_picks_evenly() {
        assert_eq!(spread(&[0, 1, 2, 3, 4, 5, 6, 7], 2), [2, 6]);
        assert_eq!(spread(&[0, 1], 4), [0, 1]);
        assert!(spread::<u8>(&[], 3).is_empty());
    }
}
