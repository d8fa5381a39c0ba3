//! Twins of `shaders/tree.wgsl`, the renderer's shader: the frame's uniform block ([`Globals`]), the
//! per-draw, per-leaf, per-rect and per-original records ([`NodeDraw`], [`LeafInfo`], [`RectMap`],
//! [`TamEntry`]), the bindings of its one bind group ([`binding`]), its overrides ([`overrides`]) and its
//! codes. [`RectMap::texel_f32`] is the shader's `rect_texel` on the CPU.

use crate::model::RectWrap;
use bytemuck::{Pod, Zeroable};
use glam::Vec2;

/// The shader's source.
pub const WGSL: &str = include_str!("../../../shaders/tree.wgsl");

wgsl_consts! {
    /// [`overrides::PASS`] of the opaque pipelines (the discriminants of [`crate::render::batch::Pass`]).
    PASS_OPAQUE: u32 = 0;
    /// [`overrides::PASS`] of the alpha-mask pipelines (and of a blend node's depth pre-pass).
    PASS_MASK: u32 = 1;
    /// [`overrides::PASS`] of the alpha-blend pipelines.
    PASS_BLEND: u32 = 2;

    /// [`overrides::SOURCE`] of the pipelines drawing atlases.
    SOURCE_ATLAS: u32 = 0;
    /// [`overrides::SOURCE`] of the pipelines drawing original textures.
    SOURCE_ORIGINAL: u32 = 1;

    /// [`overrides::DENSITY`] of the colour pipelines.
    DENSITY_OFF: u32 = 0;
    /// [`overrides::DENSITY`] of the texel-density debug pipelines ([`crate::render::density`]).
    DENSITY_ON: u32 = 1;

    /// [`Globals::mode`]: textured (modes tree and dummy).
    MODE_TEXTURED: u32 = 0;
    /// [`Globals::mode`]: coloured by the level of the atlas drawn (mode tree-levels).
    MODE_LEVELS: u32 = 1;

    /// Atlas array bindings `atlas0 …` ([`crate::render::textures::MAX_ATLAS_ARRAYS`]).
    MAX_ATLAS_ARRAYS: u32 = crate::render::textures::MAX_ATLAS_ARRAYS as u32;
    /// Class array bindings `class0 …`, class `k` of size `4 << k`
    /// ([`crate::render::textures::CLASS_COUNT`]).
    CLASS_COUNT: u32 = crate::render::textures::CLASS_COUNT as u32;

    /// The level an original-texture draw reports (white in mode tree-levels; the density target's `a`).
    LEVEL_ORIGINAL: u32 = 255;

    /// Atlas layers per array the shader can address: the vertex stage packs a draw's layer, array, level
    /// and depth below its leaf into one flat `u32` (one interpolant location fewer per field;
    /// `VertexOut.draw`), the layer in the bits below [`ARRAY_SHIFT`]. Arrays never get more layers
    /// ([`crate::render::textures::layer_limit`]).
    MAX_LAYERS: u32 = 1 << 16;
    /// The atlas array (< [`MAX_ATLAS_ARRAYS`]) sits this many bits up in `VertexOut.draw.x`.
    ARRAY_SHIFT: u32 = 16;
    /// The drawn level (< 256, [`LEVEL_ORIGINAL`] included) sits this many bits up.
    LEVEL_SHIFT: u32 = 18;
    /// The levels between the leaf and the drawn level (≤ 31) sit this many bits up.
    DEPTH_SHIFT: u32 = 26;

    /// [`LeafInfo::cell_level`]: the level in the bits below [`CELL_X_SHIFT`] (a mask of them:
    /// [`LEVEL_MASK`]), the cell's `ix` and `iy` at [`CELL_X_SHIFT`] and [`CELL_Y_SHIFT`], [`CELL_MASK`]
    /// wide; leaves deeper than [`PACKED_LEVELS`] hold [`CELL_LEVEL_WIDE`] (read `cell` and `level`).
    LEVEL_MASK: u32 = 31;
    CELL_X_SHIFT: u32 = 5;
    CELL_Y_SHIFT: u32 = 18;
    CELL_MASK: u32 = 0x1fff;
    PACKED_LEVELS: u32 = 13;
    CELL_LEVEL_WIDE: u32 = 0xffff_ffff;

    /// `wrap_t` sits this many bits above `wrap_s` in [`RectMap::wrap`] and [`TamEntry::wrap`].
    WRAP_T_SHIFT: u32 = 2;
    /// The material's alpha mode sits this many bits up in [`RectMap::wrap`].
    ALPHA_SHIFT: u32 = 4;
    /// Mask of one code (a wrap or alpha mode) in a packed `wrap`.
    CODE_MASK: u32 = 3;

    /// [`TamEntry::wrap`] codes per axis, the paging file's ([`crate::store::format::WRAP_REPEAT`] …):
    /// repeat.
    WRAP_REPEAT: u32 = crate::store::format::WRAP_REPEAT;
    /// Mirrored repeat.
    WRAP_MIRROR: u32 = crate::store::format::WRAP_MIRROR;
    /// Clamp to edge.
    WRAP_CLAMP: u32 = crate::store::format::WRAP_CLAMP;

    /// [`RectMap::wrap`] codes per axis, [`RectWrap::code`]: linear (baked repeats).
    RECT_WRAP_LINEAR: u32 = RectWrap::Linear.code();
    /// Repeat, wrapped in the shader.
    RECT_WRAP_REPEAT: u32 = RectWrap::Repeat.code();
    /// Mirrored repeat, folded in the shader.
    RECT_WRAP_MIRROR: u32 = RectWrap::Mirror.code();
    /// Clamp to edge, clamped in the shader.
    RECT_WRAP_CLAMP: u32 = RectWrap::Clamp.code();

    /// Alpha modes ([`TamEntry::alpha_mode`], and in [`RectMap::wrap`]), the paging file's
    /// ([`crate::store::format::ALPHA_OPAQUE`] …): opaque.
    ALPHA_OPAQUE: u32 = crate::store::format::ALPHA_OPAQUE;
    /// Alpha mask: discarded below the material's cutoff.
    ALPHA_MASK: u32 = crate::store::format::ALPHA_MASK;
    /// Alpha blend.
    ALPHA_BLEND: u32 = crate::store::format::ALPHA_BLEND;

    /// Alpha at and above which a BLEND material's texel counts as opaque in the depth pre-pass of blend
    /// nodes (the mask pipeline): about `1 − 0.5/255`, as the literal the shader has always had (3 f32
    /// ulps below `1 − 0.5/255`).
    OPAQUE_ALPHA: f32 = 0.998039;
    /// Alpha below which a fragment of a BLEND material is discarded in the blend pass.
    BLEND_MIN_ALPHA: f32 = 0.5 / 255.0;

    /// Texels of the inner rectangle at the mip a flat fragment's texel and gradients name
    /// ([`RectMap::texel_f32`]; the shader shows the rect's mean there instead, [`RectMap::sample_f32`]).
    CELLS: f32 = 2.0;
    /// A footprint larger than this share of the period gets the period's average.
    FLAT_SHARE: f32 = 1.0;
    /// Where the footprint reaches past the border (coarse levels, whose borders are halved per level),
    /// the gradients are sharpened by `k ≤ 1` to what the border protects; below this `k` the sharpened
    /// sample would alias, and the pixel gets the period's average instead.
    SHARPEN_MIN: f32 = 0.25;
    /// Drawn texels around a constant-UV sample that its bilinear taps' box-filtered texels reach (one tap
    /// each side, half a texel beyond): nearer the outer edge than this, the fragment shows the rect's
    /// mean ([`RectMap::sample_f32`]).
    POINT_REACH: f32 = 1.5;
    /// From this share of the rect's longer side on, a sampled fragment's footprint mixes the rect's mean
    /// into its sample, up to all of it where it covers the rect ([`RectSampleF32::mix_mean`]).
    MEAN_MIX_FROM: f32 = 0.5;
    /// [`RectMap::footprint_cap`] stays this much below the power of two whose coarser mip would reach
    /// too far, so the sampler's rounding of the lod never blends that mip in.
    REACH_SAFETY: f32 = 0.99;
}

