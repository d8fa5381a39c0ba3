//! On-disk layout of the paging file: fixed-size `#[repr(C)]` Pod records read in place (paper §6 blocks).
//!
//! ```text
//! 0                 Header (HEADER_SIZE bytes, checksummed)
//! align16           section Params           1 × ParamsRecord
//! align16           section Materials        n × MaterialRecord
//! align16           section Strings          material names, UTF-8, back to back
//! align16           section Trees            1–2 × TreeRecord
//! align16           section Nodes            all trees' NodeRecords, tree by tree
//! align16           section Leaves           all trees' LeafRecords
//! align16           section Rects            all trees' RectRecords
//! align16           section Originals        all trees' OriginalRecords
//! align16           section Vertices         all trees' TreeVertex
//! align16           section Indices          all trees' u32 indices
//! align16           section SourceTriangles  all trees' u32 scene-triangle ids
//! align16           section Blocks           BlockRecord per block (with the blocks' checksums)
//! align4096         block 0, block 1, …      in block-id order, each 4 KiB aligned, opaque bytes
//! ```
//!
//! Everything is **little-endian**; the reader and writer refuse to run on big-endian targets rather than
//! byte-swap. Ids inside a tree's records (node, leaf, rect, original, vertex and index numbers) are local to
//! that tree: `NodeId(0)` is the root of every tree. Block ids are global (index into the Blocks section).
//! Placement is canonical: each section starts at the end of the one before rounded up to
//! [`SECTION_ALIGN`], each block at the end of what precedes it rounded up to [`BLOCK_ALIGN`], and the file
//! ends exactly where the last block ends (where the tables end when there is no block). Every gap is
//! zero, and so are the records' `_pad` fields. Every byte of a file is thus covered by a checksum (header,
//! sections, blocks) or a zero check: the reader checks the gaps up to the first block at open and the
//! padding after a block whenever it reads that block ([`crate::store::TreeFile::block`]); the length check
//! at open refuses truncated files and appended bytes.
//!
//! Every record has explicit padding fields (bytemuck's derive rejects implicit padding) and a const-asserted
//! size, so a change of layout is a compile error, not a silent format change.

use crate::ids::{BlockId, Cell, ImageId, LeafId, Level, MaterialId, NONE, NodeId};
use crate::model::{
    AtlasRect, BlockDesc, BlockKind, BuildParams, Leaf, Node, OriginalRef, RectWrap, TreeKind,
    TreeVertex,
};
use crate::scene::{AlphaMode, Material, UpAxis, Wrap};
use crate::texfmt::TexFormat;
use bytemuck::{Pod, Zeroable};

/// First eight bytes of every paging file.
pub const MAGIC: [u8; 8] = *b"ATLTREE\0";
/// The format version this build reads and writes. Bump on any layout change.
///
/// History: 1 = RGBA8 blocks only; 2 = per-tree block format ([`TreeRecord::format`]) and per-block
/// compression error ([`BlockRecord::sse`]); 3 = repeats wrapped in the shader: per-rect wrap and cap flags
/// ([`RectRecord::flags`]), vertices without a baked atlas UV but with their rect ([`TreeVertex::rect`]);
/// 4 = original textures stored once per tree: an [`OriginalRecord`] may name a block another leaf owns;
/// 5 = original textures stored non-square ([`OriginalRecord::width`], [`OriginalRecord::height`]);
/// 6 = each rect's mean colour ([`RectRecord::mean`]), what a pixel covering a period shows.
pub const FORMAT_VERSION: u32 = 6;
/// Alignment of every section's offset, bytes.
pub const SECTION_ALIGN: u64 = 16;
/// Alignment of every block's offset, bytes (one page: a block can be mapped or read with O_DIRECT alone).
pub const BLOCK_ALIGN: u64 = 4096;
/// Number of sections; fixed by [`FORMAT_VERSION`].
pub const SECTION_COUNT: usize = 12;
/// Header flags this version understands (none yet: any set bit is refused).
pub const KNOWN_FLAGS: u32 = 0;

