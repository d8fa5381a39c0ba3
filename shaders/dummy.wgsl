// The paper's dummy baseline (`render --mode dummy`, Buchholz & Döllner 2005 §7: "the same geometry drawn with
// one texture"): the tree's draws exactly as mode tree submits them (the same cut, indirect records, one
// multi_draw_indexed_indirect per pipeline, the same passes and depth pre-pass of blend nodes), but every
// fragment samples one ordinary texture at its vertex UV. No rect wrapping, no level transform, no
// texture-class selection, no alpha test: tree ÷ dummy is what the tree's texturing costs per frame.
//
// Rust twins (structs, bindings, override names and every `const` below, checked by tests/cpu/shaders.rs):
// render::wgsl::dummy.

// Values of PASS (tree.wgsl's). The pipelines of every pass set it (render::pipeline), but the dummy draws
// every pass alike: opaque colour, depth as the pass's pipeline writes it.
const PASS_OPAQUE: u32 = 0u;

override PASS: u32 = PASS_OPAQUE;

// The frame's uniform block, the same buffer as tree.wgsl's (this shader reads only view_proj).
struct Globals {
    view_proj: mat4x4<f32>,
    mode: u32,
    atlas_texels: f32,
    _p1: u32,
    _p2: u32,
}

// tree.wgsl's per-record data, the same buffer (bound, not read: the vertices carry their global leaf).
struct NodeDraw {
    atlas_layer: u32,
    atlas_array: u32,
    level: u32,
    leaf_base: u32,
    alpha_cutoff: f32,
    node: u32,
    tree: u32,
    draw_bits: u32,
}

@group(0) @binding(0) var<uniform> globals: Globals;
@group(0) @binding(1) var<storage, read> draws: array<NodeDraw>;
@group(0) @binding(2) var<storage, read> offsets: array<vec4<f32>>;
@group(0) @binding(3) var tex: texture_2d<f32>;
@group(0) @binding(4) var tex_sampler: sampler;

struct VertexIn {
    @location(0) pos: vec3<f32>,
    @location(1) orig_uv: vec2<f32>,
    @location(2) leaf: u32,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    @location(0) uv: vec2<f32>,
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    let rel = offsets[v.leaf].xyz + v.pos;
    var out: VertexOut;
    out.clip = globals.view_proj * vec4<f32>(rel, 1.0);
    out.uv = v.orig_uv;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return vec4<f32>(textureSample(tex, tex_sampler, in.uv).rgb, 1.0);
}
