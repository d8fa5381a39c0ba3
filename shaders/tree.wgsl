// The texture-atlas tree renderer with texture-array batching (Buchholz & Döllner 2005 §4; Trapp & Döllner
// 2015). One bind group per frame, one multi_draw_indexed_indirect per pipeline: every indirect record draws
// one selected node, and its `first_instance` indexes `draws`.
//
// Rust twins (structs, bindings, override names and every `const` below, checked by tests/cpu/shaders.rs):
// render::wgsl::tree.
//
// Positions: vertices are relative to their leaf origin (f32); `offsets[leaf]` is `leaf.origin - eye`
// (`leaf`: the vertex's leaf, numbered across trees in the GPU copy, render::resident::tables),
// computed per frame in f64 on the CPU, so the view-projection matrix has no translation (docs/DESIGN.md
// "Precision").
// Atlas UVs (docs/DESIGN.md "Repeats" and "Precision"): per fragment the original UV is wrapped into its rect of
// the leaf atlas (`rect_texel`, twin of render::wgsl::tree::RectMap::texel_f32: repeat, mirror or clamp per
// axis, then onto the inner rectangle, kept a filter footprint inside the outer one), then taken to the atlas
// of the drawn level j: `uv_j = uv_leaf * 2^(j-K) + ((ix, iy) mod 2^(K-j)) * 2^(j-K)`, exactly the f32
// arithmetic of `model::transform::atlas_uv_at_f32`. Sampling uses the gradients of the unwrapped UV
// carried through the same maps (`textureSampleGrad`), so mip selection and anisotropy are continuous
// across seams.
// Originals: the per-vertex `original` is an entry of the leaf's range of the texture-array mapping (TAM;
// the GPU copy of the vertices holds it as a global index, as `rect` and `leaf`), which
// names the class array binding (one per class size, a class past the layer limit continuing in unused
// bindings when everything is resident; lavapipe has no binding arrays, so the arrays are separate
// bindings and the shader switches), the layer, the wrap modes and the material factor.

// Values of PASS (render::batch::Pass).
const PASS_OPAQUE: u32 = 0u;
const PASS_MASK: u32 = 1u;
const PASS_BLEND: u32 = 2u;
// Values of SOURCE.
const SOURCE_ATLAS: u32 = 0u;
const SOURCE_ORIGINAL: u32 = 1u;
// Values of DENSITY.
const DENSITY_OFF: u32 = 0u;
const DENSITY_ON: u32 = 1u;
// Values of Globals.mode.
const MODE_TEXTURED: u32 = 0u;
const MODE_LEVELS: u32 = 1u;
// Atlas array bindings (atlas0..) and class array bindings (class0.., class 4 << k).
const MAX_ATLAS_ARRAYS: u32 = 4u;
const CLASS_COUNT: u32 = 10u;
// The level of an original-texture draw (white in the level colouring; the density target's alpha).
const LEVEL_ORIGINAL: u32 = 255u;
// VertexOut.draw.x: atlas layer | atlas array << ARRAY_SHIFT | level << LEVEL_SHIFT | (leaf level − level)
// << DEPTH_SHIFT; the layer below MAX_LAYERS, the level below 256, the depth below 32.
const MAX_LAYERS: u32 = 65536u;
const ARRAY_SHIFT: u32 = 16u;
const LEVEL_SHIFT: u32 = 18u;
const DEPTH_SHIFT: u32 = 26u;
// LeafInfo.cell_level: level, cell.x and cell.y packed (CELL_MASK wide) up to PACKED_LEVELS deep.
const LEVEL_MASK: u32 = 31u;
const CELL_X_SHIFT: u32 = 5u;
const CELL_Y_SHIFT: u32 = 18u;
const CELL_MASK: u32 = 0x1fffu;
const PACKED_LEVELS: u32 = 13u;
const CELL_LEVEL_WIDE: u32 = 0xffffffffu;

