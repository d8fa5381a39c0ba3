//! The paging simulator on data/city's tree along the overview-dive: determinism (byte-identical CSVs),
//! conservation (bytes loaded = sizes of the blocks made resident), capacity respected every frame,
//! monotonicity of the mean coarser share in capacity and bandwidth under the paper's policy, and the
//! I/O model's timing on a hand-computed case.

use atlastree::camera::{Camera, CameraPath};
use atlastree::paging::{Event, Policy, UploadBudget};
use atlastree::preprocess::{BuildOptions, DMin, NoProgress, build};
use atlastree::sim::grid::{GridSpec, RunKey, run_grid, write_csvs};
use atlastree::sim::{SimInput, simulate, simulate_with};
use atlastree::store::TreeFile;
use glam::DVec3;
use std::path::{Path, PathBuf};

fn city(dir: &Path) -> PathBuf {
    let scene = atlastree::scene::import(
        &Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf"),
        &Default::default(),
    )
    .unwrap();
    let out = dir.join("city.atlastree");
    let opts = BuildOptions {
        d_min: DMin::Ratio(10.0),
        atlas_size: 512,
        border: 8,
        // The paper's tree: every node that does not fit one atlas is split (multi-level).
        leaf_originals_atlases: 0.0,
        ..BuildOptions::default()
    };
    build(&scene, &opts, &out, &NoProgress).unwrap();
    out
}

fn cameras(file: &TreeFile, fps: f64, n: usize) -> Vec<Camera> {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for t in 0..file.trees() {
        let r = file.tree(t).unwrap().nodes[0];
        lo = lo.min(r.bounds_min.into());
        hi = hi.max(r.bounds_max.into());
    }
    let path = CameraPath::overview_dive(lo, hi, file.to_params().up).unwrap();
    path.frames(fps, n)
        .map(|mut c| {
            c.aspect = 4.0 / 3.0;
            c
        })
        .collect()
}

/// Each camera's min-distance scale at 800 px (its own field of view).
fn scales(file: &TreeFile, cams: &[Camera]) -> Vec<f64> {
    cams.iter()
        .map(|c| crate::views::scale_800(&file.to_params(), c.fov_x_deg))
        .collect()
}

fn spec(capacities: Vec<Option<u32>>, bandwidths: Vec<Option<f64>>, policy: Policy) -> GridSpec {
    GridSpec {
        capacities,
        bandwidths,
        latencies: vec![0.0, 0.08],
        policies: vec![policy],
        fps: 60.0,
        max_queue: 8,
        budget: UploadBudget::Unlimited,
        max_in_flight: 4,
        overhead: 0.0,
    }
}

/// Run labels are the `run` key of the CSVs: distinct values give distinct labels (100 B/s and 200 B/s
/// were both `0.MBps`), tiny and huge values stay short, and a value given twice is found.
#[test]
fn run_labels_are_distinct_short_and_duplicates_found() {
    let mut g = spec(
        vec![Some(40)],
        vec![Some(100.0), Some(200.0)],
        Policy::Paper,
    );
    g.latencies = vec![1e-7, 1e300, 0.08, 0.0805];
    let labels: Vec<String> = g.cells().iter().map(|c| c.label()).collect();
    assert_eq!(
        labels,
        [
            "k40_1e-4MBps_1e-4ms_paper",
            "k40_1e-4MBps_1e303ms_paper",
            "k40_1e-4MBps_80ms_paper",
            "k40_1e-4MBps_80.5ms_paper",
            "k40_2e-4MBps_1e-4ms_paper",
            "k40_2e-4MBps_1e303ms_paper",
            "k40_2e-4MBps_80ms_paper",
            "k40_2e-4MBps_80.5ms_paper",
        ]
    );
    assert_eq!(g.duplicate_label(), None);
    g.bandwidths.push(Some(100.0));
    assert_eq!(
        g.duplicate_label().as_deref(),
        Some("k40_1e-4MBps_1e-4ms_paper")
    );
}

