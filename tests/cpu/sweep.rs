//! The sweep's CPU parts: grid presets and JSON, the star expansion, the per-variant means, the Pareto
//! front and the recommendation (pure functions on hand-made rows), and the build's `mip_filter` knob
//! (Kaiser changes texels, never the layout). The GPU run of the small grid is `tests/gpu/sweep.rs`.

use atlastree::plan::PlanStats;
use atlastree::preprocess::image_ops::MipFilter;
use atlastree::preprocess::{BuildOptions, DMin, NoProgress, build};
use atlastree::render::FrameStats;
use atlastree::report::metrics::Histogram;
use atlastree::sweep::summary::{
    ReportContext, base_row, frame_time_front, knob_effects, markdown, mean, median, recommend,
    summarise,
};
use atlastree::sweep::{
    BuildKnobs, BuildRow, FrameRow, Grid, RuntimeKnobs, SweepData, merge_histogram,
};
use std::path::Path;

#[test]
fn small_preset_is_a_star_of_four_builds_and_seventeen_variants() {
    let g = Grid::preset("small").expect("preset");
    g.validate("small").expect("valid");
    let p = g.plan();
    let ids: Vec<String> = p.builds.iter().map(|b| b.knobs.id()).collect();
    assert_eq!(
        ids,
        [
            "r15_a512_b16_box",
            "r15_a1024_b16_box",
            "r15_a512_b16_kaiser",
            "r15_a512_b16_box_bake"
        ]
    );
    assert!(p.builds[0].is_base && !p.builds[1].is_base);
    // Base: 4 texel ratios + 1 capacity; the others 4 ratios each.
    let counts: Vec<usize> = p.builds.iter().map(|b| b.runtimes.len()).collect();
    assert_eq!(counts, [5, 4, 4, 4]);
    assert_eq!(p.variants(), 17);
    let base: Vec<String> = p.builds[0].runtimes.iter().map(|r| r.id()).collect();
    assert_eq!(
        base,
        ["t0.25_all", "t0.5_all", "t1_all", "t2_all", "t1_k24"]
    );
    assert_eq!((p.frames, p.width, p.height), (6, 320, 240));
}

#[test]
fn full_preset_has_twelve_builds() {
    let p = Grid::preset("full").expect("preset").plan();
    // base + d_min 10, 60 + atlas 512, 2048 + border 2, 8 + kaiser + bc1, bc7 + bake + coverage mips.
    assert_eq!(p.builds.len(), 12);
    assert_eq!(p.builds[0].runtimes.len(), 6);
    assert_eq!(p.variants(), 6 + 11 * 4);
    let ids: Vec<String> = p.builds.iter().map(|b| b.knobs.id()).collect();
    assert!(
        ids.contains(&"r30_a1024_b16_box_bc1".to_string())
            && ids.contains(&"r30_a1024_b16_box_bake".to_string())
            && ids.contains(&"r30_a1024_b16_box_alpha-coverage".to_string()),
        "{ids:?}"
    );
    assert_eq!(ids[0], "r30_a1024_b16_box");
    assert!(Grid::preset("nope").is_none());
}

#[test]
fn json_grid_round_trips_and_bad_values_name_the_file() {
    let text = r#"{"base": {"d_min_ratio": 8, "atlas_size": 1024, "border": 8, "filter": "kaiser",
        "texel_ratio": 1, "capacity": 64}, "atlas_size": [512, 1024], "frames": 3,
        "texel_ratio_on_every_build": false, "texel_ratio": [0.5, 1]}"#;
    let g = Grid::from_json(text, "g.json").expect("parses");
    g.validate("g.json").expect("valid");
    assert_eq!(g.base.filter, MipFilter::Kaiser);
    let p = g.plan();
    assert_eq!(p.builds.len(), 2);
    // Non-base builds run only the base runtime (ratio 1, k 64) when ratios are not on every build.
    assert_eq!(p.builds[1].runtimes.len(), 1);
    assert_eq!(p.builds[0].runtimes.len(), 2);
    let again = Grid::from_json(&serde_json::to_string(&g).expect("json"), "x").expect("again");
    assert_eq!(again, g);

    let unknown = Grid::from_json(
        r#"{"base": {"d_min_ratio": 8, "atlas_size": 1024, "border": 8, "filter": "box",
            "texel_ratio": 1, "colour": 3}}"#,
        "u.json",
    )
    .expect_err("unknown field");
    assert!(unknown.to_string().contains("u.json") && unknown.to_string().contains("colour"));
    let bad_filter = Grid::from_json(
        r#"{"base": {"d_min_ratio": 8, "atlas_size": 1024, "border": 8, "filter": "gauss",
            "texel_ratio": 1}}"#,
        "f.json",
    )
    .expect_err("bad filter");
    assert!(bad_filter.to_string().contains("gauss"));
    let mut g2 = g.clone();
    g2.atlas_size.push(500);
    let e = g2
        .validate("g.json")
        .expect_err("500 is not a power of two");
    assert!(e.to_string().contains("atlas_size 500"), "{e}");
    let mut g3 = g;
    g3.texel_ratio.push(-1.0);
    assert!(g3.validate("g.json").is_err());
}