// Packed codes (RectMap.wrap, TamEntry.wrap): wrap_s | wrap_t << WRAP_T_SHIFT, and for rects
// | alpha_mode << ALPHA_SHIFT; every code CODE_MASK wide.
const WRAP_T_SHIFT: u32 = 2u;
const ALPHA_SHIFT: u32 = 4u;
const CODE_MASK: u32 = 3u;
// TamEntry wrap codes per axis (the paging file's).
const WRAP_REPEAT: u32 = 0u;
const WRAP_MIRROR: u32 = 1u;
const WRAP_CLAMP: u32 = 2u;
// RectMap wrap codes per axis (model::RectWrap codes): linear (baked), repeat, mirror, clamp.
const RECT_WRAP_LINEAR: u32 = 0u;
const RECT_WRAP_REPEAT: u32 = 1u;
const RECT_WRAP_MIRROR: u32 = 2u;
const RECT_WRAP_CLAMP: u32 = 3u;
// Alpha modes of a material (TamEntry.alpha_mode, RectMap.wrap >> ALPHA_SHIFT; the paging file's).
const ALPHA_OPAQUE: u32 = 0u;
const ALPHA_MASK: u32 = 1u;
const ALPHA_BLEND: u32 = 2u;

// Pipeline pass: PASS_OPAQUE, PASS_MASK or PASS_BLEND.
override PASS: u32 = PASS_OPAQUE;
// Texture source of the pipeline's records: SOURCE_ATLAS or SOURCE_ORIGINAL. Atlas and original draws are
// separate pipelines (render::batch::Group): software rasterisers run every texture fetch of a shader
// under an execution mask, so one shader able to sample every array would pay for all on every pixel.
override SOURCE: u32 = SOURCE_ATLAS;
// The one atlas array (< MAX_ATLAS_ARRAYS) an atlas pipeline's records sample: records are grouped by
// array too (render::batch::Group), so an atlas fragment runs one texture fetch (lavapipe runs every fetch
// of a shader under an execution mask: a chain over two arrays cost 15–25 % of cornfield_crossing's tree
// frame along the whole path). The class arrays present (bit k: class 4 << k); the rest is compiled out.
override ATLAS_ARRAY: u32 = 0u;
override CLASS_MASK: u32 = (1u << CLASS_COUNT) - 1u;
// DENSITY_ON: the texel-density debug pipeline (render::density): instead of the colour, write the texels
// of mip 0 per screen pixel of the sampled texture (Rgba32Float target, no blending).
override DENSITY: u32 = DENSITY_OFF;

struct Globals {
    view_proj: mat4x4<f32>,
    // MODE_TEXTURED (tree, dummy) or MODE_LEVELS (colour by level).
    mode: u32,
    // Side of every atlas, texels.
    atlas_texels: f32,
    _p1: u32,
    _p2: u32,
}

// One per indirect record (32 bytes).
struct NodeDraw {
    atlas_layer: u32,
    atlas_array: u32,
    level: u32,
    leaf_base: u32,
    alpha_cutoff: f32,
    node: u32,
    tree: u32,
    // atlas_layer | atlas_array << ARRAY_SHIFT | level << LEVEL_SHIFT of an atlas draw (0 for originals):
    // what the vertex stage reads (each 32-bit storage load a vertex costs on a software rasteriser).
    draw_bits: u32,
}

// One per leaf (32 bytes).
struct LeafInfo {
    cell: vec2<u32>,
    level: u32,
    first_tam: u32,
    first_rect: u32,
    // level | cell.x << CELL_X_SHIFT | cell.y << CELL_Y_SHIFT for leaves at most PACKED_LEVELS deep, else
    // CELL_LEVEL_WIDE (then read cell and level): one load a vertex instead of three.
    cell_level: u32,
    _p1: u32,
    _p2: u32,
}

