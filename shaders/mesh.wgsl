// dmu-render: chunk geometry, chunk-id oracle and occlusion-query boxes.
//
// Positions arrive part-local (f32); each part's model-view was formed in f64 on
// the CPU, camera-relative, so nothing here ever sees a large coordinate.
// What a draw's vertices share (its model-view, colour and entry; a proxy's or
// a box's frame) arrives as instance-rate vertex attributes, not storage reads:
// a CPU rasterizer fetches those once per draw, where it gathers a storage
// read lane by lane for every vertex.
// Depth is reverse-Z (1 at the near plane); front faces are counter-clockwise,
// but CAD windings are unreliable: back faces are culled (by the pipeline) only
// for meshes found solid at import, and shading is two-sided.

struct ViewUniform {
    // View space to clip space (reverse-Z, infinite far plane), shared by the
    // eyes of a stereo pair (parallel eyes, symmetric frusta).
    proj: mat4x4<f32>,
    // Colour mixed into selected parts (rgb) and its weight (a).
    highlight: vec4<f32>,
    // Colour mixed into parts clashing with a moved part, as highlight.
    clash: vec4<f32>,
    // Colour mixed into the part under the pointer, as highlight.
    hover: vec4<f32>,
    // Colour of cut faces.
    section_cap: vec3<f32>,
    // The eye single-view entry points draw (0 but for a stereo pair drawn a
    // layer at a time).
    eye: u32,
    // The headlight in eye k's view space at light[k] (the eye itself, or
    // one lamp between a pair's eyes).
    light: array<vec4<f32>, 2>,
    // Section planes (n, d) in eye k's view space at clip[k * 6 ..]: a point
    // p with dot(n, p) + d < 0 is cut away. Unused ones are (0, 0, 0, 1).
    clip: array<vec4<f32>, 12>,
}

// Rows of a part's affine model-view (part-local to view space).
struct ModelView {
    r0: vec4<f32>,
    r1: vec4<f32>,
    r2: vec4<f32>,
}

// A chunk draw's instance: its part's model-view in the eye drawn, its
// colour (material and tint, formed on the CPU) and its tree entry.
struct Instance {
    @location(2) r0: vec4<f32>,
    @location(3) r1: vec4<f32>,
    @location(4) r2: vec4<f32>,
    @location(5) base: vec3<f32>,
    @location(6) entry: u32,
}

// One chunk instance of the tree, by entry: `look` holds its material id in
// the low bits and its part's flags from FLAGS_SHIFT on (the CPU rewrites a
// part's entries when its flags change). Only proxies read it: their
// vertices come from many entries.
struct EntryGpu {
    look: u32,
}

// A world-aligned box in view space, or a proxy's frame: centre plus three
// half-axes (world axes), so the CPU does the f64 work and the GPU only adds
// small vectors. An instance of box and proxy draws.
struct Frame {
    @location(7) center: vec4<f32>,
    @location(8) axis_x: vec4<f32>,
    @location(9) axis_y: vec4<f32>,
    @location(10) axis_z: vec4<f32>,
}

@group(0) @binding(0) var<uniform> view: ViewUniform;
@group(0) @binding(1) var<storage, read> entries: array<EntryGpu>;
@group(0) @binding(2) var<storage, read> materials: array<vec4<f32>>;

// Whether the pipeline cuts with section planes: the uncut ones compile
// without the discard, which would cost early depth testing.
override SECTIONED: bool = false;

// Part flag bits, from FLAGS_SHIFT on in EntryGpu.look; the tint goes by
// priority: selected, clashing, hovered.
const PART_SELECTED: u32 = 1u;
const PART_CLASHING: u32 = 2u;
const PART_HOVERED: u32 = 4u;
const FLAGS_SHIFT: u32 = 29u;
const MATERIAL_MASK: u32 = (1u << FLAGS_SHIFT) - 1u;