fn knobs(atlas: u32) -> BuildKnobs {
    BuildKnobs {
        d_min_ratio: 10.0,
        atlas_size: atlas,
        border: 8,
        filter: MipFilter::Box,
        compress: Default::default(),
        repeat: Default::default(),
        alpha_mips: Default::default(),
    }
}

fn frame(b: BuildKnobs, t: f64, i: usize, psnr: f64, ms: f64) -> FrameRow {
    FrameRow {
        build: b,
        runtime: RuntimeKnobs {
            texel_ratio: t,
            capacity: None,
        },
        frame: i,
        time_s: i as f64,
        psnr_db: psnr,
        psnr_covered_db: psnr,
        covered_pixels: 100,
        ssim: 0.9,
        original_psnr_db: f64::NAN,
        original_psnr_covered_db: f64::NAN,
        original_ssim: f64::NAN,
        magnified_share: 0.1,
        below_target_share: 0.2,
        stats: FrameStats {
            plan: PlanStats {
                nodes_drawn: 3,
                select_us: 10.0,
                ..PlanStats::default()
            },
            encode_us: 20.0,
            gpu_ms: None,
            frame_ms: ms,
            draw_calls: 1,
            ..FrameStats::default()
        },
    }
}

fn build_row(b: BuildKnobs, bytes: u64, secs: f64) -> BuildRow {
    BuildRow {
        knobs: b,
        file_bytes: bytes,
        nodes: 1,
        leaves: 1,
        depth: 0,
        blocks: 1,
        stage_s: vec![("rasterise".into(), secs)],
        build_s: secs,
        peak_rss_bytes: Some(1),
    }
}