// One per (leaf, rect) (72 bytes), leaf-atlas texels.
struct RectMap {
    uv_min: vec2<f32>,
    texels_per_uv: vec2<f32>,
    inner_lo: vec2<f32>,
    half_gap: vec2<f32>,
    outer_lo: vec2<f32>,
    outer_hi: vec2<f32>,
    // wrap_s | wrap_t << WRAP_T_SHIFT (RECT_WRAP_* codes) | alpha_mode << ALPHA_SHIFT (the material's
    // ALPHA_* code).
    wrap: u32,
    cutoff: f32,
    inner_size: vec2<f32>,
    // The inner rectangle's mean colour, sRGB8 straight alpha packed as unpack4x8unorm reads it: what a
    // fragment covering a whole period shows (rect_mean).
    mean: u32,
    // 1 for a point rect (one UV, one inner texel: a palette cell's): its mean at any footprint.
    point: u32,
}

// One per (leaf, original texture) (48 bytes).
struct TamEntry {
    class_index: u32,
    layer: u32,
    // wrap_s | wrap_t << WRAP_T_SHIFT (WRAP_* codes).
    wrap: u32,
    alpha_mode: u32,
    factor: vec4<f32>,
    cutoff: f32,
    class_size: f32,
    // Stored sides of the texture, texels (each <= class_size): the layer holds it tiled (texfmt::rect),
    // so the wrapped UV is scaled by extent / class_size.
    extent: vec2<f32>,
}

@group(0) @binding(0) var<uniform> globals: Globals;
@group(0) @binding(1) var<storage, read> draws: array<NodeDraw>;
@group(0) @binding(2) var<storage, read> leaves: array<LeafInfo>;
@group(0) @binding(3) var<storage, read> offsets: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> tam: array<TamEntry>;
@group(0) @binding(5) var<storage, read> rects: array<RectMap>;
@group(0) @binding(6) var atlas_sampler: sampler;
@group(0) @binding(7) var original_sampler: sampler;
@group(0) @binding(8) var atlas0: texture_2d_array<f32>;
@group(0) @binding(9) var atlas1: texture_2d_array<f32>;
@group(0) @binding(10) var atlas2: texture_2d_array<f32>;
@group(0) @binding(11) var atlas3: texture_2d_array<f32>;
@group(0) @binding(12) var class0: texture_2d_array<f32>;
@group(0) @binding(13) var class1: texture_2d_array<f32>;
@group(0) @binding(14) var class2: texture_2d_array<f32>;
@group(0) @binding(15) var class3: texture_2d_array<f32>;
@group(0) @binding(16) var class4: texture_2d_array<f32>;
@group(0) @binding(17) var class5: texture_2d_array<f32>;
@group(0) @binding(18) var class6: texture_2d_array<f32>;
@group(0) @binding(19) var class7: texture_2d_array<f32>;
@group(0) @binding(20) var class8: texture_2d_array<f32>;
@group(0) @binding(21) var class9: texture_2d_array<f32>;

struct VertexIn {
    @builtin(instance_index) instance: u32,
    @location(0) pos: vec3<f32>,
    @location(1) orig_uv: vec2<f32>,
    // Global in the GPU copy of the vertices (render::resident::tables adds the bases): the vertex's leaf
    // in `leaves` and `offsets`, its TAM entry in `tam`, its rect in `rects`.
    @location(2) leaf: u32,
    @location(3) original: u32,
    @location(4) rect: u32,
}

// Two locations: a software rasteriser (lavapipe) sets up every location of every triangle, and with
// millions of triangles smaller than a pixel that setup, not the fragments, is most of a frame (each
// further location cost 5–6 % of the all-tracks world's tree frame; docs/DESIGN.md "Interpolants").
struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    // The original UV (unbounded; atlas draws wrap it into the rect per fragment).
    @location(0) uv: vec2<f32>,
    // x: the draw (atlas layer, atlas array, level, leaf level − level; see DEPTH_SHIFT); y: the rect
    // (atlas draw, global index) or TAM entry (original draw); zw: the leaf's cell modulo
    // 2^(leaf level − level), the offset of the level transform (atlas draws).
    @location(1) @interpolate(flat) draw: vec4<u32>,
}

