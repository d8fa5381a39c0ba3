//! Deep leaves on the GPU: a leaf below level 13 (or in a cell past 2^13) does not fit the packed
//! `LeafInfo::cell_level` word, and the vertex stage reads its cell and level from their own fields
//! (`CELL_LEVEL_WIDE` in tree.wgsl). The CPU suite checks the transform's arithmetic at depth 24
//! (`tests/cpu/preprocess/deep_tree.rs`); this draws such a leaf's atlas and compares it with the
//! originals.

use atlastree::camera::Camera;
use atlastree::gpu::GpuContext;
use atlastree::ids::NONE;
use atlastree::preprocess::{NoProgress, build};
use atlastree::render::Mode;
use atlastree::render::wgsl::tree::{CELL_LEVEL_WIDE, LeafInfo};
use atlastree::select::Source;
use atlastree::store::TreeFile;
use glam::DVec3;

use crate::harness::GpuTest;
use crate::peel_strip::{peel_strip, strip_options};
use crate::render::{H, W, e, psnr_covered, renderer};

pub fn tests() -> Vec<GpuTest> {
    vec![GpuTest {
        name: "deep::a_level_16_leaf_draws_its_atlas_like_the_originals",
        run: a_level_16_leaf_draws_its_atlas_like_the_originals,
    }]
}

/// The depth of the strip: its deepest leaf is at level 16 in cell (65535, 65535), past the packed word.
const DEPTH: u32 = 16;

/// The peeling strip built to depth 16, seen from straight above its deepest leaf at 0.75× the leaf's
/// extent, with the selection scaled so that leaf's own atlas suffices there and its parent's does not:
/// the cut draws the level-16 leaf from its atlas (its `cell_level` is `CELL_LEVEL_WIDE`), and the tree
/// frame matches the originals to ≥ 35 dB over the covered pixels, the floor of the other tree-vs-original
/// tests. Every triangle has a texture of one colour, so a leaf drawn with a wrong cell or level samples
/// another triangle's area, or the border between them, and fails this (measured on lavapipe: 99 dB,
/// the frames identical; with the wide branch removed from tree.wgsl, so the packed word's 13-bit cell is
/// read instead, 14.1 dB).
fn a_level_16_leaf_draws_its_atlas_like_the_originals(ctx: &GpuContext) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(e)?;
    let out = dir.path().join("strip.atlastree");
    build(&peel_strip(DEPTH), &strip_options(), &out, &NoProgress).map_err(e)?;
    let file = TreeFile::open(&out).map_err(e)?;
    let t = file.tree(0).ok_or("no tree 0")?;
    let (deep, node) = t
        .nodes
        .iter()
        .enumerate()
        .filter(|(_, n)| n.leaf != NONE)
        .max_by_key(|(_, n)| n.level)
        .ok_or("no leaf")?;
    let packed = LeafInfo::pack_cell_level(node.level, [node.cell.ix, node.cell.iy]);
    if node.level != DEPTH || packed != CELL_LEVEL_WIDE {
        return Err(format!(
            "the deepest leaf is at level {} in cell {:?}, packed {packed:#x}: the test needs a level-{DEPTH} \
             leaf past the packed word",
            node.level, node.cell
        ));
    }
    let (lo, hi) = (
        DVec3::from_array(node.bounds_min),
        DVec3::from_array(node.bounds_max),
    );
    let centre = (lo + hi) / 2.0;
    let height = 0.75 * (hi - lo).max_element();
    let cam = Camera {
        eye: centre + DVec3::Y * height,
        target: centre,
        up: DVec3::NEG_Z,
        fov_x_deg: 60.0,
        aspect: f64::from(W) / f64::from(H),
        near: height / 100.0,
        far: 10_000.0,
    };
    // The leaf's atlas suffices beyond scale · min_distance: 0.8 of the camera's height.
    let scale = 0.8 * height / node.min_distance;
    let mut r = renderer(ctx, &file)?;
    r.render(&cam, scale, Mode::Tree).map_err(e)?;
    let drawn = r.cuts()[0]
        .items
        .iter()
        .find(|i| i.node.idx() == deep)
        .map(|i| (i.source, i.level));
    if drawn != Some((Source::Atlas, DEPTH as u8)) {
        return Err(format!(
            "the cut must draw leaf {deep} from its own atlas, drew it as {drawn:?}"
        ));
    }
    let tree = r.read_frame().map_err(e)?;
    r.render(&cam, scale, Mode::Original).map_err(e)?;
    let original = r.read_frame().map_err(e)?;
    let (psnr, covered) = psnr_covered(&tree, &original);
    println!(
        "  level-{DEPTH} leaf {deep} in cell ({}, {}) from its atlas: tree vs original {psnr:.2} dB over \
         {covered} px",
        node.cell.ix, node.cell.iy
    );
    if covered < (W * H / 8) as usize {
        return Err(format!(
            "the view must show the strip over an eighth of the frame: {covered} px"
        ));
    }
    if psnr < 35.0 {
        return Err(format!("tree vs original {psnr:.2} dB < 35 dB"));
    }
    Ok(())
}