#[test]
fn summary_means_front_and_recommendation() {
    let (a, b) = (knobs(512), knobs(1024));
    let frames = vec![
        frame(a, 0.5, 0, 30.0, 10.0),
        frame(a, 0.5, 1, 32.0, 30.0),
        frame(a, 0.5, 2, 34.0, 20.0),
        frame(a, 1.0, 0, 40.0, 50.0),
        frame(a, 1.0, 1, 40.4, 70.0),
        frame(b, 1.0, 0, 39.9, 15.0),
        frame(b, 1.0, 1, 40.1, 25.0),
    ];
    let builds = vec![build_row(a, 300, 2.0), build_row(b, 100, 5.0)];
    let rows = summarise(&builds, &frames);
    assert_eq!(rows.len(), 3);
    assert_eq!(rows[0].id, "r10_a512_b8_box_t0.5_all");
    assert_eq!(rows[0].frames, 3);
    // PSNR over frames: their squared errors averaged (30, 32 and 34 dB → 31.70 dB), not their dB.
    let over = |dbs: &[f64]| {
        let mse = dbs.iter().map(|d| 10f64.powf(-d / 10.0)).sum::<f64>() / dbs.len() as f64;
        -10.0 * mse.log10()
    };
    assert!((rows[0].psnr_db - over(&[30.0, 32.0, 34.0])).abs() < 1e-9);
    assert!(
        (rows[0].psnr_db - 31.698).abs() < 1e-3,
        "{}",
        rows[0].psnr_db
    );
    assert_eq!(rows[0].frame_ms, 20.0);
    assert_eq!(rows[0].frame_ms_median, 20.0);
    assert!(rows[0].gpu_ms.is_nan(), "all-NaN column stays NaN");
    assert!((rows[1].psnr_covered_db - over(&[40.0, 40.4])).abs() < 1e-9);
    assert_eq!(rows[1].frame_ms_median, 60.0);
    assert_eq!((rows[2].file_bytes, rows[2].build_s), (100, 5.0));
    // Front over (median ms, PSNR): a/0.5 is 20 ms at 31.7 dB, b/1 20 ms at 40.0 dB (dominates a/0.5),
    // a/1 60 ms at 40.2 dB (slower but more accurate): the front is b/1 then a/1.
    assert_eq!(frame_time_front(&rows), vec![2, 1]);
    let rec = recommend(&rows, 0.5).expect("some rows");
    assert_eq!(rec.best, 1);
    assert_eq!(rec.fastest_frames, 2);
    assert_eq!(rec.smallest_file, 2);
    assert_eq!(rec.fastest_build, 1);
    // A tight tolerance leaves only the best.
    let tight = recommend(&rows, 0.1).expect("rows");
    assert_eq!((tight.fastest_frames, tight.smallest_file), (1, 1));
    assert!(recommend(&[], 0.5).is_none());
    // Two variants of one build, equally accurate and fast: every role names the same one (the smallest
    // file was the other variant of the same file).
    let frames = vec![frame(a, 0.5, 0, 40.0, 50.0), frame(a, 1.0, 0, 40.0, 50.0)];
    let rows = summarise(&[build_row(a, 300, 2.0)], &frames);
    let rec = recommend(&rows, 0.5).expect("rows");
    assert_eq!(
        (rec.fastest_frames, rec.smallest_file, rec.fastest_build),
        (rec.best, rec.best, rec.best)
    );
    // Variants of one build that draw identical frames share their mean time (their differences are
    // noise: four identical sweeps named four "fastest"), and times within 10 % of the least are equal;
    // equals name the most accurate, then the first. Here b/1 is 14 ms, the three of a 16.6, 11.6 and
    // 14.0 (mean 14.07): all within 10 %, so the more accurate a (40.0 dB) over b (39.9), its first row.
    let frames = vec![
        frame(a, 0.5, 0, 40.0, 16.6),
        frame(a, 1.0, 0, 40.0, 11.6),
        frame(a, 2.0, 0, 40.0, 14.0),
        frame(b, 1.0, 0, 39.9, 14.0),
    ];
    let rows = summarise(&[build_row(a, 300, 2.0), build_row(b, 100, 2.1)], &frames);
    let rec = recommend(&rows, 0.5).expect("rows");
    assert_eq!(rows[0].id, "r10_a512_b8_box_t0.5_all");
    assert_eq!((rec.best, rec.fastest_frames, rec.fastest_build), (0, 0, 0));
    // The smallest file is exact: b's.
    assert_eq!(rec.smallest_file, 3);
    // Beyond 10 %, the faster wins: b at 10 ms against a's 14.07.
    let mut faster_b = frames.clone();
    faster_b[3] = frame(b, 1.0, 0, 39.9, 10.0);
    let rows = summarise(&[build_row(a, 300, 2.0), build_row(b, 100, 2.1)], &faster_b);
    assert_eq!(recommend(&rows, 0.5).expect("rows").fastest_frames, 3);
}

/// Knob effects: every single-knob change from the base (texel ratio 1, all resident) with its PSNR
/// delta and cost ratios; a row differing in two knobs is left out.
#[test]
fn knob_effects_against_the_base() {
    let (a, b) = (knobs(512), knobs(1024));
    // Differs from the base in two knobs (border and, at t 0.5, the texel ratio): not an effect.
    let mut c = knobs(512);
    c.border = 16;
    let frames = vec![
        frame(a, 0.5, 0, 30.0, 10.0),
        frame(a, 1.0, 0, 40.0, 50.0),
        frame(b, 1.0, 0, 39.0, 25.0),
        frame(c, 0.5, 0, 35.0, 5.0),
    ];
    let builds = vec![
        build_row(a, 300, 2.0),
        build_row(b, 100, 5.0),
        build_row(c, 100, 5.0),
    ];
    let rows = summarise(&builds, &frames);
    let all = RuntimeKnobs {
        texel_ratio: 1.0,
        capacity: None,
    };
    let base = base_row(&rows, &a, &all).expect("base");
    assert_eq!(rows[base].id, "r10_a512_b8_box_t1_all");
    let e = knob_effects(&rows, base);
    let got: Vec<(&str, &str, usize)> = e
        .iter()
        .map(|e| (e.knob, e.value.as_str(), e.row))
        .collect();
    assert_eq!(
        got,
        vec![("texel_ratio", "0.5", 0), ("atlas_size", "1024", 2)]
    );
    assert_eq!(e[0].psnr_delta_db, -10.0);
    assert_eq!(e[0].frame_ratio, 0.2);
    assert_eq!(e[1].psnr_delta_db, -1.0);
    assert_eq!((e[1].frame_ratio, e[1].build_ratio), (0.5, 2.5));
    assert!((e[1].file_ratio - 1.0 / 3.0).abs() < 1e-12);
    assert_eq!(base_row(&rows, &knobs(2048), &all), None);
    // The grid's own base runtime, not texel ratio 1 (a base at 0.5 was measured against 1).
    let half = RuntimeKnobs {
        texel_ratio: 0.5,
        ..all
    };
    let base = base_row(&rows, &a, &half).expect("base at 0.5");
    assert_eq!(rows[base].id, "r10_a512_b8_box_t0.5_all");
    let e = knob_effects(&rows, base);
    let mut got: Vec<(&str, &str)> = e.iter().map(|e| (e.knob, e.value.as_str())).collect();
    got.sort();
    // c (border 16 at 0.5) is one knob from this base; b (atlas 1024 at 1) is two.
    assert_eq!(got, vec![("border", "16"), ("texel_ratio", "1")]);
}