/// The sections of a file, in file order. `Section as usize` indexes [`Header::sections`].
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
#[repr(u32)]
pub enum Section {
    Params = 0,
    Materials = 1,
    Strings = 2,
    Trees = 3,
    Nodes = 4,
    Leaves = 5,
    Rects = 6,
    Originals = 7,
    Vertices = 8,
    Indices = 9,
    SourceTriangles = 10,
    Blocks = 11,
}

impl Section {
    /// The sections holding per-triangle data (vertices, indices, source triangles): what a table prefix
    /// read with its geometry vouched for ([`crate::store::TreeFile::skeleton_prefix`]) leaves unread.
    pub fn is_geometry(self) -> bool {
        matches!(
            self,
            Section::Vertices | Section::Indices | Section::SourceTriangles
        )
    }

    /// All sections in file order.
    pub const ALL: [Section; SECTION_COUNT] = [
        Section::Params,
        Section::Materials,
        Section::Strings,
        Section::Trees,
        Section::Nodes,
        Section::Leaves,
        Section::Rects,
        Section::Originals,
        Section::Vertices,
        Section::Indices,
        Section::SourceTriangles,
        Section::Blocks,
    ];

    /// Lower-case name used in errors and summaries.
    pub fn name(self) -> &'static str {
        match self {
            Section::Params => "params",
            Section::Materials => "materials",
            Section::Strings => "strings",
            Section::Trees => "trees",
            Section::Nodes => "nodes",
            Section::Leaves => "leaves",
            Section::Rects => "rects",
            Section::Originals => "originals",
            Section::Vertices => "vertices",
            Section::Indices => "indices",
            Section::SourceTriangles => "source_triangles",
            Section::Blocks => "blocks",
        }
    }

    /// Size of one record of this section, bytes.
    pub fn record_size(self) -> u32 {
        let size = match self {
            Section::Params => size_of::<ParamsRecord>(),
            Section::Materials => size_of::<MaterialRecord>(),
            Section::Strings => 1,
            Section::Trees => size_of::<TreeRecord>(),
            Section::Nodes => size_of::<NodeRecord>(),
            Section::Leaves => size_of::<LeafRecord>(),
            Section::Rects => size_of::<RectRecord>(),
            Section::Originals => size_of::<OriginalRecord>(),
            Section::Vertices => size_of::<TreeVertex>(),
            Section::Indices | Section::SourceTriangles => size_of::<u32>(),
            Section::Blocks => size_of::<BlockRecord>(),
        };
        size as u32
    }
}

/// `value` rounded up to a multiple of `align` (a power of two); `None` on overflow.
pub fn align_up(value: u64, align: u64) -> Option<u64> {
    debug_assert!(align.is_power_of_two());
    Some(value.checked_add(align - 1)? & !(align - 1))
}

/// Where one section lives and what it holds.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct SectionEntry {
    /// Byte offset from the start of the file, a multiple of [`SECTION_ALIGN`].
    pub offset: u64,
    /// Byte length; `count * record_size`.
    pub length: u64,
    /// Number of records.
    pub count: u64,
    /// `xxh3_64` of the section's `length` bytes.
    pub checksum: u64,
    /// Size of one record, bytes (must equal [`Section::record_size`]).
    pub record_size: u32,
    /// `Section as u32`: the entry at position `i` has kind `i`.
    pub kind: u32,
}
const _: () = assert!(size_of::<SectionEntry>() == 40);

/// The file header at offset 0.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct Header {
    /// [`MAGIC`].
    pub magic: [u8; 8],
    /// [`FORMAT_VERSION`].
    pub version: u32,
    /// Feature bits; none are defined ([`KNOWN_FLAGS`]).
    pub flags: u32,
    /// Exact length of the file, bytes (end of the last block, or of the tables when there is no block).
    pub file_len: u64,
    /// `size_of::<Header>()`.
    pub header_size: u32,
    /// [`SECTION_COUNT`].
    pub section_count: u32,
    /// [`BLOCK_ALIGN`].
    pub block_align: u32,
    /// [`SECTION_ALIGN`].
    pub section_align: u32,
    /// One entry per [`Section`], in [`Section::ALL`] order.
    pub sections: [SectionEntry; SECTION_COUNT],
    /// `xxh3_64` of all header bytes before this field.
    pub checksum: u64,
}
/// Size of the header, bytes.
pub const HEADER_SIZE: usize = size_of::<Header>();
const _: () = assert!(HEADER_SIZE == 528);

