// The texture-atlas tree renderer with texture-array batching (Buchholz & Döllner 2005 §4; Trapp & Döllner
// 2015). One bind group per frame, one multi_draw_indexed_indirect per pipeline: every indirect record draws
// one selected node, and its `first_instance` indexes `draws` (Rust twin: render::batch::NodeRecordGpu).
//
// Positions: vertices are relative to their leaf origin (f32); `offsets[leaf]` is `leaf.origin - eye`,
// computed per frame in f64 on the CPU, so the view-projection matrix has no translation (DESIGN.md
// "Precision").
// Atlas UVs: `uv_j = uv_leaf * 2^(j-K) + ((ix, iy) mod 2^(K-j)) * 2^(j-K)`, exactly the f32 arithmetic of
// `build::transform::atlas_uv_at_f32`.
// Originals: the per-vertex `original` indexes the leaf's range of the texture-array mapping (TAM), which
// names the class array binding (one per class size, a class past the layer limit continuing in unused
// bindings when everything is resident; lavapipe has no binding arrays, so the arrays are separate
// bindings and the shader switches), the layer, the wrap modes and the material factor.

const NONE: u32 = 0xffffffffu;

// Pipeline pass: 0 opaque, 1 alpha mask, 2 alpha blend.
override PASS: u32 = 0u;
// Texture source of the pipeline's records: 0 atlases, 1 original textures. Atlas and original draws are
// separate pipelines (render::batch::Group): software rasterisers run every texture fetch of a shader
// under an execution mask, so one shader able to sample every array would pay for all on every pixel.
override SOURCE: u32 = 0u;
// Atlas arrays in use (1..4) and the class arrays present (bit k: class 4 << k); the rest is compiled out.
override ATLAS_ARRAYS: u32 = 4u;
override CLASS_MASK: u32 = 0x3ffu;
// 1: the texel-density debug pipeline (render::density): instead of the colour, write the texels of mip 0
// per screen pixel of the sampled texture (Rgba32Float target, no blending).
override DENSITY: u32 = 0u;

struct Globals {
    view_proj: mat4x4<f32>,
    // 0 textured (tree, dummy), 1 colour by level.
    mode: u32,
    _p0: u32,
    _p1: u32,
    _p2: u32,
}

// Twin of render::batch::NodeRecordGpu (32 bytes).
struct NodeDraw {
    atlas_layer: u32,
    atlas_array: u32,
    level: u32,
    leaf_base: u32,
    alpha_cutoff: f32,
    node: u32,
    tree: u32,
    _pad: u32,
}

// Twin of render::batch::LeafGpu (16 bytes).
struct LeafInfo {
    cell: vec2<u32>,
    level: u32,
    first_tam: u32,
}

// Twin of render::batch::TamEntry (48 bytes).
struct TamEntry {
    class_index: u32,
    layer: u32,
    wrap: u32,
    alpha_mode: u32,
    factor: vec4<f32>,
    cutoff: f32,
    class_size: f32,
    _p0: u32,
    _p1: u32,
}

@group(0) @binding(0) var<uniform> globals: Globals;
@group(0) @binding(1) var<storage, read> draws: array<NodeDraw>;
@group(0) @binding(2) var<storage, read> leaves: array<LeafInfo>;
@group(0) @binding(3) var<storage, read> offsets: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> tam: array<TamEntry>;
@group(0) @binding(5) var atlas_sampler: sampler;
@group(0) @binding(6) var original_sampler: sampler;
@group(0) @binding(7) var atlas0: texture_2d_array<f32>;
@group(0) @binding(8) var atlas1: texture_2d_array<f32>;
@group(0) @binding(9) var atlas2: texture_2d_array<f32>;
@group(0) @binding(10) var atlas3: texture_2d_array<f32>;
@group(0) @binding(11) var class0: texture_2d_array<f32>;
@group(0) @binding(12) var class1: texture_2d_array<f32>;
@group(0) @binding(13) var class2: texture_2d_array<f32>;
@group(0) @binding(14) var class3: texture_2d_array<f32>;
@group(0) @binding(15) var class4: texture_2d_array<f32>;
@group(0) @binding(16) var class5: texture_2d_array<f32>;
@group(0) @binding(17) var class6: texture_2d_array<f32>;
@group(0) @binding(18) var class7: texture_2d_array<f32>;
@group(0) @binding(19) var class8: texture_2d_array<f32>;
@group(0) @binding(20) var class9: texture_2d_array<f32>;