wgsl_overrides! {
    /// The pipeline's pass: [`PASS_OPAQUE`](super::PASS_OPAQUE), [`PASS_MASK`](super::PASS_MASK) or
    /// [`PASS_BLEND`](super::PASS_BLEND).
    PASS,
    /// The texture source of the pipeline's records: [`SOURCE_ATLAS`](super::SOURCE_ATLAS) or
    /// [`SOURCE_ORIGINAL`](super::SOURCE_ORIGINAL).
    SOURCE,
    /// The one atlas array (below [`MAX_ATLAS_ARRAYS`](super::MAX_ATLAS_ARRAYS)) an atlas pipeline's
    /// records sample ([`crate::render::batch::Group::array`]); the other arrays are compiled out.
    ATLAS_ARRAY,
    /// Class arrays present: bit `k` for class `4 << k`; the others are compiled out.
    CLASS_MASK,
    /// [`DENSITY_ON`](super::DENSITY_ON): the texel-density variant.
    DENSITY,
}

/// `@binding` numbers of the shader's one bind group (group 0), named after its variables.
pub mod binding {
    use super::{CLASS_COUNT, MAX_ATLAS_ARRAYS};
    use crate::render::wgsl::Binding;

    /// `globals`: [`Globals`](super::Globals).
    pub const GLOBALS: u32 = 0;
    /// `draws`: [`NodeDraw`](super::NodeDraw) per indirect record.
    pub const DRAWS: u32 = 1;
    /// `leaves`: [`LeafInfo`](super::LeafInfo) per leaf.
    pub const LEAVES: u32 = 2;
    /// `offsets`: per leaf `origin − eye` (`vec4<f32>`).
    pub const OFFSETS: u32 = 3;
    /// `tam`: [`TamEntry`](super::TamEntry) per (leaf, original).
    pub const TAM: u32 = 4;
    /// `rects`: [`RectMap`](super::RectMap) per (leaf, rect).
    pub const RECTS: u32 = 5;
    /// `atlas_sampler` (clamp to edge).
    pub const ATLAS_SAMPLER: u32 = 6;
    /// `original_sampler` (repeat; the shader wraps).
    pub const ORIGINAL_SAMPLER: u32 = 7;
    /// `atlas0`; atlas array `i` is `atlas{i}` at `ATLAS0 + i`, `i < MAX_ATLAS_ARRAYS`.
    pub const ATLAS0: u32 = 8;
    /// `class0`; class binding `k` is `class{k}` at `CLASS0 + k`, `k < CLASS_COUNT`.
    pub const CLASS0: u32 = ATLAS0 + MAX_ATLAS_ARRAYS;

