//! Stereo pairs: two parallel eyes culled once, against a frustum enclosing
//! both, and drawn in one multiview pass into a 2-layer target (or a pass per
//! layer where multiview is missing or broken).

use dmu_geom::{Camera, Frustum};

use crate::capture::attachment_texture;

/// Two eyes either side of a centre camera, `ipd` apart along its screen right,
/// looking along parallel axes with the centre camera's projection (its
/// symmetric one, or the view's off-centre `View::fov`, shared by both eyes):
/// a parallel rig, no toe-in, so no vertical parallax.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StereoCamera {
    /// The centre ("cyclopean") eye; the eyes share its field of view, near
    /// plane and up.
    pub center: Camera,
    /// Interpupillary distance, world units (65 for a model in millimetres);
    /// finite and not negative.
    pub ipd: f64,
}

impl StereoCamera {
    /// The left and right eyes: the centre camera moved by `∓ipd / 2` along its
    /// screen right, eye and target alike, so each is an ordinary [`Camera`]
    /// that a single-view render of that eye uses as it is.
    ///
    /// # Panics
    /// When `ipd` is negative or not finite.
    pub fn eyes(&self) -> [Camera; 2] {
        assert!(
            self.ipd >= 0.0 && self.ipd.is_finite(),
            "interpupillary distance must be finite and not negative, got {}",
            self.ipd
        );
        let c = &self.center;
        // The view matrix's x axis: screen right in world space.
        let right = (c.target - c.eye).cross(c.up).normalize();
        let eye = |side: f64| {
            let offset = right * (side * 0.5 * self.ipd);
            Camera {
                eye: c.eye + offset,
                target: c.target + offset,
                ..*c
            }
        };
        [eye(-1.0), eye(1.0)]
    }

    /// A frustum containing both eyes' frusta: the left eye's left plane, the
    /// right eye's right plane, and the bottom, top, near and (infinite) far
    /// planes the eyes share with the centre camera (the eyes sit on a line
    /// in all of those planes). It adds to the union of the two frusta only the
    /// wedge in front of the eyes that neither sees, which closes within
    /// `ipd / (2 tan(horizontal fov / 2))` of them; anything it culls is
    /// outside both eyes' frusta.
    pub fn enclosing_frustum(&self, aspect: f64) -> Frustum {
        self.enclosing(|c| c.frustum(aspect))
    }

    /// [`StereoCamera::enclosing_frustum`] for any projection both eyes
    /// share (an off-centre `View::fov`: the eyes still sit on a line in its
    /// bottom, top and near planes), `frustum_at` giving it from a camera.
    pub(crate) fn enclosing(&self, frustum_at: impl Fn(&Camera) -> Frustum) -> Frustum {
        let [left, right] = self.eyes();
        let mut frustum = frustum_at(&self.center);
        frustum.planes[0] = frustum_at(&left).planes[0];
        frustum.planes[1] = frustum_at(&right).planes[1];
        frustum
    }
}

/// How a stereo pair's drawn set reaches its two layers. Culling is the same
/// either way: once, for both eyes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum StereoMode {
    /// [`StereoMode::Multiview`] where the device has multiview and draws it
    /// correctly (checked once, when the renderer is made, by drawing a
    /// near-clipped triangle into the second view), else
    /// [`StereoMode::LayerPasses`].
    #[default]
    Auto,
    /// One multiview pass draws both layers ([`wgpu::Features::MULTIVIEW`]);
    /// occlusion queries run per layer after it.
    Multiview,
    /// Each eye's layer in passes of its own, draws and queries alike, for
    /// devices without (correct) multiview. Mesa 22.3's lavapipe draws the
    /// near-clipped triangles of the second view into the first layer.
    LayerPasses,
}

/// Whether the device draws a near-clipped triangle of each view of a
/// multiview pass into that view's layer, and only there. `module` holds
/// `stereo.wgsl`.
pub(crate) fn multiview_clips_correctly(
    device: &wgpu::Device,
    queue: &wgpu::Queue,
    module: &wgpu::ShaderModule,
) -> bool {
    const SIZE: u32 = 8;
    let format = wgpu::TextureFormat::Rgba8Unorm;
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("dmu multiview probe"),
        layout: None,
        vertex: wgpu::VertexState {
            module,
            entry_point: Some("vs_probe"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: Default::default(),
        depth_stencil: None,
        multisample: Default::default(),
        fragment: Some(wgpu::FragmentState {
            module,
            entry_point: Some("fs_probe"),
            compilation_options: Default::default(),
            targets: &[Some(format.into())],
        }),
        multiview_mask: std::num::NonZeroU32::new(0b11),
        cache: None,
    });
    let texture = attachment_texture(device, "dmu multiview probe", (SIZE, SIZE), 2, format);
    let view = texture.create_view(&wgpu::TextureViewDescriptor {
        dimension: Some(wgpu::TextureViewDimension::D2Array),
        ..Default::default()
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("dmu multiview probe"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: &view,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(wgpu::Color::TRANSPARENT),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: std::num::NonZeroU32::new(0b11),
        });
        pass.set_pipeline(&pipeline);
        pass.draw(0..3, 0..1);
    }
    queue.submit([encoder.finish()]);
    // Covered texels of a layer, and whether all are in the colour of its view.
    let coverage = |layer: u32| {
        let texels = crate::capture::read_texture(
            device,
            queue,
            &texture,
            (SIZE, SIZE),
            layer,
            "multiview probe",
        )
        .ok()?;
        let own = if layer == 0 { 0 } else { 255 };
        let covered: Vec<&[u8]> = texels.chunks_exact(4).filter(|t| t[0] != 0).collect();
        Some((covered.len(), covered.iter().all(|t| t[1] == own)))
    };
    matches!(
        (coverage(0), coverage(1)),
        (Some((a, true)), Some((b, true))) if a > 0 && a == b
    )
}
