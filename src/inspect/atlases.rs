//! `verify` of the opaque tree's inner atlases (paper §5.1: an inner atlas is its four children halved):
//! each child's quadrant of its parent's level 0 against the child's own stored level 1. Checksums vouch
//! only for the bytes written; a build or merge that combined the wrong children, or a block replaced and
//! resealed, left every invariant holding (fault hunt, session 30: a greyed inner atlas passed).
//!
//! The two sides are encoded apart (a parent's level 0 from its children's f32 level 1, each child's
//! level 1 from the same values), so they differ by encoding alone: rounding uncompressed, block
//! compression's error twice compressed. The alpha tree is not compared: with `--alpha-mips coverage` a
//! stored level 1 keeps its own coverage, which the file does not record.

use super::VerifyReport;
use crate::ids::{BlockId, NONE};
use crate::model::TreeKind;
use crate::store::TreeFile;
use crate::texfmt::{TexFormat, decode_level};

/// Largest mean difference (sRGB8 levels, RGB) allowed between a child's quadrant of its parent's level 0
/// and the child's level 1: rounding and the mip filter's own rounding uncompressed; two block encodings
/// of one image compressed. A replaced or misplaced atlas differs by tens of levels.
fn inner_atlas_tolerance(format: TexFormat) -> f64 {
    match format {
        TexFormat::Rgba8 => 2.0,
        TexFormat::Bc7 => 8.0,
        _ => 16.0,
    }
}

/// Level `k` (0 or 1) of a square atlas chain of side `size` as RGBA8 texels; `None` where the block is
/// shorter.
pub(super) fn level_rgba8(format: TexFormat, bytes: &[u8], size: u32, k: u32) -> Option<Vec<u8>> {
    let (start, side) = if k == 0 {
        (0, size)
    } else {
        (format.level_bytes(size) as usize, size / 2)
    };
    let level = bytes.get(start..start + format.level_bytes(side) as usize)?;
    Some(if format.is_compressed() {
        decode_level(format, level, side)
    } else {
        level.to_vec()
    })
}

/// Compares every child's quadrant of every inner atlas of the opaque tree with the child's level 1.
pub(super) fn verify_inner_atlases(file: &TreeFile, r: &mut VerifyReport) {
    let size = file.params().atlas_size;
    let half = size / 2;
    for ti in 0..file.trees() {
        let Some(t) = file.tree(ti) else { continue };
        if t.kind != TreeKind::Opaque {
            continue;
        }
        let format = t.format();
        let tol = inner_atlas_tolerance(format);
        for (ni, n) in t.nodes.iter().enumerate() {
            if n.children.iter().all(|&c| c == NONE) {
                continue;
            }
            // A bad checksum or a short block is reported by the block pass.
            let Some(parent) = (file.block(BlockId(n.atlas_block)).ok())
                .and_then(|b| level_rgba8(format, &b, size, 0))
            else {
                continue;
            };
            for &c in n.children.iter().filter(|&&c| c != NONE) {
                let Some(child) = t.nodes.get(c as usize) else {
                    continue;
                };
                let Some(level1) = (file.block(BlockId(child.atlas_block)).ok())
                    .and_then(|b| level_rgba8(format, &b, size, 1))
                else {
                    continue;
                };
                let (qx, qy) = ((child.cell.ix & 1) * half, (child.cell.iy & 1) * half);
                let mean = quadrant_difference(&parent, size, (qx, qy), &level1, half);
                r.inner_quadrants_checked += 1;
                r.inner_quadrant_mean_max = r.inner_quadrant_mean_max.max(mean);
                if mean > tol {
                    r.fail(format!(
                        "tree {ti} node {ni}: its quadrant of child {c} differs from the child's level 1 by \
                         {mean:.2} sRGB levels on average (tolerance {tol} for {}): not the child halved",
                        format.name()
                    ));
                }
            }
        }
    }
}

/// Mean absolute difference (sRGB8 levels, R, G and B) between the `side`² texels of `parent` (an image
/// of `size` columns) from `at` and the `side`² texels of `child`.
fn quadrant_difference(parent: &[u8], size: u32, at: (u32, u32), child: &[u8], side: u32) -> f64 {
    let (size, side) = (size as usize, side as usize);
    let (x0, y0) = (at.0 as usize, at.1 as usize);
    let mut sum = 0u64;
    for y in 0..side {
        let p = ((y0 + y) * size + x0) * 4;
        let (Some(prow), Some(crow)) = (
            parent.get(p..p + side * 4),
            child.get(y * side * 4..(y + 1) * side * 4),
        ) else {
            return f64::INFINITY;
        };
        for (a, b) in prow.chunks_exact(4).zip(crow.chunks_exact(4)) {
            sum += (0..3).map(|k| u64::from(a[k].abs_diff(b[k]))).sum::<u64>();
        }
    }
    sum as f64 / (3 * side * side).max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_quadrant_is_compared_with_its_child() {
        // A 4² parent whose top-right quadrant is the 2² child exactly, the rest zero.
        let (size, side) = (4u32, 2u32);
        let child: Vec<u8> = (0..side * side * 4).map(|i| (i * 7 % 251) as u8).collect();
        let mut parent = vec![0u8; (size * size * 4) as usize];
        for y in 0..side as usize {
            for x in 0..side as usize {
                let p = (y * size as usize + 2 + x) * 4;
                let c = (y * side as usize + x) * 4;
                parent[p..p + 4].copy_from_slice(&child[c..c + 4]);
            }
        }
        assert_eq!(
            quadrant_difference(&parent, size, (2, 0), &child, side),
            0.0
        );
        assert!(quadrant_difference(&parent, size, (0, 0), &child, side) > 10.0);
        // A short child is no match at all.
        assert_eq!(
            quadrant_difference(&parent, size, (2, 0), &child[..8], side),
            f64::INFINITY
        );
    }
}