// The fields of VertexOut.draw.x.
fn draw_layer(in: VertexOut) -> u32 {
    return in.draw.x & (MAX_LAYERS - 1u);
}
fn draw_level(in: VertexOut) -> u32 {
    return (in.draw.x >> LEVEL_SHIFT) & 255u;
}

// 2^-d for 0 <= d <= 31, exactly (built from the exponent bits).
fn exp2_neg(d: u32) -> f32 {
    return bitcast<f32>((127u - d) << 23u);
}

// The levels between a leaf and the ancestor at `level` drawn for it (at most 31).
fn level_depth(leaf_level: u32, level: u32) -> u32 {
    return min(leaf_level - min(level, leaf_level), 31u);
}

// The leaf's cell modulo 2^depth: which cell of the ancestor's atlas the leaf's atlas is.
fn cell_offset(cell: vec2<u32>, depth: u32) -> vec2<u32> {
    let mask = (1u << depth) - 1u;
    return cell & vec2<u32>(mask);
}

// VertexOut.draw of an atlas draw: `bits` = NodeDraw.draw_bits (layer, array and drawn level), for a leaf
// at `leaf_level` in `cell`, the fragment's rect `rect` (global index).
fn atlas_draw(bits: u32, leaf_level: u32, cell: vec2<u32>, rect: u32) -> vec4<u32> {
    let depth = level_depth(leaf_level, (bits >> LEVEL_SHIFT) & 255u);
    return vec4<u32>(bits | depth << DEPTH_SHIFT, rect, cell_offset(cell, depth));
}

// The level transform of model::transform::atlas_uv_at_f32 as (2^(j-K), offset), from a draw's
// VertexOut.draw: the leaf-local UV in the atlas of the ancestor at the drawn level is
// `uv_leaf * x + offset` (both factors exact).
fn level_transform(in: VertexOut) -> vec3<f32> {
    let s = exp2_neg(in.draw.x >> DEPTH_SHIFT);
    let o = vec2<f32>(f32(in.draw.z), f32(in.draw.w));
    return vec3<f32>(s, o * s);
}

// One axis of RectMap::axis_f32: (the rect coordinate of u, the sign of its derivative).
fn rect_axis(u: f32, mode: u32, uv_min: f32, half_gap: f32) -> vec2<f32> {
    if mode == RECT_WRAP_REPEAT {
        let x = u - uv_min;
        return vec2<f32>(x - floor(x + half_gap), 1.0);
    }
    if mode == RECT_WRAP_MIRROR {
        let p = u - 2.0 * floor(u * 0.5);
        if p > 1.0 {
            return vec2<f32>(2.0 - p - uv_min, -1.0);
        }
        return vec2<f32>(p - uv_min, 1.0);
    }
    if mode == RECT_WRAP_CLAMP {
        return vec2<f32>(clamp(u, 0.0, 1.0) - uv_min, 1.0);
    }
    return vec2<f32>(u - uv_min, 1.0);
}

struct RectSample {
    // Leaf-atlas texel coordinates.
    texel: vec2<f32>,
    // Their screen derivatives.
    gx: vec2<f32>,
    gy: vec2<f32>,
    // The footprint covers the period: the fragment shows the rect's mean (rect_mean), not a sample.
    flat: bool,
    // Otherwise, how much of the rect's mean is mixed into the sample (MEAN_MIX_FROM of a period on).
    mix_mean: f32,
}

