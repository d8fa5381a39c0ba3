//! `atlastree sweep --grid small` on data/city end to end (3 builds, 13 variants, 6 frames of 320×240), and
//! its CSV checked for sanity:
//!
//! - every row complete: `sweep.csv` has one row per planned variant, `frames.csv` one per variant and
//!   frame, every cell parses, accuracy and cost cells are finite (NaN only where documented: GPU ms
//!   without timestamp queries); the density shares are in [0, 1] for paged variants too (the density
//!   pass executes the frame's plan again, it does not step the pager);
//! - PSNR rises with the texel ratio on every static view: per frame and build, the covered PSNR at the
//!   next larger ratio is at least the smaller ratio's minus 0.1 dB (the frames are deterministic; 0.1 dB
//!   allows for a different but equally fine cut, measured differences of such cuts are ≤ 0.02 dB), and
//!   on the base build the mean over frames rises by ≥ 0.5 dB from ratio 0.25 to 2;
//! - bigger atlases hold more: the 1024² build has fewer leaves than the 512² build (same d_min). The
//!   file does *not* grow with the atlas size on this scene (each leaf stores its original textures and
//!   every node a full atlas, so fewer, bigger nodes are smaller in total: 276 → 120 MiB); the test checks
//!   that the file sizes are positive and that the two filter builds (same layout) have equal size;
//! - the paged variant: coarser share in [0, 1], some bytes paged;
//! - the report and every plot (SVG + PNG) exist.

use atlastree::render::reference::Reference;
use atlastree::report::csv::{CsvTable, read_csv};
use atlastree::sweep::output::write_outputs;
use atlastree::sweep::{Grid, SweepOptions, run_sweep};
use atlastree::sweep::{NoSweepProgress, sample_path};
use std::path::Path;

use crate::harness::GpuTest;
use crate::render::e;

pub fn tests() -> Vec<GpuTest> {
    vec![
        GpuTest {
            name: "sweep::small_grid_on_city_csv_is_sane",
            run: small_grid_on_city_csv_is_sane,
        },
        GpuTest {
            name: "sweep::supersampled_reference_measures_tree_and_original",
            run: supersampled_reference_measures_tree_and_original,
        },
        GpuTest {
            name: "sweep::a_capacity_above_the_block_count_scores_as_all_resident",
            run: a_capacity_above_the_block_count_scores_as_all_resident,
        },
        GpuTest {
            name: "sweep::a_failed_sweep_leaves_no_folder_it_made",
            run: a_failed_sweep_leaves_no_folder_it_made,
        },
    ]
}

/// A sweep whose build fails (a file past `--max-file-gib`) into a new `--out` leaves none of the folders
/// it made, its `builds/` among them: the sweep made that one itself, so `--out` kept an empty
/// `builds/` (fault hunt, session 37). Runs the binary (the folders are the CLI's).
fn a_failed_sweep_leaves_no_folder_it_made(_: &atlastree::gpu::GpuContext) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(e)?;
    let fresh = dir.path().join("sweep");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_atlastree"))
        .args([
            "sweep",
            "--frames",
            "2",
            "-q",
            "--max-file-gib",
            "0.0000001",
            "--out",
        ])
        .arg(fresh.join("deep"))
        .arg(&scene)
        .output()
        .map_err(e)?;
    let stderr = String::from_utf8_lossy(&o.stderr);
    if o.status.code() != Some(2) || !stderr.contains("--max-file-gib") {
        return Err(format!(
            "expected the build's refusal, got {:?}: {stderr}",
            o.status
        ));
    }
    if fresh.exists() {
        return Err(format!("the folders it made stay: {stderr}"));
    }
    Ok(())
}