/// Sweep data of `builds` and `frames` on the small preset's plan cut to those builds, reference the
/// original textures, anisotropy `anisotropy`.
fn sweep_data(builds: Vec<BuildRow>, frames: Vec<FrameRow>, anisotropy: u16) -> SweepData {
    let mut plan = Grid::preset("small").expect("preset").plan();
    plan.builds.truncate(builds.len());
    for (p, b) in plan.builds.iter_mut().zip(&builds) {
        p.knobs = b.knobs;
    }
    SweepData {
        plan,
        builds,
        frames,
        histograms: vec![],
        resident_bytes: vec![],
        adapter: "test".into(),
        anisotropy,
        software: false,
        reference: atlastree::render::reference::Reference::Original,
        skipped: vec![],
    }
}

/// The report: one line per distinct recommended variant naming all its roles, the knob-effects table
/// against the base, and the builds that could not be drawn (with their error).
#[test]
fn report_names_roles_once_effects_and_skipped_builds() {
    let (a, b) = (knobs(512), knobs(1024));
    let frames = vec![
        frame(a, 1.0, 0, 40.0, 50.0),
        frame(a, 0.5, 0, 39.9, 10.0),
        frame(b, 1.0, 0, 30.0, 5.0),
    ];
    let builds = vec![build_row(a, 100, 2.0), build_row(b, 300, 5.0)];
    let rows = summarise(&builds, &frames);
    let data = SweepData {
        skipped: vec![("r10_a2048_b8_box".into(), "out of memory".into())],
        ..sweep_data(builds[..1].to_vec(), frames, 16)
    };
    let data = SweepData { builds, ..data };
    let cx = ReportContext {
        scene: "s.gltf".into(),
        path: "overview-dive".into(),
        plots: vec![],
    };
    let md = markdown(&data, &rows, &cx);
    // a/1 is the best and (same build, ties go to accuracy) also the smallest file and fastest build;
    // a/0.5 is within 0.5 dB of it and the fastest frames. One line each, every role named.
    let rec: Vec<&str> = md
        .lines()
        .filter(|l| l.starts_with("- ") && l.contains("covered PSNR"))
        .take(2)
        .collect();
    assert!(
        rec[0].starts_with(
            "- Most accurate, smallest file within 0.5 dB, fastest build within 0.5 dB: `r10_a512_b8_box_t1_all`"
        ),
        "{md}"
    );
    assert!(
        rec[1].starts_with("- **Fastest frames within 0.5 dB of it** (the recommended runtime default; times within 10 % of the least count as equal")
            && rec[1].contains("): `r10_a512_b8_box_t0.5_all`"),
        "{md}"
    );
    assert!(md.contains("sampler anisotropy 16×"), "{md}");
    assert!(
        !md.contains("software rasteriser"),
        "adapter `test` is no CPU device: {md}"
    );
    let cpu = SweepData {
        software: true,
        ..data.clone()
    };
    assert!(markdown(&cpu, &rows, &cx).contains("`--anisotropy 1` isolates"));
    assert!(md.contains("| texel_ratio | 0.5 | -0.10 |"), "{md}");
    assert!(md.contains("| atlas_size | 1024 | -10.00 |"), "{md}");
    assert!(
        md.contains("## Builds not rendered") && md.contains("- `r10_a2048_b8_box`: out of memory"),
        "{md}"
    );
}