// See render::wgsl::tree::CELLS, FLAT_SHARE, SHARPEN_MIN, POINT_REACH and REACH_SAFETY.
const CELLS: f32 = 2.0;
const FLAT_SHARE: f32 = 1.0;
const SHARPEN_MIN: f32 = 0.25;
const POINT_REACH: f32 = 1.5;
const REACH_SAFETY: f32 = 0.99;
// RectSampleF32::mix_mean.
const MEAN_MIX_FROM: f32 = 0.5;

// RectMap::mean_linear: the rect's mean as a texture sample gives it, linear colour and straight alpha.
fn rect_mean(packed: u32) -> vec4<f32> {
    let c = unpack4x8unorm(packed);
    let low = c.rgb / 12.92;
    let high = pow((c.rgb + vec3<f32>(0.055)) / 1.055, vec3<f32>(2.4));
    return vec4<f32>(select(high, low, c.rgb <= vec3<f32>(0.04045)), c.a);
}

// RectMap::footprint_cap: the largest footprint (leaf texels) whose filter stays within `room` leaf texels
// of the sample. The sampler is isotropic trilinear: the longer gradient sets its mip along both axes, and
// at lod > 0 its bilinear taps on the coarser of the two mips it blends (2^(floor(lod)+1) drawn texels of
// `level_texels` leaf texels, box-filtered blocks not aligned to the rect) read up to 1.5 of its texels
// either side; at lod <= 0 it reads half a drawn texel. REACH_SAFETY keeps the lod off the power of two.
fn footprint_cap(room: f32, level_texels: f32) -> f32 {
    if room < 0.5 * level_texels {
        return 0.0;
    }
    let m = max(floor(log2(max(room / (1.5 * level_texels), 1.0))), 0.0);
    return level_texels * exp2(m) * REACH_SAFETY;
}

// RectMap::texel_f32: the fragment's texel in its leaf's atlas. The gradients are sharpened by k <= 1 so
// that the sampler's filter (footprint_cap) stays inside the outer rectangle around the sample: a footprint
// of more than FLAT_SHARE of the inner rectangle along both axes, or k < SHARPEN_MIN, covers (about) a
// period: it shows the period's mean (`flat`; its texel and gradients, the rect's centre on the mip where
// the inner rectangle is CELLS texels wide, are the twin's); one covered axis alone is sampled at its
// centre, the other keeps its detail.
fn rect_texel(r: RectMap, uv: vec2<f32>, ddx: vec2<f32>, ddy: vec2<f32>, level_texels: f32) -> RectSample {
    let s = rect_axis(uv.x, r.wrap & CODE_MASK, r.uv_min.x, r.half_gap.x);
    let t = rect_axis(uv.y, (r.wrap >> WRAP_T_SHIFT) & CODE_MASK, r.uv_min.y, r.half_gap.y);
    let tpu = r.texels_per_uv * vec2<f32>(s.y, t.y);
    var out: RectSample;
    out.gx = ddx * tpu;
    out.gy = ddy * tpu;
    let period = min(r.inner_size.x, r.inner_size.y);
    let footprint = max(length(out.gx), length(out.gy));
    let centre = r.inner_lo + 0.5 * r.inner_size;
    // An axis the footprint covers (an elongated rect's short one) is averaged: sampled at its centre.
    let covered = vec2<f32>(footprint) > r.inner_size * FLAT_SHARE;
    let lo = r.outer_lo + vec2<f32>(0.5 * level_texels);
    let hi = r.outer_hi - vec2<f32>(0.5 * level_texels);
    let p = clamp(r.inner_lo + vec2<f32>(s.x, t.x) * r.texels_per_uv, lo, max(lo, hi));
    let q = select(p, centre, covered | (lo > hi));
    // The filter is isotropic: the nearer outer edge, along either axis, bounds it.
    let d = min(q - r.outer_lo, r.outer_hi - q);
    let cap = footprint_cap(min(d.x, d.y), level_texels);
    // A constant UV (zero footprint) reaches past nothing; nearer the outer edge than the drawn level's
    // bilinear taps reach (1.5 of its texels: a palette cell's rect on a coarse level), it shows the mean.
    let k = select(min(1.0, cap / footprint), 1.0, footprint == 0.0);
    let point_mixed = footprint == 0.0 && min(d.x, d.y) < POINT_REACH * level_texels;
    // A point rect (one UV, one inner texel: a palette cell's) has one colour, its mean: shown whatever
    // the gradients (a constant UV's interpolation jitters them off zero by an ulp).
    if all(covered) || k < SHARPEN_MIN || point_mixed || r.point != 0u {
        let kk = select(period / CELLS / footprint, 0.0, footprint == 0.0);
        out.gx = out.gx * kk;
        out.gy = out.gy * kk;
        out.texel = centre;
        out.flat = true;
        out.mix_mean = 1.0;
        return out;
    }
    out.gx = out.gx * k;
    out.gy = out.gy * k;
    out.texel = q;
    out.flat = false;
    out.mix_mean = smoothstep(MEAN_MIX_FROM, 1.0, footprint / max(r.inner_size.x, r.inner_size.y));
    return out;
}