/// A paged variant whose k exceeds the file's blocks never evicts, so once its pager has settled at each
/// measured view it draws what the all-resident variant draws: the same PSNR and SSIM on every frame.
/// Before paged variants were settled, each sampled frame (seconds apart on the path) had one paging
/// step from a cold start: k = 100,000 scored 36.8 dB where all-resident scored 99 (fault hunt, session
/// 32).
fn a_capacity_above_the_block_count_scores_as_all_resident(
    ctx: &atlastree::gpu::GpuContext,
) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(e)?;
    let (scene, plan, cameras) = tiny_city_grid(vec![], vec![100_000])?;
    let opts = SweepOptions {
        builds_dir: dir.path().join("builds"),
        ..SweepOptions::default()
    };
    let data = run_sweep(ctx, &scene, &plan, &cameras, &opts, &NoSweepProgress).map_err(e)?;
    let paged = |f: &&atlastree::sweep::FrameRow| f.runtime.capacity.is_some();
    let (p, a): (Vec<_>, Vec<_>) = data.frames.iter().partition(paged);
    if p.len() != plan.frames || a.len() != plan.frames {
        return Err(format!("{} paged and {} resident rows", p.len(), a.len()));
    }
    for (p, a) in p.iter().zip(&a) {
        if p.frame != a.frame || p.psnr_db != a.psnr_db || p.ssim != a.ssim {
            return Err(format!(
                "frame {}: paged {} dB / SSIM {}, all resident {} dB / SSIM {}",
                p.frame, p.psnr_db, p.ssim, a.psnr_db, a.ssim
            ));
        }
        let loaded = p.stats.paging().map_or(0, |s| s.pager().bytes_loaded);
        if p.frame == 0 && loaded == 0 {
            return Err("the first paged frame loaded nothing".into());
        }
    }
    Ok(())
}

/// `--reference supersampled:2` on a two-build grid (atlas 512 and 1024, texel ratio 1, a paged variant),
/// 3 frames of 160×120: every variant row and frame row has the original textures' PSNR and SSIM against
/// the ground truth, finite, and below identity on some frame (the originals at 1× are not the
/// 2×-supersampled truth), tree and original at least [`SUPERSAMPLED_FLOOR_DB`] on every frame that
/// covers a pixel, tree and original alike on the street-level middle frame (all magnified, the tree draws
/// the originals: 35.9 dB each, measured), equal for the variants of one build on each frame (the originals are the build's), and the report
/// names the reference and shows the original columns.
fn supersampled_reference_measures_tree_and_original(
    ctx: &atlastree::gpu::GpuContext,
) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(e)?;
    let (scene, plan, cameras) = tiny_city_grid(vec![512, 1024], vec![24])?;
    let opts = SweepOptions {
        builds_dir: dir.path().join("builds"),
        reference: Reference::Supersampled(2),
        ..SweepOptions::default()
    };
    let data = run_sweep(ctx, &scene, &plan, &cameras, &opts, &NoSweepProgress).map_err(e)?;
    write_outputs(dir.path(), &data, "data/city", "overview-dive").map_err(e)?;
    let sweep = read_csv(&dir.path().join("sweep.csv")).map_err(e)?;
    let frames = read_csv(&dir.path().join("frames.csv")).map_err(e)?;
    check_complete(&sweep, &frames, plan.variants(), plan.frames, MEASURED)?;
    check_floor(&frames, "psnr_covered_db", SUPERSAMPLED_FLOOR_DB)?;
    check_floor(&frames, "original_psnr_covered_db", SUPERSAMPLED_FLOOR_DB)?;
    let (tree, original) = (
        num(&frames, "psnr_covered_db")?,
        num(&frames, "original_psnr_covered_db")?,
    );
    let street: Vec<usize> = (col(&frames, "frame")?.iter().enumerate())
        .filter(|(_, f)| **f == "1")
        .map(|(i, _)| i)
        .collect();
    if let Some(&i) = street.iter().find(|&&i| tree[i] != original[i]) {
        return Err(format!(
            "frames.csv row {i} (the street-level frame, all magnified): tree {} dB, original {} dB",
            tree[i], original[i]
        ));
    }
    if street.len() != plan.variants() {
        return Err(format!(
            "{} street-level rows, expected {}",
            street.len(),
            plan.variants()
        ));
    }
    for (table, name) in [(&sweep, "sweep.csv"), (&frames, "frames.csv")] {
        for c in [
            "original_psnr_db",
            "original_psnr_covered_db",
            "original_ssim",
        ] {
            let v = num_or_nan(table, c)?;
            // NaN where a frame covers nothing: nothing measured.
            let covered = frames
                .column_index("covered_pixels")
                .ok_or("no covered_pixels column")?;
            let unmeasured = |i: usize| {
                name == "frames.csv" && c.contains("covered") && frames.rows[i][covered] == "0"
            };
            if let Some(i) =
                (0..v.len()).find(|&i| !unmeasured(i) && (!v[i].is_finite() || v[i] <= 0.0))
            {
                return Err(format!("{name} row {i}: {c} = {}", v[i]));
            }
        }
        let psnr = num(table, "original_psnr_db")?;
        if psnr.iter().all(|&x| x >= 99.0) {
            return Err(format!(
                "{name}: the originals equal the supersampled truth: {psnr:?}"
            ));
        }
    }
    // Per build and frame, every variant carries the same original scores.
    let (builds, frame_ids) = (col(&frames, "build")?, col(&frames, "frame")?);
    let orig = num_or_nan(&frames, "original_psnr_covered_db")?;
    for i in 0..orig.len() {
        for j in 0..i {
            let same = orig[i] == orig[j] || orig[i].is_nan() && orig[j].is_nan();
            if builds[i] == builds[j] && frame_ids[i] == frame_ids[j] && !same {
                return Err(format!(
                    "build {} frame {}: original scores differ between variants ({} vs {})",
                    builds[i], frame_ids[i], orig[i], orig[j]
                ));
            }
        }
    }
    let report = std::fs::read_to_string(dir.path().join("report.md")).map_err(e)?;
    if !report.contains("supersampled:2") || !report.contains("original covered PSNR dB") {
        return Err(
            "report.md does not name the supersampled reference and its original columns".into(),
        );
    }
    Ok(())
}