    /// Every resource of the shader.
    pub const ALL: &[Binding] = &[
        Binding::one("globals", 0, GLOBALS),
        Binding::one("draws", 0, DRAWS),
        Binding::one("leaves", 0, LEAVES),
        Binding::one("offsets", 0, OFFSETS),
        Binding::one("tam", 0, TAM),
        Binding::one("rects", 0, RECTS),
        Binding::one("atlas_sampler", 0, ATLAS_SAMPLER),
        Binding::one("original_sampler", 0, ORIGINAL_SAMPLER),
        Binding::numbered("atlas", 0, ATLAS0, MAX_ATLAS_ARRAYS),
        Binding::numbered("class", 0, CLASS0, CLASS_COUNT),
    ];
}

/// The uniform block, written once per frame. `naive.wgsl` declares the same block (the naive pipelines
/// bind the same buffer).
#[derive(Copy, Clone, Debug, Pod, Zeroable)]
#[repr(C)]
pub struct Globals {
    /// View-projection without translation (positions are eye-relative), reverse Z.
    pub view_proj: [[f32; 4]; 4],
    /// [`MODE_TEXTURED`] or [`MODE_LEVELS`].
    pub mode: u32,
    /// Side of every atlas, texels (the rect maps are in leaf-atlas texels).
    pub atlas_texels: f32,
    pub _p1: u32,
    pub _p2: u32,
}
const _: () = assert!(size_of::<Globals>() == 80);

/// Per-draw data, indexed by `instance_index` (= the record's `first_instance`).
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct NodeDraw {
    /// Layer of the node's atlas in atlas array `atlas_array`; [`crate::ids::NONE`] for an original-texture draw (diagnostics: the shader reads [`NodeDraw::draw_bits`]).
    pub atlas_layer: u32,
    /// Which atlas array (0 unless the layers exceed the device limit, see `render::textures`).
    pub atlas_array: u32,
    /// The node's level j: vertices map their leaf-local atlas UV into this ancestor's atlas.
    pub level: u32,
    /// Index of the tree's leaf 0 in the leaves and leaf-offset buffers (diagnostics: the GPU copy of the
    /// vertices carries global leaf numbers, render::resident::tables).
    pub leaf_base: u32,
    /// The smallest MASK cutoff below the node (diagnostics; fragments are tested with their material's
    /// cutoff, from its rect or TAM entry).
    pub alpha_cutoff: f32,
    /// Tree-local node id (diagnostics).
    pub node: u32,
    /// Tree index.
    pub tree: u32,
    /// `atlas_layer | atlas_array << ARRAY_SHIFT | level << LEVEL_SHIFT`, packed once on the CPU
    /// ([`NodeDraw::pack`]): what the vertex stage reads of an atlas draw (one load a vertex instead of
    /// three; on lavapipe each 32-bit storage load a vertex costs ~4 % of the all-tracks world's tree
    /// frame). 0 for an original-texture draw (not read).
    pub draw_bits: u32,
}
const _: () = assert!(size_of::<NodeDraw>() == 32);