@vertex
fn vs_main(v: VertexIn) -> VertexOut {
    // Only the fields this pipeline's source uses are loaded (SOURCE is the records' source: atlas and
    // original records are separate pipelines); on lavapipe each 32-bit storage load a vertex cost ~4 % of
    // the all-tracks world's tree frame.
    let li = v.leaf;
    let rel = offsets[li].xyz + v.pos;
    var out: VertexOut;
    out.clip = globals.view_proj * vec4<f32>(rel, 1.0);
    out.uv = v.orig_uv;
    if SOURCE == SOURCE_ATLAS {
        let packed = leaves[li].cell_level;
        var level = packed & LEVEL_MASK;
        var cell = vec2<u32>((packed >> CELL_X_SHIFT) & CELL_MASK, (packed >> CELL_Y_SHIFT) & CELL_MASK);
        if packed == CELL_LEVEL_WIDE {
            level = leaves[li].level;
            cell = leaves[li].cell;
        }
        out.draw = atlas_draw(draws[v.instance].draw_bits, level, cell, v.rect);
    } else {
        out.draw = vec4<u32>(LEVEL_ORIGINAL << LEVEL_SHIFT, v.original, 0u, 0u);
    }
    // A blend node's MASK triangles were drawn by its depth pre-pass (the mask pipeline, which writes
    // depth); drawn again here each of their fragments would fail the Greater test against the equal or
    // nearer depth already stored, or be discarded below the cutoff as it was there. The blend pass's
    // records draw the tree's blend list, which leaves them out (render::batch::blend_list); any that
    // reach this pass anyway are dropped before rasterisation: every vertex of such a triangle (a
    // triangle's vertices share their material) goes to one point outside the clip volume.
    if PASS == PASS_BLEND && DENSITY == DENSITY_OFF {
        var alpha_mode: u32;
        if SOURCE == SOURCE_ATLAS {
            alpha_mode = (rects[out.draw.y].wrap >> ALPHA_SHIFT) & CODE_MASK;
        } else {
            alpha_mode = tam[out.draw.y].alpha_mode;
        }
        if alpha_mode == ALPHA_MASK {
            out.clip = vec4<f32>(2.0, 2.0, 2.0, 1.0);
        }
    }
    return out;
}