struct VertexIn {
    @builtin(instance_index) instance: u32,
    @location(0) pos: vec3<f32>,
    @location(1) atlas_uv: vec2<f32>,
    @location(2) orig_uv: vec2<f32>,
    @location(3) leaf: u32,
    @location(4) original: u32,
}

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    // Atlas UV at the node's level, or the original UV.
    @location(0) uv: vec2<f32>,
    // Atlas layer, or NONE for an original-texture draw.
    @location(1) @interpolate(flat) layer: u32,
    // Atlas array (atlas draw) or TAM index (original draw).
    @location(2) @interpolate(flat) which: u32,
    @location(3) @interpolate(flat) level: u32,
    @location(4) @interpolate(flat) cutoff: f32,
}

// 2^-d for 0 <= d <= 31, exactly (built from the exponent bits).
fn exp2_neg(d: u32) -> f32 {
    return bitcast<f32>((127u - d) << 23u);
}

// build::transform::atlas_uv_at_f32: the leaf-local UV in the atlas of the ancestor at `level`.
fn atlas_uv_at(uv_leaf: vec2<f32>, cell: vec2<u32>, leaf_level: u32, level: u32) -> vec2<f32> {
    let d = min(leaf_level - min(level, leaf_level), 31u);
    let mask = (1u << d) - 1u;
    let o = vec2<f32>(f32(cell.x & mask), f32(cell.y & mask));
    let s = exp2_neg(d);
    return uv_leaf * s + o * s;
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    let d = draws[v.instance];
    let li = d.leaf_base + v.leaf;
    let leaf = leaves[li];
    let rel = offsets[li].xyz + v.pos;
    var out: VertexOut;
    out.clip = globals.view_proj * vec4<f32>(rel, 1.0);
    out.layer = d.atlas_layer;
    out.level = d.level;
    out.cutoff = d.alpha_cutoff;
    if d.atlas_layer != NONE {
        out.uv = atlas_uv_at(v.atlas_uv, leaf.cell, leaf.level, d.level);
        out.which = d.atlas_array;
    } else {
        out.uv = v.orig_uv;
        out.which = leaf.first_tam + v.original;
        out.level = 255u;
    }
    return out;
}

fn sample_atlas(array: u32, uv: vec2<f32>, layer: u32, ddx: vec2<f32>, ddy: vec2<f32>) -> vec4<f32> {
    var c = textureSampleGrad(atlas0, atlas_sampler, uv, layer, ddx, ddy);
    if ATLAS_ARRAYS > 1u && array == 1u {
        c = textureSampleGrad(atlas1, atlas_sampler, uv, layer, ddx, ddy);
    }
    if ATLAS_ARRAYS > 2u && array == 2u {
        c = textureSampleGrad(atlas2, atlas_sampler, uv, layer, ddx, ddy);
    }
    if ATLAS_ARRAYS > 3u && array == 3u {
        c = textureSampleGrad(atlas3, atlas_sampler, uv, layer, ddx, ddy);
    }
    return c;
}

// Bit k of CLASS_MASK is set and the entry's class is k.
fn is_class(class_index: u32, k: u32) -> bool {
    return (CLASS_MASK & (1u << k)) != 0u && class_index == k;
}

fn sample_class(class_index: u32, uv: vec2<f32>, layer: u32, ddx: vec2<f32>, ddy: vec2<f32>) -> vec4<f32> {
    let s = original_sampler;
    var c = vec4<f32>(0.0);
    if is_class(class_index, 0u) { c = textureSampleGrad(class0, s, uv, layer, ddx, ddy); }
    if is_class(class_index, 1u) { c = textureSampleGrad(class1, s, uv, layer, ddx, ddy); }
    if is_class(class_index, 2u) { c = textureSampleGrad(class2, s, uv, layer, ddx, ddy); }
    if is_class(class_index, 3u) { c = textureSampleGrad(class3, s, uv, layer, ddx, ddy); }
    if is_class(class_index, 4u) { c = textureSampleGrad(class4, s, uv, layer, ddx, ddy); }
    if is_class(class_index, 5u) { c = textureSampleGrad(class5, s, uv, layer, ddx, ddy); }
    if is_class(class_index, 6u) { c = textureSampleGrad(class6, s, uv, layer, ddx, ddy); }
    if is_class(class_index, 7u) { c = textureSampleGrad(class7, s, uv, layer, ddx, ddy); }
    if is_class(class_index, 8u) { c = textureSampleGrad(class8, s, uv, layer, ddx, ddy); }
    if is_class(class_index, 9u) { c = textureSampleGrad(class9, s, uv, layer, ddx, ddy); }
    return c;
}

// One axis of a wrap mode, into [0, 1] for a sampler that repeats. Repeat: fract (the repeating sampler
// filters across the seam). Mirror and clamp: additionally kept half a texel (of mip 0) inside the edge,
// so the repeating sampler does not blend in the opposite edge there; that is exactly what mirror and
// clamp filtering give at mip 0 (coarser mips blend at most half a texel of the opposite edge).
fn wrap_axis(u: f32, mode: u32, size: f32) -> f32 {
    let h = 0.5 / size;
    if mode == 1u {
        let t = fract(u * 0.5) * 2.0;
        let m = select(t, 2.0 - t, t > 1.0);
        return clamp(m, h, 1.0 - h);
    }
    if mode == 2u {
        return clamp(u, h, 1.0 - h);
    }
    return fract(u);
}

