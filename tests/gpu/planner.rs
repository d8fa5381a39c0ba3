//! The frame planner against the GPU executor, on data/city's deep tree (187 blocks, atlases and leaves'
//! original textures):
//!
//! - the capacity k counts every block: a paged renderer created for k = all blocks returns to all of them
//!   after the slider went down (it was clamped to the atlas layers, fewer than the blocks);
//! - `render` warm-up frames and extra `--mode`s step no pager: the paging columns of `stats.csv` are the
//!   same with `--warmup 3 --mode tree,dummy` as with `--warmup 0 --mode tree`;
//! - executing a plan on a renderer that did not receive its residency changes skips the draws whose
//!   atlas holds no layer and counts them (`skipped_draws`), never drawing a wrong texture silently;
//! - the density pass of a paged frame draws, and executing the plan again (density, colour) gives the
//!   same pixels and counters.

use atlastree::gpu::GpuContext;
use atlastree::paging::{FileSource, UploadBudget};
use atlastree::plan::FramePlanner;
use atlastree::render::{Mode, Renderer, RendererOptions};
use atlastree::report::csv::read_csv;
use atlastree::store::TreeFile;
use std::path::Path;
use std::process::Command;
use std::sync::Arc;

use crate::harness::GpuTest;
use crate::paging::paged;
use crate::render::{H, W, city_deep, dive_cameras, e, scale_for};

pub fn tests() -> Vec<GpuTest> {
    vec![
        GpuTest {
            name: "planner::capacity_returns_to_every_block_not_just_the_atlas_layers",
            run: capacity_returns_to_every_block_not_just_the_atlas_layers,
        },
        GpuTest {
            name: "planner::warm_up_and_extra_modes_step_no_pager",
            run: warm_up_and_extra_modes_step_no_pager,
        },
        GpuTest {
            name: "planner::a_path_that_never_looks_at_the_scene_reports_no_frame_ratios",
            run: a_path_that_never_looks_at_the_scene_reports_no_frame_ratios,
        },
        GpuTest {
            name: "planner::selection_json_says_what_drew_each_item",
            run: selection_json_says_what_drew_each_item,
        },
        GpuTest {
            name: "planner::draws_without_a_gpu_layer_are_skipped_and_counted",
            run: draws_without_a_gpu_layer_are_skipped_and_counted,
        },
        GpuTest {
            name: "planner::a_paged_plan_executes_again_to_the_same_frame",
            run: a_paged_plan_executes_again_to_the_same_frame,
        },
    ]
}

fn source(path: &Path) -> Result<Arc<FileSource>, String> {
    Ok(Arc::new(FileSource::new(Arc::new(
        TreeFile::open(path).map_err(e)?,
    ))))
}

fn capacity_returns_to_every_block_not_just_the_atlas_layers(
    ctx: &GpuContext,
) -> Result<(), String> {
    let path = city_deep()?;
    let file = TreeFile::open(&path).map_err(e)?;
    let blocks = file.blocks().len() as u32;
    let mut r = paged(
        ctx,
        &file,
        blocks,
        UploadBudget::Unlimited,
        source(&path)?,
        0,
    )?;
    let atlas_layers = r.renderer.resident.stats.atlas_layers;
    if atlas_layers >= blocks {
        return Err(format!(
            "{atlas_layers} atlas layers for {blocks} blocks: the file has no original blocks, the test proves nothing"
        ));
    }
    r.planner.set_capacity(4);
    r.planner.set_capacity(blocks);
    let k = r.pager().ok_or("no pager")?.options().capacity;
    if k != blocks {
        return Err(format!(
            "capacity {k} after asking for all {blocks} blocks (atlas layers: {atlas_layers})"
        ));
    }
    // And the arrays take the blocks the flight brings without a residency error.
    let cams = dive_cameras(&file, 30)?;
    let scale = scale_for(&file, &cams[0])?;
    for (i, cam) in cams.iter().enumerate() {
        r.set_clock(i as f64 / 30.0);
        let s = r.render(cam, scale, Mode::Tree).map_err(e)?;
        let p = s.plan.paging.ok_or("no paging stats")?;
        if p.apply_errors > 0 || s.skipped_draws > 0 {
            return Err(format!(
                "frame {i}: {} apply errors, {} skipped draws ({:?})",
                p.apply_errors,
                s.skipped_draws,
                r.planner.last_error()
            ));
        }
    }
    Ok(())
}

