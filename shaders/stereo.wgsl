// dmu-render: the multiview entry point of stereo pairs, appended to mesh.wgsl
// in a module of its own, made only on devices with multiview (a module that
// names `view_index` does not validate without it).
//
// Each layer of the 2-layer target is one eye: the view index picks that eye's
// model-view, formed in f64 on the CPU relative to that eye exactly as a
// single-eye render forms it, so a layer equals the single-eye image. The
// left eye's comes with the instance, the right eye's from a second
// instance buffer.

// The right eye's model-view of a chunk draw.
struct RightEye {
    @location(11) r0: vec4<f32>,
    @location(12) r1: vec4<f32>,
    @location(13) r2: vec4<f32>,
}

@vertex
fn vs_mesh_stereo(
    @location(0) position: vec3<f32>,
    @location(1) normal: vec4<f32>,
    instance: Instance,
    right: RightEye,
    @builtin(view_index) eye: u32,
) -> MeshOut {
    var m = ModelView(instance.r0, instance.r1, instance.r2);
    if eye == 1u {
        m = ModelView(right.r0, right.r1, right.r2);
    }
    return mesh_vertex(position, normal, m, instance, eye);
}

// The multiview probe: the same triangle in both views, cut by the near plane
// (its third vertex has depth 2 > w), coloured by view. A driver that clips
// multiview primitives correctly draws it into each layer in that view's
// colour; Mesa 22.3's lavapipe draws view 1's clipped triangle into layer 0.
struct ProbeOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) @interpolate(flat) eye: u32,
}

@vertex
fn vs_probe(@builtin(vertex_index) vertex: u32, @builtin(view_index) eye: u32) -> ProbeOut {
    let corners = array<vec4<f32>, 3>(
        vec4<f32>(-1.0, -1.0, 0.5, 1.0),
        vec4<f32>(3.0, -1.0, 0.5, 1.0),
        vec4<f32>(-1.0, 3.0, 2.0, 1.0),
    );
    return ProbeOut(corners[vertex], eye);
}

@fragment
fn fs_probe(in: ProbeOut) -> @location(0) vec4<f32> {
    return vec4<f32>(1.0, f32(in.eye), 0.0, 1.0);
}
