//! A far field's capture: six square views from the cell's centre, read
//! back and meshed.

use std::collections::BTreeSet;
use std::time::Instant;

use dmu_scene::Scene;
use dmu_tree::Tree;

use crate::capture::Capture;
use crate::error::RenderError;
use crate::geometry::GeometrySource;
use crate::renderer::Renderer;
use crate::settings::Culling;
use crate::view::View;

use super::mesh::{Lens, mesh_faces};
use super::{
    FAR_FIELD_RESOLUTIONS, FarField, FarFieldBuild, FarFieldOptions, FarFieldRegion, FarOnly,
    OVERLAP_PX, face_camera,
};

impl Renderer {
    /// Captures the far field of `region`'s viewpoint cell around its
    /// centre ([`FarFieldRegion`]): six faces of `options.resolution`
    /// pixels, meshed as the module says. The renderer's colour format must
    /// be [`crate::CAPTURE_FORMAT`].
    pub fn capture_far_field(
        &mut self,
        scene: &Scene,
        tree: &Tree,
        geometry: &dyn GeometrySource,
        region: FarFieldRegion<'_>,
        options: &FarFieldOptions,
    ) -> Result<(FarField, FarFieldBuild), RenderError> {
        let FarFieldRegion {
            cell,
            near_box,
            excluded,
        } = region;
        let start = Instant::now();
        let r = options.resolution;
        assert!(
            FAR_FIELD_RESOLUTIONS.contains(&r),
            "far-field resolution {r} out of range"
        );
        let center = cell.center();
        let tan_half = 1.0 + 2.0 * OVERLAP_PX / f64::from(r);
        // Far geometry lies outside the cull box, which holds the centre.
        let half = (near_box.max - center)
            .min(center - near_box.min)
            .min_element();
        let near = (0.5 * half).max(1e-6 * (center.length() + 1.0));
        let capture = Capture::new(&self.device, (r, r));
        let texels = (r * r) as usize;
        let mut color = Vec::with_capacity(6 * texels * 4);
        let mut parts = Vec::with_capacity(6 * texels);
        let mut depths = Vec::with_capacity(6);
        for face in 0..6 {
            let camera = face_camera(center, face, tan_half, near).camera;
            let mut view = View::new(camera, (r, r), Culling::Frustum);
            view.options.lod_error_px = options.lod_error_px;
            view.options.target_ms = None;
            view.far_only = Some(FarOnly {
                near_box,
                excluded: excluded.clone(),
            });
            self.render(&mut view, scene, tree, geometry, capture.frame_target())?;
            color.extend_from_slice(capture.read_color(&self.device, &self.queue)?.as_raw());
            depths.push(capture.read_depth(&self.device, &self.queue)?);
            let ids = self.render_ids(&mut view, scene, tree, geometry, &capture)?;
            parts.extend(ids.ids.iter().map(|&id| match id {
                0 => 0,
                e => tree.entries()[e as usize - 1].part.0 + 1,
            }));
        }
        let capture_ms = start.elapsed().as_secs_f64() * 1e3;
        let mesh_start = Instant::now();
        // A parallax of one pixel: the cell's corner seen from its centre.
        let reach = (cell.extent() * 0.5).length();
        let focal = f64::from(r) / (2.0 * tan_half);
        let lens = Lens {
            resolution: r,
            tan_half,
            near,
            parallax_scale: reach * focal,
        };
        let mut build = FarFieldBuild::default();
        let (vertices, indices, face_starts) = mesh_faces(&depths, options, lens, &mut build);
        build.triangles = indices.len() as u64 / 3;
        build.capture_ms = capture_ms;
        build.mesh_ms = mesh_start.elapsed().as_secs_f64() * 1e3;
        let seen: BTreeSet<u32> = parts.iter().filter_map(|&p| p.checked_sub(1)).collect();
        Ok((
            FarField {
                center,
                cell,
                near_box,
                resolution: r,
                tan_half: tan_half as f32,
                vertices,
                indices,
                face_starts,
                color,
                parts,
                seen: seen.into_iter().collect(),
                excluded: excluded.iter().copied().collect(),
                mesh_error_px: options.mesh_error_px as f32,
                build_ms: start.elapsed().as_secs_f64() * 1e3,
            },
            build,
        ))
    }
}