impl Header {
    /// The entry of `section`.
    pub fn section(&self, section: Section) -> &SectionEntry {
        &self.sections[section as usize]
    }

    /// The checksum this header should carry: `xxh3_64` of its bytes before the `checksum` field.
    pub fn compute_checksum(&self) -> u64 {
        let bytes = bytemuck::bytes_of(self);
        xxhash_rust::xxh3::xxh3_64(&bytes[..HEADER_SIZE - size_of::<u64>()])
    }
}

/// Build parameters ([`BuildParams`]).
#[derive(Copy, Clone, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct ParamsRecord {
    /// d_min, world units.
    pub d_min: f64,
    /// Horizontal field of view, degrees.
    pub fov_deg: f64,
    /// Texels per pixel at d_min.
    pub texel_ratio: f64,
    /// Screen width, pixels.
    pub screen_width: u32,
    /// Atlas side, texels.
    pub atlas_size: u32,
    /// Border, texels.
    pub border: u32,
    /// Depth cap.
    pub max_depth: u32,
    /// 0 = X, 1 = Y, 2 = Z.
    pub up: u32,
    pub _pad: u32,
}
const _: () = assert!(size_of::<ParamsRecord>() == 48);

impl ParamsRecord {
    pub fn encode(p: &BuildParams) -> Self {
        ParamsRecord {
            d_min: p.d_min,
            fov_deg: p.fov_deg,
            texel_ratio: p.texel_ratio,
            screen_width: p.screen_width,
            atlas_size: p.atlas_size,
            border: p.border,
            max_depth: u32::from(p.max_depth),
            up: encode_up(p.up),
            _pad: 0,
        }
    }

    /// The parameters; `None` if `up` or `max_depth` is out of range.
    pub fn decode(&self) -> Option<BuildParams> {
        Some(BuildParams {
            d_min: self.d_min,
            screen_width: self.screen_width,
            fov_deg: self.fov_deg,
            texel_ratio: self.texel_ratio,
            atlas_size: self.atlas_size,
            border: self.border,
            max_depth: u8::try_from(self.max_depth).ok()?,
            up: decode_up(self.up)?,
        })
    }
}

fn encode_up(up: UpAxis) -> u32 {
    match up {
        UpAxis::X => 0,
        UpAxis::Y => 1,
        UpAxis::Z => 2,
    }
}

fn decode_up(raw: u32) -> Option<UpAxis> {
    match raw {
        0 => Some(UpAxis::X),
        1 => Some(UpAxis::Y),
        2 => Some(UpAxis::Z),
        _ => None,
    }
}

/// Alpha modes in [`MaterialRecord::alpha_mode`].
pub const ALPHA_OPAQUE: u32 = 0;
pub const ALPHA_MASK: u32 = 1;
pub const ALPHA_BLEND: u32 = 2;

/// Wrap modes in [`MaterialRecord::wrap`] (per axis).
pub const WRAP_REPEAT: u32 = 0;
pub const WRAP_MIRROR: u32 = 1;
pub const WRAP_CLAMP: u32 = 2;

/// One scene material ([`Material`]); the name lives in the Strings section.
#[derive(Copy, Clone, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct MaterialRecord {
    /// Linear RGBA multiplier.
    pub base_color_factor: [f32; 4],
    /// MASK cutoff (0 for other modes).
    pub alpha_cutoff: f32,
    /// [`ALPHA_OPAQUE`], [`ALPHA_MASK`] or [`ALPHA_BLEND`].
    pub alpha_mode: u32,
    /// `[wrap_s, wrap_t]`: [`WRAP_REPEAT`], [`WRAP_MIRROR`] (mirrored repeat) or [`WRAP_CLAMP`] (clamp to
    /// edge).
    pub wrap: [u32; 2],
    /// Scene image id.
    pub image: u32,
    /// glTF texCoord set.
    pub tex_coord: u32,
    /// Byte offset of the name in the Strings section.
    pub name_offset: u32,
    /// Byte length of the name (UTF-8).
    pub name_len: u32,
    /// 1 if `KHR_texture_transform` was baked, else 0.
    pub texture_transform: u32,
    pub _pad: u32,
}
const _: () = assert!(size_of::<MaterialRecord>() == 56);

