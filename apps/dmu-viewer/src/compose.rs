//! Which of egui's primitives a frame must paint, and which it can copy from
//! the panels painted last time.
//!
//! On a CPU rasterizer every pixel painted costs: repainting the whole window's
//! panels each frame (text, rounded frames, blending) cost more than the 3D
//! view itself. The panels rarely change while the view does, so the window is
//! composed from a copy of the panels as last painted, a copy of each 3D
//! view's image into its rectangle (the views are drawn in the window's own
//! format, so that is a copy too) and, clipped to those rectangles, whatever
//! egui draws over the views (the stats overlay, clash markers, tooltips):
//! exactly the primitives a full paint would draw there, in the same order, so
//! the pixels are the same.
//!
//! The split is decided on the tessellated primitives themselves, not on a
//! "did the UI change" flag: the panels are repainted when any primitive
//! outside the views differs from the last paint (compared whole, vertex for
//! vertex), so nothing a widget does can be missed.

use egui::epaint::{ClippedPrimitive, Mesh, Primitive};
use egui::{Rect, TextureId};

/// A frame's primitives, split.
#[derive(Debug, Default)]
pub struct Split {
    /// Every primitive a full paint would draw outside the views' rectangles
    /// (with its clip rectangle): the panels are painted from these, and a
    /// later frame with equal ones can reuse that paint.
    pub panels: Vec<(Rect, Mesh)>,
    /// Each view's image: its texture and its rectangle in whole pixels
    /// (x, y, width, height).
    pub images: Vec<(TextureId, [u32; 4])>,
    /// What to paint each frame over the copied panels and images: every
    /// primitive after a view's image that reaches into it, clipped to the
    /// view.
    pub over_views: Vec<ClippedPrimitive>,
}

/// Splits `jobs` (egui's tessellated output, in paint order) around the
/// images of `view_textures`. `None` when the frame cannot be split (a paint
/// callback, whose pixels are unknown here): paint it whole.
///
/// Each view's rectangle is its image's footprint, which must lie on whole
/// pixels at `pixels_per_point` (else `None`); the image is opaque, so whatever
/// was painted there before it does not show.
pub fn split(
    jobs: &[ClippedPrimitive],
    view_textures: &[TextureId],
    pixels_per_point: f32,
) -> Option<Split> {
    let mut out = Split::default();
    let mut regions: Vec<Rect> = Vec::new();
    for job in jobs {
        let Primitive::Mesh(mesh) = &job.primitive else {
            return None;
        };
        let footprint = job.clip_rect.intersect(bounds(mesh));
        if view_textures.contains(&mesh.texture_id) && footprint.is_positive() {
            // An image edge inside a pixel blends with what lies under it,
            // which a copy of the last paint would show stale.
            let pixels = pixel_rect(footprint, pixels_per_point)?;
            regions.push(footprint);
            out.images.push((mesh.texture_id, pixels));
            continue;
        }
        let mut inside_one = false;
        for region in &regions {
            let overlap = footprint.intersect(*region);
            if overlap.is_positive() {
                inside_one |= region.contains_rect(footprint);
                out.over_views.push(ClippedPrimitive {
                    clip_rect: job.clip_rect.intersect(*region),
                    primitive: job.primitive.clone(),
                });
            }
        }
        if !inside_one && footprint.is_positive() {
            out.panels.push((job.clip_rect, mesh.clone()));
        }
    }
    Some(out)
}

/// The box of a mesh's vertices (nothing for an empty mesh).
fn bounds(mesh: &Mesh) -> Rect {
    let mut r = Rect::NOTHING;
    for v in &mesh.vertices {
        r.extend_with(v.pos);
    }
    r
}

/// `r` (points) in whole pixels, `[x, y, width, height]`, when each edge lies
/// on a pixel boundary (within 1/1000 of a pixel: `116.99999` is 117 at a
/// scale of 1.3); `None` otherwise.
pub fn pixel_rect(r: Rect, pixels_per_point: f32) -> Option<[u32; 4]> {
    let whole = |v: f32| {
        let px = v * pixels_per_point;
        ((px - px.round()).abs() < 1e-3 && px.round() >= 0.0).then_some(px.round() as u32)
    };
    let (x0, y0, x1, y1) = (
        whole(r.min.x)?,
        whole(r.min.y)?,
        whole(r.max.x)?,
        whole(r.max.y)?,
    );
    Some([x0, y0, x1.checked_sub(x0)?, y1.checked_sub(y0)?])
}

#[cfg(test)]
mod tests {
    use super::*;
    use egui::{Color32, Pos2};

    fn quad(texture: TextureId, r: Rect, colour: Color32) -> Mesh {
        let mut mesh = Mesh::with_texture(texture);
        mesh.add_rect_with_uv(
            r,
            Rect::from_min_max(Pos2::ZERO, Pos2::new(1.0, 1.0)),
            colour,
        );
        mesh
    }