/// data/city, and a grid of the small preset with only these atlas sizes and capacities, 3 frames of
/// 160×120 sampled along the overview-dive.
type TinyGrid = (
    atlastree::scene::Scene,
    atlastree::sweep::Plan,
    Vec<(f64, atlastree::camera::Camera)>,
);
fn tiny_city_grid(atlas_size: Vec<u32>, capacity: Vec<u32>) -> Result<TinyGrid, String> {
    let scene_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf");
    let scene = atlastree::scene::import(&scene_path, &Default::default()).map_err(e)?;
    let mut grid = Grid::preset("small").ok_or("no small preset")?;
    grid.atlas_size = atlas_size;
    grid.filter = vec![];
    grid.repeat = vec![];
    grid.texel_ratio = vec![];
    grid.capacity = capacity;
    grid.frames = 3;
    grid.width = 160;
    grid.height = 120;
    grid.validate("tiny").map_err(e)?;
    let plan = grid.plan();
    let path = city_overview_dive(&scene)?;
    let cameras = sample_path(&path, plan.frames, 160.0 / 120.0);
    Ok((scene, plan, cameras))
}

/// The overview-dive over `scene` as `sweep` flies it (over the ground its triangles make, not the
/// bounds-only path: on data/city that path's middle frame sees nothing, so the street-level view was
/// never measured).
fn city_overview_dive(
    scene: &atlastree::scene::Scene,
) -> Result<atlastree::camera::CameraPath, String> {
    let ground = atlastree::camera::Ground::from_scene(scene).map_err(e)?;
    atlastree::camera::CameraPath::overview_dive_on(&ground).map_err(e)
}

/// Tolerance of the per-frame monotonicity of PSNR in the texel ratio, dB.
const MONOTONE_TOL_DB: f64 = 0.1;