struct MeshOut {
    // Invariant: the colour, id and query pipelines must cover identical pixels.
    @builtin(position) @invariant clip: vec4<f32>,
    @location(0) view_pos: vec3<f32>,
    @location(1) normal: vec3<f32>,
    @location(2) @interpolate(flat) entry: u32,
    @location(3) @interpolate(flat) eye: u32,
    // The entry's material with its part's tint, formed once per vertex: read
    // per fragment, the entry and its material cost a CPU rasterizer more
    // than the rest of the shading.
    @location(4) @interpolate(flat) base: vec3<f32>,
}

// A chunk vertex of `instance` as eye `eye` sees it, through model-view `m`.
// Every mesh entry point goes through here, so a stereo layer computes
// exactly what a single-eye render does.
fn mesh_vertex(position: vec3<f32>, normal: vec4<f32>, m: ModelView, instance: Instance, eye: u32) -> MeshOut {
    let p = vec4<f32>(position, 1.0);
    let view_pos = vec3<f32>(dot(m.r0, p), dot(m.r1, p), dot(m.r2, p));
    // Normals go through the cofactor matrix (the inverse transpose up to a
    // scale), so scaled parts shade correctly without a second matrix.
    let c0 = vec3<f32>(m.r0.x, m.r1.x, m.r2.x);
    let c1 = vec3<f32>(m.r0.y, m.r1.y, m.r2.y);
    let c2 = vec3<f32>(m.r0.z, m.r1.z, m.r2.z);
    let n = normal.xyz;
    let view_normal = cross(c1, c2) * n.x + cross(c2, c0) * n.y + cross(c0, c1) * n.z;
    return mesh_out(view_pos, view_normal, instance.entry, instance.base, eye);
}

// What every mesh vertex passes on, from its view-space position and normal.
fn mesh_out(view_pos: vec3<f32>, view_normal: vec3<f32>, entry: u32, base: vec3<f32>, eye: u32) -> MeshOut {
    var out: MeshOut;
    out.clip = view.proj * vec4<f32>(view_pos, 1.0);
    out.view_pos = view_pos;
    out.normal = view_normal;
    out.entry = entry;
    out.eye = eye;
    out.base = base;
    return out;
}

// An entry's colour from its look: its material, mixed with its part's tint
// (selected, else clashing, else hovered) where it has one. The CPU forms
// the same for chunk draws (`Renderer::instance`).
fn base_colour(look: u32) -> vec3<f32> {
    let base = materials[look & MATERIAL_MASK].rgb;
    let flags = look >> FLAGS_SHIFT;
    if flags == 0u {
        return base;
    }
    var tint = view.hover;
    if (flags & PART_SELECTED) != 0u {
        tint = view.highlight;
    } else if (flags & PART_CLASHING) != 0u {
        tint = view.clash;
    }
    return mix(base, tint.rgb, tint.a);
}

// Whether a fragment at view_pos of eye `eye` is cut away by a section plane.
// A face lying in a plane stays whole: the test allows the f32 rounding of
// camera-relative positions (about 1e-7 of the distance to the eye), so it
// does not flicker between cut and kept.
fn cut_away(view_pos: vec3<f32>, eye: u32) -> bool {
    let tolerance = 1e-5 * length(view_pos);
    var cut = false;
    for (var i = 0u; i < 6u; i++) {
        let plane = view.clip[eye * 6u + i];
        cut = cut || dot(plane.xyz, view_pos) + plane.w < -tolerance;
    }
    return cut;
}

@vertex
fn vs_mesh(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec4<f32>,
    instance: Instance,
) -> MeshOut {
    let m = ModelView(instance.r0, instance.r1, instance.r2);
    return mesh_vertex(position, normal, m, instance, view.eye);
}

// A proxy's vertex (a merged, simplified subtree) as stored: its position
// is relative to the proxy's origin along the world axes; it carries the
// entry it came from and that entry's material colour.
struct ProxyVertex {
    @location(0) position: vec3<f32>,
    @location(1) normal: vec4<f32>,
    @location(2) entry: u32,
    @location(5) base: vec3<f32>,
}

