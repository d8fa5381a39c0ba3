//! Phase 7 of `render` (docs in [`super::render_cmd`]): each mode's `stats.csv`, contact sheet and
//! summary lines, the median frame times and their ratios, what the HTTP client did, and `summary.json`.

use super::render_cmd::ModeRun;
use anyhow::Context;
use atlastree::paging::HttpStats;
use atlastree::render::reference::Reference;
use atlastree::render::{FrameStats, Mode};
use atlastree::report::columns;
use atlastree::report::csv::CsvWriter;
use atlastree::sweep::summary::median;
use std::path::Path;

/// Phase 7: per mode `stats.csv`, the contact sheet and a summary on stdout; then the median frame times
/// of the modes and their ratios (tree ÷ dummy, original ÷ dummy, tree ÷ original: the paper's
/// comparison), on stdout and in `OUT/summary.json`.
pub(super) fn write_and_report(
    out: &Path,
    reference: Option<Reference>,
    runs: &[ModeRun],
    http: Option<HttpStats>,
) -> anyhow::Result<()> {
    let mut medians = Vec::new();
    for run in runs {
        write_stats_csv(&run.dir.join("stats.csv"), &run.stats)?;
        if !run.thumbs.is_empty() {
            let sheet = run.dir.join("contact_sheet.png");
            atlastree::util::save_png(&sheet, &contact_sheet(&run.thumbs))
                .with_context(|| format!("writing {}", sheet.display()))?;
        }
        medians.push(ModeMedians::of(run.mode, &run.stats));
        print_summary(run.mode, &run.stats, &run.dir);
        if let (Some(r), Some(q)) = (reference, Quality::of(&run.quality)) {
            println!(
                "  against the {} reference: PSNR {:.2} dB over all frames (worst frame {:.2}), SSIM mean \
                 {:.4} (min {:.4})",
                r.name(),
                q.psnr_all,
                q.psnr_min,
                q.ssim_mean,
                q.ssim_min
            );
        }
    }
    // A path that never looks at the scene times empty frames: their ratios would read as a measurement.
    let drew = runs.iter().any(|r| r.stats.iter().any(|s| s.triangles > 0));
    let ratios = if drew {
        frame_ratios(&medians)
    } else {
        eprintln!(
            "warning: no frame of the path draws any geometry (does it look at the scene?): the frame \
             times measure empty frames, so their ratios are left out"
        );
        Vec::new()
    };
    for (name, r) in &ratios {
        println!("median frame time {name}: {r:.3}");
    }
    if let Some(h) = &http {
        print_http(h);
    }
    let json = serde_json::json!({
        "complete": true,
        // False: the path never looks at the scene; the frames and their PSNR measure nothing.
        "drew_geometry": drew,
        "modes": medians.iter().map(|m| (m.mode.name().to_string(), {
            let run = runs.iter().find(|r| r.mode == m.mode);
            serde_json::json!({
            "frames": m.frames,
            "median_frame_ms": m.frame_ms,
            "median_gpu_ms": m.gpu_ms,
            // Paged runs: block loads that failed (a corrupt or unreachable block); null all-resident.
            "load_failures": run.and_then(|r| load_failures(&r.stats)),
            "reference": run.and_then(|r| Quality::of(&r.quality)).map(|q| serde_json::json!({
                "psnr_db_all_frames": q.psnr_all,
                "psnr_db_min": q.psnr_min,
                "ssim_mean": q.ssim_mean,
                "ssim_min": q.ssim_min,
                "psnr_db": q.psnr,
                "ssim": q.ssim,
            })),
        })})).collect::<serde_json::Map<String, serde_json::Value>>(),
        "reference": reference.map(|r| r.name()),
        "http": http,
        "ratios": ratios.iter().map(|(name, r)| (ratio_key(name), serde_json::json!(r)))
            .collect::<serde_json::Map<String, serde_json::Value>>(),
    });
    let path = out.join("summary.json");
    atlastree::util::write_atomic(
        &path,
        (serde_json::to_string_pretty(&json)? + "\n").as_bytes(),
    )
    .with_context(|| format!("writing {}", path.display()))?;
    Ok(())
}

