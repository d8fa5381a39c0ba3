//! Paged rendering (paper §6) end to end on lavapipe: data/city's deep tree (187 blocks, k = 24) flown along the
//! overview-dive with a capacity far below the block count and a one-block-per-frame upload budget, so
//! frames are drawn with coarser ancestors while blocks load:
//!
//! - every frame: resident ≤ k; every selected triangle drawn (the batch's triangles equal the cut's, no
//!   item skipped) and the covered pixels the same as the all-resident frame's (coverage; alpha-masked
//!   texels may differ at coarser levels, so ≤ 0.5 % of pixels);
//! - some frames are coarser than target (the budget makes blocks late), and are counted;
//! - after the camera stops, the frame converges to the all-resident image (identical RGB).

use atlastree::camera::Camera;
use atlastree::gpu::GpuContext;
use atlastree::paging::{FileSource, PagerOptions, Policy, UploadBudget};
use atlastree::render::{FrameLoop, Mode, PagingSetup, RendererOptions};
use atlastree::store::TreeFile;
use std::sync::Arc;

use crate::harness::GpuTest;
use crate::render::{H, W, city_deep, dive_cameras, e, frame, is_sky, renderer, scale_for};

pub fn tests() -> Vec<GpuTest> {
    vec![
        GpuTest {
            name: "paging::paged_frames_stay_under_k_draw_everything_and_converge",
            run: paged_frames_stay_under_k_draw_everything_and_converge,
        },
        GpuTest {
            name: "paging::simulator_resident_sets_match_the_renderer",
            run: simulator_resident_sets_match_the_renderer,
        },
        GpuTest {
            name: "paging::over_http_with_the_server_stopped_and_restarted",
            run: over_http_with_the_server_stopped_and_restarted,
        },
        GpuTest {
            name: "paging::render_over_http_reports_what_the_client_did",
            run: render_over_http_reports_what_the_client_did,
        },
    ]
}

pub(crate) fn paged<'f>(
    ctx: &'f GpuContext,
    file: &'f TreeFile,
    k: u32,
    budget: UploadBudget,
    source: Arc<dyn atlastree::paging::BlockSource>,
    threads: usize,
) -> Result<FrameLoop<'f>, String> {
    paged_with(ctx, file, k, budget, source, threads, Policy::Paper)
}

pub(crate) fn paged_with<'f>(
    ctx: &'f GpuContext,
    file: &'f TreeFile,
    k: u32,
    budget: UploadBudget,
    source: Arc<dyn atlastree::paging::BlockSource>,
    threads: usize,
    policy: Policy,
) -> Result<FrameLoop<'f>, String> {
    FrameLoop::new_paged(
        ctx,
        file,
        RendererOptions::sized(W, H),
        PagingSetup {
            pager: PagerOptions {
                capacity: k,
                max_queue: 4,
                budget,
                policy,
                retry_frames: 4,
            },
            source,
            loader_threads: threads,
        },
    )
    .map_err(e)
}

/// Pixels whose background/foreground status differs.
pub(crate) fn coverage_mismatch(a: &[u8], b: &[u8]) -> usize {
    a.chunks_exact(4)
        .zip(b.chunks_exact(4))
        .filter(|(x, y)| is_sky(x) != is_sky(y))
        .count()
}

/// Checks one paged frame against the all-resident one; returns whether it was drawn coarser.
pub(crate) fn check_frame(
    paged: &mut FrameLoop<'_>,
    full: &mut FrameLoop<'_>,
    file: &TreeFile,
    cam: &Camera,
    k: u32,
    i: usize,
) -> Result<(bool, Vec<u8>, Vec<u8>), String> {
    let (s, img) = frame(paged, file, cam, Mode::Tree)?;
    let (fs, full_img) = frame(full, file, cam, Mode::Tree)?;
    let p = s.plan.paging.ok_or("no paging stats on a paged renderer")?;
    if p.session.pager.resident > k {
        return Err(format!(
            "frame {i}: {} resident > k = {k}",
            p.session.pager.resident
        ));
    }
    let cut_tris: u64 = paged
        .cuts()
        .iter()
        .flat_map(|c| &c.items)
        .map(|it| u64::from(it.index_count / 3))
        .sum();
    if s.triangles != cut_tris || s.triangles != fs.triangles {
        return Err(format!(
            "frame {i}: drew {} triangles, the cut has {cut_tris}, all-resident drew {}",
            s.triangles, fs.triangles
        ));
    }
    let mismatch = coverage_mismatch(&img, &full_img);
    let limit = (W * H) as usize / 200;
    if mismatch > limit {
        return Err(format!(
            "frame {i}: coverage differs from the all-resident frame in {mismatch} pixels (> {limit})"
        ));
    }
    if p.apply_errors > 0 {
        return Err(format!(
            "frame {i}: {} residency changes failed on the GPU",
            p.apply_errors
        ));
    }
    Ok((p.coarse.coarser_items > 0, img, full_img))
}