/// The paging columns of `dir/stats.csv` (from `blocks_needed` on), one string per frame.
fn paging_columns(dir: &Path) -> Result<Vec<String>, String> {
    let t = read_csv(&dir.join("stats.csv")).map_err(e)?;
    let first = t
        .header
        .iter()
        .position(|h| h == "blocks_needed")
        .ok_or("no paging columns in stats.csv")?;
    // upload_ms is a wall-clock time: compare everything else.
    let skip = t.header.iter().position(|h| h == "upload_ms");
    Ok(t.rows
        .iter()
        .map(|r| {
            r.iter()
                .enumerate()
                .filter(|(i, _)| *i >= first && Some(*i) != skip)
                .map(|(_, c)| c.as_str())
                .collect::<Vec<_>>()
                .join(",")
        })
        .collect())
}

fn warm_up_and_extra_modes_step_no_pager(_: &GpuContext) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(e)?;
    let path = city_deep()?;
    let run = |out: &Path, warmup: &str, modes: &str| -> Result<(), String> {
        let o = Command::new(env!("CARGO_BIN_EXE_atlastree"))
            .arg("render")
            .arg(&path)
            .args([
                "--capacity",
                "24",
                "--loader-threads",
                "0",
                "--frames",
                "12",
            ])
            .args(["--width", "160", "--height", "120", "--every", "0"])
            .args([
                "--upload-budget",
                "1MB",
                "--warmup",
                warmup,
                "--mode",
                modes,
            ])
            .arg("--out")
            .arg(out)
            .output()
            .map_err(e)?;
        if !o.status.success() {
            return Err(format!(
                "render failed: {}",
                String::from_utf8_lossy(&o.stderr)
            ));
        }
        Ok(())
    };
    let plain = dir.path().join("plain");
    let warm = dir.path().join("warm");
    run(&plain, "0", "tree")?;
    run(&warm, "3", "tree,dummy")?;
    let base = paging_columns(&plain)?;
    if base.windows(2).all(|w| w[0] == w[1]) {
        return Err("the paging columns never change: the test proves nothing".into());
    }
    // summary.json: the modes' medians and tree ÷ dummy from them; no original, so no ratio with it.
    let text = std::fs::read_to_string(warm.join("summary.json")).map_err(e)?;
    let v: serde_json::Value = serde_json::from_str(&text).map_err(e)?;
    let median = |m: &str| v["modes"][m]["median_frame_ms"].as_f64();
    let (Some(t), Some(d)) = (median("tree"), median("dummy")) else {
        return Err(format!("summary.json lacks the medians: {v}"));
    };
    // serde_json's default float parser may be 1 ulp off: compare to 1e-12 relative.
    let ratio = v["ratios"]["tree_over_dummy"].as_f64();
    if ratio.is_none_or(|r| (r - t / d).abs() > 1e-12 * (t / d))
        || v["ratios"].get("original_over_dummy").is_some()
    {
        return Err(format!(
            "summary.json ratios wrong (tree {t}, dummy {d}): {v}"
        ));
    }
    for mode in ["tree", "dummy"] {
        let other = paging_columns(&warm.join(mode))?;
        if let Some(i) = (0..base.len().max(other.len())).find(|&i| base.get(i) != other.get(i)) {
            return Err(format!(
                "{mode} with warm-up and two modes differs from one mode without warm-up at frame {i}:\n  {:?}\n  {:?}",
                base.get(i),
                other.get(i)
            ));
        }
    }
    Ok(())
}

