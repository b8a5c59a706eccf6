//! Data shared with the shaders (`shaders/mesh.wgsl`): `Pod`, `#[repr(C)]`,
//! sizes asserted against the WGSL layouts.

use bytemuck::{Pod, Zeroable};

use crate::settings::MAX_SECTION_PLANES;

/// The WGSL source of every single-view pipeline.
pub(crate) const SHADER: &str = include_str!("../../../shaders/mesh.wgsl");
/// The WGSL source of the multiview pipeline: `mesh.wgsl` plus the entry point
/// that reads `view_index`, which only validates on devices with multiview.
pub(crate) const STEREO_SHADER: &str = concat!(
    include_str!("../../../shaders/mesh.wgsl"),
    include_str!("../../../shaders/stereo.wgsl")
);

/// `ViewUniform`: projection and highlight colours of one view, and which eye
/// the single-view pipelines draw (a stereo pair drawn a layer at a time
/// binds one per eye).
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct ViewUniform {
    /// View to clip, column-major, reverse-Z (every eye of a view shares it).
    pub proj: [[f32; 4]; 4],
    /// Selection colour (rgb) and how much of it is mixed in (a).
    pub highlight: [f32; 4],
    /// Colour mixed into clashing parts, as `highlight`.
    pub clash: [f32; 4],
    /// Colour mixed into the hovered part, as `highlight`.
    pub hover: [f32; 4],
    /// Colour of cut faces (rgb).
    pub section_cap: [f32; 3],
    /// The eye single-view pipelines draw (0 for a view).
    pub eye: u32,
    /// The headlight in each eye's view space (w unused).
    pub light: [[f32; 4]; 2],
    /// Section planes `(n, d)` in each eye's view space, eye `k`'s at
    /// `k * MAX_SECTION_PLANES`; a point is cut away where `n·p + d < 0`.
    /// Unused slots are `(0, 0, 0, 1)`, which keep everything.
    pub clip: [[f32; 4]; 2 * MAX_SECTION_PLANES],
}
const _: () = assert!(size_of::<ViewUniform>() == 160 + 16 * 2 * MAX_SECTION_PLANES);

/// `Instance`: what the vertices of one chunk draw share, read by the mesh
/// pipelines as instance-rate vertex attributes (the draw's instance index
/// selects it).
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct InstanceGpu {
    /// The rows `[m0, m1, m2, t]` of its part's camera-relative affine
    /// model-view in the eye drawn, formed in f64 and narrowed to f32 only
    /// once small.
    pub rows: [[f32; 4]; 3],
    /// Its material's colour with its part's tint (rgb).
    pub base: [f32; 3],
    /// Its tree entry (what the id pipelines write, less one).
    pub entry: u32,
}
const _: () = assert!(size_of::<InstanceGpu>() == 64);

/// The attributes of a pooled chunk vertex (`crate::geometry::PoolVertex`):
/// position and normal.
pub(crate) const CHUNK_VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 2] =
    wgpu::vertex_attr_array![0 => Float32x3, 1 => Snorm8x4];
/// The attributes of a proxy's vertex (`crate::proxy::ProxyVertex`):
/// position, normal, the entry it came from and its material's colour.
pub(crate) const PROXY_VERTEX_ATTRIBUTES: [wgpu::VertexAttribute; 4] =
    wgpu::vertex_attr_array![0 => Float32x3, 1 => Snorm8x4, 2 => Uint32, 5 => Float32x3];
/// The instance-rate attributes of [`InstanceGpu`], at the shader's locations.
pub(crate) const INSTANCE_ATTRIBUTES: [wgpu::VertexAttribute; 5] = wgpu::vertex_attr_array![
    2 => Float32x4, 3 => Float32x4, 4 => Float32x4, 5 => Float32x3, 6 => Uint32
];
/// The right eye's model-view rows of the multiview pipeline, read from a
/// second [`InstanceGpu`] buffer.
pub(crate) const RIGHT_EYE_ATTRIBUTES: [wgpu::VertexAttribute; 3] =
    wgpu::vertex_attr_array![11 => Float32x4, 12 => Float32x4, 13 => Float32x4];
/// The instance-rate attributes of a [`QueryBox`] (a box or a proxy's frame).
pub(crate) const FRAME_ATTRIBUTES: [wgpu::VertexAttribute; 4] = wgpu::vertex_attr_array![
    7 => Float32x4, 8 => Float32x4, 9 => Float32x4, 10 => Float32x4
];

/// `EntryGpu`: a chunk instance's look, indexed by entry id; the proxies'
/// vertices read it by the entry they came from.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct EntryGpu {
    /// Material id (index into materials) in the low [`FLAGS_SHIFT`] bits,
    /// the part's flags above them.
    pub look: u32,
}