#[test]
fn simulate_is_deterministic_conserves_bytes_and_respects_k() {
    let dir = tempfile::tempdir().unwrap();
    let path = city(dir.path());
    let file = TreeFile::open(&path).unwrap();
    let cams = cameras(&file, 60.0, 600);
    let s = scales(&file, &cams);
    let input = SimInput::from_file(&file).unwrap();
    let grid = spec(
        vec![Some(8), Some(24), None],
        vec![None, Some(5e6), Some(50e6)],
        Policy::Paper,
    );
    let a = run_grid(&input, &cams, &s, &grid, &|| {}).unwrap();
    let b = run_grid(&input, &cams, &s, &grid, &|| {}).unwrap();
    let (da, db) = (dir.path().join("a"), dir.path().join("b"));
    std::fs::create_dir_all(&da).unwrap();
    std::fs::create_dir_all(&db).unwrap();
    write_csvs(&da, &a, grid.overhead).unwrap();
    write_csvs(&db, &b, grid.overhead).unwrap();
    for name in ["frames.csv", "summary.csv"] {
        let (x, y) = (
            std::fs::read(da.join(name)).unwrap(),
            std::fs::read(db.join(name)).unwrap(),
        );
        assert!(x.len() > 1000, "{name} is nearly empty");
        assert!(x == y, "{name} differs between two identical runs");
    }
    // frames.csv names its counters as every per-frame table does (report::columns), without timings.
    let t = atlastree::report::csv::read_csv(&da.join("frames.csv")).unwrap();
    let counters: Vec<&str> = atlastree::report::columns::paging_columns(&Default::default())
        .into_iter()
        .filter(|c| !c.timing)
        .map(|c| c.name)
        .collect();
    let mut want = vec![
        "run",
        "capacity",
        "bandwidth_bytes_per_s",
        "latency_ms",
        "overhead_ms",
        "policy",
        "frame",
        "time_s",
    ];
    want.extend(&counters);
    want.push("time_to_ideal");
    assert_eq!(t.header, want);
    for old in [
        "needed",
        "bytes",
        "bytes_originals",
        "coarser_levels",
        "upload_ms",
    ] {
        assert!(
            !t.header.iter().any(|h| h == old),
            "{old} is still a column"
        );
    }
    let rows: usize = a.iter().map(|r| r.rows.len()).sum();
    assert_eq!(t.rows.len(), rows);
    // summary.csv says whether the path drew any node (a path looking away reads as ideal paging
    // otherwise; fault hunt, session 36): these runs draw, and its value is the rows'.
    let sum = atlastree::report::csv::read_csv(&da.join("summary.csv")).unwrap();
    let drew = sum.header.iter().position(|h| h == "drew_nodes").unwrap();
    assert!(a.iter().all(|r| r.drew_nodes()));
    assert!(sum.rows.iter().all(|r| r[drew] == "true"), "{:?}", sum.rows);
    // The bytes_loaded column is the rows' bytes, frame by frame.
    let col = t.header.iter().position(|h| h == "bytes_loaded").unwrap();
    let written: Vec<u64> = t.rows.iter().map(|r| r[col].parse().unwrap()).collect();
    let held: Vec<u64> = a
        .iter()
        .flat_map(|r| r.rows.iter().map(|x| x.bytes_loaded()))
        .collect();
    assert_eq!(written, held);
    // A frame that loads uploads what a renderer would (the bytes the upload budget counts): the column
    // read 0 on every frame.
    let up = t.header.iter().position(|h| h == "bytes_uploaded").unwrap();
    let mut loads = 0;
    for row in &t.rows {
        let (loaded, uploaded): (u64, u64) = (row[col].parse().unwrap(), row[up].parse().unwrap());
        assert_eq!(loaded > 0, uploaded > 0, "{row:?}");
        // An upload is the stored bytes or more (an original padded to its square class).
        assert!(uploaded >= loaded, "{row:?}");
        loads += usize::from(loaded > 0);
    }
    assert!(
        loads > 10,
        "only {loads} frames load: the check proves little"
    );
    for r in &a {
        let k = r.key.capacity.unwrap_or(u32::MAX);
        for row in &r.rows {
            assert!(
                row.paging.session.pager.resident <= k,
                "{}: frame {} has {} > k",
                r.key.label(),
                row.frame,
                row.paging.session.pager.resident
            );
        }
        // Conservation: replay the run with the event log; loaded bytes = sizes of the loaded blocks.
        let (mut loaded, mut loaded_originals) = (0u64, 0u64);
        let mut resident = std::collections::HashSet::new();
        let (rows, _) = simulate_with(
            &input,
            &cams,
            &s,
            &grid.options(&r.key),
            &mut |_, e| match e {
                Event::Loaded { block, .. } => {
                    assert!(
                        resident.insert(*block),
                        "{block} loaded twice without eviction"
                    );
                    let m = input.table.meta(*block);
                    loaded += m.bytes;
                    if !m.item.is_atlas() {
                        loaded_originals += m.bytes;
                    }
                }
                Event::Evicted { block } => {
                    assert!(resident.remove(block), "{block} evicted but not resident");
                }
            },
        )
        .unwrap();
        let bytes: u64 = rows.iter().map(|x| x.bytes_loaded()).sum();
        assert_eq!(bytes, loaded, "{}", r.key.label());
        // Originals and atlases apart: loaded and resident bytes add up per kind.
        let originals: u64 = rows.iter().map(|x| x.paging.loaded_original_bytes).sum();
        assert_eq!(originals, loaded_originals, "{}", r.key.label());
        assert_eq!(r.summary.bytes_originals_total, loaded_originals);
        let last = rows.last().unwrap();
        // The roots are loaded by the bootstrap, before the first frame's events.
        resident.extend(input.table.roots());
        let resident_bytes: u64 = resident.iter().map(|b| input.table.meta(*b).bytes).sum();
        assert_eq!(
            last.paging.resident_atlas_bytes + last.paging.resident_original_bytes,
            resident_bytes,
            "{}",
            r.key.label()
        );
        assert_eq!(rows, r.rows, "{}: replay differs", r.key.label());
    }
    // The I/O model costs: at 5 MB/s the same flight is never better than instant arrival.
    let mean = |cap: Option<u32>, bw: Option<f64>| {
        a.iter()
            .find(|r| r.key.capacity == cap && r.key.bandwidth == bw && r.key.latency == 0.0)
            .unwrap()
            .summary
            .mean_coarser
    };
    assert!(mean(Some(24), Some(5e6)) >= mean(Some(24), None));
    assert_eq!(
        mean(None, None),
        0.0,
        "with every block allowed and instant loads nothing is coarser"
    );
}