/// What the HTTP client did over the whole run (tables, warm-up and every mode), with warnings for a
/// server that ignores `Range` (each block then costs the whole file) and for answers that failed their
/// checksum (the served file changed, or bytes were corrupted on the way).
fn print_http(h: &HttpStats) {
    use atlastree::util::human_bytes;
    println!(
        "http: {} requests ({} retries, {} fetches failed, counting loads still queued when the frames ended), {} received for {} blocks",
        h.requests,
        h.retries,
        h.failures,
        human_bytes(h.bytes),
        h.blocks
    );
    if h.full_responses > 0 {
        println!(
            "  warning: {} answers ignored Range and sent the whole file (the blocks were cut from it): serve \
             it with a server that honours Range, e.g. `atlastree serve`",
            h.full_responses
        );
    }
    if h.checksum_failures > 0 {
        // Not every failed answer was asked again (the last attempt of a fetch is not), and a block
        // failing every attempt points at the served file itself (fault hunt, session 32).
        // Only fetches whose every answer failed its checksum point at the file (a 404 or a timeout of
        // another block did, and the file verified clean; fault hunt, session 36).
        let corrupt = if h.checksum_fetch_failures > 0 {
            format!(
                "; {} fetches failed it on every attempt, so the served file itself may be corrupt: run \
                 `atlastree inspect --verify` on it",
                h.checksum_fetch_failures
            )
        } else {
            String::new()
        };
        println!(
            "  warning: {} answers failed their block checksum: the served file changed during the run, or \
             bytes were corrupted on the way{corrupt}",
            h.checksum_failures
        );
    }
}

/// A mode's frames against the reference.
struct Quality {
    /// [`atlastree::report::metrics::psnr_over_frames`]: the frames' squared errors averaged.
    psnr_all: f64,
    psnr_min: f64,
    ssim_mean: f64,
    ssim_min: f64,
    psnr: Vec<f64>,
    ssim: Vec<f64>,
}

impl Quality {
    /// `None` when no frame was measured.
    fn of(frames: &[(f64, f64)]) -> Option<Quality> {
        if frames.is_empty() {
            return None;
        }
        let n = frames.len() as f64;
        let psnr: Vec<f64> = frames.iter().map(|q| q.0).collect();
        let ssim: Vec<f64> = frames.iter().map(|q| q.1).collect();
        Some(Quality {
            psnr_all: atlastree::report::metrics::psnr_over_frames(psnr.iter().copied()),
            psnr_min: psnr.iter().copied().fold(f64::INFINITY, f64::min),
            ssim_mean: ssim.iter().sum::<f64>() / n,
            ssim_min: ssim.iter().copied().fold(f64::INFINITY, f64::min),
            psnr,
            ssim,
        })
    }
}

/// One mode's medians over the run.
struct ModeMedians {
    mode: Mode,
    frames: usize,
    frame_ms: f64,
    /// `None` without GPU timestamps.
    gpu_ms: Option<f64>,
}

impl ModeMedians {
    fn of(mode: Mode, stats: &[FrameStats]) -> ModeMedians {
        let gpu: Vec<f64> = stats.iter().filter_map(|s| s.gpu_ms).collect();
        ModeMedians {
            mode,
            frames: stats.len(),
            frame_ms: median(stats.iter().map(|s| s.frame_ms)),
            gpu_ms: (!gpu.is_empty()).then(|| median(gpu)),
        }
    }
}

/// The ratios of median frame times between the modes measured: `tree ÷ dummy`, `original ÷ dummy`,
/// `tree ÷ original` (those whose two modes ran).
fn frame_ratios(medians: &[ModeMedians]) -> Vec<(String, f64)> {
    let of = |m: Mode| medians.iter().find(|k| k.mode == m).map(|k| k.frame_ms);
    [
        (Mode::Tree, Mode::Dummy),
        (Mode::Original, Mode::Dummy),
        (Mode::Tree, Mode::Original),
    ]
    .into_iter()
    .filter_map(|(a, b)| {
        let (x, y) = (of(a)?, of(b)?);
        Some((format!("{} ÷ {}", a.name(), b.name()), x / y))
    })
    .collect()
}

/// `tree ÷ dummy` → `tree_over_dummy`.
fn ratio_key(name: &str) -> String {
    name.replace(" ÷ ", "_over_")
}

/// Block loads that failed over a paged run (`None` for an all-resident one).
fn load_failures(stats: &[FrameStats]) -> Option<u32> {
    let paged: Vec<_> = stats.iter().filter_map(FrameStats::paging).collect();
    (!paged.is_empty()).then(|| paged.iter().map(|p| p.pager().failures).sum())
}

/// Mean and max of a column.
fn mean_max(values: impl Iterator<Item = f64>) -> (f64, f64) {
    let (mut n, mut sum, mut max) = (0usize, 0.0, f64::NEG_INFINITY);
    for v in values {
        n += 1;
        sum += v;
        max = max.max(v);
    }
    if n == 0 {
        (0.0, 0.0)
    } else {
        (sum / n as f64, max)
    }
}

