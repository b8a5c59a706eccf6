// Two-pass hierarchical-Z occlusion culling (`Culling::Hzb`): a depth pyramid
// built from what the first pass drew, and every candidate's box tested
// against it, writing the draws of those newly visible for the second pass.
//
// Reverse-Z: depth 1 at the near plane, 0 at infinity (the clear value).
// A pyramid texel holds the farthest (least) depth of the pixels it covers, so
// a box whose nearest point is farther than that everywhere is hidden.
// Level 0 covers 2x2 pixels (its size rounded up); level k covers 2^(k+1)
// pixels a side, texel (x, y) pixels [x, x+1) * 2^(k+1), and the last texel of
// a row or column covers the rest of it too.

struct Params {
    // View to clip, column-major (the view's projection).
    proj: mat4x4<f32>,
    // The depth target's size in pixels.
    size: vec2<u32>,
    // Pyramid levels.
    levels: u32,
    // Candidates to test.
    count: u32,
}

// --- pyramid -----------------------------------------------------------------

@group(0) @binding(0) var depth_in: texture_depth_2d;
@group(0) @binding(1) var level0_out: texture_storage_2d<r32float, write>;
// Nearest, clamped to the edge: the last pixel of a row or column stands for
// the one past it (the least of a pixel and itself is the pixel).
@group(0) @binding(2) var depth_sampler: sampler;

// Level 0: the least depth of each 2x2 block of the depth target, gathered
// in one fetch at the block's centre.
@compute @workgroup_size(8, 8)
fn reduce_depth(@builtin(global_invocation_id) id: vec3<u32>) {
    let dims = textureDimensions(level0_out);
    if id.x >= dims.x || id.y >= dims.y {
        return;
    }
    let at = vec2<f32>(id.xy * 2u + 1u) / vec2<f32>(textureDimensions(depth_in));
    let d = textureGather(depth_in, depth_sampler, at);
    textureStore(level0_out, id.xy, vec4(min(min(d.x, d.y), min(d.z, d.w)), 0.0, 0.0, 0.0));
}

@group(0) @binding(0) var level_in: texture_2d<f32>;
@group(0) @binding(1) var level_out: texture_storage_2d<r32float, write>;

// Level k + 1: the least of each 2x2 block of level k. Levels halve rounding
// down, so the last texel of a row or column also takes level k's odd one out.
@compute @workgroup_size(8, 8)
fn reduce_level(@builtin(global_invocation_id) id: vec3<u32>) {
    let dims = textureDimensions(level_out);
    if id.x >= dims.x || id.y >= dims.y {
        return;
    }
    let size = textureDimensions(level_in);
    // Written out, not as loops over the block: loops with per-lane bounds
    // cost a CPU rasterizer's compute more than the loads.
    let p = id.xy * 2u;
    let q = min(p + 1u, size - 1u);
    var m = min(
        min(textureLoad(level_in, p, 0).x, textureLoad(level_in, vec2(q.x, p.y), 0).x),
        min(textureLoad(level_in, vec2(p.x, q.y), 0).x, textureLoad(level_in, q, 0).x),
    );
    // The last texel of a row or column also takes the odd one out.
    let r = select(q, size - 1u, id.xy == dims - 1u);
    if any(r != q) {
        m = min(m, min(
            min(textureLoad(level_in, vec2(r.x, p.y), 0).x, textureLoad(level_in, vec2(r.x, q.y), 0).x),
            min(
                min(textureLoad(level_in, vec2(p.x, r.y), 0).x, textureLoad(level_in, vec2(q.x, r.y), 0).x),
                textureLoad(level_in, r, 0).x,
            ),
        ));
    }
    textureStore(level_out, id.xy, vec4(m, 0.0, 0.0, 0.0));
}

// --- box tests ---------------------------------------------------------------

// A candidate: its box in view space (centre and half-axes, as the query
// boxes), the draw it makes when newly visible, and where that draw goes.
struct Candidate {
    center: vec4<f32>,
    axis_x: vec4<f32>,
    axis_y: vec4<f32>,
    axis_z: vec4<f32>,
    index_count: u32,
    first_index: u32,
    base_vertex: i32,
    first_instance: u32,
    // Its draw group (a page pair, or one proxy) and the group's first slot.
    group: u32,
    slot_base: u32,
    // Bit 0: drawn by the first pass; bit 1: visible without a test (the
    // near plane may cut its box).
    flags: u32,
    _pad: u32,
}