fn small_grid_on_city_csv_is_sane(ctx: &atlastree::gpu::GpuContext) -> Result<(), String> {
    let dir = tempfile::tempdir().map_err(e)?;
    let scene_path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf");
    let scene = atlastree::scene::import(&scene_path, &Default::default()).map_err(e)?;
    let grid = Grid::preset("small").ok_or("no small preset")?;
    grid.validate("small").map_err(e)?;
    let plan = grid.plan();
    let path = city_overview_dive(&scene)?;
    let cameras = sample_path(
        &path,
        plan.frames,
        f64::from(plan.width) / f64::from(plan.height),
    );
    let opts = SweepOptions {
        builds_dir: dir.path().join("builds"),
        ..SweepOptions::default()
    };
    let data = run_sweep(ctx, &scene, &plan, &cameras, &opts, &NoSweepProgress).map_err(e)?;
    let (_, written) = write_outputs(dir.path(), &data, "data/city", "overview-dive").map_err(e)?;
    for w in &written {
        if !w.is_file() {
            return Err(format!("{} was not written", w.display()));
        }
    }
    let left = std::fs::read_dir(dir.path().join("builds"))
        .map(|d| d.count())
        .unwrap_or(0);
    if left != 0 {
        return Err(format!(
            "{left} build files left behind without --keep-builds"
        ));
    }
    let sweep = read_csv(&dir.path().join("sweep.csv")).map_err(e)?;
    let frames = read_csv(&dir.path().join("frames.csv")).map_err(e)?;
    let builds = read_csv(&dir.path().join("builds.csv")).map_err(e)?;
    check_complete(&sweep, &frames, plan.variants(), plan.frames, !MEASURED)?;
    check_floor(&frames, "psnr_covered_db", TREE_FLOOR_DB)?;
    check_monotone(&frames)?;
    check_base_rise(&sweep)?;
    check_builds(&builds)?;
    check_paged(&sweep)
}

/// The least covered PSNR a frame of the small grid's tree may score against the original, dB (measured
/// on lavapipe: 40.6–44.5 dB where not identical; `render`'s tests hold the tree to 35 dB at 800×600).
const TREE_FLOOR_DB: f64 = 38.0;

/// The least covered PSNR tree and original may score against the 2× supersampled truth on the tiny
/// grid's 160×120 frames, dB (measured on lavapipe: 27.96–35.90 dB, both).
const SUPERSAMPLED_FLOOR_DB: f64 = 25.0;

/// Every frame row of `frames` that covers a pixel scores at least `floor` dB in `column` (a sweep
/// that drew nearly black frames, or the wrong texels, has finite, monotone scores far below it).
fn check_floor(frames: &CsvTable, column: &str, floor: f64) -> Result<(), String> {
    let v = num_or_nan(frames, column)?;
    let covered = num(frames, "covered_pixels")?;
    let scored: Vec<(usize, f64)> = (v.iter().copied().enumerate())
        .filter(|&(i, _)| covered[i] > 0.0)
        .collect();
    if scored.is_empty() {
        return Err(format!("frames.csv: no frame covers a pixel ({column})"));
    }
    match scored.iter().find(|(_, x)| x.is_nan() || *x < floor) {
        Some((i, x)) => Err(format!(
            "frames.csv row {i}: {column} = {x} dB, below {floor} dB"
        )),
        None => Ok(()),
    }
}

fn col<'a>(t: &'a CsvTable, name: &str) -> Result<Vec<&'a str>, String> {
    t.column(name).ok_or(format!("missing column {name}"))
}

fn num(t: &CsvTable, name: &str) -> Result<Vec<f64>, String> {
    t.column_f64(name)
        .ok_or(format!("column {name} missing or not numeric"))
}

/// [`num`], an empty cell (not measured) read as NaN.
fn num_or_nan(t: &CsvTable, name: &str) -> Result<Vec<f64>, String> {
    let cells = t.column(name).ok_or(format!("no column {name}"))?;
    (cells.iter())
        .map(|c| match c.is_empty() {
            true => Ok(f64::NAN),
            false => c
                .parse()
                .map_err(|_| format!("column {name}: {c:?} is not a number")),
        })
        .collect()
}

/// `originals_measured` for [`check_complete`]: the original's scores were taken (a supersampled
/// reference), so their cells are filled; else (the original is the reference) they are empty.
const MEASURED: bool = true;

