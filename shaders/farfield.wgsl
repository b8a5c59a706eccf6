// dmu-render: far fields, depth meshes textured projectively from the six
// captures they were made of (see crates/dmu-render/src/farfield.rs).
//
// Vertices are f32 relative to the far field's centre; the CPU hands over the
// centre in view space and the world axes there (formed in f64), so large
// coordinates never reach the GPU. Each fragment finds its texel by projecting
// its position (relative to the centre) with its face's capture camera: exact
// projective texturing, however coarse the mesh. Texels showing a part that
// has moved since the capture are discarded: the part is drawn as geometry.

struct FarUniform {
    proj: mat4x4<f32>,
    origin: vec4<f32>,
    axis_x: vec4<f32>,
    axis_y: vec4<f32>,
    axis_z: vec4<f32>,
    // Each face's capture view-projection, relative to the centre.
    faces: array<mat4x4<f32>, 6>,
    resolution: u32,
}

@group(0) @binding(0) var<uniform> far: FarUniform;
@group(0) @binding(1) var color: texture_2d_array<f32>;
@group(0) @binding(2) var color_sampler: sampler;
@group(0) @binding(3) var parts: texture_2d_array<u32>;
// Moved parts, a bit each.
@group(0) @binding(4) var<storage, read> moved: array<u32>;

struct FarOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) relative: vec3<f32>,
    @location(1) @interpolate(flat) face: u32,
}

@vertex
fn vs_far(@location(0) v: vec4<f32>) -> FarOut {
    let view_pos = far.origin.xyz + far.axis_x.xyz * v.x + far.axis_y.xyz * v.y
        + far.axis_z.xyz * v.z;
    var out: FarOut;
    out.clip = far.proj * vec4<f32>(view_pos, 1.0);
    out.relative = v.xyz;
    out.face = u32(v.w);
    return out;
}

@fragment
fn fs_far(in: FarOut) -> @location(0) vec4<f32> {
    let c = far.faces[in.face] * vec4<f32>(in.relative, 1.0);
    let ndc = c.xy / c.w;
    let uv = vec2<f32>(ndc.x * 0.5 + 0.5, 0.5 - ndc.y * 0.5);
    let colour = textureSampleLevel(color, color_sampler, uv, i32(in.face), 0.0);
    let last = i32(far.resolution) - 1;
    let texel = clamp(vec2<i32>(uv * f32(far.resolution)), vec2<i32>(0), vec2<i32>(last));
    let part = textureLoad(parts, texel, i32(in.face), 0).x;
    if part != 0u {
        let p = part - 1u;
        let word = min(p / 32u, arrayLength(&moved) - 1u);
        if ((moved[word] >> (p % 32u)) & 1u) == 1u {
            discard;
        }
    }
    return colour;
}
