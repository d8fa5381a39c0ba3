//! Pictures of a paging file for people: a node's atlas, the leaves' map, two images side by side
//! (the demo and the README's pictures).

use crate::ids::NONE;
use crate::store::{StoreError, TreeFile};

/// Level 0 of a node's atlas as an RGBA8 image (reads and checksums its block, decodes BC formats).
pub fn atlas_image(
    file: &TreeFile,
    tree: usize,
    node: usize,
) -> Result<image::RgbaImage, StoreError> {
    let t = file.tree(tree).ok_or(StoreError::BadReference {
        table: "trees",
        index: tree as u64,
        field: "index",
        value: tree as u64,
        limit: file.trees() as u64,
    })?;
    let size = file.params().atlas_size;
    let n = t.nodes.get(node).ok_or(StoreError::BadReference {
        table: "nodes",
        index: node as u64,
        field: "index",
        value: node as u64,
        limit: t.nodes.len() as u64,
    })?;
    let bytes = file.block(crate::ids::BlockId(n.atlas_block))?;
    let format = t.format();
    let level0 = format.level_bytes(size) as usize;
    let img = bytes.get(..level0).and_then(|b| {
        image::RgbaImage::from_raw(size, size, crate::texfmt::decode_level(format, b, size))
    });
    img.ok_or(StoreError::BlockLength {
        block: crate::ids::BlockId(n.atlas_block),
        expected: level0 as u64,
        got: bytes.len() as u64,
    })
}

/// A top-down map of a tree's leaves over the distribution plane, `px` pixels on the long side: each leaf's
/// plane bounds filled with a colour for its depth (blue = shallow … red = deep) and outlined.
pub fn leaf_map_image(file: &TreeFile, tree: usize, px: u32) -> image::RgbaImage {
    let Some(t) = file.tree(tree) else {
        return image::RgbaImage::new(1, 1);
    };
    let up = file.to_params().up;
    let plane = |p: [f64; 3]| up.plane(glam::DVec3::from_array(p));
    let (Some(root), px) = (t.nodes.first(), px.max(16)) else {
        return image::RgbaImage::new(1, 1);
    };
    let (lo, hi) = (plane(root.bounds_min), plane(root.bounds_max));
    let ext = (hi - lo).max(glam::DVec2::splat(1e-9));
    let s = f64::from(px - 8) / ext.x.max(ext.y);
    let (w, h) = ((ext.x * s) as u32 + 8, (ext.y * s) as u32 + 8);
    let mut img = image::RgbaImage::from_pixel(w, h, image::Rgba([255, 255, 255, 255]));
    let depth = t.nodes.iter().map(|n| n.level).max().unwrap_or(0).max(1) as f32;
    let to_px = |p: glam::DVec2| ((p.x - lo.x) * s + 4.0, (p.y - lo.y) * s + 4.0);
    for n in t.nodes.iter().filter(|n| n.leaf != NONE) {
        let (a, b) = (to_px(plane(n.bounds_min)), to_px(plane(n.bounds_max)));
        let f = n.level as f32 / depth;
        let col = [
            (60.0 + 195.0 * f) as u8,
            (90.0 + 80.0 * (1.0 - (2.0 * f - 1.0).abs())) as u8,
            (255.0 - 195.0 * f) as u8,
        ];
        let (x0, x1) = (a.0.min(b.0) as u32, (a.0.max(b.0) as u32).min(w - 1));
        let (y0, y1) = (a.1.min(b.1) as u32, (a.1.max(b.1) as u32).min(h - 1));
        for y in y0..=y1 {
            for x in x0..=x1 {
                let edge = x == x0 || x == x1 || y == y0 || y == y1;
                let p = img.get_pixel_mut(x, y);
                for (ch, &c) in p.0.iter_mut().zip(col.iter()) {
                    let target = if edge { c / 2 } else { c };
                    *ch = ((u16::from(*ch) + u16::from(target) * 3) / 4) as u8;
                }
            }
        }
    }
    img
}

/// Two images side by side on white, `b` scaled (nearest) to `a`'s height, with a `gap` in pixels.
pub fn side_by_side(a: &image::RgbaImage, b: &image::RgbaImage, gap: u32) -> image::RgbaImage {
    let h = a.height().max(1);
    let bw = (u64::from(b.width()) * u64::from(h) / u64::from(b.height().max(1))).max(1) as u32;
    let b = image::imageops::resize(b, bw, h, image::imageops::FilterType::Triangle);
    let mut out =
        image::RgbaImage::from_pixel(a.width() + gap + bw, h, image::Rgba([255, 255, 255, 255]));
    image::imageops::overlay(&mut out, a, 0, 0);
    image::imageops::overlay(&mut out, &b, i64::from(a.width() + gap), 0);
    out
}