impl EntryGpu {
    /// The entry of a chunk drawn in `material` while its part has `flags`.
    /// Material ids past the field's range (more than 5e8 materials) wrap;
    /// no store comes near.
    pub fn new(material: u32, flags: u32) -> Self {
        EntryGpu {
            look: (material & ((1 << FLAGS_SHIFT) - 1)) | (flags << FLAGS_SHIFT),
        }
    }
}
const _: () = assert!(size_of::<EntryGpu>() == 4);

/// `Frame` of `mesh.wgsl`: a world-aligned box in view space, centre and
/// half-axes (a query box, or a proxy's frame).
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

/// The WGSL source of the depth pyramid and box tests of `Culling::Hzb`.
pub(crate) const HZB_SHADER: &str = include_str!("../../../shaders/hzb.wgsl");

/// The WGSL source of the stereo reprojection (`crate::reproject`).
pub(crate) const REPROJECT_SHADER: &str = include_str!("../../../shaders/reproject.wgsl");

/// `Params` of `hzb.wgsl`: the projection, the target's size, pyramid levels
/// and candidates.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct HzbParams {
    /// View to clip, column-major.
    pub proj: [[f32; 4]; 4],
    /// The depth target's size, pixels.
    pub size: [u32; 2],
    /// Pyramid levels.
    pub levels: u32,
    /// Candidates to test.
    pub count: u32,
}
const _: () = assert!(size_of::<HzbParams>() == 80);

/// `Candidate` of `hzb.wgsl`: a box to test and the draw it makes when newly
/// visible.
#[derive(Clone, Copy, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub(crate) struct HzbCandidate {
    /// The box in view space, as the query boxes.
    pub bounds: QueryBox,
    /// `DrawIndexedIndirectArgs` less the instance count.
    pub index_count: u32,
    pub first_index: u32,
    pub base_vertex: i32,
    pub first_instance: u32,
    /// Its draw group and the group's first slot in the draw buffer.
    pub group: u32,
    pub slot_base: u32,
    /// [`HZB_DRAWN`], [`HZB_FORCED`].
    pub flags: u32,
    pub _pad: u32,
}
const _: () = assert!(size_of::<HzbCandidate>() == 96);

/// Candidate flag: the first pass drew it (no second draw).
pub(crate) const HZB_DRAWN: u32 = 1;
/// Candidate flag: visible without a test (an eye may be in its box).
pub(crate) const HZB_FORCED: u32 = 2;

/// Part flag bit: the part is selected (highlighted). The shader's tint goes
/// by priority: selected over clashing over hovered.
pub(crate) const PART_SELECTED: u32 = 1;
/// Part flag bit: the part clashes with the moved part.
pub(crate) const PART_CLASHING: u32 = 2;
/// Part flag bit: the pointer is over the part.
pub(crate) const PART_HOVERED: u32 = 4;
/// Where the part flags start in [`EntryGpu::look`].
const FLAGS_SHIFT: u32 = 29;

#[cfg(test)]
mod tests {
    use naga::valid::{Capabilities, ValidationFlags, Validator};

    /// Parses and validates `source` with `capabilities`; its entry point names.
    fn validate(source: &str, capabilities: Capabilities) -> Vec<String> {
        let module = naga::front::wgsl::parse_str(source).expect("WGSL parses");
        Validator::new(ValidationFlags::all(), capabilities)
            .validate(&module)
            .expect("WGSL validates");
        module.entry_points.iter().map(|e| e.name.clone()).collect()
    }

    /// The single-view shader validates with naga without multiview, as a
    /// device without it will see it.
    #[test]
    fn shader_validates_with_naga() {
        let entries = validate(super::SHADER, Capabilities::empty());
        for entry in ["vs_mesh", "fs_shade", "fs_id", "vs_box", "fs_box"] {
            assert!(
                entries.iter().any(|e| e == entry),
                "missing entry point {entry}"
            );
        }
    }

    /// The part flags and where they sit in an entry's look are the shader's,
    /// and a look keeps its material and flags apart.
    #[test]
    fn entry_looks_match_the_shader() {
        let module = naga::front::wgsl::parse_str(super::SHADER).expect("WGSL parses");
        let constant = |name: &str| -> u32 {
            let (_, c) = module
                .constants
                .iter()
                .find(|(_, c)| c.name.as_deref() == Some(name))
                .unwrap_or_else(|| panic!("the shader has no {name}"));
            match module.global_expressions[c.init] {
                naga::Expression::Literal(naga::Literal::U32(v)) => v,
                ref e => panic!("{name} is {e:?}"),
            }
        };
        assert_eq!(constant("FLAGS_SHIFT"), super::FLAGS_SHIFT);
        assert_eq!(constant("PART_SELECTED"), super::PART_SELECTED);
        assert_eq!(constant("PART_CLASHING"), super::PART_CLASHING);
        assert_eq!(constant("PART_HOVERED"), super::PART_HOVERED);
        let all = super::PART_SELECTED | super::PART_CLASHING | super::PART_HOVERED;
        let mask = (1 << super::FLAGS_SHIFT) - 1;
        for (material, flags) in [(0, 0), (1, all), (mask, super::PART_CLASHING), (12_345, 0)] {
            let look = super::EntryGpu::new(material, flags).look;
            assert_eq!((look & mask, look >> super::FLAGS_SHIFT), (material, flags));
        }
    }