struct DrawArgs {
    index_count: u32,
    instance_count: u32,
    first_index: u32,
    base_vertex: i32,
    first_instance: u32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var<storage, read> candidates: array<Candidate>;
@group(0) @binding(2) var pyramid: texture_2d<f32>;
@group(0) @binding(3) var<storage, read_write> draws: array<DrawArgs>;
@group(0) @binding(4) var<storage, read_write> counts: array<atomic<u32>>;
@group(0) @binding(5) var<storage, read_write> visible: array<u32>;

// True unless the box is certainly behind the pyramid's depth everywhere it
// covers on screen, tested as its eight octants: an octant's rectangle and
// nearest depth fit far better than the whole box's where the box reaches
// away from the eye (5 % fewer triangles drawn inside the plant). Written
// out: the same test as a loop over octants around the loop over corners
// dropped visible chunks on Mesa 22.3's llvmpipe (a miscompile; the tests
// in crates/dmu-render/tests/hzb.rs caught it).
fn box_visible(c: Candidate) -> bool {
    // Clip coordinates are linear in the point: the centre's, and each
    // half-axis's as a direction, give every corner of the box and of its
    // octants as sums.
    let o = params.proj * vec4(c.center.xyz, 1.0);
    let x = params.proj * vec4(c.axis_x.xyz, 0.0);
    let y = params.proj * vec4(c.axis_y.xyz, 0.0);
    let z = params.proj * vec4(c.axis_z.xyz, 0.0);
    // The whole box first: where it is hidden, so is every octant (an
    // octant's nearest depth is no nearer and its texels' farthest depth
    // no farther), and most boxes are hidden.
    if !part_visible(o, x, y, z) {
        return false;
    }
    let hx = 0.5 * x;
    let hy = 0.5 * y;
    let hz = 0.5 * z;
    return part_visible(o - hx - hy - hz, hx, hy, hz) || part_visible(o + hx - hy - hz, hx, hy, hz)
        || part_visible(o - hx + hy - hz, hx, hy, hz) || part_visible(o + hx + hy - hz, hx, hy, hz)
        || part_visible(o - hx - hy + hz, hx, hy, hz) || part_visible(o + hx - hy + hz, hx, hy, hz)
        || part_visible(o - hx + hy + hz, hx, hy, hz) || part_visible(o + hx + hy + hz, hx, hy, hz);
}

// Whether the box with these clip coordinates of its centre and half-axes may
// show.
fn part_visible(center: vec4<f32>, axis_x: vec4<f32>, axis_y: vec4<f32>, axis_z: vec4<f32>) -> bool {
    var lo = vec2(1e30, 1e30);
    var hi = vec2(-1e30, -1e30);
    var nearest = 0.0;
    for (var k = 0u; k < 8u; k++) {
        let clip = center + select(-axis_x, axis_x, (k & 1u) != 0u)
            + select(-axis_y, axis_y, (k & 2u) != 0u) + select(-axis_z, axis_z, (k & 4u) != 0u);
        // A corner at or behind the eye plane: the box reaches the eye.
        if clip.w <= 0.0 {
            return true;
        }
        let ndc = clip.xyz / clip.w;
        lo = min(lo, ndc.xy);
        hi = max(hi, ndc.xy);
        nearest = max(nearest, ndc.z);
    }
    // Beyond the near plane (depth above 1): visible, as the CPU's near test.
    if nearest >= 1.0 {
        return true;
    }
    let size = vec2<f32>(params.size);
    // Pixels, y down; the rectangle of pixels the box may cover.
    let x0 = clamp(floor((lo.x * 0.5 + 0.5) * size.x), 0.0, size.x - 1.0);
    let x1 = clamp(floor((hi.x * 0.5 + 0.5) * size.x), 0.0, size.x - 1.0);
    let y0 = clamp(floor((0.5 - hi.y * 0.5) * size.y), 0.0, size.y - 1.0);
    let y1 = clamp(floor((0.5 - lo.y * 0.5) * size.y), 0.0, size.y - 1.0);
    // The finest level where the rectangle spans at most 8x8 texels: inside
    // the plant, 4x4 drew 12 % more triangles for 0.5 ms less testing, and
    // 32x32 4 % fewer for 5 ms more.
    let p0 = vec2(u32(x0), u32(y0));
    let p1 = vec2(u32(x1), u32(y1));
    var level = 0u;
    var a = vec2(0u);
    var b = vec2(0u);
    // Each level's size from level 0's: Mesa 22.3's llvmpipe answers a size
    // query at a level that differs between lanes with the first lane's
    // (a coarser first test that asked it dropped visible chunks).
    let base = textureDimensions(pyramid);
    loop {
        let top = max(base >> vec2(level), vec2(1u)) - 1u;
        a = min(p0 >> vec2(level + 1u), top);
        b = min(p1 >> vec2(level + 1u), top);
        if level + 1u >= params.levels || (b.x - a.x <= 7u && b.y - a.y <= 7u) {
            break;
        }
        level++;
    }
    var farthest = 1.0;
    for (var y = a.y; y <= b.y; y++) {
        for (var x = a.x; x <= b.x; x++) {
            farthest = min(farthest, textureLoad(pyramid, vec2(x, y), i32(level)).x);
        }
    }
    // Equal counts as visible, as the query boxes pass on equality.
    return nearest >= farthest;
}

@compute @workgroup_size(64)
fn test_boxes(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x + id.y * 65535u * 64u;
    if i >= params.count {
        return;
    }
    let c = candidates[i];
    let seen = (c.flags & 2u) != 0u || box_visible(c);
    visible[i] = u32(seen);
    if seen && (c.flags & 1u) == 0u {
        let slot = c.slot_base + atomicAdd(&counts[c.group], 1u);
        draws[slot] = DrawArgs(c.index_count, 1u, c.first_index, c.base_vertex, c.first_instance);
    }
}
