// The naive baseline (`render --mode original`): every original texture is an ordinary texture_2d with its own
// bind group (texture, sampler with the material's hardware wrap modes, material parameters), and every
// (leaf, original texture) pair is its own draw call. Same positions as tree.wgsl: leaf-relative vertices
// plus per-frame camera-relative leaf offsets, indexed by the vertex's leaf (global in the GPU copy).
//
// Rust twins (structs, bindings, override names and every `const` below, checked by tests/cpu/shaders.rs):
// render::wgsl::naive.

// Values of PASS (tree.wgsl's): every other pass tests the material's alpha mode.
const PASS_OPAQUE: u32 = 0u;
const PASS_MASK: u32 = 1u;
// Material.alpha_mode codes (tree.wgsl's).
const ALPHA_OPAQUE: u32 = 0u;
const ALPHA_MASK: u32 = 1u;
const ALPHA_BLEND: u32 = 2u;
// In the blend pass, fragments below it are discarded.
const BLEND_MIN_ALPHA: f32 = 0.5 / 255.0;
// In the mask pass (the depth pre-pass of a leaf's BLEND triangles, as the tree's blend nodes have), BLEND
// texels at or above it are opaque and write depth; the rest wait for the blend pass.
const OPAQUE_ALPHA: f32 = 0.998039;

override PASS: u32 = PASS_OPAQUE;

// The frame's uniform block, the same buffer as tree.wgsl's (this shader reads only view_proj).
struct Globals {
    view_proj: mat4x4<f32>,
    mode: u32,
    atlas_texels: f32,
    _p1: u32,
    _p2: u32,
}

struct Material {
    factor: vec4<f32>,
    alpha_mode: u32,
    cutoff: f32,
    _p0: u32,
    _p1: u32,
}

@group(0) @binding(0) var<uniform> globals: Globals;
@group(0) @binding(1) var<storage, read> offsets: array<vec4<f32>>;
@group(1) @binding(0) var tex: texture_2d<f32>;
@group(1) @binding(1) var tex_sampler: sampler;
@group(1) @binding(2) var<uniform> material: Material;

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
    // `leaf`: global in the GPU copy of the vertices (render::resident::tables).
    let rel = offsets[v.leaf].xyz + v.pos;
    var out: VertexOut;
    out.clip = globals.view_proj * vec4<f32>(rel, 1.0);
    out.uv = v.orig_uv;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    // The derivatives of the UV passed explicitly: identical to textureSample by definition, and the same
    // sampling path as the tree's draws (which need explicit gradients for their wrapped UVs), so the
    // reference differs from the tree only by what the tree stores (lavapipe filters implicit and explicit
    // gradients differently under anisotropy: 28–44 dB apart at 16).
    let colour = textureSampleGrad(tex, tex_sampler, in.uv, dpdx(in.uv), dpdy(in.uv)) * material.factor;
    if PASS == PASS_OPAQUE || material.alpha_mode == ALPHA_OPAQUE {
        return vec4<f32>(colour.rgb, 1.0);
    }
    if PASS == PASS_MASK && material.alpha_mode == ALPHA_BLEND {
        if colour.a < OPAQUE_ALPHA {
            discard;
        }
        return vec4<f32>(colour.rgb, 1.0);
    }
    if material.alpha_mode == ALPHA_MASK {
        if colour.a < material.cutoff {
            discard;
        }
        return vec4<f32>(colour.rgb, 1.0);
    }
    if colour.a < BLEND_MIN_ALPHA {
        discard;
    }
    return colour;
}
