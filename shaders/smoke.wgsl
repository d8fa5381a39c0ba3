// Smoke test: one triangle with per-vertex colours, drawn into an offscreen RGBA8 target.
// Used by tests/gpu/smoke.rs to prove that the pipeline, rasterisation and readback work on this machine.

struct VertexIn {
    @location(0) position: vec2<f32>, // clip space, z = 0, w = 1
    @location(1) color: vec4<f32>,    // linear RGBA in [0, 1], written unchanged to a Unorm target
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) color: vec4<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = vec4<f32>(v.position, 0.0, 1.0);
    out.color = v.color;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return in.color;
}
