//! A frame, from the caller's entry points (a view, a stereo pair, the id
//! oracle) to its stats: the per-frame context, the view's uniforms, the
//! culling strategy that draws it, the far field.

use std::time::Instant;

use dmu_geom::Plane;
use dmu_scene::Scene;
use dmu_tree::Tree;
use glam::{DAffine3, DMat4};

use crate::budget::KnobsInEffect;
use crate::capture::{Capture, IdImage};
use crate::cull::{Cull, Frame, sort_draws};
use crate::culling;
use crate::error::RenderError;
use crate::farfield::FarCut;
use crate::geometry::GeometrySource;
use crate::gpu::ViewUniform;
use crate::renderer::Renderer;
use crate::round::{Model, ProxyRound, Round, Shading, ViewGpu};
use crate::settings::{Culling, MAX_SECTION_PLANES};
use crate::state::EntryState;
use crate::stats::FrameStats;
use crate::stereo::StereoMode;
use crate::target::{FrameTarget, RoundTarget, StereoTarget};
use crate::view::{StereoView, View};

impl Renderer {
    /// A frame of `view`, or with `ipd` of the stereo pair around its camera
    /// (culled once, drawn in one multiview pass): the frame's context, then
    /// the view's culling strategy draws it, then the far field, then the
    /// knobs and the strategy's own bookkeeping for the next frame.
    pub(crate) fn render_frame(
        &mut self,
        view: &mut View,
        ipd: Option<f64>,
        model: Model<'_>,
        target: RoundTarget<'_>,
    ) -> Result<FrameStats, RenderError> {
        let Model {
            scene,
            tree,
            geometry,
        } = model;
        let start = Instant::now();
        view.state.next_frame();
        self.hierarchy.sync(tree);
        self.sync_part_flags(scene, tree);
        let proxy_time = self.sync_proxies(scene, tree, geometry);
        if view.state.entries.len() != tree.entries().len() {
            view.state.entries = vec![EntryState::default(); tree.entries().len()];
        }
        let mut stats = FrameStats {
            frame: u64::from(view.state.frame),
            ..FrameStats::default()
        };
        let knobs = match view.options.target_ms {
            Some(_) => (view.state.knobs)
                .unwrap_or(KnobsInEffect::of(&view.options))
                .within(&view.options),
            None => KnobsInEffect::of(&view.options),
        };
        stats.lod_error_px = knobs.lod_error_px;
        stats.min_pixels = knobs.min_pixels;
        let mut cull = Cull::new(view, ipd, knobs);
        let cell_distance = self.cell_distances(tree, cull.eye());
        self.sync_far(scene, tree);
        // Every mode but `none` (which `auto` never runs) draws a far field
        // that serves a single view's eye.
        let near = match view.culling {
            Culling::None => None,
            _ if target.eye_count() > 1 => None,
            _ => self.near_field(view, tree),
        };
        if let Some(near) = &near {
            cull.far = FarCut::Near(near.clone());
        }
        let mut gpu = self.prepare_view(view, cull.eye_views());
        view.state.drawn.clear();
        // Counted over the whole frame: rounds upload chunks, and so do
        // passes that resolve their draws outside a round (hzb's).
        let uploaded_before = self.pool.upload_time;
        let strategy = culling::strategy(view.culling);
        let outcome = strategy.draw(
            self,
            &mut Frame {
                view: &mut *view,
                gpu: &mut gpu,
                model,
                target,
                cull: &cull,
                cell_distance: &cell_distance,
                stats: &mut stats,
            },
        );
        view.state.gpu = Some(gpu);
        outcome?;
        if let Some(near) = &near {
            stats.far_field = true;
            stats.far_field_moved_parts = near.always.len() as u64;
            stats.far_field_triangles = self.draw_far_field(view, target.all())?;
        }
        let uploaded = self.pool.upload_time - uploaded_before;
        stats.upload_ms = (uploaded + proxy_time).as_secs_f64() * 1e3;
        stats.proxies_stale = self.proxies.as_ref().map_or(0, |p| p.cpu.stale());
        stats.cpu_ms = start.elapsed().as_secs_f64() * 1e3;
        view.state.knobs = Some(knobs.next(&view.options, stats.cpu_ms - stats.upload_ms));
        strategy.after_frame(self, view, &mut stats);
        view.state.last = stats;
        Ok(stats)
    }

    /// Renders one frame of `view` into `target`: culls, draws and (with
    /// [`Culling::Occlusion`]) queries in rounds, waits for the GPU, and
    /// returns what it did. `geometry` supplies chunks not yet on the GPU.
    pub fn render(
        &mut self,
        view: &mut View,
        scene: &Scene,
        tree: &Tree,
        geometry: &dyn GeometrySource,
        target: FrameTarget<'_>,
    ) -> Result<FrameStats, RenderError> {
        let target = RoundTarget::single(target).keeping_color(view.keep_color);
        self.render_frame(
            view,
            None,
            Model {
                scene,
                tree,
                geometry,
            },
            target,
        )
    }