fn contact_sheet(thumbs: &[image::RgbaImage]) -> image::RgbaImage {
    let cols = (thumbs.len() as f64).sqrt().ceil().max(1.0) as u32;
    let rows = (thumbs.len() as u32).div_ceil(cols);
    let (tw, th) = thumbs.first().map_or((1, 1), |t| t.dimensions());
    let mut sheet = image::RgbaImage::from_pixel(cols * tw, rows * th, image::Rgba([0, 0, 0, 255]));
    for (i, t) in thumbs.iter().enumerate() {
        let (x, y) = ((i as u32 % cols) * tw, (i as u32 / cols) * th);
        image::imageops::replace(&mut sheet, t, i64::from(x), i64::from(y));
    }
    sheet
}

/// Frames without an answer before a run calls its source unresponsive ([`unanswered_requests`]).
const DEAD_AFTER_FRAMES: usize = 10;

/// What the run's end says of the requests still unanswered at its last frame (`None`: there were
/// none). A server that stopped responding holds them up to its timeout × attempts; they are abandoned
/// at exit, not counted as failures. Nothing arrived and nothing failed over at least
/// [`DEAD_AFTER_FRAMES`] frames: a dead source from the start (a shorter run may simply end before a
/// healthy source's first answers are drawn: one frame over a local server said "dead"). Nothing
/// arrived in the last frames while loads failed there: a source that died mid-run (more
/// frames or a synchronous loader cannot help). Otherwise the run simply ended before a slow source
/// answered (its latency × the requests per frame).
fn unanswered_requests(paged: &[&atlastree::plan::PagingFrame], failures: u32) -> Option<String> {
    let last = paged.last()?;
    let (in_flight, queued) = (last.session.in_flight, last.session.queued);
    if in_flight + queued == 0 {
        return None;
    }
    let loaded = paged.iter().map(|p| p.pager().loaded).sum::<u32>();
    let quiet: Vec<_> = paged
        .iter()
        .rev()
        .take_while(|p| p.pager().loaded == 0)
        .collect();
    let quiet_failures: u32 = quiet.iter().map(|p| p.pager().failures).sum();
    Some(
        if loaded == 0 && failures == 0 && paged.len() >= DEAD_AFTER_FRAMES {
            format!(
                "warning: no block request was answered during the run ({in_flight} in flight, {queued} queued at \
             the end): is the source responding?"
            )
        } else if quiet_failures > 0 {
            format!(
                "warning: the source stopped answering: nothing arrived in the last {} frames and {quiet_failures} \
             loads failed there ({in_flight} requests in flight and {queued} queued at the end)",
                quiet.len()
            )
        } else {
            format!(
                "note: the run ended with {in_flight} block requests in flight and {queued} queued (a source slower \
             than the frames: more frames, or --loader-threads 0 to wait for each load, let them arrive)"
            )
        },
    )
}

/// `stats.csv`: `frame`, the frame's counters and timings ([`atlastree::render::frame_columns`]) and, when paged,
/// the paging columns ([`columns::paging_columns`]).
fn write_stats_csv(path: &Path, stats: &[FrameStats]) -> anyhow::Result<()> {
    let paged = stats.iter().any(|s| s.paging().is_some());
    let row = |s: &FrameStats| {
        let mut c = atlastree::render::frame_columns(s);
        if paged {
            c.extend(columns::paging_columns_or_empty(s.paging()));
        }
        c
    };
    let mut header = vec!["frame"];
    header.extend(columns::names(&row(&FrameStats::default())));
    let mut w = CsvWriter::create(path, &header)?;
    for (i, s) in stats.iter().enumerate() {
        let mut cells = vec![atlastree::report::csv::Cell::from(i)];
        cells.extend(columns::cells(row(s)));
        w.row(&cells)?;
    }
    w.finish()?;
    Ok(())
}