impl NodeDraw {
    /// [`NodeDraw::draw_bits`] of an atlas draw: `layer` (< [`MAX_LAYERS`]) of array `array`
    /// (< [`MAX_ATLAS_ARRAYS`]) drawn at `level` (< 256): the u32 arithmetic the vertex stage did before.
    pub fn pack(layer: u32, array: u32, level: u32) -> u32 {
        layer | array << ARRAY_SHIFT | level << LEVEL_SHIFT
    }
}

/// Static per-leaf data.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct LeafInfo {
    /// The leaf's cell `(ix, iy)` at its level (paper Fig. 4).
    pub cell: [u32; 2],
    /// The leaf's level K.
    pub level: u32,
    /// First entry of the leaf's texture-array mapping in the TAM buffer (global index).
    pub first_tam: u32,
    /// First entry of the leaf's rects in the rect buffer (global index).
    pub first_rect: u32,
    /// `level | ix << CELL_X_SHIFT | iy << CELL_Y_SHIFT` for leaves at most [`PACKED_LEVELS`] deep (every
    /// cell coordinate below 2^13), else [`CELL_LEVEL_WIDE`] ([`LeafInfo::pack_cell_level`]): the vertex
    /// stage loads one word instead of three (docs/DESIGN.md "Storage loads in the vertex stage").
    pub cell_level: u32,
    pub _p1: u32,
    pub _p2: u32,
}
const _: () = assert!(size_of::<LeafInfo>() == 32);

impl LeafInfo {
    /// [`LeafInfo::cell_level`] of a leaf at `level` in cell `cell`.
    pub fn pack_cell_level(level: u32, cell: [u32; 2]) -> u32 {
        if level > PACKED_LEVELS || cell[0] > CELL_MASK || cell[1] > CELL_MASK {
            return CELL_LEVEL_WIDE;
        }
        level | cell[0] << CELL_X_SHIFT | cell[1] << CELL_Y_SHIFT
    }
}

/// How a fragment's original UV reaches its texture's rect in its leaf's atlas (docs/DESIGN.md "Repeats"): the
/// rect's per-axis wrap ([`RectWrap`]), then the linear map onto the inner rectangle, kept inside the
/// outer rectangle by the filter footprint. [`RectMap::texel_f32`] is the shader's arithmetic on the CPU,
/// [`crate::model::transform::rect_texel`] its f64 reference; `RectMap::new` (in
/// [`crate::render::batch`]) builds it from a stored rect. All lengths in leaf-atlas texels.
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct RectMap {
    /// UV shown at the inner rectangle's low edge (after the wrap).
    pub uv_min: [f32; 2],
    /// Leaf-atlas texels per unit of UV.
    pub texels_per_uv: [f32; 2],
    /// Low corner of the inner rectangle.
    pub inner_lo: [f32; 2],
    /// REPEAT axes: half the part of the period the rect does not hold ([`crate::model::transform::half_gap`]).
    pub half_gap: [f32; 2],
    /// The outer rectangle (border included).
    pub outer_lo: [f32; 2],
    pub outer_hi: [f32; 2],
    /// `wrap_s | wrap_t << WRAP_T_SHIFT` ([`RECT_WRAP_LINEAR`] … [`RECT_WRAP_CLAMP`])
    /// `| alpha_mode << ALPHA_SHIFT` (the material's [`ALPHA_OPAQUE`], [`ALPHA_MASK`] or [`ALPHA_BLEND`], as
    /// [`TamEntry::alpha_mode`]): atlas draws test and blend per material, as originals do.
    pub wrap: u32,
    /// The material's MASK cutoff (0.5 for other modes).
    pub cutoff: f32,
    /// Size of the inner rectangle.
    pub inner_size: [f32; 2],
    /// [`crate::model::AtlasRect::mean`] as a little-endian `u32` (`unpack4x8unorm` in the shader): what
    /// a flat fragment shows ([`RectMap::mean_linear`]).
    pub mean: u32,
    /// 1 for a rect of one UV and one inner texel (a palette cell's, `crate::preprocess::palette`): one
    /// colour, its mean, at any footprint; else 0.
    pub point: u32,
}
const _: () = assert!(size_of::<RectMap>() == 72);