    fn job(clip: Rect, mesh: Mesh) -> ClippedPrimitive {
        ClippedPrimitive {
            clip_rect: clip,
            primitive: Primitive::Mesh(mesh),
        }
    }

    fn rect(x0: f32, y0: f32, x1: f32, y1: f32) -> Rect {
        Rect::from_min_max(Pos2::new(x0, y0), Pos2::new(x1, y1))
    }

    const VIEW: TextureId = TextureId::User(7);
    const FONT: TextureId = TextureId::Managed(0);

    /// A window: a side panel, the view's background, the view's image, an
    /// overlay inside the view, a popup reaching from the panel into the view.
    fn window() -> Vec<ClippedPrimitive> {
        let screen = rect(0.0, 0.0, 400.0, 300.0);
        let view = rect(100.0, 0.0, 400.0, 300.0);
        vec![
            job(
                screen,
                quad(FONT, rect(0.0, 0.0, 100.0, 300.0), Color32::GRAY),
            ),
            job(view, quad(FONT, view, Color32::BLACK)),
            job(view, quad(VIEW, view, Color32::WHITE)),
            job(
                view,
                quad(FONT, rect(300.0, 10.0, 390.0, 60.0), Color32::RED),
            ),
            job(
                screen,
                quad(FONT, rect(50.0, 100.0, 150.0, 140.0), Color32::BLUE),
            ),
        ]
    }

    #[test]
    fn panels_are_what_lies_outside_the_views_and_views_what_reaches_in() {
        let jobs = window();
        let s = split(&jobs, &[VIEW], 1.0).expect("meshes only");
        // The side panel, the background painted before the image (hidden
        // under it but kept with the panels) and the popup reaching out.
        let colours: Vec<Color32> = s.panels.iter().map(|(_, m)| m.vertices[0].color).collect();
        assert_eq!(colours, [Color32::GRAY, Color32::BLACK, Color32::BLUE]);
        // Each frame: the image, then the overlay and the popup's part in
        // the view.
        let view = rect(100.0, 0.0, 400.0, 300.0);
        assert_eq!(s.images, [(VIEW, [100, 0, 300, 300])]);
        let painted: Vec<(Rect, Color32)> = s
            .over_views
            .iter()
            .map(|j| match &j.primitive {
                Primitive::Mesh(m) => (j.clip_rect, m.vertices[0].color),
                Primitive::Callback(_) => unreachable!(),
            })
            .collect();
        assert_eq!(painted, [(view, Color32::RED), (view, Color32::BLUE)]);
    }

    #[test]
    fn a_change_inside_a_view_keeps_the_panels_and_one_outside_does_not() {
        let before = split(&window(), &[VIEW], 1.0).unwrap();
        let mut jobs = window();
        // The overlay's text changes every frame.
        jobs[3] = job(
            jobs[3].clip_rect,
            quad(FONT, rect(280.0, 10.0, 390.0, 70.0), Color32::RED),
        );
        assert_eq!(split(&jobs, &[VIEW], 1.0).unwrap().panels, before.panels);
        // The side panel's does not.
        jobs[0] = job(
            jobs[0].clip_rect,
            quad(FONT, rect(0.0, 0.0, 101.0, 300.0), Color32::GRAY),
        );
        assert_ne!(split(&jobs, &[VIEW], 1.0).unwrap().panels, before.panels);
    }

    #[test]
    fn a_view_not_on_whole_pixels_is_painted_whole() {
        let view = rect(100.5, 0.5, 399.5, 300.0);
        let jobs = vec![job(view, quad(VIEW, view, Color32::WHITE))];
        assert!(split(&jobs, &[VIEW], 1.0).is_none());
        // At 2 pixels per point it is on whole pixels.
        let s = split(&jobs, &[VIEW], 2.0).unwrap();
        assert!(s.panels.is_empty() && s.over_views.is_empty());
        assert_eq!(s.images, [(VIEW, [201, 1, 598, 599])]);
        // Edges a float rounding away from whole pixels are whole.
        let scaled = rect(90.0, 10.0, 390.0, 310.0);
        assert_eq!(
            pixel_rect(scaled, 1.3),
            Some([117, 13, 390, 390]),
            "{:?}",
            scaled.min.x * 1.3
        );
    }

    #[test]
    fn a_frame_with_nothing_but_panels_has_no_views() {
        let mut jobs = window();
        jobs.remove(2);
        let callback = ClippedPrimitive {
            clip_rect: jobs[0].clip_rect,
            primitive: Primitive::Callback(egui::epaint::PaintCallback {
                rect: jobs[0].clip_rect,
                callback: std::sync::Arc::new(()),
            }),
        };
        // Its pixels are unknown here: the frame is painted whole.
        assert!(split(&[jobs.clone(), vec![callback]].concat(), &[VIEW], 1.0).is_none());
        let s = split(&jobs, &[VIEW], 1.0).unwrap();
        assert!(s.images.is_empty() && s.over_views.is_empty());
        assert_eq!(s.panels.len(), 4);
    }
}