    /// Renders one frame of a stereo pair into `target`'s two layers: culls
    /// once, against [`crate::StereoCamera::enclosing_frustum`] (coverage and
    /// occlusion alike, a sample in either eye counting as visible), and
    /// draws what survives in one multiview pass (or a pass per layer, per
    /// [`Renderer::stereo_mode`]). Each layer is the image a single-view
    /// [`Renderer::render`] of that eye ([`crate::StereoCamera::eyes`]) draws, given
    /// the same drawn set; draws are ordered from the eyes' midpoint, so only
    /// coplanar overlapping faces in different cells could resolve otherwise.
    ///
    /// # Errors
    /// [`RenderError::Unsupported`] when [`StereoMode::Multiview`] was asked
    /// for on a device without multiview; readback errors as
    /// [`Renderer::render`].
    pub fn render_stereo(
        &mut self,
        view: &mut StereoView,
        scene: &Scene,
        tree: &Tree,
        geometry: &dyn GeometrySource,
        target: StereoTarget<'_>,
    ) -> Result<FrameStats, RenderError> {
        if self.stereo_unsupported() {
            return Err(RenderError::Unsupported {
                feature: "multiview (asked for stereo pairs)",
            });
        }
        let multiview = self.stereo_mode() == StereoMode::Multiview;
        view.view.camera = view.camera.center;
        let keep_color = view.view.keep_color;
        self.render_frame(
            &mut view.view,
            Some(view.camera.ipd),
            Model {
                scene,
                tree,
                geometry,
            },
            RoundTarget::stereo(&target, multiview).keeping_color(keep_color),
        )
    }

    /// The chunk instances owning at least one pixel of `view`, by drawing
    /// every non-hidden chunk instance in the frustum (no occlusion culling)
    /// as ids; `capture` must have the view's size.
    pub fn render_ids(
        &mut self,
        view: &mut View,
        scene: &Scene,
        tree: &Tree,
        geometry: &dyn GeometrySource,
        capture: &Capture,
    ) -> Result<IdImage, RenderError> {
        assert_eq!(capture.size(), view.size, "capture and view sizes differ");
        self.hierarchy.sync(tree);
        self.sync_part_flags(scene, tree);
        let cull = Cull {
            min_pixels: 0.0,
            ..Cull::new(view, None, KnobsInEffect::default())
        };
        let cell_distance = self.cell_distances(tree, cull.eye());
        let mut gpu_state = self.prepare_view(view, cull.eye_views());
        let mut scratch = FrameStats::default();
        let mut draws = self.frustum_draws(scene, tree, &cull, &mut scratch);
        sort_draws(&self.hierarchy, &cell_distance, &mut draws);
        let round = self.submit_round(
            &mut gpu_state,
            RoundTarget::single(capture.id_target()),
            Model {
                scene,
                tree,
                geometry,
            },
            &Round {
                shading: Shading::Ids,
                clear: true,
                draws: &draws,
                boxes: &[],
                lod: None,
                proxies: ProxyRound::default(),
            },
        );
        let result = self.finish_round(&gpu_state, round);
        view.state.gpu = Some(gpu_state);
        result?;
        capture.read_ids(&self.device, &self.queue)
    }

    /// Sets a view's uniforms for its eyes (world-to-view `eye_views`) and
    /// keeps the eyes for its rounds, which form their draws' model-views.
    pub(crate) fn prepare_view(&self, view: &mut View, eye_views: &[DAffine3]) -> ViewGpu {
        let proj = view.projection();
        let clip = section_in_eyes(&view.section, eye_views);
        let mut g = view
            .state
            .gpu
            .take()
            .unwrap_or_else(|| self.make_view_gpu());
        g.sectioned = !view.section.is_empty();
        g.eye_views.clear();
        g.eye_views.extend_from_slice(eye_views);
        let mut light = [[0.0; 4]; 2];
        if let Some(at) = view.light {
            for (l, v) in light.iter_mut().zip(eye_views) {
                *l = v.transform_point3(at).as_vec3().extend(0.0).to_array();
            }
        }
        for eye in 0..eye_views.len() {
            let uniform = ViewUniform {
                proj: proj.as_mat4().to_cols_array_2d(),
                highlight: self.options.highlight,
                clash: self.options.clash_highlight,
                hover: self.options.hover_highlight,
                section_cap: self.options.section_cap,
                eye: eye as u32,
                light,
                clip,
            };
            self.queue.write_buffer(
                &g.uniform,
                eye as u64 * self.uniform_stride,
                bytemuck::bytes_of(&uniform),
            );
        }
        g
    }
}

/// The section planes in each eye's view space, six per eye (unused slots are
/// `(0, 0, 0, 1)`: every point is 1 above them, kept). The plane
/// goes through the inverse transpose of world-to-view in f64, so a plane far
/// from the origin becomes a small camera-relative one before narrowing to f32.
fn section_in_eyes(
    section: &[Plane],
    eye_views: &[DAffine3],
) -> [[f32; 4]; 2 * MAX_SECTION_PLANES] {
    let mut clip = [[0.0, 0.0, 0.0, 1.0]; 2 * MAX_SECTION_PLANES];
    for (eye, view) in eye_views.iter().take(2).enumerate() {
        let view_to_world_t = DMat4::from(view.inverse()).transpose();
        for (i, p) in section.iter().enumerate() {
            let v = view_to_world_t * p.normal.extend(p.d);
            clip[eye * MAX_SECTION_PLANES + i] = v.as_vec4().to_array();
        }
    }
    clip
}