/// Frames whose reference covers nothing are measured as nothing: with one of two empty, the variants'
/// covered PSNR is the other frame's and the report names the empty one; with every frame empty, the
/// outputs are written without accuracy plots (they failed on "no finite point to plot"), and the report
/// says the path measured nothing (review and fault hunt, session 38).
#[test]
fn frames_that_cover_nothing_are_left_out_not_scored() {
    let (a, b) = (knobs(512), knobs(1024));
    let empty = |mut f: FrameRow| {
        f.covered_pixels = 0;
        f.psnr_covered_db = f64::NAN;
        f
    };
    let frames = vec![
        frame(a, 1.0, 0, 30.0, 5.0),
        empty(frame(a, 1.0, 1, 99.0, 5.0)),
        frame(b, 1.0, 0, 32.0, 6.0),
        empty(frame(b, 1.0, 1, 99.0, 6.0)),
    ];
    let builds = vec![build_row(a, 100, 2.0), build_row(b, 300, 5.0)];
    let data = sweep_data(builds, frames, 1);
    let rows = summarise(&data.builds, &data.frames);
    assert_eq!(rows[0].psnr_covered_db, 30.0, "{rows:?}");
    assert_eq!(data.empty_frames(), vec![1]);
    let cx = ReportContext {
        scene: "s.gltf".into(),
        path: "overview-dive".into(),
        plots: vec![],
    };
    let md = markdown(&data, &rows, &cx);
    assert!(
        md.contains("1 of 2 frames cover no pixel of the scene in the reference (frame 1)"),
        "{md}"
    );
    let nothing = SweepData {
        frames: (data.frames.iter().cloned()).map(empty).collect(),
        ..data.clone()
    };
    assert!(nothing.measures_nothing());
    let dir = tempfile::tempdir().expect("tempdir");
    let (rows, _) =
        atlastree::sweep::output::write_outputs(dir.path(), &nothing, "s.gltf", "overview-dive")
            .expect("outputs written though nothing was measured");
    assert!(rows.iter().all(|r| r.psnr_covered_db.is_nan()));
    let md = std::fs::read_to_string(dir.path().join("report.md")).expect("report.md");
    assert!(md.contains("no frame of the path covers any pixel"), "{md}");
    assert!(!dir.path().join("pareto_frame_time.png").exists());
}

#[test]
fn mean_median_skip_nan_and_histograms_merge() {
    assert_eq!(mean([1.0, f64::NAN, 3.0]), 2.0);
    assert!(mean([f64::NAN]).is_nan());
    assert_eq!(median([5.0, 1.0, f64::NAN, 3.0, 100.0]), 4.0);
    let mut h = Histogram::log2(&[0.5, 1.0, 2.0], -2, 2);
    merge_histogram(&mut h, &Histogram::log2(&[1.5, 8.0, f32::NAN], -2, 2));
    assert_eq!(h.counts, vec![0, 1, 2, 1]);
    assert_eq!((h.above, h.skipped), (1, 1));
    let before = h.clone();
    merge_histogram(&mut h, &Histogram::log2(&[1.0], -1, 2));
    assert_eq!(h, before, "different edges are not merged");
}

/// The filter changes only texels: same blocks, same file size; different atlas bytes.
#[test]
fn kaiser_filter_changes_texels_not_layout() {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf");
    let scene = atlastree::scene::import(&path, &Default::default()).expect("data/city");
    let dir = tempfile::tempdir().expect("tempdir");
    let run = |f: MipFilter| {
        let out = dir.path().join(format!("{}.atlastree", f.name()));
        let r = build(
            &scene,
            &BuildOptions {
                d_min: DMin::Ratio(4.0),
                atlas_size: 256,
                mip_filter: f,
                // The paper's tree: every node that does not fit one atlas is split (multi-level).
                leaf_originals_atlases: 0.0,
                ..BuildOptions::default()
            },
            &out,
            &NoProgress,
        )
        .expect("build");
        (r, std::fs::read(&out).expect("read"))
    };
    let (rb, bb) = run(MipFilter::Box);
    let (rk, bk) = run(MipFilter::Kaiser);
    assert_eq!(rb.blocks, rk.blocks);
    assert_eq!(rb.file_bytes, rk.file_bytes);
    assert_eq!(bb.len(), bk.len());
    let differing = bb.iter().zip(&bk).filter(|(a, b)| a != b).count();
    assert!(
        differing > 1000,
        "only {differing} bytes differ between box and Kaiser builds"
    );
    assert_eq!("kaiser".parse::<MipFilter>(), Ok(MipFilter::Kaiser));
    assert!("lanczos".parse::<MipFilter>().is_err());
}

