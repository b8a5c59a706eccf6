//! Data shared with the shaders (`shaders/mesh.wgsl`): `Pod`, `#[repr(C)]`,
//! sizes asserted against the WGSL layouts.

use bytemuck::{Pod, Zeroable};

/// The WGSL source of every pipeline.
pub(crate) const SHADER: &str = include_str!("../../../shaders/mesh.wgsl");

/// `ViewUniform`: projection and highlight colour of one view.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct ViewUniform {
    /// View to clip, column-major, reverse-Z.
    pub proj: [[f32; 4]; 4],
    /// Selection colour (rgb) and how much of it is mixed in (a).
    pub highlight: [f32; 4],
}
const _: () = assert!(size_of::<ViewUniform>() == 80);

/// `ModelView`: rows of a part's camera-relative affine model-view, formed in
/// f64 and narrowed to f32 only once small.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct ModelView {
    /// Three rows `[m0, m1, m2, t]`.
    pub rows: [[f32; 4]; 3],
}
const _: () = assert!(size_of::<ModelView>() == 48);

/// `EntryGpu`: a chunk instance's part and material; indexed by entry id, which
/// the draw passes as its instance index.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct EntryGpu {
    /// Part id (index into model-views and part flags).
    pub part: u32,
    /// Material id (index into materials).
    pub material: u32,
}
const _: () = assert!(size_of::<EntryGpu>() == 8);

/// `QueryBox`: a world-aligned box in view space, centre and half-axes.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct QueryBox {
    /// Centre (w unused).
    pub center: [f32; 4],
    /// World x half-extent in view space (w unused).
    pub axis_x: [f32; 4],
    /// World y half-extent in view space.
    pub axis_y: [f32; 4],
    /// World z half-extent in view space.
    pub axis_z: [f32; 4],
}
const _: () = assert!(size_of::<QueryBox>() == 64);

/// Part flag bit: the part is selected (highlighted).
pub(crate) const PART_SELECTED: u32 = 1;

#[cfg(test)]
mod tests {
    /// The shader parses and validates with naga, as every backend will see it.
    #[test]
    fn shader_validates_with_naga() {
        let module = naga::front::wgsl::parse_str(super::SHADER).expect("WGSL parses");
        naga::valid::Validator::new(
            naga::valid::ValidationFlags::all(),
            naga::valid::Capabilities::all(),
        )
        .validate(&module)
        .expect("WGSL validates");
        for entry in ["vs_mesh", "fs_shade", "fs_id", "vs_box", "fs_box"] {
            assert!(
                module.entry_points.iter().any(|e| e.name == entry),
                "missing entry point {entry}"
            );
        }
    }
}