/// A path that never looks at the scene draws empty frames; their median times were still divided
/// ("median frame time tree ÷ dummy: 1.057") and written to summary.json as if measured. Now a warning
/// says so and the ratios are left out (the modes' medians stay).
fn a_path_that_never_looks_at_the_scene_reports_no_frame_ratios(
    _: &GpuContext,
) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(e)?;
    let cam = dir.path().join("away.json");
    let away = r#"{ "keyframes": [
        { "time": 0, "eye": [0, 100000, 0], "target": [0, 200000, 0], "fov": 60 },
        { "time": 1, "eye": [10, 100000, 0], "target": [10, 200000, 0], "fov": 60 } ],
        "up": [0, 0, 1] }"#;
    std::fs::write(&cam, away).map_err(e)?;
    let out = dir.path().join("r");
    let o = Command::new(env!("CARGO_BIN_EXE_atlastree"))
        .arg("render")
        .arg(city_deep()?)
        .args(["--mode", "tree,dummy", "--frames", "3", "--every", "0"])
        .args(["--width", "64", "--height", "48", "--path"])
        .arg(&cam)
        .arg("--out")
        .arg(&out)
        .output()
        .map_err(e)?;
    let (stdout, stderr) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    if !o.status.success() || !stderr.contains("no frame of the path draws any geometry") {
        return Err(format!("no warning (exit {:?}): {stderr}", o.status.code()));
    }
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).map_err(e)?)
            .map_err(e)?;
    let none = v["ratios"].as_object().is_some_and(|m| m.is_empty());
    if !none || stdout.contains("median frame time") || v["modes"]["tree"]["frames"] != 3 {
        return Err(format!("ratios of empty frames reported: {stdout}\n{v}"));
    }
    Ok(())
}

/// `--selection` listed the cut as selected only: with the roots alone resident (k = the root atlases)
/// the fault hunt's frame listed 7 leaves and 3 originals as if drawn. Each item now says what drew it:
/// paged at the roots' capacity, some item is drawn by another node's atlas, coarser; all resident,
/// every item by itself.
fn selection_json_says_what_drew_each_item(_: &GpuContext) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(e)?;
    let path = city_deep()?;
    let roots = TreeFile::open(&path).map_err(e)?.trees().to_string();
    let items = |capacity: Option<&str>, out: &Path| -> Result<Vec<serde_json::Value>, String> {
        let mut cmd = Command::new(env!("CARGO_BIN_EXE_atlastree"));
        cmd.arg("render")
            .arg(&path)
            .args(["--path", "street", "--frames", "4", "--every", "0"]);
        cmd.args(["--width", "64", "--height", "48", "--selection", "--out"])
            .arg(out);
        if let Some(k) = capacity {
            cmd.args(["--capacity", k, "--loader-threads", "0"]);
        }
        let o = cmd.output().map_err(e)?;
        if !o.status.success() {
            return Err(format!(
                "render failed: {}",
                String::from_utf8_lossy(&o.stderr)
            ));
        }
        let text = std::fs::read_to_string(out.join("selection.json")).map_err(e)?;
        let v: serde_json::Value = serde_json::from_str(&text).map_err(e)?;
        let frames = v["frames"].as_array().ok_or(format!("no frames: {v}"))?;
        let mut items = Vec::new();
        for f in frames {
            items.extend(
                f["items"]
                    .as_array()
                    .ok_or(format!("a frame without items: {f}"))?
                    .clone(),
            );
        }
        Ok(items)
    };
    let redrawn = |i: &serde_json::Value| {
        i["drawn_node"] != i["node"] || i["drawn_source"] != i["source"] || i["coarser_levels"] != 0
    };
    let paged = items(Some(&roots), &dir.path().join("paged"))?;
    let all = items(None, &dir.path().join("all"))?;
    if all.is_empty() || all.iter().any(redrawn) {
        return Err(format!(
            "all resident, an item is drawn by another: {all:?}"
        ));
    }
    if !paged
        .iter()
        .any(|i| redrawn(i) && i["coarser_levels"].as_u64() > Some(0))
    {
        return Err(format!(
            "roots alone resident, every item drawn as selected: {paged:?}"
        ));
    }
    Ok(())
}