/// A knob listing more than 64 values is refused before the grid is expanded (duplicates are removed by
/// linear search, and each value costs at least one build or variant).
#[test]
fn a_knob_with_too_many_values_is_refused() {
    let mut g = Grid::preset("small").expect("preset");
    g.d_min_ratio = (1..=65).map(f64::from).collect();
    let e = g.validate("test").unwrap_err().to_string();
    assert!(
        e.contains("d_min_ratio lists 65 values; at most 64 per knob"),
        "{e}"
    );
    g.d_min_ratio.truncate(64);
    g.validate("test").unwrap();
    // Frames below SSIM's window are refused before any build (they failed after the first variant).
    let mut small = Grid::preset("small").expect("preset");
    small.width = 8;
    let e = small.validate("test").unwrap_err().to_string();
    assert!(e.contains("SSIM, which needs at least 11×11"), "{e}");
    // Two values that print alike (ids keep 12 significant digits) would be two rows under one id.
    let mut g = Grid::preset("small").expect("preset");
    g.texel_ratio = vec![1.0000000000001, 2.0];
    let e = g.validate("test").unwrap_err().to_string();
    assert!(
        e.contains("two variants print as") && e.contains("t1_"),
        "{e}"
    );
}

/// A closed path's start and end see one view: `repeated_views` finds the pair the sweep warns about
/// (with `--frames 2` on the overview-dive every variant measured the overview twice, and the texel ratio
/// seemed to change nothing); a street flight repeats no view.
#[test]
fn repeated_views_find_a_closed_paths_start_and_end() {
    use atlastree::camera::CameraPath;
    use atlastree::scene::UpAxis;
    use atlastree::sweep::{repeated_views, sample_path};
    use glam::DVec3;
    let (lo, hi) = (DVec3::ZERO, DVec3::new(800.0, 60.0, 500.0));
    let dive = CameraPath::overview_dive(lo, hi, UpAxis::Y).unwrap();
    assert_eq!(repeated_views(&sample_path(&dive, 2, 4.0 / 3.0)), [(0, 1)]);
    // Five frames: the start and end, and the descent's and the climb's mirrored halfway views.
    assert_eq!(
        repeated_views(&sample_path(&dive, 5, 4.0 / 3.0)),
        [(0, 4), (1, 3)]
    );
    let street = CameraPath::street(lo, hi, UpAxis::Y).unwrap();
    assert!(repeated_views(&sample_path(&street, 5, 4.0 / 3.0)).is_empty());
}

/// A capacity below the scene's root atlases (one per tree) is refused before any build, naming the
/// number needed; the grid alone cannot tell (one root without alpha materials, two with).
#[test]
fn a_capacity_below_the_root_atlases_is_refused_before_any_build() {
    use atlastree::scene::synthetic::SceneBuilder;
    use atlastree::scene::{AlphaMode, UpAxis, Wrap};
    use glam::{DVec2, DVec3};
    let scene = |alpha: bool| {
        let mut b = SceneBuilder::new(UpAxis::Y);
        let img = b.pattern_image("ground", 16, 0);
        let m = b.material(img, [Wrap::Repeat; 2], AlphaMode::Opaque);
        let quad = |x: f64| {
            [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
                .map(|(dx, dz)| DVec3::new(x + dx, 0.0, dz))
        };
        b.quad(quad(0.0), DVec2::ZERO, DVec2::ONE, m);
        if alpha {
            let leaves = b.pattern_image("leaves", 16, 1);
            let m = b.material(leaves, [Wrap::Repeat; 2], AlphaMode::Mask { cutoff: 0.5 });
            b.quad(quad(2.0), DVec2::ZERO, DVec2::ONE, m);
        }
        b.build()
    };
    let grid = |k: u32| {
        let text = format!(
            r#"{{"base": {{"d_min_ratio": 8, "atlas_size": 1024, "border": 8, "filter": "box",
            "texel_ratio": 1, "capacity": {k}}}, "frames": 2}}"#
        );
        let g = Grid::from_json(&text, "g.json").expect("parses");
        g.validate("g.json").expect("valid");
        g.plan()
    };
    let refused = atlastree::sweep::check_capacities(&scene(true), &grid(1))
        .expect_err("k 1 with two trees")
        .to_string();
    assert!(refused.contains("needs at least 2"), "{refused}");
    atlastree::sweep::check_capacities(&scene(true), &grid(2)).expect("k 2, two trees");
    atlastree::sweep::check_capacities(&scene(false), &grid(1)).expect("k 1, one tree");
}