fn check_complete(
    sweep: &CsvTable,
    frames: &CsvTable,
    variants: usize,
    n: usize,
    originals_measured: bool,
) -> Result<(), String> {
    if sweep.rows.len() != variants || frames.rows.len() != variants * n {
        return Err(format!(
            "{} variant rows and {} frame rows, expected {variants} and {}",
            sweep.rows.len(),
            frames.rows.len(),
            variants * n
        ));
    }
    for name in [
        "psnr_db",
        "psnr_covered_db",
        "ssim",
        "coarser_share",
        "select_us",
        "encode_us",
        "frame_ms",
        "frame_ms_median",
        "file_bytes",
        "build_s",
    ] {
        if let Some(i) = num(sweep, name)?.iter().position(|v| !v.is_finite()) {
            return Err(format!("sweep.csv row {i}: {name} is not finite"));
        }
    }
    for name in ["magnified_share", "below_target_share"] {
        for (i, v) in num(sweep, name)?.iter().enumerate() {
            if !(0.0..=1.0).contains(v) {
                let capacity = col(sweep, "capacity")?[i];
                return Err(format!(
                    "sweep.csv row {i}: {name} = {v} (capacity {capacity})"
                ));
            }
        }
    }
    for (i, s) in num(sweep, "ssim")?.iter().enumerate() {
        if !(0.0..=1.0).contains(s) {
            return Err(format!("sweep.csv row {i}: SSIM {s} outside [0, 1]"));
        }
    }
    // The paging columns (from `blocks_needed` on) are empty exactly for all-resident variants.
    let paging = frames
        .column_index("blocks_needed")
        .ok_or("frames.csv has no paging columns")?;
    let cap = frames
        .column_index("capacity")
        .ok_or("no capacity column")?;
    // The original's scores are empty exactly where they were not measured (the reference is the original
    // itself), in every row.
    let originals: Vec<usize> = [
        "original_psnr_db",
        "original_psnr_covered_db",
        "original_ssim",
    ]
    .iter()
    .map(|c| {
        frames
            .column_index(c)
            .ok_or(format!("frames.csv has no {c}"))
    })
    .collect::<Result<_, _>>()?;
    // Covered PSNR is empty (NaN: nothing measured) exactly on frames whose reference covers no pixel.
    let covered = frames
        .column_index("covered_pixels")
        .ok_or("no covered_pixels column")?;
    let nothing_covered = frames.rows.iter().filter(|r| r[covered] == "0").count();
    let covered_db = [
        frames.column_index("psnr_covered_db"),
        frames.column_index("original_psnr_covered_db"),
    ];
    for &j in &originals {
        let empty = frames.rows.iter().filter(|r| r[j].is_empty()).count();
        let want = if !originals_measured {
            frames.rows.len()
        } else if covered_db.contains(&Some(j)) {
            nothing_covered
        } else {
            0
        };
        if empty != want {
            return Err(format!(
                "frames.csv column {j}: {empty} of {} rows empty, {want} expected (originals measured: \
                 {originals_measured})",
                frames.rows.len()
            ));
        }
    }
    for (i, r) in frames.rows.iter().enumerate() {
        let all = r[cap] == "all";
        let wrong: Vec<&str> = (r.iter().enumerate())
            .filter(|(j, _)| !originals.contains(j))
            .filter(|(j, c)| {
                let unmeasured = r[covered] == "0" && covered_db.contains(&Some(*j));
                c.is_empty() != (all && *j >= paging || unmeasured)
            })
            .map(|(j, _)| frames.header[j].as_str())
            .collect();
        if !wrong.is_empty() {
            return Err(format!(
                "frames.csv row {i}: cells empty or not as expected: {wrong:?}"
            ));
        }
    }
    Ok(())
}