impl MaterialRecord {
    /// Encodes `m` with its name at `name_offset` in the Strings section.
    pub fn encode(m: &Material, name_offset: u32, name_len: u32) -> Self {
        let (alpha_mode, alpha_cutoff) = match m.alpha {
            AlphaMode::Opaque => (ALPHA_OPAQUE, 0.0),
            AlphaMode::Mask { cutoff } => (ALPHA_MASK, cutoff),
            AlphaMode::Blend => (ALPHA_BLEND, 0.0),
        };
        MaterialRecord {
            base_color_factor: m.base_color_factor,
            alpha_cutoff,
            alpha_mode,
            wrap: m.wrap.map(encode_wrap),
            image: m.image.0,
            tex_coord: m.tex_coord,
            name_offset,
            name_len,
            texture_transform: u32::from(m.texture_transform),
            _pad: 0,
        }
    }

    /// The alpha mode; `None` for an unknown code.
    pub fn alpha(&self) -> Option<AlphaMode> {
        match self.alpha_mode {
            ALPHA_OPAQUE => Some(AlphaMode::Opaque),
            ALPHA_MASK => Some(AlphaMode::Mask {
                cutoff: self.alpha_cutoff,
            }),
            ALPHA_BLEND => Some(AlphaMode::Blend),
            _ => None,
        }
    }

    /// `[wrap_s, wrap_t]`; `None` for an unknown code.
    pub fn wraps(&self) -> Option<[Wrap; 2]> {
        Some([decode_wrap(self.wrap[0])?, decode_wrap(self.wrap[1])?])
    }

    /// The material with the given name; `None` for unknown codes.
    pub fn decode(&self, name: &str) -> Option<Material> {
        Some(Material {
            name: name.to_owned(),
            image: ImageId(self.image),
            tex_coord: self.tex_coord,
            wrap: self.wraps()?,
            alpha: self.alpha()?,
            base_color_factor: self.base_color_factor,
            texture_transform: self.texture_transform != 0,
            gltf_material: None,
        })
    }
}

/// The stored (and shader) code of a wrap mode.
pub fn encode_wrap(w: Wrap) -> u32 {
    match w {
        Wrap::Repeat => WRAP_REPEAT,
        Wrap::MirroredRepeat => WRAP_MIRROR,
        Wrap::ClampToEdge => WRAP_CLAMP,
    }
}

fn decode_wrap(raw: u32) -> Option<Wrap> {
    match raw {
        WRAP_REPEAT => Some(Wrap::Repeat),
        WRAP_MIRROR => Some(Wrap::MirroredRepeat),
        WRAP_CLAMP => Some(Wrap::ClampToEdge),
        _ => None,
    }
}

/// A `[first, count]` range of records in a section.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct Range64 {
    pub first: u64,
    pub count: u64,
}
const _: () = assert!(size_of::<Range64>() == 16);

impl Range64 {
    /// `first + count`, `None` on overflow.
    pub fn end(&self) -> Option<u64> {
        self.first.checked_add(self.count)
    }
}

/// Tree kinds in [`TreeRecord::kind`].
pub const TREE_OPAQUE: u32 = 0;
pub const TREE_ALPHA: u32 = 1;

/// One tree: its kind and its record ranges in the shared sections.
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct TreeRecord {
    /// [`TREE_OPAQUE`] or [`TREE_ALPHA`].
    pub kind: u32,
    /// Storage format of all the tree's blocks, a [`TexFormat`] code (0 RGBA8, 1 BC1, 2 BC3, 3 BC7).
    pub format: u32,
    pub nodes: Range64,
    pub leaves: Range64,
    pub rects: Range64,
    pub originals: Range64,
    pub vertices: Range64,
    pub indices: Range64,
    pub source_triangles: Range64,
}
const _: () = assert!(size_of::<TreeRecord>() == 120);

