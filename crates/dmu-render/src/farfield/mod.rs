//! Far fields (MMR's textured depth meshes): beyond a cull box around the
//! viewer, the model is replaced by six depth meshes captured from the centre
//! of the viewpoint cell the eye is in, textured projectively with the
//! captured colour.
//!
//! A far field is made by [`Renderer::capture_far_field`]: six square views
//! (a cube map whose faces overlap by a few pixels, so no seam opens between
//! them) draw every chunk instance that does not touch the cull box, their
//! colour, depth and part ids are read back, and each face's depth becomes a
//! grid mesh that is simplified with meshoptimizer in the space of (pixel x,
//! pixel y, parallax): a vertex's third coordinate is how many pixels it moves
//! when the eye moves from the centre to the cell's corner, so the one bound
//! `mesh_error_px` holds for image position and for parallax alike. Planes stay
//! planes in that space (a plane's inverse depth is linear in the pixel
//! coordinates), so planar runs merge into a few triangles. Quads across a
//! depth discontinuity are kept ("skins": seen edge-on from the centre, they
//! show the silhouette's colour stretched when the eye moves off it) or
//! dropped (holes instead), by [`FarFieldOptions::skins`]; the walk measures
//! both against the full image.
//!
//! A frame of a [`View`] whose [`View::far_field`] serves the eye draws the
//! chunk instances touching the cull box (the near field) as usual, then the
//! far field's meshes into the same depth. Edits: a part whose transform or
//! visibility differs from the model the far fields were made from
//! ([`Renderer::enable_far_fields`]) is drawn as geometry wherever it is, and
//! the far field's texels showing it are discarded, so it never shows at its
//! old place; [`FarField::is_stale`] says which far fields need capturing
//! again (their owner does it, [`Renderer::capture_far_field`] leaving out the
//! moved parts).
//!
//! The module holds the far field's data; `capture` makes one, `mesh` turns
//! a face's depth into its mesh, `draw` keeps moved parts and draws far
//! fields into frames, `codec` writes and reads them as bytes.

mod capture;
pub(crate) mod codec;
mod draw;
mod mesh;

use std::collections::BTreeSet;
use std::sync::Arc;

use dmu_geom::Aabb3d;
use dmu_tree::{EntryId, Revision};
use glam::{DMat4, DVec3};

use crate::Camera;

/// The six faces of a far field: +X, -X, +Y, -Y, +Z, -Z (forward, up).
const FACES: [(DVec3, DVec3); 6] = [
    (DVec3::X, DVec3::Z),
    (DVec3::NEG_X, DVec3::Z),
    (DVec3::Y, DVec3::Z),
    (DVec3::NEG_Y, DVec3::Z),
    (DVec3::Z, DVec3::Y),
    (DVec3::NEG_Z, DVec3::Y),
];

/// Pixels by which neighbouring faces overlap at their shared edge.
const OVERLAP_PX: f64 = 2.0;

/// Resolutions a far field may have (pixels per face side).
pub const FAR_FIELD_RESOLUTIONS: std::ops::RangeInclusive<u32> = 16..=4096;

/// How a far field is captured and meshed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FarFieldOptions {
    /// Pixels per face side (the texture's, and the grid's before meshing).
    pub resolution: u32,
    /// Pixels between depth-mesh grid vertices.
    pub grid_step: u32,
    /// Simplification bound of the depth meshes, pixels of the capture: of
    /// image position, and of parallax as the eye moves to the cell's corner.
    pub mesh_error_px: f64,
    /// LOD error the captures draw with, pixels of the capture.
    pub lod_error_px: f64,
    /// Keep the triangles across depth discontinuities (skins) rather than
    /// leaving holes there.
    pub skins: bool,
}

impl Default for FarFieldOptions {
    fn default() -> Self {
        Self {
            resolution: 512,
            grid_step: 4,
            mesh_error_px: 1.0,
            lod_error_px: 0.5,
            skins: true,
        }
    }
}

/// A quad is a skin when its farthest corner is this much farther than its
/// nearest (1.25: a wall seen at 80 degrees off its normal over 4 pixels of
/// a 512-pixel face still is not one).
const SKIN_RATIO: f64 = 1.25;

/// The background (where a capture hit nothing) lies this many times
/// farther than the farthest sample that hit something.
const BACKGROUND: f64 = 4.0;

/// One viewpoint cell's far field: depth meshes and their captured colour
/// and part ids. Positions are f32 relative to `center` (an f64 origin).
#[derive(Clone, Debug, PartialEq)]
pub struct FarField {
    /// Where it was captured from: the cell's centre.
    pub center: DVec3,
    /// The eye positions it serves.
    pub cell: Aabb3d,
    /// The cull box: chunk instances touching it are the near field, drawn
    /// as geometry; the rest is in the far field.
    pub near_box: Aabb3d,
    /// Pixels per face side.
    pub resolution: u32,
    /// Tangent of each face's half angle (a little over 1: faces overlap).
    pub tan_half: f32,
    /// Depth-mesh vertices: x, y, z relative to `center`, and the face (0-5).
    pub vertices: Vec<[f32; 4]>,
    /// Triangles, face by face.
    pub indices: Vec<u32>,
    /// Where each face's triangles start in `indices` (and the end).
    pub face_starts: [u32; 7],
    /// Colour of the six faces, face-major, rows top to bottom, RGBA8 sRGB.
    pub color: Vec<u8>,
    /// Part id + 1 of each texel (0: nothing there), as `color`.
    pub parts: Vec<u32>,
    /// Parts showing in it, sorted.
    pub seen: Vec<u32>,
    /// Parts left out of it (moved when it was captured; drawn as geometry),
    /// sorted.
    pub excluded: Vec<u32>,
    /// The depth meshes' simplification bound, pixels.
    pub mesh_error_px: f32,
    /// Time the capture and meshing took, ms.
    pub build_ms: f64,
}

