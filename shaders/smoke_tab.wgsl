// Smoke test of texture-array batching (TAB): every draw record selects its per-draw data through
// `instance_index` (= the record's first_instance + instance), and that data names the texture-array layer
// the fragment samples. One bind group and one multi_draw_indexed_indirect call serve all records.

struct DrawData {
    layer: u32,      // texture-array layer of this draw
    _pad0: u32,
    _pad1: u32,
    _pad2: u32,
}

struct VertexIn {
    @builtin(instance_index) instance: u32,
    @location(0) position: vec2<f32>, // clip space
    @location(1) uv: vec2<f32>,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
    @location(1) @interpolate(flat) layer: u32,
}

@group(0) @binding(0) var<storage, read> draws: array<DrawData>;
@group(0) @binding(1) var atlas: texture_2d_array<f32>;
@group(0) @binding(2) var atlas_sampler: sampler;

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    var out: VertexOut;
    out.clip = vec4<f32>(v.position, 0.0, 1.0);
    out.uv = v.uv;
    out.layer = draws[v.instance].layer;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return textureSample(atlas, atlas_sampler, in.uv, in.layer);
}