impl TreeRecord {
    /// The tree kind; `None` for an unknown code.
    pub fn tree_kind(&self) -> Option<TreeKind> {
        match self.kind {
            TREE_OPAQUE => Some(TreeKind::Opaque),
            TREE_ALPHA => Some(TreeKind::Alpha),
            _ => None,
        }
    }

    /// The block format; `None` for an unknown code.
    pub fn tex_format(&self) -> Option<TexFormat> {
        TexFormat::from_code(self.format)
    }

    pub fn encode_kind(kind: TreeKind) -> u32 {
        match kind {
            TreeKind::Opaque => TREE_OPAQUE,
            TreeKind::Alpha => TREE_ALPHA,
        }
    }
}

/// One quadtree node ([`Node`]); ids are tree-local, [`NONE`] marks "absent".
#[derive(Copy, Clone, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct NodeRecord {
    /// World-space bounds of the node's triangles.
    pub bounds_min: [f64; 3],
    pub bounds_max: [f64; 3],
    /// Minimum camera distance at which this node's atlas suffices, world units.
    pub min_distance: f64,
    /// Cell at `level` (`ix, iy < 2^level`).
    pub cell: Cell,
    /// Depth, root = 0 (< 32).
    pub level: u32,
    /// Parent node, [`NONE`] for the root.
    pub parent: u32,
    /// Children by quadrant, [`NONE`] where empty.
    pub children: [u32; 4],
    /// Index range of the subtree in the tree's index buffer.
    pub first_index: u32,
    pub index_count: u32,
    /// Global block id of the node's atlas.
    pub atlas_block: u32,
    /// Leaf id, [`NONE`] for inner nodes.
    pub leaf: u32,
}
const _: () = assert!(size_of::<NodeRecord>() == 104);

fn raw(id: Option<u32>) -> u32 {
    id.unwrap_or(NONE)
}

impl NodeRecord {
    pub fn encode(n: &Node) -> Self {
        NodeRecord {
            bounds_min: n.bounds_min.to_array(),
            bounds_max: n.bounds_max.to_array(),
            min_distance: n.min_distance,
            cell: n.cell,
            level: u32::from(n.level.0),
            parent: raw(n.parent.map(|p| p.0)),
            children: n.children.map(|c| raw(c.map(|c| c.0))),
            first_index: n.first_index,
            index_count: n.index_count,
            atlas_block: n.atlas_block.0,
            leaf: raw(n.leaf.map(|l| l.0)),
        }
    }

    /// The node; `None` if `level` does not fit a [`Level`].
    pub fn decode(&self) -> Option<Node> {
        Some(Node {
            bounds_min: self.bounds_min.into(),
            bounds_max: self.bounds_max.into(),
            level: Level(u8::try_from(self.level).ok()?),
            cell: self.cell,
            parent: NodeId::from_raw(self.parent),
            children: self.children.map(NodeId::from_raw),
            min_distance: self.min_distance,
            first_index: self.first_index,
            index_count: self.index_count,
            atlas_block: BlockId(self.atlas_block),
            leaf: LeafId::from_raw(self.leaf),
        })
    }
}

/// One leaf ([`Leaf`]); ranges are tree-local record ranges.
#[derive(Copy, Clone, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct LeafRecord {
    /// Vertex positions are relative to this point, world units.
    pub origin: [f64; 3],
    /// Resolution clamp (1.0 normally).
    pub clamp_scale: f64,
    /// The leaf's node.
    pub node: u32,
    pub first_vertex: u32,
    pub vertex_count: u32,
    pub first_index: u32,
    pub index_count: u32,
    /// Range in the tree's rects.
    pub first_rect: u32,
    pub rect_count: u32,
    /// Range in the tree's originals.
    pub first_original: u32,
    pub original_count: u32,
    pub _pad: u32,
}
const _: () = assert!(size_of::<LeafRecord>() == 72);