// Proxy vertex `v` in colour `base`. Its instance is the proxy's frame in
// the eye's view space (the origin, formed in f64 on the CPU, and the world
// axes), so positions go through a rotation and a small translation only.
fn proxy_vertex(v: ProxyVertex, base: vec3<f32>, f: Frame) -> MeshOut {
    let p = v.position;
    let view_pos = f.center.xyz + f.axis_x.xyz * p.x + f.axis_y.xyz * p.y + f.axis_z.xyz * p.z;
    let n = v.normal;
    let view_normal = f.axis_x.xyz * n.x + f.axis_y.xyz * n.y + f.axis_z.xyz * n.z;
    return mesh_out(view_pos, view_normal, v.entry, base, view.eye);
}

// A proxy's vertex in its material's colour, which it carries.
@vertex
fn vs_proxy(v: ProxyVertex, f: Frame) -> MeshOut {
    return proxy_vertex(v, v.base, f);
}

// A proxy's vertex tinted as its entry's part is (drawn only for proxies
// that may hold a tinted part: the look is a storage read per vertex).
@vertex
fn vs_proxy_tinted(v: ProxyVertex, f: Frame) -> MeshOut {
    return proxy_vertex(v, base_colour(entries[v.entry].look), f);
}

@fragment
fn fs_shade(in: MeshOut) -> @location(0) vec4<f32> {
    if SECTIONED {
        if cut_away(in.view_pos, in.eye) {
            discard;
        }
        // A face seen from behind under a section is the inside of a closed
        // part through the cut: it shows as the cut face, flat in the section
        // colour. Behind by the normal the shading uses, not by the winding,
        // which CAD exports get wrong (cut frames cull nothing, for this).
        if dot(in.normal, in.view_pos) > 0.0 {
            return vec4<f32>(view.section_cap, 1.0);
        }
    }
    // Headlight: the light sits at the eye (or between a pair's eyes), so
    // every visible face is lit and two-sided lighting hides inconsistent CAD
    // windings.
    // One inverse square root for both lengths: the normalisations
    // cost a CPU rasterizer a measurable share of the frame.
    let n = in.normal;
    let l = view.light[in.eye].xyz - in.view_pos;
    let lambert = abs(dot(n, l)) * inverseSqrt(dot(n, n) * dot(l, l));
    return vec4<f32>(in.base * (0.2 + 0.8 * lambert), 1.0);
}

@fragment
fn fs_id(in: MeshOut) -> @location(0) u32 {
    if SECTIONED && cut_away(in.view_pos, in.eye) {
        discard;
    }
    // 0 is the background.
    return in.entry + 1u;
}

// The 36 corner indices of a box's 12 triangles (corner bit 0 = +x, 1 = +y, 2 = +z).
const BOX_CORNERS = array<u32, 36>(
    0u, 2u, 1u, 1u, 2u, 3u,
    4u, 5u, 6u, 5u, 7u, 6u,
    0u, 1u, 4u, 1u, 5u, 4u,
    2u, 6u, 3u, 3u, 6u, 7u,
    0u, 4u, 2u, 2u, 4u, 6u,
    1u, 3u, 5u, 3u, 7u, 5u,
);

@vertex
fn vs_box(@builtin(vertex_index) vertex: u32, b: Frame) -> @builtin(position) @invariant vec4<f32> {
    let corner = BOX_CORNERS[vertex];
    let s = vec3<f32>(f32(corner & 1u), f32((corner >> 1u) & 1u), f32((corner >> 2u) & 1u)) * 2.0 - 1.0;
    let p = b.center.xyz + b.axis_x.xyz * s.x + b.axis_y.xyz * s.y + b.axis_z.xyz * s.z;
    return view.proj * vec4<f32>(p, 1.0);
}

@fragment
fn fs_box() -> @location(0) vec4<f32> {
    // Colour writes are masked off; the query counts depth-passing samples.
    return vec4<f32>(0.0);
}