impl RectMap {
    /// `(rect coordinate, sign of its derivative)` of `u` on axis `k`: `rect_axis` in the shader.
    pub fn axis_f32(&self, u: f32, k: usize) -> (f32, f32) {
        let mode = (self.wrap >> (WRAP_T_SHIFT * k as u32)) & CODE_MASK;
        let lo = self.uv_min[k];
        if mode == RECT_WRAP_REPEAT {
            let x = u - lo;
            return (x - (x + self.half_gap[k]).floor(), 1.0);
        }
        if mode == RECT_WRAP_MIRROR {
            let p = u - 2.0 * (u * 0.5).floor();
            return if p > 1.0 {
                (2.0 - p - lo, -1.0)
            } else {
                (p - lo, 1.0)
            };
        }
        if mode == RECT_WRAP_CLAMP {
            return (u.clamp(0.0, 1.0) - lo, 1.0);
        }
        (u - lo, 1.0)
    }

    /// The shader's `footprint_cap`: the largest footprint (leaf texels, the longer gradient) whose
    /// filter stays within `room` leaf texels of the sample. The sampler is isotropic trilinear: the
    /// longer gradient sets its mip along both axes, and at lod > 0 its bilinear taps on the coarser of
    /// the two mips it blends — texels of `2^(floor(lod)+1)` drawn texels, box-filtered blocks that need
    /// not be aligned to the rect — read up to 1.5 of those texels either side of the sample; at lod ≤ 0
    /// it reads half a drawn texel. 0 where `room` is less than half a drawn texel.
    pub fn footprint_cap(room: f32, level_texels: f32) -> f32 {
        if room < 0.5 * level_texels {
            return 0.0;
        }
        let m = (room / (1.5 * level_texels))
            .max(1.0)
            .log2()
            .floor()
            .max(0.0);
        level_texels * m.exp2() * REACH_SAFETY
    }

    /// The shader's `rect_texel`: leaf-atlas texel coordinates of UV `uv` with screen derivatives `ddx`,
    /// `ddy` drawn at a level `level_texels` leaf texels per texel of the drawn atlas (`2^(K − j)`), and the
    /// derivatives the sampler is given.
    ///
    /// - The gradients are scaled by `k ≤ 1` so that the sampler's filter ([`Self::footprint_cap`]:
    ///   isotropic, so the nearer outer edge along either axis bounds it) stays inside the outer
    ///   rectangle around the sample: it reads the rect's border (the sampler's rule) and never a
    ///   neighbouring rect. Only samples near the border are sharpened.
    /// - A pixel whose footprint exceeds [`FLAT_SHARE`] of the inner rectangle along both axes, or whose
    ///   `k` is below [`SHARPEN_MIN`], covers (about) a period: it is flat ([`RectMap::sample_f32`]) and
    ///   shows the period's mean, measured when the file was written ([`RectMap::mean_linear`]) — no
    ///   aliasing, and every such pixel of the rect shows the same colour. Its texel is the inner centre
    ///   and its gradients name the mip where the inner rectangle's smaller side is [`CELLS`] texels
    ///   (the mean's stand-in before format 6, which read the middle of the period where the rect sat
    ///   off that mip's texel grid).
    /// - A constant UV (zero footprint, [`crate::preprocess::palette`]) nearer the outer edge than
    ///   [`POINT_REACH`] drawn texels is flat too: on a coarse level its rect (a palette cell's: 1 × 1
    ///   inner, a uniform border) is smaller than the texels the sampler would mix; its mean is its colour.
    ///   Its gradients stay zero. A point rect ([`RectMap::point`]: one UV, one inner texel) is flat at
    ///   any footprint: the constant UV of a palette cell, interpolated, has gradients an ulp off zero,
    ///   which took the sampled branch on coarse levels and read neighbouring rects (banded cells at
    ///   `--border 2`, session 30's hunt). A rect of one inner texel with a UV span (a 2 × 2 texture in a
    ///   leaf scaled to half) is sampled as before.
    /// - A footprint that covers one axis only (the short side of an elongated rect, say 992 × 16 texels
    ///   seen from afar) averages that axis alone: the sample sits at the inner centre there; the other
    ///   axis keeps its detail.
    /// - The sample is kept half a drawn texel inside the outer rectangle; at the inner centre where the
    ///   rectangle is narrower than that.
    pub fn texel_f32(
        &self,
        uv: Vec2,
        ddx: Vec2,
        ddy: Vec2,
        level_texels: f32,
    ) -> (Vec2, Vec2, Vec2) {
        let s = self.sample_f32(uv, ddx, ddy, level_texels);
        (s.texel, s.gx, s.gy)
    }