// The pipeline's atlas array (ATLAS_ARRAY, a constant: one fetch is compiled in).
fn sample_atlas(uv: vec2<f32>, layer: u32, ddx: vec2<f32>, ddy: vec2<f32>) -> vec4<f32> {
    if ATLAS_ARRAY == 1u {
        return textureSampleGrad(atlas1, atlas_sampler, uv, layer, ddx, ddy);
    }
    if ATLAS_ARRAY == 2u {
        return textureSampleGrad(atlas2, atlas_sampler, uv, layer, ddx, ddy);
    }
    if ATLAS_ARRAY == 3u {
        return textureSampleGrad(atlas3, atlas_sampler, uv, layer, ddx, ddy);
    }
    return textureSampleGrad(atlas0, atlas_sampler, uv, layer, ddx, ddy);
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
// filters across the seam). Mirror and clamp: additionally kept `inset` (in UV) inside the edge, so the
// repeating sampler does not blend in the opposite edge there ([`edge_inset`]: half a texel of the
// mip level the trilinear filter reads most).
fn wrap_axis(u: f32, mode: u32, inset: f32) -> f32 {
    if mode == WRAP_MIRROR {
        let t = fract(u * 0.5) * 2.0;
        let m = select(t, 2.0 - t, t > 1.0);
        return clamp(m, inset, 1.0 - inset);
    }
    if mode == WRAP_CLAMP {
        return clamp(u, inset, 1.0 - inset);
    }
    return fract(u);
}

// Per axis, half a texel (in UV of a texture of `extent` texels) of the mip level a trilinear sample
// with UV derivatives `ddx`, `ddy` reads most: level round(log2 ρ) for ρ the footprint's longer side in
// texels (the isotropic level; an anisotropic sample reads a level no coarser). The coarser of the two
// levels (⌈log2 ρ⌉) kept the opposite edge out at coarse mips but put the finer level's sample a whole
// texel inside, so just above one texel per pixel a clamped band showed the edge texel's neighbour, not
// the edge (10.5 dB against original mode's hardware clamp; 41 dB now; fault hunt, session 36). At most
// 0.5: a texel wider than the texture is its average, read at the centre, as clamp and mirror give there.
fn edge_inset(ddx: vec2<f32>, ddy: vec2<f32>, extent: vec2<f32>) -> vec2<f32> {
    let r = max(length(ddx * extent), length(ddy * extent));
    // NaN derivatives (a degenerate triangle) read as one texel: the inset stays finite.
    let rho = select(1.0, r, r == r);
    let texel = exp2(round(log2(max(rho, 1.0))));
    return min(vec2<f32>(0.5 * texel) / extent, vec2<f32>(0.5));
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
    if level == LEVEL_ORIGINAL {
        return vec3<f32>(1.0, 1.0, 1.0);
    }
    return palette[level % 8u];
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

// An atlas draw's sample position at the drawn level and its gradients (UV units of that atlas).
struct AtlasSample {
    uv: vec2<f32>,
    ddx: vec2<f32>,
    ddy: vec2<f32>,
    // RectSample::flat and mix_mean.
    flat: bool,
    mix_mean: f32,
}

// `rm`: the draw's rect map, `rects[in.draw.y]`, read once per fragment by the caller (lavapipe does not
// merge two reads of it: reading it twice cost 8 % of cornfield_crossing's tree frame).
fn atlas_sample(in: VertexOut, rm: RectMap, ddx: vec2<f32>, ddy: vec2<f32>) -> AtlasSample {
    let x = level_transform(in);
    let size = globals.atlas_texels;
    let r = rect_texel(rm, in.uv, ddx, ddy, 1.0 / x.x);
    var out: AtlasSample;
    out.uv = (r.texel / size) * x.x + x.yz;
    out.ddx = r.gx * (x.x / size);
    out.ddy = r.gy * (x.x / size);
    out.flat = r.flat;
    out.mix_mean = r.mix_mean;
    return out;
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    // Gradients of the unwrapped UV, taken in uniform control flow: mip selection stays right across
    // wrap seams and inside the switches below.
    let ddx = dpdx(in.uv);
    let ddy = dpdy(in.uv);
    if globals.mode == MODE_LEVELS {
        return vec4<f32>(level_colour(draw_level(in)), 1.0);
    }
    if SOURCE == SOURCE_ATLAS {
        let rm = rects[in.draw.y];
        let a = atlas_sample(in, rm, ddx, ddy);
        let layer = draw_layer(in);
        var c: vec4<f32>;
        if a.flat {
            c = rect_mean(rm.mean);
        } else {
            c = sample_atlas(a.uv, layer, a.ddx, a.ddy);
            if a.mix_mean > 0.0 {
                c = mix(c, rect_mean(rm.mean), a.mix_mean);
            }
        }
        // Per material, as original draws: MASK tested against its cutoff, BLEND blended (or, in a blend
        // node's depth pre-pass, written where opaque).
        let shaded = finish(c, rm.cutoff, (rm.wrap >> ALPHA_SHIFT) & CODE_MASK);
        if DENSITY == DENSITY_ON {
            // (texels/pixel min, max, source (SOURCE_ATLAS, SOURCE_ORIGINAL), level; LEVEL_ORIGINAL for
            // originals), from the footprint itself (not the one capped for sampling); only where the
            // colour pass draws (`finish` discarded the texels a MASK cutoff cuts out: they counted as
            // covered, and a sweep's covered PSNR measured background as scene; fault hunt, session 38).
            let tpu = rm.texels_per_uv * (level_transform(in).x / globals.atlas_texels);
            let sv = singular_values(ddx * tpu, ddy * tpu, globals.atlas_texels);
            return vec4<f32>(sv.x, sv.y, f32(SOURCE_ATLAS), f32(draw_level(in)));
        }
        return shaded;
    }
    let e = tam[in.draw.y];
    // The texture's UV into its tiled layer: one period is extent / class_size of the layer per axis.
    let scale = e.extent / e.class_size;
    let inset = edge_inset(ddx, ddy, e.extent);
    let wrapped = vec2<f32>(
        wrap_axis(in.uv.x, e.wrap & CODE_MASK, inset.x),
        wrap_axis(in.uv.y, (e.wrap >> WRAP_T_SHIFT) & CODE_MASK, inset.y),
    ) * scale;
    let colour = sample_class(e.class_index, wrapped, e.layer, ddx * scale, ddy * scale) * e.factor;
    let shaded = finish(colour, e.cutoff, e.alpha_mode);
    if DENSITY == DENSITY_ON {
        // Where the colour pass draws, as for atlases above.
        let sv = singular_values(ddx * scale, ddy * scale, e.class_size);
        return vec4<f32>(sv.x, sv.y, f32(SOURCE_ORIGINAL), f32(draw_level(in)));
    }
    return shaded;
}

// In the mask pass (a blend node's depth pre-pass), BLEND texels at or above OPAQUE_ALPHA are opaque and
// write depth; in the blend pass, fragments below BLEND_MIN_ALPHA are discarded.
const OPAQUE_ALPHA: f32 = 0.998039;
const BLEND_MIN_ALPHA: f32 = 0.5 / 255.0;

// The colour of a textured fragment (tree and dummy modes) in the pipeline's pass, or discard (alpha mask
// and blend). `alpha_mode` and `cutoff`: the material's (its TAM entry, or its rect for atlas draws).
fn finish(colour: vec4<f32>, cutoff: f32, alpha_mode: u32) -> vec4<f32> {
    if PASS == PASS_OPAQUE {
        return vec4<f32>(colour.rgb, 1.0);
    }
    if PASS == PASS_MASK && alpha_mode == ALPHA_BLEND {
        if colour.a < OPAQUE_ALPHA {
            discard;
        }
        return vec4<f32>(colour.rgb, 1.0);
    }
    if PASS == PASS_MASK || alpha_mode == ALPHA_MASK {
        if colour.a < cutoff {
            discard;
        }
        return vec4<f32>(colour.rgb, 1.0);
    }
    if alpha_mode == ALPHA_OPAQUE {
        return vec4<f32>(colour.rgb, 1.0);
    }
    if colour.a < BLEND_MIN_ALPHA {
        discard;
    }
    return colour;
}