impl LeafRecord {
    /// Encodes `l` with its rects and originals at the given tree-local positions.
    pub fn encode(l: &Leaf, first_rect: u32, first_original: u32) -> Option<Self> {
        Some(LeafRecord {
            origin: l.origin.to_array(),
            clamp_scale: l.clamp_scale,
            node: l.node.0,
            first_vertex: l.first_vertex,
            vertex_count: l.vertex_count,
            first_index: l.first_index,
            index_count: l.index_count,
            first_rect,
            rect_count: u32::try_from(l.rects.len()).ok()?,
            first_original,
            original_count: u32::try_from(l.originals.len()).ok()?,
            _pad: 0,
        })
    }

    /// The leaf with the given rects and originals.
    pub fn decode(&self, rects: &[RectRecord], originals: &[OriginalRecord]) -> Leaf {
        Leaf {
            node: NodeId(self.node),
            origin: self.origin.into(),
            first_vertex: self.first_vertex,
            vertex_count: self.vertex_count,
            first_index: self.first_index,
            index_count: self.index_count,
            rects: rects.iter().map(RectRecord::decode).collect(),
            originals: originals.iter().map(OriginalRecord::decode).collect(),
            clamp_scale: self.clamp_scale,
        }
    }
}

/// Where one material's area sits in a leaf atlas ([`AtlasRect`]).
#[derive(Copy, Clone, Debug, PartialEq, Pod, Zeroable)]
#[repr(C)]
pub struct RectRecord {
    /// A_tex in the material's UV space.
    pub uv_min: [f64; 2],
    pub uv_max: [f64; 2],
    pub material: u32,
    /// Outer rectangle incl. border `[x, y, w, h]`, texels.
    pub outer: [u32; 4],
    /// Inner rectangle `[x, y, w, h]`, texels.
    pub inner: [u32; 4],
    /// `wrap_s | wrap_t << 2 | capped_s << 4 | capped_t << 5` ([`RectWrap::code`]); other bits zero.
    pub flags: u32,
    /// [`AtlasRect::mean`] (format 6): written when the leaf's atlas block is, by
    /// [`crate::store::FileWriter`].
    pub mean: [u8; 4],
    pub _reserved: u32,
}
const _: () = assert!(size_of::<RectRecord>() == 80);

/// Bits of [`RectRecord::flags`] this version defines.
pub const RECT_FLAGS_KNOWN: u32 = 0x3f;

impl RectRecord {
    pub fn encode(r: &AtlasRect) -> Self {
        RectRecord {
            uv_min: r.uv_min,
            uv_max: r.uv_max,
            material: r.material.0,
            outer: r.outer,
            inner: r.inner,
            flags: r.wrap[0].code()
                | r.wrap[1].code() << 2
                | u32::from(r.capped[0]) << 4
                | u32::from(r.capped[1]) << 5,
            mean: r.mean,
            _reserved: 0,
        }
    }

    /// Per-axis wrap of the rect (`None` for flags this version does not define; validated files have
    /// none).
    pub fn wrap(&self) -> Option<[RectWrap; 2]> {
        if self.flags & !RECT_FLAGS_KNOWN != 0 {
            return None;
        }
        Some([
            RectWrap::from_code(self.flags & 3)?,
            RectWrap::from_code((self.flags >> 2) & 3)?,
        ])
    }

    /// Per axis, whether the source cap limited the rect's texels per period.
    pub fn capped(&self) -> [bool; 2] {
        [self.flags & 16 != 0, self.flags & 32 != 0]
    }

    /// The rect; unknown flags decode as [`RectWrap::Linear`] (validated files have none).
    pub fn decode(&self) -> AtlasRect {
        AtlasRect {
            material: MaterialId(self.material),
            outer: self.outer,
            inner: self.inner,
            uv_min: self.uv_min,
            uv_max: self.uv_max,
            wrap: self.wrap().unwrap_or_default(),
            capped: self.capped(),
            mean: self.mean,
        }
    }
}

