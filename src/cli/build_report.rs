//! What `atlastree build` prints: the build's report (trees, sizing, palettes, leaves, originals, blocks),
//! its stage times, throughput and peak memory, and the import's counts and first warnings.

use atlastree::preprocess::BuildReport;
use atlastree::util::{fixed_number, human_bytes, short_number};

/// `n` texels as "12.3 Mtexels".
pub(super) fn human_texels(n: u64) -> String {
    let n = n as f64;
    if n >= 1e9 {
        format!("{:.2} Gtexels", n / 1e9)
    } else if n >= 1e6 {
        format!("{:.1} Mtexels", n / 1e6)
    } else {
        format!("{:.0} ktexels", n / 1e3)
    }
}

pub(super) fn print_report(r: &BuildReport, out: &std::path::Path) {
    let p = &r.params;
    println!("wrote {} ({})", out.display(), human_bytes(r.file_bytes));
    println!(
        "  d_min {} m (scene diagonal {} m), screen {} px, fov {}°, texel ratio {}, atlas {}², border {}",
        fixed_number(p.d_min, 3),
        fixed_number(r.scene_diagonal, 1),
        p.screen_width,
        short_number(p.fov_deg),
        short_number(p.texel_ratio),
        p.atlas_size,
        p.border
    );
    for t in &r.trees {
        // Where repeats are baked, sizing cuts triangles into pieces, which the lines below and
        // `inspect` count (fault hunt, session 32: "1290 triangles" beside sizing counts of 43,984).
        let cut = if t.pieces != t.triangles {
            format!(" ({} pieces after cutting baked repeats)", t.pieces)
        } else {
            String::new()
        };
        println!(
            "  {:?} tree: {} triangles{cut} → {} nodes, {} leaves, depth {}, {} vertices; occupancy mean {:.0}% (min {:.0}%, max {:.0}%); root min_distance {} m",
            t.kind,
            t.triangles,
            t.nodes,
            t.leaves,
            t.depth,
            t.vertices,
            100.0 * t.occupancy_mean,
            100.0 * t.occupancy_min,
            100.0 * t.occupancy_max,
            fixed_number(t.root_min_distance, 1)
        );
        let s = &t.sizing;
        println!(
            "    sizing: {} exact, {} edge fallback, {} all-UV-equal, {} world-degenerate; {} rects capped to source; {} scaled leaves",
            s.exact,
            s.edge_fallback,
            s.all_uv_equal,
            s.world_degenerate,
            t.capped_rects,
            t.clamped_leaves
        );
        if s.palette.materials > 0 {
            println!(
                "    palettes: {} constant-UV texels of {} materials kept as rects of their own",
                s.palette.cells, s.palette.materials
            );
        }
        if let Some(line) = capped_line(t.capped_rects, &t.capped_shortfall) {
            println!("    {line}");
        }
        let lr = &t.leaf_reasons;
        println!(
            "    leaves: {} fit, {} scaled for an oversized rect, {} scaled at source resolution, {} scaled within \
             --leaf-originals, {} shared-texture, {} clamped triangles; smallest scale {}; originals of scaled \
             leaves {} (largest leaf {})",
            lr.fits,
            lr.oversized,
            lr.source_resolution,
            lr.scaled,
            lr.shared,
            lr.clamped,
            atlastree::util::fraction_text(lr.scale_min),
            human_texels(lr.scaled_original_texels),
            human_texels(lr.scaled_original_texels_max)
        );
        println!(
            "    periods stored {:.1} of the {:.1} the rects' UV boxes span ({})",
            t.periods_stored,
            t.periods_spanned,
            periods_ratio(t.periods_stored, t.periods_spanned)
        );
        let o = &t.originals;
        println!(
            "    originals: {} stored, one per image, wrap and MASK cutoff ({} leaf references, {} images), {} ({} as square classes); the sources once in {} with mips {} ({:.2}×)",
            o.stored,
            o.references,
            o.images,
            human_bytes(o.bytes),
            human_bytes(o.square_bytes),
            t.format.name(),
            human_bytes(o.source_bytes),
            o.bytes as f64 / o.source_bytes.max(1) as f64
        );
        println!(
            "    blocks stored as {} ({} bytes per 4×4 texels); atlas PSNR vs uncompressed {}",
            t.format.name(),
            t.format.bytes_per_block(),
            fmt_psnr(t.atlas_psnr_db)
        );
    }
    println!(
        "  blocks: {} ({} atlases, {} original-texture blocks)",
        r.blocks, r.atlas_blocks, r.original_blocks
    );
    print_times(&r.stages.timings);
    print_throughput(r);
    println!(
        "  images decoded {} ({} fallbacks, alpha ignored in {} used only by OPAQUE materials), peak memory {}",
        r.images_decoded,
        r.image_fallbacks,
        r.images_alpha_ignored,
        r.stages.peak_rss_bytes.map_or("?".into(), human_bytes)
    );
    print_stage_peaks(&r.stages.stage_peak_rss);
    print_import(&r.import);
    for w in &r.warnings {
        println!("  warning: {w}");
    }
}