fn print_summary(mode: Mode, stats: &[FrameStats], dir: &Path) {
    let col = |f: &dyn Fn(&FrameStats) -> f64| mean_max(stats.iter().map(f));
    let rows: [(&str, (f64, f64)); 9] = [
        ("nodes visited", col(&|s| f64::from(s.plan.nodes_visited))),
        ("nodes drawn", col(&|s| f64::from(s.plan.nodes_drawn))),
        ("indirect records", col(&|s| f64::from(s.indirect_records))),
        ("draw calls", col(&|s| f64::from(s.draw_calls))),
        (
            "bind-group changes",
            col(&|s| f64::from(s.bind_group_changes)),
        ),
        ("triangles", col(&|s| s.triangles as f64)),
        ("select µs", col(&|s| s.plan.select_us)),
        ("encode µs", col(&|s| s.encode_us)),
        ("frame ms", col(&|s| s.frame_ms)),
    ];
    println!(
        "mode {} ({} frames, {}):",
        mode.name(),
        stats.len(),
        dir.display()
    );
    for (name, (mean, max)) in rows {
        println!("  {name:<20} mean {mean:>10.2}  max {max:>10.2}");
    }
    let skipped: u64 = stats.iter().map(|s| u64::from(s.skipped_draws)).sum();
    if skipped > 0 {
        println!(
            "  warning: {skipped} draws skipped over the run (their atlas held no GPU layer; see stats.csv skipped_draws)"
        );
    }
    let gpu: Vec<f64> = stats.iter().filter_map(|s| s.gpu_ms).collect();
    if !gpu.is_empty() {
        let (mean, max) = mean_max(gpu.iter().copied());
        println!("  {:<20} mean {mean:>10.2}  max {max:>10.2}", "GPU ms");
    }
    let paged: Vec<_> = stats.iter().filter_map(FrameStats::paging).collect();
    if !paged.is_empty() {
        let peak = paged.iter().map(|p| p.pager().resident).max().unwrap_or(0);
        let bytes: u64 = paged.iter().map(|p| p.pager().bytes_loaded).sum();
        let (share, max_share) = mean_max(paged.iter().map(|p| p.coarse.share()));
        let failures = load_failures(stats).unwrap_or(0);
        println!(
            "  paging: peak resident {peak}, {} loaded after the root atlases (resident before the first \
             frame), coarser share mean {:.3} max {:.3}, {} load failures",
            atlastree::util::human_bytes(bytes),
            share,
            max_share,
            failures
        );
        if failures > 0 {
            // Only where some frame drew coarser: a block fetched ahead of need fails unseen (it said
            // "those nodes drew coarser" beside a coarser share of 0: fault hunt, session 33).
            let drawn = if max_share > 0.0 {
                "nodes whose blocks were missing drew a coarser resident atlas"
            } else {
                "no frame drew coarser for them: they were fetched ahead of need"
            };
            println!(
                "  warning: {failures} block loads failed ({drawn}; see stats.csv failures): a corrupt file or an unreachable server?"
            );
        }
        if let Some(line) = unanswered_requests(&paged, failures) {
            println!("  {line}");
        }
    }
    // Medians: robust against one-off stalls (a software rasteriser compiles shader variants on first use).
    let frame: Vec<f64> = stats.iter().map(|s| s.frame_ms).collect();
    // Without GPU timing (`--no-gpu-timing`, or no timestamp queries) there is no GPU median to print.
    let gpu_median = if gpu.is_empty() {
        String::new()
    } else {
        format!("  GPU median {:>8.2}", median(gpu))
    };
    println!(
        "  {:<20} median {:>8.2}{gpu_median}",
        "frame ms",
        median(frame)
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use atlastree::plan::PagingFrame;

    fn frame(loaded: u32, failures: u32, in_flight: u32) -> PagingFrame {
        let mut f = PagingFrame::default();
        f.session.pager.loaded = loaded;
        f.session.pager.failures = failures;
        f.session.in_flight = in_flight;
        f
    }

    /// A source that died mid-run is named as such (the note said "slower than the frames: more
    /// frames, or --loader-threads 0", which cannot help); a slow one and a dead-from-the-start one keep
    /// their messages; nothing unanswered, nothing said.
    #[test]
    fn the_end_of_run_line_tells_a_dead_source_from_a_slow_one() {
        let run = |frames: &[PagingFrame]| {
            let refs: Vec<&PagingFrame> = frames.iter().collect();
            let failures = frames.iter().map(|f| f.session.pager.failures).sum();
            unanswered_requests(&refs, failures)
        };
        let died = [frame(5, 0, 0), frame(0, 2, 1), frame(0, 1, 2)];
        let line = run(&died).unwrap();
        assert!(
            line.starts_with(
                "warning: the source stopped answering: nothing arrived in the last 2 frames and 3"
            ),
            "{line}"
        );
        let slow = [frame(5, 0, 0), frame(0, 0, 2)];
        assert!(
            run(&slow)
                .unwrap()
                .starts_with("note: the run ended with 2 block requests")
        );
        let dead: Vec<PagingFrame> = (0..DEAD_AFTER_FRAMES as u32)
            .map(|k| frame(0, 0, k + 1))
            .collect();
        assert!(run(&dead).unwrap().contains("is the source responding?"));
        // Shorter, the run may have ended before a healthy source's first answers: a note.
        let short = [frame(0, 0, 1), frame(0, 0, 2)];
        assert!(
            run(&short)
                .unwrap()
                .starts_with("note: the run ended with 2 block requests")
        );
        assert_eq!(run(&[frame(5, 0, 0)]), None);
    }
}