    /// The shader's `rect_texel` whole ([`RectSampleF32`]): [`RectMap::texel_f32`], whether the
    /// fragment is flat, and how much of the rect's mean a sampled one mixes in.
    pub fn sample_f32(&self, uv: Vec2, ddx: Vec2, ddy: Vec2, level_texels: f32) -> RectSampleF32 {
        let (ts, ss) = self.axis_f32(uv.x, 0);
        let (tt, st) = self.axis_f32(uv.y, 1);
        let tpu = Vec2::from(self.texels_per_uv) * Vec2::new(ss, st);
        let gx = ddx * tpu;
        let gy = ddy * tpu;
        let inner_lo = Vec2::from(self.inner_lo);
        let inner = Vec2::from(self.inner_size);
        let centre = inner_lo + 0.5 * inner;
        let period = inner.x.min(inner.y);
        let footprint = gx.length().max(gy.length());
        let (outer_lo, outer_hi) = (Vec2::from(self.outer_lo), Vec2::from(self.outer_hi));
        // An axis the footprint covers (an elongated rect's short one) is averaged: sampled at its centre.
        let covered = Vec2::splat(footprint).cmpgt(inner * FLAT_SHARE);
        let lo = outer_lo + Vec2::splat(0.5 * level_texels);
        let hi = outer_hi - Vec2::splat(0.5 * level_texels);
        let p =
            (inner_lo + Vec2::new(ts, tt) * Vec2::from(self.texels_per_uv)).clamp(lo, lo.max(hi));
        let q = Vec2::select(covered | lo.cmpgt(hi), centre, p);
        // The filter is isotropic: the nearer outer edge, along either axis, bounds it.
        let d = (q - outer_lo).min(outer_hi - q);
        let cap = Self::footprint_cap(d.min_element(), level_texels);
        // A constant UV (zero footprint, as on a triangle with degenerate UVs) reaches past nothing: k 1,
        // not the period branch with gradients scaled by ∞ (NaN).
        let k = if footprint == 0.0 {
            1.0
        } else {
            (cap / footprint).min(1.0)
        };
        // Nearer the outer edge than the drawn level's bilinear taps reach, a constant UV (a palette
        // cell's rect on a coarse level, crate::preprocess::palette) shows the rect's mean.
        let point_mixed = footprint == 0.0 && d.min_element() < POINT_REACH * level_texels;
        // A point rect (one UV, one inner texel: a palette cell's) has one colour, its mean: shown whatever
        // the gradients (a constant UV's interpolation jitters them off zero by an ulp).
        if covered.all() || k < SHARPEN_MIN || point_mixed || self.point != 0 {
            let kk = if footprint == 0.0 {
                0.0
            } else {
                period / CELLS / footprint
            };
            return RectSampleF32 {
                texel: centre,
                gx: gx * kk,
                gy: gy * kk,
                flat: true,
                mix_mean: 1.0,
            };
        }
        let share = footprint / inner.max_element();
        let t = ((share - MEAN_MIX_FROM) / (1.0 - MEAN_MIX_FROM)).clamp(0.0, 1.0);
        RectSampleF32 {
            texel: q,
            gx: gx * k,
            gy: gy * k,
            flat: false,
            mix_mean: t * t * (3.0 - 2.0 * t),
        }
    }

    /// The shader's `rect_mean`: [`RectMap::mean`] as a texture sample gives it, linear colour (IEC
    /// 61966-2-1) and straight alpha.
    pub fn mean_linear(&self) -> [f32; 4] {
        let [r, g, b, a] = self.mean.to_le_bytes().map(|v| f32::from(v) / 255.0);
        let lin = |c: f32| {
            if c <= 0.04045 {
                c / 12.92
            } else {
                ((c + 0.055) / 1.055).powf(2.4)
            }
        };
        [lin(r), lin(g), lin(b), a]
    }
}