/// How many of the import's warnings the build summary quotes (`scene-info` lists up to 100).
pub(super) const IMPORT_WARNINGS_SHOWN: usize = 5;

/// The import's counts and first warnings, when it skipped or replaced anything.
pub(super) fn print_import(r: &atlastree::scene::ImportReport) {
    if r.warnings_total == 0 {
        return;
    }
    println!(
        "  import: {} warnings: {} missing images (drawn with the magenta/black checker), {} truncated images, {} \
         primitives and {} triangles skipped, {} primitives without their TEXCOORD, {} triangles with huge UVs",
        r.warnings_total,
        r.missing_images,
        r.truncated_images,
        r.skipped_primitives,
        r.skipped_triangles,
        r.missing_texcoords,
        r.large_uv_triangles
    );
    for w in r.warnings.iter().take(IMPORT_WARNINGS_SHOWN) {
        println!("    warning: {w}");
    }
    let shown = r.warnings.len().min(IMPORT_WARNINGS_SHOWN) as u64;
    if r.warnings_total > shown {
        // `scene-info` lists the warnings the import kept, not all it counted (fault hunt, session 37).
        let listed = r.warnings.len() as u64;
        let where_ = if listed >= r.warnings_total {
            "`atlastree scene-info` lists them".to_string()
        } else {
            format!("`atlastree scene-info` lists the first {listed}")
        };
        println!("    … {} more ({where_})", r.warnings_total - shown);
    }
}

/// `  time: import 0.10s, sizing Opaque 0.20s, …`
pub(super) fn print_times(timings: &[(String, f64)]) {
    let times: Vec<String> = timings
        .iter()
        .map(|(n, s)| format!("{n} {s:.2}s"))
        .collect();
    println!("  time: {}", times.join(", "));
}

/// `  throughput: sizing Opaque 6.1 M triangles/s, …, rasterise 412 Mtexels/s stored (95 Mtexels/s of
/// source decoded)`: the plan stages per triangle of their tree, the pixel pass per texel it wrote and read.
pub(super) fn print_throughput(r: &BuildReport) {
    let mut parts = Vec::new();
    for (name, secs) in &r.stages.timings {
        let rate = |n: u64| n as f64 / secs.max(1e-9) / 1e6;
        if let Some((stage, kind)) = name.split_once(' ') {
            let tree = r.trees.iter().find(|t| format!("{:?}", t.kind) == kind);
            if let (Some(t), "sizing" | "layout" | "assemble") = (tree, stage) {
                parts.push(format!("{name} {:.2} M triangles/s", rate(t.triangles)));
            }
        } else if name == "rasterise" {
            parts.push(format!(
                "rasterise {:.0} Mtexels/s stored ({:.0} Mtexels/s of source decoded)",
                rate(r.texels_stored),
                rate(r.texels_decoded)
            ));
        }
    }
    if !parts.is_empty() {
        println!("  throughput: {}", parts.join(", "));
    }
}

