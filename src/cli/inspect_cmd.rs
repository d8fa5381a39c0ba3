use super::build_report::fmt_psnr;
use anyhow::Context;
use atlastree::inspect::{InspectReport, VerifyReport, inspect, reference_mismatch, verify_with};
use atlastree::store::TreeFile;
use atlastree::util::{fixed_number, human_bytes, short_number};
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

#[derive(Args, Debug)]
pub(crate) struct InspectArgs {
    /// A paging file written by `atlastree build`.
    pub file: PathBuf,
    /// Check every block checksum and every tree invariant; exit with status 1 on any violation (a file
    /// whose header or tables break the format included; 2 when it cannot be read at all). For
    /// compressed trees also lists each atlas's PSNR against its uncompressed version (recorded at build
    /// time; the file holds only the compressed texels).
    #[arg(long)]
    pub verify: bool,
    /// With --verify: a file built from the same scene and parameters with `--compress none`; every
    /// compressed atlas is decoded and its PSNR re-measured against it (must match the recorded value).
    #[arg(long, requires = "verify")]
    pub reference: Option<PathBuf>,
    /// Print JSON instead of text.
    #[arg(long)]
    pub json: bool,
}

/// "opening FILE: why", without FILE twice where the error names it already.
fn opening_message(file: &std::path::Path, e: &atlastree::store::StoreError) -> String {
    let why = e.to_string();
    let name = file.display().to_string();
    if why.starts_with(&name) {
        format!("opening {why}")
    } else {
        format!("opening {name}: {why}")
    }
}

pub(super) fn run(a: InspectArgs) -> anyhow::Result<ExitCode> {
    super::reject_url(&a.file, "inspect")?;
    // The reference too: a URL was "No such file or directory" (fault hunt, session 38).
    if let Some(reference) = &a.reference {
        super::reject_url(reference, "inspect --reference")?;
    }
    // The tables in memory, blocks read through the handle: `--verify` reads for long, and a file
    // truncated meanwhile is then an error naming the block, not SIGBUS (fault hunt, session 28).
    let file = match TreeFile::open_with(&a.file, atlastree::store::LoadMode::Tables) {
        Ok(file) => file,
        // With --verify a file that opens but breaks the format (a checksum, a bad header, table or value)
        // is a violation like a corrupt block: status 1. An unreadable one is an error (status 2).
        Err(e) if a.verify && !matches!(e, atlastree::store::StoreError::Io { .. }) => {
            let message = opening_message(&a.file, &e);
            if a.json {
                // The schema of a file that opens: `ok`, the count and the list (the message in it), and
                // `open_error` beside them; no inspection.
                let verify = serde_json::json!({
                    "ok": false,
                    "violation_count": 1,
                    "violations": [message.clone()],
                    "open_error": message,
                });
                println!(
                    "{}",
                    serde_json::to_string_pretty(
                        &serde_json::json!({ "inspect": null, "verify": verify })
                    )?
                );
            } else {
                eprintln!("error: {message}");
                println!("verify: 1 violation: the file is not a valid paging file");
            }
            return Ok(ExitCode::from(1));
        }
        Err(e) => {
            return Err(anyhow::anyhow!(opening_message(&a.file, &e)));
        }
    };
    let reference = match a.reference.as_deref() {
        Some(p) if a.verify => Some(
            TreeFile::open_with(p, atlastree::store::LoadMode::Tables)
                .with_context(|| format!("opening the reference {}", p.display()))?,
        ),
        _ => None,
    };
    // A reference of other parameters is a usage error (exit 2), not a violation of this file.
    if let Some(why) = (reference.as_ref()).and_then(|rf| reference_mismatch(&file, rf)) {
        anyhow::bail!("--reference: {why}");
    }
    // Said, not ignored (fault hunt, session 32): only compressed atlases are re-measured.
    let compressed = || {
        (0..file.trees())
            .filter_map(|t| file.tree(t))
            .any(|t| t.format().is_compressed())
    };
    if reference.is_some() && !compressed() {
        eprintln!(
            "note: --reference: {} stores no compressed atlas, so there is nothing to re-measure against it",
            a.file.display()
        );
    }
    let rep = inspect(&file);
    let ver = a.verify.then(|| verify_with(&file, reference.as_ref()));
    if a.json {
        // `ok` as a file that does not open has it (scripts read `verify.ok` either way).
        let verify = match &ver {
            Some(v) => {
                let mut j = serde_json::to_value(v)?;
                j["ok"] = serde_json::Value::Bool(v.ok());
                j["open_error"] = serde_json::Value::Null;
                j
            }
            None => serde_json::Value::Null,
        };
        println!(
            "{}",
            serde_json::to_string_pretty(&serde_json::json!({ "inspect": rep, "verify": verify }))?
        );
    } else {
        print_inspect(&rep);
        if let Some(v) = &ver {
            print_verify(v);
        }
    }
    Ok(match ver {
        Some(v) if !v.ok() => ExitCode::from(1),
        _ => ExitCode::SUCCESS,
    })
}