/// The shader's `RectSample`, from [`RectMap::sample_f32`]: where a fragment reads its leaf's atlas.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct RectSampleF32 {
    /// Leaf-atlas texel and its screen derivatives ([`RectMap::texel_f32`]).
    pub texel: Vec2,
    pub gx: Vec2,
    pub gy: Vec2,
    /// The footprint covers the period: the fragment shows [`RectMap::mean_linear`], no sample.
    pub flat: bool,
    /// The share of the mean mixed into a sample: `smoothstep(MEAN_MIX_FROM, 1, footprint / longer side)`
    /// (1 where flat). A footprint just under a period read one sharpened sample of it, which aliased
    /// (moiré at 0.6–0.95 periods a pixel: 21.8–26.2 dB against original mode; with the mix 29.6–53.4).
    pub mix_mean: f32,
}

/// One entry of TAB's texture-array mapping (TAM): where an original texture lives and how it is sampled.
#[derive(Copy, Clone, Debug, Default, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct TamEntry {
    /// Class array binding (`class0..class9` in the shader). Paged: `log2(class_size) − 2` (class 4 → 0 …
    /// class 2048 → 9); all resident, a class past the layer limit continues in unused bindings
    /// (`resident::class_slots`), so the binding's size is `class_size`, not derived from the index.
    pub class_index: u32,
    /// Layer in the class array.
    pub layer: u32,
    /// `wrap_s | wrap_t << WRAP_T_SHIFT` ([`WRAP_REPEAT`], [`WRAP_MIRROR`], [`WRAP_CLAMP`]).
    pub wrap: u32,
    /// [`ALPHA_OPAQUE`], [`ALPHA_MASK`] or [`ALPHA_BLEND`].
    pub alpha_mode: u32,
    /// Linear RGBA multiplier (the atlas has it baked in; originals are stored without it).
    pub factor: [f32; 4],
    /// MASK cutoff.
    pub cutoff: f32,
    /// Side of the class, texels.
    pub class_size: f32,
    /// Stored width and height of the texture, texels (each ≤ `class_size`): the layer holds it tiled,
    /// and the shader scales its wrapped UV by `extent / class_size` (see [`crate::texfmt::tile_chain_to_square`]).
    pub extent: [f32; 2],
}
const _: () = assert!(size_of::<TamEntry>() == 48);

#[cfg(test)]
mod tests {
    use super::*;

    /// What `vs_main` unpacks from [`LeafInfo::cell_level`] (`level`, `cell` of the wide fields where
    /// it is [`CELL_LEVEL_WIDE`]).
    fn unpack(packed: u32, level: u32, cell: [u32; 2]) -> (u32, [u32; 2]) {
        if packed == CELL_LEVEL_WIDE {
            return (level, cell);
        }
        (
            packed & LEVEL_MASK,
            [
                (packed >> CELL_X_SHIFT) & CELL_MASK,
                (packed >> CELL_Y_SHIFT) & CELL_MASK,
            ],
        )
    }

    #[test]
    fn cell_level_packs_shallow_leaves_and_defers_deep_ones() {
        let last = (1u32 << PACKED_LEVELS) - 1;
        for (level, cell) in [
            (0, [0, 0]),
            (1, [1, 0]),
            (7, [127, 3]),
            (PACKED_LEVELS, [last, last]),
            (PACKED_LEVELS, [0, last]),
        ] {
            let packed = LeafInfo::pack_cell_level(level, cell);
            assert_ne!(packed, CELL_LEVEL_WIDE);
            assert_eq!(
                unpack(packed, 99, [99, 99]),
                (level, cell),
                "{level} {cell:?}"
            );
        }
        // Deeper than PACKED_LEVELS, or a cell past the mask (not a valid cell at its level): the wide
        // fields.
        for (level, cell) in [
            (PACKED_LEVELS + 1, [0, 0]),
            (31, [1 << 30, 5]),
            (3, [last + 1, 0]),
            (3, [0, last + 1]),
        ] {
            let packed = LeafInfo::pack_cell_level(level, cell);
            assert_eq!(packed, CELL_LEVEL_WIDE, "{level} {cell:?}");
            assert_eq!(unpack(packed, level, cell), (level, cell));
        }
    }
}