    /// The vertex inputs of each vertex entry point, location by location,
    /// against the attributes of the buffers its pipelines bind: every
    /// input is fed, with as many components, and nothing else is.
    #[test]
    fn vertex_inputs_match_the_buffers() {
        use super::*;
        let module = naga::front::wgsl::parse_str(STEREO_SHADER).expect("WGSL parses");
        let components = |ty: naga::Handle<naga::Type>| match module.types[ty].inner {
            naga::TypeInner::Scalar(_) => 1,
            naga::TypeInner::Vector { size, .. } => size as u64,
            ref t => panic!("vertex input of type {t:?}"),
        };
        let inputs = |name: &str| {
            let entry = (module.entry_points.iter())
                .find(|e| e.name == name)
                .unwrap_or_else(|| panic!("no entry point {name}"));
            let mut found = Vec::new();
            for arg in &entry.function.arguments {
                match (&arg.binding, &module.types[arg.ty].inner) {
                    (Some(naga::Binding::Location { location, .. }), _) => {
                        found.push((*location, components(arg.ty)));
                    }
                    (Some(naga::Binding::BuiltIn(_)), _) => {}
                    (None, naga::TypeInner::Struct { members, .. }) => {
                        for m in members {
                            if let Some(naga::Binding::Location { location, .. }) = m.binding {
                                found.push((location, components(m.ty)));
                            }
                        }
                    }
                    (b, t) => panic!("{name}: input {b:?} of type {t:?}"),
                }
            }
            found.sort_unstable();
            found
        };
        let fed = |buffers: &[&[wgpu::VertexAttribute]]| {
            let mut found: Vec<(u32, u64)> = (buffers.iter())
                .flat_map(|b| b.iter())
                .map(|a| {
                    let n = match a.format {
                        wgpu::VertexFormat::Uint32 => 1,
                        wgpu::VertexFormat::Float32x3 => 3,
                        wgpu::VertexFormat::Float32x4 | wgpu::VertexFormat::Snorm8x4 => 4,
                        f => panic!("a format this test does not know: {f:?}"),
                    };
                    (a.shader_location, n)
                })
                .collect();
            found.sort_unstable();
            found
        };
        let cases: [(&str, &[&[wgpu::VertexAttribute]]); 5] = [
            ("vs_mesh", &[&CHUNK_VERTEX_ATTRIBUTES, &INSTANCE_ATTRIBUTES]),
            (
                "vs_mesh_stereo",
                &[
                    &CHUNK_VERTEX_ATTRIBUTES,
                    &INSTANCE_ATTRIBUTES,
                    &RIGHT_EYE_ATTRIBUTES,
                ],
            ),
            ("vs_proxy", &[&PROXY_VERTEX_ATTRIBUTES, &FRAME_ATTRIBUTES]),
            (
                "vs_proxy_tinted",
                &[&PROXY_VERTEX_ATTRIBUTES, &FRAME_ATTRIBUTES],
            ),
            ("vs_box", &[&FRAME_ATTRIBUTES]),
        ];
        for (name, buffers) in cases {
            assert_eq!(inputs(name), fed(buffers), "{name}");
        }
    }

    /// The pyramid and box-test shader validates, with its three entry points.
    #[test]
    fn hzb_shader_validates_with_naga() {
        let entries = validate(super::HZB_SHADER, Capabilities::empty());
        assert_eq!(entries, ["reduce_depth", "reduce_level", "test_boxes"]);
    }

    /// The stereo reprojection shader validates, with its one pass.
    #[test]
    fn reproject_shader_validates_with_naga() {
        let entries = validate(super::REPROJECT_SHADER, Capabilities::empty());
        assert_eq!(entries, ["reproject_rows"]);
    }

    /// The stereo shader validates with multiview, and only with it.
    #[test]
    fn stereo_shader_validates_with_multiview() {
        let entries = validate(super::STEREO_SHADER, Capabilities::MULTIVIEW);
        for entry in ["vs_mesh_stereo", "vs_probe", "fs_probe"] {
            assert!(
                entries.iter().any(|e| e == entry),
                "missing entry point {entry}"
            );
        }
        let module = naga::front::wgsl::parse_str(super::STEREO_SHADER).expect("WGSL parses");
        assert!(
            Validator::new(ValidationFlags::all(), Capabilities::empty())
                .validate(&module)
                .is_err(),
            "view_index must need the multiview capability"
        );
    }
}