/// `  peak memory per stage: import 12 MiB, …` (nothing where the platform does not tell).
pub(super) fn print_stage_peaks(peaks: &[(String, u64)]) {
    let stages: Vec<String> = peaks
        .iter()
        .filter(|(n, _)| n != "total")
        .map(|(n, b)| format!("{n} {}", human_bytes(*b)))
        .collect();
    if !stages.is_empty() {
        println!("  peak memory per stage: {}", stages.join(", "));
    }
}

/// A PSNR for humans: `lossless` at the cap ([`atlastree::texfmt::PSNR_CAP_DB`]) and above.
pub(super) fn fmt_psnr(db: f64) -> String {
    if db >= atlastree::texfmt::PSNR_CAP_DB {
        "lossless".into()
    } else if db < 0.0 {
        // Only a recorded error read from a file can be past the largest 8-bit error (255 per channel:
        // 0 dB); plain `inspect` printed a forged one as a PSNR without a word (fault hunt, session 38).
        format!(
            "{db:.2} dB (impossible: a recorded error above the largest 8-bit one; `inspect --verify` \
             names the block)"
        )
    } else {
        format!("{db:.2} dB")
    }
}

/// The build summary's line on capped rects drawn coarser than their sources (docs/DESIGN.md "Where the
/// guarantee does not hold: capped rects above their leaf"), or `None` where nothing falls short.
pub(super) fn capped_line(
    rects: u64,
    s: &atlastree::preprocess::CappedShortfall,
) -> Option<String> {
    // A tree without a level above its leaves (depth 0) has its root for its leaf.
    let root = if s.one_up > 1.0 { s.at_root } else { 1.0 };
    let parts: Vec<String> = [
        (s.at_leaf, "in leaves scaled to fit"),
        (s.one_up, "one level above their leaf"),
        (root, "from the root"),
    ]
    .iter()
    .filter(|(f, _)| *f > 1.0)
    .map(|(f, where_)| format!("{f:.1}× {where_}"))
    .collect();
    if rects == 0 || parts.is_empty() {
        return None;
    }
    Some(format!(
        "capped rects drawn with fewer texels than their originals show at the same distance: up to {} \
         (close views draw the originals; the design document's \"capped rects above their leaf\")",
        parts.join(", ")
    ))
}

/// How many times fewer periods a tree stores than its rects' UV boxes span, in words: "1× fewer" was
/// printed for any ratio under 1.5 and where more were stored than spanned (baked repeats; fault hunt,
/// session 32).
fn periods_ratio(stored: f64, spanned: f64) -> String {
    if spanned.is_nan() || spanned <= 0.0 {
        // Rects of constant UVs (palettes) span no period.
        return "none spanned".to_string();
    }
    let ratio = spanned / stored.max(1e-9);
    if ratio >= 10.0 {
        format!("{ratio:.0}× fewer")
    } else if ratio >= 1.005 {
        format!("{ratio:.2}× fewer")
    } else if ratio > 1.0 / 1.005 {
        "as many".to_string()
    } else {
        format!("{:.2}× more", 1.0 / ratio.max(1e-300))
    }
}

#[cfg(test)]
mod periods_tests {
    use super::periods_ratio;

    #[test]
    fn the_periods_ratio_says_fewer_or_more() {
        assert_eq!(periods_ratio(1.0, 250.0), "250× fewer");
        assert_eq!(periods_ratio(16.1, 18.1), "1.12× fewer");
        assert_eq!(periods_ratio(617835.7, 617794.1), "as many");
        assert_eq!(periods_ratio(2.0, 1.0), "2.00× more");
        assert_eq!(periods_ratio(3.0, 0.0), "none spanned");
    }
}