pub(super) fn print_inspect(r: &InspectReport) {
    let p = &r.params;
    println!("{} — {}", r.path, human_bytes(r.file_bytes));
    println!(
        "  built with d_min {} m, screen {} px, fov {}°, texel ratio {}, atlas {}², border {}, up {:?}",
        fixed_number(p.d_min, 3),
        p.screen_width,
        short_number(p.fov_deg),
        short_number(p.texel_ratio),
        p.atlas_size,
        p.border,
        p.up
    );
    println!(
        "  {} materials, {} blocks ({})",
        r.materials,
        r.blocks,
        human_bytes(r.block_bytes_total)
    );
    for t in &r.trees {
        println!(
            "  {:?} tree: {} nodes, {} leaves, depth {}, {} triangles{}, {} vertices, {} atlas + {} original blocks ({}), {} scaled leaves",
            t.kind,
            t.nodes,
            t.leaves,
            t.depth,
            t.triangles,
            if t.pieces == t.triangles {
                String::new()
            } else {
                format!(" ({} pieces)", t.pieces)
            },
            t.vertices,
            t.atlas_blocks,
            t.original_blocks,
            human_bytes(t.block_bytes),
            t.clamped_leaves
        );
        println!(
            "    format {} ({} bytes per 4×4 texels); atlas PSNR vs uncompressed {} (worst atlas {}), originals {}",
            t.format.name(),
            t.bytes_per_block,
            fmt_psnr(t.atlas_psnr_db),
            fmt_psnr(t.atlas_psnr_min_db),
            fmt_psnr(t.originals_psnr_db)
        );
        if t.originals_stored > 0 {
            let hist: Vec<String> = t
                .originals_sharing
                .iter()
                .map(|(leaves, n)| format!("{n}×{leaves}"))
                .collect();
            println!(
                "    originals: {} stored, one per image, wrap and MASK cutoff, {} references by leaf and material (stored originals × leaves sharing each: {})",
                t.originals_stored,
                t.original_refs,
                hist.join(", ")
            );
            let b = &t.original_blocks_cost;
            let shared: Vec<String> = b
                .users_per_block
                .iter()
                .map(|(leaves, n)| format!("{n}×{leaves}"))
                .collect();
            println!(
                "    original blocks: {} ({}) of {:.3} / {:.3} / {:.3} atlases (smallest / median / largest; {} over one atlas); \
                 leaves load {} of blocks for {} of their own textures ({:.2}×); blocks × leaves sharing each: {}",
                t.original_blocks,
                human_bytes(b.bytes),
                b.size_vs_atlas[0],
                b.size_vs_atlas[1],
                b.size_vs_atlas[2],
                b.over_atlas,
                human_bytes(b.loaded_bytes),
                human_bytes(b.needed_bytes),
                b.loaded_bytes as f64 / b.needed_bytes.max(1) as f64,
                shared.join(", ")
            );
        }
        let rp = &t.repeats;
        if rp.rects > 0 {
            // Chain bytes: 4/3 of the level-0 texels at the format's bytes per texel.
            let bytes =
                |texels: f64| (texels * f64::from(t.bytes_per_block) / 16.0 * 4.0 / 3.0) as u64;
            println!(
                "    repeats: {} rects hold a full period of {} images: {} of atlas texels over all levels \
                 ({:.1}% of {}); drawn from their originals' mip chains instead: {} once \
                 (one copy per leaf, as before format 4: {})",
                rp.rects,
                rp.images,
                human_bytes(bytes(rp.atlas_texels)),
                100.0 * rp.atlas_texels / (rp.all_atlas_texels.max(1) as f64),
                human_bytes(bytes(rp.all_atlas_texels as f64)),
                human_bytes(bytes(rp.original_texels_once as f64)),
                human_bytes(bytes(rp.original_texels_per_leaf as f64)),
            );
        }
        println!(
            "    level  nodes  leaves  triangles-in-leaves  pieces-in-leaves  min_distance (m)"
        );
        for l in &t.levels {
            println!(
                "    {:>5}  {:>5}  {:>6}  {:>19}  {:>16}  {} .. {}",
                l.level,
                l.nodes,
                l.leaves,
                l.triangles_in_leaves,
                l.pieces_in_leaves,
                atlastree::util::fraction_text(l.min_distance_min),
                atlastree::util::fraction_text(l.min_distance_max)
            );
        }
    }
    for e in &r.enabled {
        println!("  {e}");
    }
}