/// Per build and frame (everything resident), covered PSNR non-decreasing in the texel ratio.
fn check_monotone(frames: &CsvTable) -> Result<(), String> {
    let build = col(frames, "build")?;
    let cap = col(frames, "capacity")?;
    let frame = num(frames, "frame")?;
    let ratio = num(frames, "texel_ratio")?;
    let psnr = num(frames, "psnr_covered_db")?;
    let mut keys: Vec<(&str, u64)> = Vec::new();
    for i in 0..frames.rows.len() {
        if cap[i] == "all" && !keys.contains(&(build[i], frame[i] as u64)) {
            keys.push((build[i], frame[i] as u64));
        }
    }
    for (b, f) in keys {
        let mut pts: Vec<(f64, f64)> = (0..frames.rows.len())
            .filter(|&i| build[i] == b && frame[i] as u64 == f && cap[i] == "all")
            .map(|i| (ratio[i], psnr[i]))
            .collect();
        pts.sort_by(|a, b| a.0.total_cmp(&b.0));
        if pts.len() < 4 {
            return Err(format!("build {b} frame {f}: only {} ratios", pts.len()));
        }
        for w in pts.windows(2) {
            if w[1].1 < w[0].1 - MONOTONE_TOL_DB {
                return Err(format!(
                    "build {b} frame {f}: PSNR falls from {:.3} dB at ratio {} to {:.3} dB at ratio {}",
                    w[0].1, w[0].0, w[1].1, w[1].0
                ));
            }
        }
    }
    Ok(())
}

/// On the base build (first row), the mean PSNR rises by ≥ 0.2 dB from the smallest to the largest ratio.
/// Measured: 40.15 → 40.46 dB at the default border 16; 37.64 → 39.04 dB at the paper's border 8, where
/// finer nodes (a higher ratio) also meant less bleeding between areas.
fn check_base_rise(sweep: &CsvTable) -> Result<(), String> {
    let build = col(sweep, "build")?;
    let cap = col(sweep, "capacity")?;
    let ratio = num(sweep, "texel_ratio")?;
    let psnr = num(sweep, "psnr_covered_db")?;
    let base = build.first().ok_or("empty sweep.csv")?;
    let at = |r: f64| {
        (0..ratio.len())
            .find(|&i| build[i] == *base && cap[i] == "all" && ratio[i] == r)
            .map(|i| psnr[i])
            .ok_or(format!("base build has no ratio {r}"))
    };
    let (lo, hi) = (at(0.25)?, at(2.0)?);
    if hi - lo < 0.2 {
        return Err(format!(
            "base build: PSNR {lo:.3} dB at ratio 0.25, {hi:.3} dB at 2 (expected ≥ 0.2 dB rise)"
        ));
    }
    Ok(())
}

fn check_builds(builds: &CsvTable) -> Result<(), String> {
    let atlas = num(builds, "atlas_size")?;
    let filter = col(builds, "filter")?;
    let leaves = num(builds, "leaves")?;
    let bytes = num(builds, "file_bytes")?;
    if bytes.iter().any(|b| *b <= 0.0) {
        return Err("a build has no bytes".into());
    }
    let find = |a: f64, f: &str| {
        (0..atlas.len())
            .find(|&i| atlas[i] == a && filter[i] == f)
            .ok_or(format!("no build with atlas {a} and filter {f}"))
    };
    let (small, big, kaiser) = (
        find(512.0, "box")?,
        find(1024.0, "box")?,
        find(512.0, "kaiser")?,
    );
    if leaves[big] > leaves[small] {
        return Err(format!(
            "atlas 1024 has {} leaves, atlas 512 {}: bigger atlases should need no more",
            leaves[big], leaves[small]
        ));
    }
    if bytes[kaiser] != bytes[small] {
        return Err(format!(
            "the filter changed the file size ({} vs {} bytes): it must only change texels",
            bytes[kaiser], bytes[small]
        ));
    }
    Ok(())
}

fn check_paged(sweep: &CsvTable) -> Result<(), String> {
    let cap = col(sweep, "capacity")?;
    let coarser = num(sweep, "coarser_share")?;
    let paged = num(sweep, "bytes_loaded")?;
    let rows: Vec<usize> = (0..cap.len()).filter(|&i| cap[i] != "all").collect();
    if rows.is_empty() {
        return Err("no paged variant".into());
    }
    for i in rows {
        if !(0.0..=1.0).contains(&coarser[i]) || paged[i] <= 0.0 {
            return Err(format!(
                "paged row {i}: coarser share {}, {} bytes paged",
                coarser[i], paged[i]
            ));
        }
    }
    Ok(())
}