/// More capacity or more bandwidth never gives a *materially* larger mean coarser share under the paper's
/// policy on this path: tolerance 0.025 (absolute share).
///
/// Documented counterexamples (exact runs, printed by this test): at 2 MB/s, k 6 → 12 raises the mean from
/// 0.805 to 0.822 — with more room, the paper's "culled" and "parent needed" prefetch requests are issued
/// while nothing needed is missing, and on a slow pipe a needed block requested after a jump waits behind
/// them (a transfer in flight cannot be taken back, only discarded); at 80 ms latency, 20 → 200 MB/s at
/// k = 48 goes from 0 to 0.005 — arrivals in a different order change which blocks are evicted.
#[test]
fn paper_policy_is_monotone_in_capacity_and_bandwidth() {
    let dir = tempfile::tempdir().unwrap();
    let path = city(dir.path());
    let file = TreeFile::open(&path).unwrap();
    let cams = cameras(&file, 60.0, 900);
    let s = scales(&file, &cams);
    let input = SimInput::from_file(&file).unwrap();
    let caps = vec![Some(6), Some(12), Some(24), Some(48), None];
    let bws = vec![Some(2e6), Some(20e6), Some(200e6), None];
    let grid = spec(caps.clone(), bws.clone(), Policy::Paper);
    let res = run_grid(&input, &cams, &s, &grid, &|| {}).unwrap();
    let mean = |c: Option<u32>, b: Option<f64>, l: f64| {
        res.iter()
            .find(|r| {
                r.key.answers(&RunKey {
                    capacity: c,
                    bandwidth: b,
                    latency: l,
                    policy: Policy::Paper,
                })
            })
            .unwrap()
            .summary
            .mean_coarser
    };
    let mut violations = Vec::new();
    for &l in &grid.latencies {
        for w in caps.windows(2) {
            for &b in &bws {
                if mean(w[1], b, l) > mean(w[0], b, l) + 1e-9 {
                    violations.push(format!(
                        "k {:?} → {:?} at {b:?} B/s, {l} s: {} → {}",
                        w[0],
                        w[1],
                        mean(w[0], b, l),
                        mean(w[1], b, l)
                    ));
                }
            }
        }
        for w in bws.windows(2) {
            for &c in &caps {
                if mean(c, w[1], l) > mean(c, w[0], l) + 1e-9 {
                    violations.push(format!(
                        "bandwidth {:?} → {:?} at k {c:?}, {l} s: {} → {}",
                        w[0],
                        w[1],
                        mean(c, w[0], l),
                        mean(c, w[1], l)
                    ));
                }
            }
        }
    }
    let material: Vec<&String> = violations
        .iter()
        .filter(|v| {
            let (a, b) = v.rsplit_once(": ").unwrap().1.split_once(" → ").unwrap();
            b.parse::<f64>().unwrap() - a.parse::<f64>().unwrap() > 0.025
        })
        .collect();
    println!(
        "exact counterexamples (within tolerance):\n{}",
        violations.join("\n")
    );
    assert!(
        material.is_empty(),
        "not monotone beyond 0.025:\n{material:?}"
    );
}

