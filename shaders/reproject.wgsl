// dmu-render: the right eye of a stereo pair reprojected from the left eye's
// image by its depth (`crate::reproject`).
//
// The eyes are parallel, `ipd` apart along screen right, with one pixel scale
// and one vertical field of view, so a point's depth is the same from either
// eye and it moves only along its row: by its disparity `ipd * fx / z`
// pixels to the left in the right eye. Depth is reverse-Z with an infinite far
// plane (d = near / z), so the disparity is `d * disparity_at_near`: linear in
// the depth value, 0 for the background.
//
// One invocation a row, scanning the left image from left to right: of two
// pixels landing on one right-eye pixel the later is the nearer (it moved
// further left by more than it started to the right), so each write simply
// replaces what was there and no depth test is needed (McMillan's
// occlusion-compatible order). Where consecutive pixels land more than one
// pixel apart, the right eye sees between them what the left eye's view hid
// behind the nearer (a gap along a near silhouette; a single column where a
// slanted surface widens in the right eye): the farther of the two fills the
// columns past the furthest reached so far (those before it are landed on or
// filled already), so the background extends into the gap and a row costs
// its width, whatever its depth changes.

struct Params {
    source_size: vec2<u32>,
    target_size: vec2<u32>,
    // Pixels per row of `out` (a multiple of 64, for the copy into the target).
    out_stride: u32,
    pad: u32,
    // The target window's first column on the source's pixel grid.
    target_offset: f32,
    // Disparity in pixels at the near plane (depth value 1): ipd * fx / near.
    disparity_at_near: f32,
}

@group(0) @binding(0) var<uniform> params: Params;
@group(0) @binding(1) var source_color: texture_2d<f32>;
@group(0) @binding(2) var source_depth: texture_depth_2d;
// Per target pixel: 1 where a left-eye pixel landed this frame (cleared to 0
// before the pass).
@group(0) @binding(3) var<storage, read_write> landed: array<u32>;
// Per target pixel: its RGBA8 colour, as the target stores it.
@group(0) @binding(4) var<storage, read_write> out: array<u32>;

// Fills the target pixels of row `y` from `first` to before `end` with
// `color` (columns past the furthest reached: nothing landed there yet).
fn fill(y: u32, first: i32, end: i32, color: u32) {
    for (var u = max(first, 0); u < min(end, i32(params.target_size.x)); u++) {
        out[y * params.out_stride + u32(u)] = color;
    }
}

@compute @workgroup_size(64)
fn reproject_rows(@builtin(global_invocation_id) id: vec3<u32>) {
    let y = id.x;
    if y >= params.target_size.y {
        return;
    }
    let w = i32(params.target_size.x);
    // The furthest column landed on or filled (-1 before the first pixel),
    // and the previous pixel's depth and colour.
    var furthest = -1;
    var prev_d = 0.0;
    var prev_color = 0u;
    for (var x = 0u; x < params.source_size.x; x++) {
        let p = vec2<u32>(x, y);
        let d = textureLoad(source_depth, p, 0);
        let color = pack4x8unorm(textureLoad(source_color, p, 0));
        // The pixel centre x + 0.5 lands on x + 0.5 - disparity -
        // target_offset, in the pixel containing it (-1 and w: off the target).
        let landing = floor(f32(x) + 0.5 - d * params.disparity_at_near - params.target_offset);
        let u = i32(clamp(landing, -1.0, f32(w)));
        if u > furthest + 1 {
            // The farther of the two (depth is reverse-Z); the first pixel
            // alone where the row starts with a gap.
            var gap = color;
            if x > 0u && prev_d < d {
                gap = prev_color;
            }
            fill(y, furthest + 1, u, gap);
        }
        if u >= 0 && u < w {
            out[y * params.out_stride + u32(u)] = color;
            landed[y * params.target_size.x + u32(u)] = 1u;
        }
        furthest = max(furthest, u);
        prev_d = d;
        prev_color = color;
    }
    // Past the last landing: the right edge beyond what the left image holds.
    fill(y, furthest + 1, w, prev_color);
}