pub(super) fn print_verify(v: &VerifyReport) {
    println!(
        "verify: {} blocks, {} nodes, {} triangles ({} corners) checked: {}",
        v.blocks_checked,
        v.nodes_checked,
        v.triangles_checked,
        v.vertices_checked,
        if v.ok() {
            "all invariants hold".to_string()
        } else {
            format!("{} VIOLATIONS", v.violation_count)
        }
    );
    for m in &v.violations {
        println!("  violation: {m}");
    }
    if let Some(ratio_min) = v.period_ratio_min {
        println!(
            "  texels per period: {} (triangle, axis) pairs checked, smallest ratio to the need {:.6}{}",
            v.periods_checked,
            ratio_min,
            if v.periods_undecidable > 0 {
                format!(
                    "; {} not decidable from the file's f32 geometry (sized in f64 by the build)",
                    v.periods_undecidable
                )
            } else {
                String::new()
            }
        );
    }
    if v.wrap_borders_checked > 0 {
        println!(
            "  wrap borders: {} sides checked, largest mean difference {:.2} sRGB levels (premultiplied)",
            v.wrap_borders_checked, v.wrap_border_mean_max
        );
    }
    if v.rect_means_checked > 0 {
        println!(
            "  rect means: {} checked against their atlases, largest difference from level 0 {} sRGB levels",
            v.rect_means_checked, v.rect_mean_level0_max
        );
    }
    if v.inner_quadrants_checked > 0 {
        println!(
            "  inner atlases: {} children's quadrants checked against the children's level 1, largest \
             mean difference {:.2} sRGB levels",
            v.inner_quadrants_checked, v.inner_quadrant_mean_max
        );
    }
    if !v.atlas_psnr.is_empty() {
        let n = v.atlas_psnr.len();
        let mut worst: Vec<_> = v.atlas_psnr.iter().collect();
        worst.sort_by(|a, b| a.recorded_db.total_cmp(&b.recorded_db));
        let measured = match &v.reference {
            Some(r) => format!("re-measured against {r}"),
            None => "recorded at build time (--reference re-measures)".into(),
        };
        println!(
            "  atlas PSNR ({n} compressed atlases, {measured}): {}; worst:",
            pooled_psnr_per_tree(&v.atlas_psnr)
        );
        for a in worst.iter().take(5) {
            println!(
                "    tree {} node {} (block {}): recorded {}{}",
                a.tree,
                a.node,
                a.block,
                fmt_psnr(a.recorded_db),
                a.measured_db
                    .map_or(String::new(), |m| format!(", measured {}", fmt_psnr(m)))
            );
        }
    }
}

/// Each tree's atlas PSNR pooled over its atlases (the mean squared error of all of them; a tree's
/// atlases are all one size), as the build summary gives it: "tree 0 35.31 dB, tree 1 41.02 dB". The
/// mean of the dB values was shown, above the pooled figure and over both trees' formats at once (fault
/// hunt, session 32).
fn pooled_psnr_per_tree(atlases: &[atlastree::inspect::AtlasPsnr]) -> String {
    let mut trees: std::collections::BTreeMap<u32, (f64, u32)> = Default::default();
    for a in atlases {
        let e = trees.entry(a.tree).or_default();
        // MSE relative to 255², from the recorded dB (+inf: identical, no error).
        e.0 += 10f64.powf(-a.recorded_db / 10.0);
        e.1 += 1;
    }
    let parts: Vec<String> = (trees.iter())
        .map(|(t, (sum, n))| {
            let db = -10.0 * (sum / f64::from(*n)).log10();
            format!("tree {t} {}", fmt_psnr(db))
        })
        .collect();
    format!("pooled {}", parts.join(", "))
}