/// A frame's needs follow its own field of view, as the renderer's do (simulate took the first
/// camera's for the whole path: the overview-dive's street part, at 75°, needed other blocks in
/// `render` than in `simulate`). Two cameras at one pose, 30° and 100°: each frame of the pair needs
/// what it needs alone; scales of another count than the cameras are refused.
#[test]
fn simulate_scales_each_frame_by_its_own_field_of_view() {
    let dir = tempfile::tempdir().unwrap();
    let path = city(dir.path());
    let file = TreeFile::open(&path).unwrap();
    let input = SimInput::from_file(&file).unwrap();
    let grid = spec(vec![None], vec![None], Policy::Paper);
    let opts = grid.options(&grid.cells()[0]);
    // Blocks needed, and the resident set after the frame (every load instant, nothing evicted).
    let needed = |cams: &[Camera]| -> Vec<(u32, u64)> {
        let (rows, _) = simulate(&input, cams, &scales(&file, cams), &opts).unwrap();
        rows.iter()
            .map(|r| (r.paging.pager().usage.needed, r.paging.resident_hash))
            .collect()
    };
    let at = |pose: Camera, fov: f64| Camera {
        fov_x_deg: fov,
        ..pose
    };
    // The first pose of the overview-dive where the two fields of view need other blocks.
    let (narrow, wide, pose) = cameras(&file, 60.0, 120)
        .into_iter()
        .find_map(|pose| {
            let (n, w) = (needed(&[at(pose, 30.0)]), needed(&[at(pose, 100.0)]));
            (n != w).then_some((n, w, pose))
        })
        .expect("a pose that needs other blocks at 30° and 100°");
    let pair = [at(pose, 30.0), at(pose, 100.0)];
    // (The pair's second resident set also holds the first frame's blocks: the counts are compared.)
    let counts: Vec<u32> = needed(&pair).iter().map(|n| n.0).collect();
    assert_eq!(counts, [narrow[0].0, wide[0].0]);
    let e = simulate(&input, &pair, &[1.0], &opts).unwrap_err();
    assert_eq!(
        e.to_string(),
        "2 cameras but 1 min-distance scales (one per camera)"
    );
}

/// Instant loads model no I/O: a grid runs them at its first latency only (two identical runs under
/// `_0ms` and `_80ms` labels read as "latency had no effect").
#[test]
fn instant_bandwidth_runs_once_whatever_the_latencies() {
    let grid = spec(vec![Some(8)], vec![None, Some(5e6)], Policy::Paper);
    let labels: Vec<String> = grid.cells().iter().map(|k| k.label()).collect();
    assert_eq!(
        labels,
        [
            "k8_instant_0ms_paper",
            "k8_5MBps_0ms_paper",
            "k8_5MBps_80ms_paper"
        ],
        "{labels:?}"
    );
}