fn level_colour(level: u32) -> vec3<f32> {
    var palette = array<vec3<f32>, 8>(
        vec3<f32>(0.90, 0.10, 0.10),
        vec3<f32>(0.10, 0.75, 0.10),
        vec3<f32>(0.10, 0.20, 0.95),
        vec3<f32>(0.95, 0.85, 0.10),
        vec3<f32>(0.85, 0.10, 0.85),
        vec3<f32>(0.10, 0.85, 0.85),
        vec3<f32>(0.95, 0.50, 0.05),
        vec3<f32>(0.50, 0.30, 0.90),
    );
    if level == 255u {
        return vec3<f32>(1.0, 1.0, 1.0);
    }
    return palette[level % 8u];
}

// Size in texels of mip 0 of the texture an atlas draw samples (array `array`).
fn atlas_size(array: u32) -> f32 {
    var d = textureDimensions(atlas0).x;
    if ATLAS_ARRAYS > 1u && array == 1u { d = textureDimensions(atlas1).x; }
    if ATLAS_ARRAYS > 2u && array == 2u { d = textureDimensions(atlas2).x; }
    if ATLAS_ARRAYS > 3u && array == 3u { d = textureDimensions(atlas3).x; }
    return f32(d);
}

// Texel density of one pixel: the singular values of the Jacobian d(texel)/d(pixel) of mip 0 of the
// sampled texture (`ddx`, `ddy`: UV derivatives; `size`: texels per unit UV). x: the smaller singular
// value = texels per pixel along the least-sampled screen direction (< 1: magnified); y: the larger.
fn singular_values(ddx: vec2<f32>, ddy: vec2<f32>, size: f32) -> vec2<f32> {
    let a = ddx * size;
    let b = ddy * size;
    let e = dot(a, a) + dot(b, b);
    let det = abs(a.x * b.y - a.y * b.x);
    let r = sqrt(max(e * e - 4.0 * det * det, 0.0));
    return vec2<f32>(sqrt(max(0.5 * (e - r), 0.0)), sqrt(0.5 * (e + r)));
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    // Gradients of the unwrapped UV, taken in uniform control flow: mip selection stays right across
    // wrap seams and inside the switches below.
    let ddx = dpdx(in.uv);
    let ddy = dpdy(in.uv);
    if globals.mode == 1u {
        return vec4<f32>(level_colour(in.level), 1.0);
    }
    let colour = shade(in, ddx, ddy);
    if DENSITY == 1u {
        // (texels/pixel min, max, source 0 atlas / 1 original, level; 255 for originals).
        var size = 0.0;
        if SOURCE == 0u {
            size = atlas_size(in.which);
        } else {
            size = tam[in.which].class_size;
        }
        let sv = singular_values(ddx, ddy, size);
        return vec4<f32>(sv.x, sv.y, f32(SOURCE), f32(in.level));
    }
    return colour;
}

// The colour of a textured fragment (tree and dummy modes), or discard (alpha mask and blend).
fn shade(in: VertexOut, ddx: vec2<f32>, ddy: vec2<f32>) -> vec4<f32> {
    var colour: vec4<f32>;
    var cutoff = in.cutoff;
    var alpha_mode = 2u;
    if SOURCE == 0u && ATLAS_ARRAYS == 1u {
        // Uniform control flow: implicit derivatives (per quad; explicit gradients cost a per-pixel LOD on
        // software rasterisers).
        colour = textureSample(atlas0, atlas_sampler, in.uv, in.layer);
    } else if SOURCE == 0u {
        colour = sample_atlas(in.which, in.uv, in.layer, ddx, ddy);
    } else {
        let e = tam[in.which];
        let wrapped = vec2<f32>(
            wrap_axis(in.uv.x, e.wrap & 3u, e.class_size),
            wrap_axis(in.uv.y, (e.wrap >> 2u) & 3u, e.class_size),
        );
        colour = sample_class(e.class_index, wrapped, e.layer, ddx, ddy) * e.factor;
        cutoff = e.cutoff;
        alpha_mode = e.alpha_mode;
    }
    if PASS == 0u {
        return vec4<f32>(colour.rgb, 1.0);
    }
    if PASS == 1u || alpha_mode == 1u {
        if colour.a < cutoff {
            discard;
        }
        return vec4<f32>(colour.rgb, 1.0);
    }
    if alpha_mode == 0u {
        return vec4<f32>(colour.rgb, 1.0);
    }
    if colour.a < 0.5 / 255.0 {
        discard;
    }
    return colour;
}