fn paged_frames_stay_under_k_draw_everything_and_converge(ctx: &GpuContext) -> Result<(), String> {
    let path = city_deep()?;
    let file = TreeFile::open(&path).map_err(e)?;
    let blocks = file.blocks().len() as u32;
    let k = 24;
    if blocks < 4 * k {
        return Err(format!(
            "fixture has only {blocks} blocks; the test wants k far below that"
        ));
    }
    let source = Arc::new(FileSource::new(Arc::new(TreeFile::open(&path).map_err(e)?)));
    let mut p = paged(ctx, &file, k, UploadBudget::Bytes(1), source, 0)?;
    let mut full = renderer(ctx, &file)?;
    let cams = dive_cameras(&file, 24)?;
    let mut coarser_frames = 0;
    for (i, cam) in cams.iter().enumerate() {
        p.set_clock(i as f64 / 30.0);
        if check_frame(&mut p, &mut full, &file, cam, k, i)?.0 {
            coarser_frames += 1;
        }
    }
    if coarser_frames == 0 {
        return Err("no frame was drawn coarser: the test did not exercise the fallback".into());
    }
    // The camera stops at the last view: the ideal set loads and the frame converges.
    let last = cams.last().ok_or("no cameras")?;
    let mut converged_at = None;
    for j in 0..80 {
        let (coarser, img, full_img) =
            check_frame(&mut p, &mut full, &file, last, k, cams.len() + j)?;
        if !coarser && img == full_img {
            converged_at = Some(j);
            break;
        }
    }
    let Some(j) = converged_at else {
        let s = p.pager().map(|pg| *pg.frame_stats());
        return Err(format!(
            "did not converge to the all-resident image in 80 frames: {s:?}"
        ));
    };
    let _ = scale_for;
    println!(
        "    {coarser_frames}/{} frames coarser while flying; converged {j} frames after the stop (k = {k}, {blocks} blocks)",
        cams.len()
    );
    Ok(())
}

/// The simulator (no I/O model, same k, budget, queue, policy and clock) logs the same resident set per
/// frame as the GPU renderer with the synchronous loader: the same paging code drives both.
fn simulator_resident_sets_match_the_renderer(ctx: &GpuContext) -> Result<(), String> {
    use atlastree::sim::{SimInput, SimOptions, simulate};
    let path = city_deep()?;
    let file = TreeFile::open(&path).map_err(e)?;
    let cams = dive_cameras(&file, 30)?;
    let budget = UploadBudget::Bytes(2_000_000);
    for (k, policy) in [
        (10u32, Policy::Paper),
        (20, Policy::Ours),
        (16, Policy::Lru),
    ] {
        let source = Arc::new(FileSource::new(Arc::new(TreeFile::open(&path).map_err(e)?)));
        let mut r = paged_with(ctx, &file, k, budget, source, 0, policy)?;
        let mut gpu_hashes = Vec::new();
        let scale = scale_for(&file, &cams[0])?;
        for (i, cam) in cams.iter().enumerate() {
            r.set_clock(i as f64 / 30.0);
            let s = r.render(cam, scale, Mode::Tree).map_err(e)?;
            gpu_hashes.push(s.plan.paging.ok_or("no paging stats")?.resident_hash);
        }
        // The renderer's pager options (see `paged`) with this policy.
        let opts = SimOptions {
            fps: 30.0,
            pager: PagerOptions {
                capacity: k,
                max_queue: 4,
                budget,
                policy,
                retry_frames: 4,
            },
            io: None,
        };
        let input = SimInput::from_file(&file).map_err(e)?;
        let (rows, _) = simulate(&input, &cams, &vec![scale; cams.len()], &opts).map_err(e)?;
        let sim_hashes: Vec<u64> = rows.iter().map(|r| r.paging.resident_hash).collect();
        if sim_hashes != gpu_hashes {
            let first = sim_hashes.iter().zip(&gpu_hashes).position(|(a, b)| a != b);
            return Err(format!(
                "{policy:?} k = {k}: resident sets differ first at frame {first:?}"
            ));
        }
        if gpu_hashes.windows(2).all(|w| w[0] == w[1]) {
            return Err(format!(
                "{policy:?} k = {k}: the resident set never changed; the test proves nothing"
            ));
        }
    }
    Ok(())
}