/// What one far field's capture did.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct FarFieldBuild {
    /// Grid triangles before simplification.
    pub grid_triangles: u64,
    /// Triangles kept.
    pub triangles: u64,
    /// Time drawing and reading the six faces back, ms.
    pub capture_ms: f64,
    /// Time meshing and simplifying, ms.
    pub mesh_ms: f64,
}

impl FarField {
    /// True when an eye at `p` may use it.
    pub fn serves(&self, p: DVec3) -> bool {
        self.cell.contains_point(p) && self.near_box.contains_point(p)
    }

    /// Triangles of its depth meshes.
    pub fn triangles(&self) -> u64 {
        self.indices.len() as u64 / 3
    }

    /// True when it no longer shows the model as it is: a part showing in it
    /// has moved (is in `moved`), or a part it left out is back in place.
    pub fn is_stale(&self, moved: &BTreeSet<u32>) -> bool {
        self.seen.iter().any(|p| moved.contains(p))
            || self.excluded.iter().any(|p| !moved.contains(p))
    }

    /// The face cameras' view-projection relative to `center` (f32 on the GPU).
    fn face_view_proj(&self, face: usize) -> DMat4 {
        face_camera(DVec3::ZERO, face, f64::from(self.tan_half), 1.0).view_proj()
    }
}

/// The camera of `face` at `center`, `tan_half` the tangent of its half angle.
fn face_camera(center: DVec3, face: usize, tan_half: f64, near: f64) -> FaceCamera {
    let (forward, up) = FACES[face];
    FaceCamera {
        camera: Camera {
            eye: center,
            target: center + forward,
            up,
            fov_y_rad: 2.0 * tan_half.atan(),
            near,
        },
    }
}

struct FaceCamera {
    camera: Camera,
}

impl FaceCamera {
    fn view_proj(&self) -> DMat4 {
        self.camera.projection(1.0) * self.camera.view_matrix()
    }
}

/// A frame's near field: the chunk instances touching the cull box and
/// those of the parts drawn as geometry wherever they are (found once a
/// frame, with the tree's box query).
#[derive(Clone, Debug)]
pub(crate) struct NearField {
    /// Sorted, each once.
    pub entries: Vec<EntryId>,
    /// Parts drawn as geometry wherever they are.
    pub always: Vec<u32>,
}

/// A capture's filter: what does not touch the cull box, less the parts left
/// out.
#[derive(Clone, Debug)]
pub(crate) struct FarOnly {
    pub near_box: Aabb3d,
    pub excluded: BTreeSet<u32>,
}

/// Which of a frame's chunk instances it draws, when far fields are involved.
#[derive(Clone, Debug, Default)]
pub(crate) enum FarCut {
    /// All (no far field).
    #[default]
    None,
    /// The near field of a far field drawn too.
    Near(NearField),
    /// What a far field captures.
    FarOnly(FarOnly),
}

/// Moved parts, against the model the far fields were made from.
#[derive(Debug)]
pub(crate) struct FarState {
    /// Per part: a hash of its world transform and hidden flag then.
    base: Vec<u64>,
    revision: Revision,
    hidden: Vec<bool>,
    moved: BTreeSet<u32>,
    /// `moved` as bits, on the GPU for the far-field shader.
    bits: wgpu::Buffer,
    bits_current: bool,
    /// Uploaded far fields, most recently used first.
    uploaded: Vec<(Arc<FarField>, FarFieldGpu)>,
}

/// Far fields kept on the GPU at once.
const UPLOADED_FAR_FIELDS: usize = 4;

#[derive(Debug)]
pub(crate) struct FarFieldGpu {
    vertices: wgpu::Buffer,
    indices: wgpu::Buffer,
    uniform: wgpu::Buffer,
    bind_group: wgpu::BindGroup,
    /// Each face's bounds relative to the centre (empty: nothing there).
    face_bounds: [Aabb3d; 6],
}

/// Where a far field is captured ([`crate::Renderer::capture_far_field`]):
/// from the centre of the viewpoint cell `cell`, everything not touching
/// `near_box` but the parts in `excluded` (which are drawn as geometry
/// wherever they are).
#[derive(Clone, Copy, Debug)]
pub struct FarFieldRegion<'a> {
    /// The viewpoint cell.
    pub cell: Aabb3d,
    /// The cull box around it: what touches it is the near field.
    pub near_box: Aabb3d,
    /// Parts left out of the far field.
    pub excluded: &'a BTreeSet<u32>,
}