/// One original texture of a leaf ([`OriginalRef`]).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct OriginalRecord {
    pub material: u32,
    pub image: u32,
    /// Stored width after resampling, texels (a power of two in 4..=2048; the block holds a
    /// `width × height` chain, [`crate::texfmt::mip_extents`]).
    pub width: u16,
    /// Stored height, texels (as `width`).
    pub height: u16,
    /// Global block id.
    pub block: u32,
    /// Position within the block.
    pub slot: u32,
}
const _: () = assert!(size_of::<OriginalRecord>() == 20);

impl OriginalRecord {
    /// Side of the class array the texture is drawn from: the larger of its sides.
    pub fn class_size(&self) -> u32 {
        u32::from(self.width.max(self.height))
    }

    /// `[width, height]`, texels.
    pub fn extent(&self) -> [u32; 2] {
        [u32::from(self.width), u32::from(self.height)]
    }

    pub fn encode(o: &OriginalRef) -> Self {
        let side = |v: u32| u16::try_from(v).unwrap_or(u16::MAX);
        OriginalRecord {
            material: o.material.0,
            image: o.image.0,
            width: side(o.extent[0]),
            height: side(o.extent[1]),
            block: o.block.0,
            slot: o.slot,
        }
    }

    pub fn decode(&self) -> OriginalRef {
        OriginalRef {
            material: MaterialId(self.material),
            image: ImageId(self.image),
            extent: self.extent(),
            block: BlockId(self.block),
            slot: self.slot,
        }
    }
}

/// Block kinds in [`BlockRecord::kind`].
pub const BLOCK_ATLAS: u32 = 0;
pub const BLOCK_ORIGINALS: u32 = 1;

/// One block: where its bytes are and what they hold ([`BlockDesc`]).
#[derive(Copy, Clone, Debug, Default, PartialEq, Eq, Pod, Zeroable)]
#[repr(C)]
pub struct BlockRecord {
    /// Byte offset in the file, a multiple of [`BLOCK_ALIGN`].
    pub offset: u64,
    /// Byte length.
    pub length: u64,
    /// `xxh3_64` of the block's bytes.
    pub checksum: u64,
    /// Compression error measured at build time: sum of squared 8-bit differences between the stored
    /// texels (decoded) and the uncompressed ones they were encoded from, over R, G, B (and A in alpha
    /// trees) of every texel of every level (0 for RGBA8). PSNR follows with the texel count
    /// ([`crate::texfmt::psnr`]).
    pub sse: u64,
    /// Index of the tree.
    pub tree: u32,
    /// [`BLOCK_ATLAS`] or [`BLOCK_ORIGINALS`].
    pub kind: u32,
    /// Tree-local node id (atlas) or leaf id (originals).
    pub item: u32,
    /// Part of the leaf's originals (0 for atlases).
    pub part: u32,
}
const _: () = assert!(size_of::<BlockRecord>() == 48);

impl BlockRecord {
    /// Encodes `d` at `offset` with checksum and error 0 (filled in when the block is written).
    pub fn encode(d: &BlockDesc, offset: u64) -> Self {
        let (kind, item, part) = match d.kind {
            BlockKind::Atlas { node } => (BLOCK_ATLAS, node.0, 0),
            BlockKind::Originals { leaf, part } => (BLOCK_ORIGINALS, leaf.0, part),
        };
        BlockRecord {
            offset,
            length: d.bytes,
            checksum: 0,
            sse: 0,
            tree: d.tree,
            kind,
            item,
            part,
        }
    }

    /// The block kind; `None` for an unknown code.
    pub fn block_kind(&self) -> Option<BlockKind> {
        match self.kind {
            BLOCK_ATLAS => Some(BlockKind::Atlas {
                node: NodeId(self.item),
            }),
            BLOCK_ORIGINALS => Some(BlockKind::Originals {
                leaf: LeafId(self.item),
                part: self.part,
            }),
            _ => None,
        }
    }

    /// The block description; `None` for an unknown kind.
    pub fn decode(&self) -> Option<BlockDesc> {
        Some(BlockDesc {
            tree: self.tree,
            kind: self.block_kind()?,
            bytes: self.length,
        })
    }
}

#[cfg(test)]
mod tests;