/// The same flight with blocks over HTTP from `atlastree serve`'s server on 127.0.0.1 (two loader
/// threads): frames stay under k and fully drawn; the server is stopped mid-path — frames keep coming,
/// loads fail and are counted, nothing panics, residency stays bounded — and restarted, after which the
/// stopped camera's frame converges to the all-resident image.
fn over_http_with_the_server_stopped_and_restarted(ctx: &GpuContext) -> Result<(), String> {
    use atlastree::paging::serve;
    use atlastree::paging::{HttpOptions, HttpSource};
    use std::time::Duration;
    let path = city_deep()?;
    let file = TreeFile::open(&path).map_err(e)?;
    let server = serve::spawn(&path, "127.0.0.1:0".parse().map_err(e)?).map_err(e)?;
    let addr = server.addr();
    let url = server.url().to_string();
    let opts = HttpOptions {
        connect_timeout: Duration::from_millis(300),
        timeout: Duration::from_secs(5),
        retries: 1,
        backoff_initial: Duration::from_millis(10),
        backoff_max: Duration::from_millis(40),
        ..HttpOptions::default()
    };
    let (tables, http) = HttpSource::open(&url, opts).map_err(e)?;
    if tables.blocks() != file.blocks() {
        return Err("the served file's block table differs".into());
    }
    let http = Arc::new(http);
    let k = 24;
    let mut p = paged(ctx, &tables, k, UploadBudget::Unlimited, http.clone(), 2)?;
    let mut full = renderer(ctx, &file)?;
    let cams = dive_cameras(&file, 24)?;
    let mut failures = 0u32;
    let mut server = Some(server);
    let mut coarser_while_down = 0;
    for (i, cam) in cams.iter().enumerate() {
        if i == 8
            && let Some(s) = server.take()
        {
            s.shutdown();
        }
        p.set_clock(i as f64 / 30.0);
        let (coarser, _, _) = check_frame(&mut p, &mut full, &tables, cam, k, i)?;
        let stats = p.pager().map(|pg| *pg.frame_stats()).ok_or("no pager")?;
        failures += stats.failures;
        if stats.staged > 4 {
            return Err(format!(
                "frame {i}: {} blocks staged > max_queue",
                stats.staged
            ));
        }
        if server.is_none() && coarser {
            coarser_while_down += 1;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    if failures == 0 || !http.stats().is_failing() && http.stats().failures == 0 {
        return Err(format!(
            "no load failed while the server was down: {:?}",
            http.stats()
        ));
    }
    // Restart on the same address; stop the camera; the frame must converge to the all-resident one.
    let server = serve::spawn(&path, addr).map_err(e)?;
    let last = cams.last().ok_or("no cameras")?;
    let mut converged = None;
    for j in 0..200 {
        let (coarser, img, full_img) =
            check_frame(&mut p, &mut full, &tables, last, k, cams.len() + j)?;
        if !coarser && img == full_img {
            converged = Some(j);
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    server.shutdown();
    let Some(j) = converged else {
        return Err(format!(
            "no convergence after the restart: {:?}, http {:?}",
            p.pager().map(|pg| *pg.frame_stats()),
            http.stats()
        ));
    };
    println!(
        "    server down from frame 8: {failures} failed loads, {coarser_while_down} coarser frames while down; converged {j} frames after restart; http {:?}",
        http.stats()
    );
    Ok(())
}

/// `render URL` (a tree served by `atlastree serve`'s server) prints and writes what its HTTP client did:
/// requests, bytes, blocks, and no answer that ignored `Range`; a local render writes `"http": null`.
fn render_over_http_reports_what_the_client_did(_ctx: &GpuContext) -> Result<(), String> {
    use atlastree::paging::serve;
    let path = city_deep()?;
    let server = serve::spawn(&path, "127.0.0.1:0".parse().map_err(e)?).map_err(e)?;
    let dir = tempfile::tempdir().map_err(e)?;
    let render =
        |tree: &str, out: &std::path::Path| -> Result<(String, serde_json::Value), String> {
            let o = std::process::Command::new(env!("CARGO_BIN_EXE_atlastree"))
                .args(["render", tree, "--capacity", "24", "--loader-threads", "0"])
                .args([
                    "--frames", "4", "--width", "64", "--height", "48", "--every", "0",
                ])
                .arg("--out")
                .arg(out)
                .output()
                .map_err(e)?;
            let stdout = String::from_utf8_lossy(&o.stdout).into_owned();
            if !o.status.success() {
                return Err(format!(
                    "render {tree} failed: {}",
                    String::from_utf8_lossy(&o.stderr)
                ));
            }
            let text = std::fs::read_to_string(out.join("summary.json")).map_err(e)?;
            Ok((stdout, serde_json::from_str(&text).map_err(e)?))
        };
    let (stdout, v) = render(server.url(), &dir.path().join("remote"))?;
    let h = &v["http"];
    let n = |k: &str| h[k].as_u64().ok_or(format!("http.{k} missing: {v}"));
    if n("blocks")? == 0 || n("requests")? <= n("blocks")? || n("bytes")? == 0 {
        return Err(format!("the client's counters say nothing was paged: {h}"));
    }
    if n("full_responses")? != 0 || n("checksum_failures")? != 0 || n("failures")? != 0 {
        return Err(format!("a healthy server's run reports trouble: {h}"));
    }
    // A paged run says how many block loads failed (none here), so a script can tell a corrupt file.
    if v["modes"]["tree"]["load_failures"].as_u64() != Some(0) {
        return Err(format!(
            "summary.json lacks the paged run's load failures: {v}"
        ));
    }
    if !stdout.contains(&format!("http: {} requests", n("requests")?)) || stdout.contains("warning")
    {
        return Err(format!("stdout does not report the client: {stdout}"));
    }
    let local = path.display().to_string();
    let (_, v) = render(&local, &dir.path().join("local"))?;
    if !v["http"].is_null() {
        return Err(format!("a local render reports HTTP: {v}"));
    }
    Ok(())
}