fn draws_without_a_gpu_layer_are_skipped_and_counted(ctx: &GpuContext) -> Result<(), String> {
    let path = city_deep()?;
    let file = TreeFile::open(&path).map_err(e)?;
    let blocks = file.blocks().len() as u32;
    let opts = RendererOptions::sized(W, H);
    let mut planned = paged(
        ctx,
        &file,
        blocks,
        UploadBudget::Unlimited,
        source(&path)?,
        0,
    )?;
    // A second renderer that only ever received the roots: the plan's resolved atlases are not on it.
    let mut other_planner = FramePlanner::paged_from_file(
        &file,
        atlastree::plan::PagingSetup {
            pager: atlastree::paging::PagerOptions {
                capacity: blocks,
                ..Default::default()
            },
            source: source(&path)?,
            loader_threads: 0,
        },
    )
    .map_err(e)?;
    let mut stale = Renderer::new_paged(ctx, &file, opts, &mut other_planner).map_err(e)?;
    let cams = dive_cameras(&file, 30)?;
    let cam = cams.last().ok_or("no cameras")?;
    let scale = scale_for(&file, cam)?;
    planned.set_clock(1.0);
    let s = planned.render(cam, scale, Mode::Tree).map_err(e)?;
    if s.skipped_draws != 0 {
        return Err(format!(
            "{} draws skipped on the renderer that holds the plan's blocks",
            s.skipped_draws
        ));
    }
    let plan = planned.planner.last().ok_or("no plan")?;
    let deep = plan
        .resolved
        .iter()
        .flatten()
        .flatten()
        .filter(|r| r.atlas_node.is_some_and(|n| n.0 != 0))
        .count();
    let stale_stats = stale.execute(plan, Mode::Tree).map_err(e)?;
    if deep == 0 {
        return Err("every item resolved to a root: the test proves nothing".into());
    }
    if stale_stats.skipped_draws == 0 {
        return Err(format!(
            "{deep} items name atlases the stale renderer does not hold, none counted as skipped"
        ));
    }
    if stale_stats.indirect_records + stale_stats.skipped_draws < s.indirect_records {
        return Err(format!(
            "stale: {} drawn + {} skipped < {} records of the same plan",
            stale_stats.indirect_records, stale_stats.skipped_draws, s.indirect_records
        ));
    }
    Ok(())
}

fn a_paged_plan_executes_again_to_the_same_frame(ctx: &GpuContext) -> Result<(), String> {
    // The renderer cannot step the pager (it only gets the plan); what can go wrong is that executing
    // a plan again gives a different frame. So: the density pass twice and the colour pass around it
    // give the same pixels, and the density pass of a paged frame draws.
    let path = city_deep()?;
    let file = TreeFile::open(&path).map_err(e)?;
    let mut r = paged(
        ctx,
        &file,
        24,
        UploadBudget::Bytes(1 << 20),
        source(&path)?,
        0,
    )?;
    let cams = dive_cameras(&file, 10)?;
    let scale = scale_for(&file, &cams[0])?;
    let mut drawn = 0;
    for (i, cam) in cams.iter().enumerate() {
        r.set_clock(i as f64 / 30.0);
        let first = r.render(cam, scale, Mode::Tree).map_err(e)?;
        let colour = r.read_frame().map_err(e)?;
        let plan = r.planner.last().ok_or("no plan")?;
        let (_, d1) = r.renderer.execute_density(plan).map_err(e)?;
        let (_, d2) = r.renderer.execute_density(plan).map_err(e)?;
        let again = r.renderer.execute(plan, Mode::Tree).map_err(e)?;
        if d1 != d2 {
            return Err(format!(
                "frame {i}: the density pass differs between two executions"
            ));
        }
        if r.renderer.read_frame().map_err(e)? != colour
            || (again.indirect_records, again.triangles, again.plan.paging)
                != (first.indirect_records, first.triangles, first.plan.paging)
        {
            return Err(format!(
                "frame {i}: the plan executed again after its density pass draws something else"
            ));
        }
        drawn += d1.pixels.iter().filter(|p| p.is_some()).count();
    }
    if drawn == 0 {
        return Err("the density passes drew nothing".into());
    }
    Ok(())
}
