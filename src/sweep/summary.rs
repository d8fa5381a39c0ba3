//! Pure functions over the sweep's rows: per-variant means, the Pareto front, recommended defaults and
//! the markdown report. No I/O, no GPU.

use super::grid::{BuildKnobs, RuntimeKnobs, variant_id};
use super::run::{BuildRow, FrameRow, SweepData};
use crate::render::reference::Reference;
use crate::report::metrics::{pareto_front, psnr_over_frames};
use crate::util::human_bytes;
use std::fmt::Write as _;

/// PSNR tolerance of the recommendations: a variant within this many dB of the best counts as "as
/// accurate" (about the frame-to-frame noise of the measure on a path).
pub const PSNR_TOLERANCE_DB: f64 = 0.5;

/// One variant: its knobs, build cost and the means of its frames.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct VariantRow {
    pub id: String,
    pub build: BuildKnobs,
    pub runtime: RuntimeKnobs,
    pub frames: usize,
    /// Over the frames: PSNRs of their averaged squared errors ([`psnr_over_frames`]), the rest means (NaN
    /// values are left out; all NaN gives NaN).
    pub psnr_db: f64,
    pub psnr_covered_db: f64,
    pub ssim: f64,
    /// The build's original textures against a supersampled reference (NaN against the originals).
    pub original_psnr_db: f64,
    pub original_psnr_covered_db: f64,
    pub original_ssim: f64,
    pub magnified_share: f64,
    pub below_target_share: f64,
    pub coarser_share: f64,
    pub select_us: f64,
    pub encode_us: f64,
    pub gpu_ms: f64,
    pub frame_ms: f64,
    /// Median frame time (robust to one-off stalls such as first-use shader compiles).
    pub frame_ms_median: f64,
    /// Bytes the pager loaded over all frames (0 when everything is resident).
    pub bytes_loaded: u64,
    pub file_bytes: u64,
    pub build_s: f64,
    pub peak_rss_bytes: Option<u64>,
}

/// Mean of the finite values (NaN when there are none).
pub fn mean(values: impl IntoIterator<Item = f64>) -> f64 {
    let (mut n, mut sum) = (0usize, 0.0);
    for v in values.into_iter().filter(|v| v.is_finite()) {
        n += 1;
        sum += v;
    }
    if n == 0 { f64::NAN } else { sum / n as f64 }
}

/// Median of the finite values (NaN when there are none).
pub fn median(values: impl IntoIterator<Item = f64>) -> f64 {
    let mut v: Vec<f64> = values.into_iter().filter(|v| v.is_finite()).collect();
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// One row per variant, in the order the variants first appear in `frames`; build cost from the
/// matching [`BuildRow`] (zero / `None` when the build is missing).
pub fn summarise(builds: &[BuildRow], frames: &[FrameRow]) -> Vec<VariantRow> {
    let mut order: Vec<(BuildKnobs, RuntimeKnobs)> = Vec::new();
    for f in frames {
        if !order.contains(&(f.build, f.runtime)) {
            order.push((f.build, f.runtime));
        }
    }
    order
        .into_iter()
        .map(|(b, r)| {
            let rows: Vec<&FrameRow> = frames
                .iter()
                .filter(|f| f.build == b && f.runtime == r)
                .collect();
            let col = |f: &dyn Fn(&FrameRow) -> f64| mean(rows.iter().map(|r| f(r)));
            // PSNR over the frames: their squared errors averaged, not their dB (an identical frame
            // counts 99 dB).
            let db = |f: &dyn Fn(&FrameRow) -> f64| psnr_over_frames(rows.iter().map(|r| f(r)));
            let build = builds.iter().find(|x| x.knobs == b);
            VariantRow {
                id: variant_id(&b, &r),
                build: b,
                runtime: r,
                frames: rows.len(),
                psnr_db: db(&|f| f.psnr_db),
                psnr_covered_db: db(&|f| f.psnr_covered_db),
                ssim: col(&|f| f.ssim),
                original_psnr_db: db(&|f| f.original_psnr_db),
                original_psnr_covered_db: db(&|f| f.original_psnr_covered_db),
                original_ssim: col(&|f| f.original_ssim),
                magnified_share: col(&|f| f.magnified_share),
                below_target_share: col(&|f| f.below_target_share),
                coarser_share: col(&|f| f.stats.paging().map_or(0.0, |p| p.coarse.share())),
                select_us: col(&|f| f.stats.plan.select_us),
                encode_us: col(&|f| f.stats.encode_us),
                gpu_ms: col(&|f| f.stats.gpu_ms.unwrap_or(f64::NAN)),
                frame_ms: col(&|f| f.stats.frame_ms),
                frame_ms_median: median(rows.iter().map(|f| f.stats.frame_ms)),
                bytes_loaded: rows
                    .iter()
                    .map(|f| f.stats.paging().map_or(0, |p| p.pager().bytes_loaded))
                    .sum(),
                file_bytes: build.map_or(0, |x| x.file_bytes),
                build_s: build.map_or(0.0, |x| x.build_s),
                peak_rss_bytes: build.and_then(|x| x.peak_rss_bytes),
            }
        })
        .collect()
}

/// Indices of the variants on the Pareto front of (median frame ms ↓, covered PSNR ↑), ascending cost.
pub fn frame_time_front(rows: &[VariantRow]) -> Vec<usize> {
    let pts: Vec<(f64, f64)> = rows
        .iter()
        .map(|r| (r.frame_ms_median, r.psnr_covered_db))
        .collect();
    pareto_front(&pts)
}

/// Recommended defaults: among the variants within [`PSNR_TOLERANCE_DB`] of the best covered PSNR, the
/// cheapest by each cost.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Recommendation {
    /// The most accurate variant (index into the rows).
    pub best: usize,
    pub tolerance_db: f64,
    /// Lowest median frame time within the tolerance, times within [`TIME_TIE_SHARE`] of the least
    /// counted as equal and the rows of one build that draw identical frames timed by their mean (the
    /// first such row named; tables and the front show each row's own median).
    pub fastest_frames: usize,
    /// Smallest file within the tolerance.
    pub smallest_file: usize,
    /// Shortest build within the tolerance.
    pub fastest_build: usize,
}

/// What a sweep whose path covers no pixel says (report, terminal).
pub const MEASURED_NOTHING: &str = "no frame of the path covers any pixel of the scene (does it look at \
     it?): nothing is measured (covered PSNR is empty; full-frame PSNR 99 dB and SSIM 1 compare two \
     backgrounds), no accuracy is plotted and no default is recommended";

/// Where some frames, not all, show nothing of the scene in the reference: which, in words (they are
/// left out of covered PSNR; `None` where every frame covers pixels or none does, [`MEASURED_NOTHING`]).
pub fn empty_frames_note(data: &SweepData) -> Option<String> {
    let empty = data.empty_frames();
    if empty.is_empty() || data.measures_nothing() {
        return None;
    }
    let mut frames: Vec<usize> = data.frames.iter().map(|f| f.frame).collect();
    frames.sort_unstable();
    frames.dedup();
    let listed: Vec<String> = empty.iter().take(8).map(usize::to_string).collect();
    let more = if empty.len() > 8 { ", …" } else { "" };
    Some(format!(
        "{} of {} frames cover no pixel of the scene in the reference (frame {}{more}): covered PSNR \
         leaves them out, full-frame PSNR and SSIM count them as the background both draw",
        empty.len(),
        frames.len(),
        listed.join(", ")
    ))
}

/// The sweep's recommendation: [`recommend`] at [`PSNR_TOLERANCE_DB`], `None` where the path measured
/// nothing ([`SweepData::measures_nothing`]).
pub fn recommendation(data: &SweepData, rows: &[VariantRow]) -> Option<Recommendation> {
    recommend(rows, PSNR_TOLERANCE_DB).filter(|_| !data.measures_nothing())
}

/// Share of the least frame or build time within which [`recommend`] counts times as equal: identical
/// sweeps on this machine named four different "fastest" variants, whose medians of a few frames
/// differed by up to 40 % (fault hunt, session 33).
pub const TIME_TIE_SHARE: f64 = 0.1;

/// [`Recommendation`] of `rows`; `None` when no row has a finite covered PSNR.
///
/// Times are measurements, so they decide only beyond [`TIME_TIE_SHARE`] of the least, and the
/// variants of one build that draw identical frames (the same covered PSNR and SSIM, to the bit: the
/// same nodes drawn) share their mean frame time. Among equals: the more accurate, then the most
/// accurate variant itself, then the first row. File sizes are exact.
pub fn recommend(rows: &[VariantRow], tolerance_db: f64) -> Option<Recommendation> {
    // Equal accuracy: the first row (exactly equal PSNR means identical frames; their times are noise):
    // `min_by` returns the first of equal minima, and the rows go in order.
    let best = (0..rows.len())
        .filter(|&i| rows[i].psnr_covered_db.is_finite())
        .min_by(|&a, &b| rows[b].psnr_covered_db.total_cmp(&rows[a].psnr_covered_db))?;
    let floor = rows[best].psnr_covered_db - tolerance_db;
    let ok: Vec<usize> = (0..rows.len())
        .filter(|&i| rows[i].psnr_covered_db >= floor)
        .collect();
    let cheapest = |cost: &dyn Fn(usize) -> f64, tie_share: f64| {
        let costs: Vec<(usize, f64)> = (ok.iter().map(|&i| (i, cost(i))))
            .filter(|c| c.1.is_finite())
            .collect();
        let Some(least) = costs.iter().map(|c| c.1).min_by(f64::total_cmp) else {
            return best;
        };
        let limit = least + least.abs() * tie_share;
        (costs.iter().filter(|c| c.1 <= limit).map(|c| c.0))
            .min_by(|&a, &b| {
                // Variants of one build share its file and build time: the best itself, not another
                // variant of the same file, is named the smallest file.
                (rows[b].psnr_covered_db.total_cmp(&rows[a].psnr_covered_db))
                    .then((a != best).cmp(&(b != best)))
            })
            .unwrap_or(best)
    };
    let frame_ms = same_frames_mean_ms(rows);
    Some(Recommendation {
        best,
        tolerance_db,
        fastest_frames: cheapest(&|i| frame_ms[i], TIME_TIE_SHARE),
        smallest_file: cheapest(&|i| rows[i].file_bytes as f64, 0.0),
        fastest_build: cheapest(&|i| rows[i].build_s, TIME_TIE_SHARE),
    })
}

/// Each row's median frame time, averaged over the rows of its build that drew identical frames (the
/// same covered PSNR and SSIM, to the bit): the same work, so their differences are noise.
fn same_frames_mean_ms(rows: &[VariantRow]) -> Vec<f64> {
    let keys: Vec<_> = (rows.iter())
        .map(|r| (r.build.id(), r.psnr_covered_db.to_bits(), r.ssim.to_bits()))
        .collect();
    let mut sums: std::collections::HashMap<_, (f64, u32)> = Default::default();
    for (key, r) in keys.iter().zip(rows) {
        if r.frame_ms_median.is_finite() {
            let e = sums.entry(key).or_default();
            *e = (e.0 + r.frame_ms_median, e.1 + 1);
        }
    }
    (keys.iter().zip(rows))
        .map(|(key, r)| match sums.get(key) {
            // An entry counts at least the row that made it.
            Some(&(sum, n)) => sum / f64::from(n),
            None => r.frame_ms_median,
        })
        .collect()
}

/// What changing one knob away from the base variant does (the grid is a star around the base; rows of
/// non-base builds at other texel ratios differ in two knobs and are not effects). Ratios are variant /
/// base; `NaN` where the base value is 0.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct KnobEffect {
    /// Knob name as in the grid JSON (`d_min_ratio`, `atlas_size`, `border`, `filter`, `compress`,
    /// `texel_ratio`, `capacity`).
    pub knob: &'static str,
    /// The variant's value of it.
    pub value: String,
    /// Index of the variant in the rows.
    pub row: usize,
    /// Covered PSNR minus the base's, dB (positive: more accurate).
    pub psnr_delta_db: f64,
    pub ssim_delta: f64,
    /// Median frame time ratio.
    pub frame_ratio: f64,
    pub file_ratio: f64,
    pub build_ratio: f64,
}

/// The knobs in which two variants differ, with the second variant's value of each.
fn differing(
    a: (&BuildKnobs, &RuntimeKnobs),
    b: (&BuildKnobs, &RuntimeKnobs),
) -> Vec<(&'static str, String)> {
    let mut d = Vec::new();
    let (ab, ar) = a;
    let (bb, br) = b;
    if ab.d_min_ratio != bb.d_min_ratio {
        d.push(("d_min_ratio", bb.d_min_ratio.to_string()));
    }
    if ab.atlas_size != bb.atlas_size {
        d.push(("atlas_size", bb.atlas_size.to_string()));
    }
    if ab.border != bb.border {
        d.push(("border", bb.border.to_string()));
    }
    if ab.filter != bb.filter {
        d.push(("filter", bb.filter.name().to_string()));
    }
    if ab.compress != bb.compress {
        d.push(("compress", bb.compress.label().to_string()));
    }
    if ab.repeat != bb.repeat {
        d.push(("repeat", bb.repeat.label().to_string()));
    }
    if ab.alpha_mips != bb.alpha_mips {
        d.push(("alpha_mips", bb.alpha_mips.name().to_string()));
    }
    if ar.texel_ratio != br.texel_ratio {
        d.push(("texel_ratio", br.texel_ratio.to_string()));
    }
    if ar.capacity != br.capacity {
        d.push((
            "capacity",
            br.capacity.map_or("all".into(), |k| k.to_string()),
        ));
    }
    d
}

/// The effect of each single-knob change against the base variant `base` (an index into `rows`), in row
/// order; rows that differ from the base in more than one knob (or none) are left out.
pub fn knob_effects(rows: &[VariantRow], base: usize) -> Vec<KnobEffect> {
    let b = &rows[base];
    let ratio = |x: f64, y: f64| if y > 0.0 { x / y } else { f64::NAN };
    rows.iter()
        .enumerate()
        .filter_map(|(i, r)| {
            let d = differing((&b.build, &b.runtime), (&r.build, &r.runtime));
            let [(knob, value)] = <[_; 1]>::try_from(d).ok()?;
            Some(KnobEffect {
                knob,
                value,
                row: i,
                psnr_delta_db: r.psnr_covered_db - b.psnr_covered_db,
                ssim_delta: r.ssim - b.ssim,
                frame_ratio: ratio(r.frame_ms_median, b.frame_ms_median),
                file_ratio: ratio(r.file_bytes as f64, b.file_bytes as f64),
                build_ratio: ratio(r.build_s, b.build_s),
            })
        })
        .collect()
}

/// Index of the grid's base variant in `rows`: the base build at the grid's base runtime knobs (it was the
/// variant at texel ratio 1 with every block resident, else the base build's first row: a base of
/// capacity 17 measured its knobs against capacity 2, and left out every build whose rows differ in
/// capacity too).
pub fn base_row(rows: &[VariantRow], base: &BuildKnobs, runtime: &RuntimeKnobs) -> Option<usize> {
    rows.iter()
        .position(|r| r.build == *base && r.runtime == *runtime)
}

/// Formats a float cell with its sign for markdown (`–` for NaN).
fn signed(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:+.decimals$}")
    } else {
        "–".into()
    }
}

/// Formats a float cell for markdown (`–` for NaN).
fn f(v: f64, decimals: usize) -> String {
    if v.is_finite() {
        format!("{v:.decimals$}")
    } else {
        "–".into()
    }
}

/// One line describing a variant's knobs and its headline numbers.
fn describe(r: &VariantRow) -> String {
    format!(
        "`{}`: d_min ratio {}, atlas {}², border {}, filter {}, compression {}, repeats {}, alpha mips {}, texel ratio {}, {} — covered PSNR {:.2} dB, \
         SSIM {:.4}, median frame {:.2} ms, file {}, build {:.2} s",
        r.id,
        r.build.d_min_ratio,
        r.build.atlas_size,
        r.build.border,
        r.build.filter.name(),
        r.build.compress.label(),
        r.build.repeat.label(),
        r.build.alpha_mips.name(),
        r.runtime.texel_ratio,
        r.runtime
            .capacity
            .map_or("all blocks resident".to_string(), |k| format!(
                "k = {k} paged"
            )),
        r.psnr_covered_db,
        r.ssim,
        r.frame_ms_median,
        human_bytes(r.file_bytes),
        r.build_s
    )
}

/// What the report needs beyond the rows: the inputs' names.
#[derive(Clone, Debug)]
pub struct ReportContext {
    pub scene: String,
    pub path: String,
    /// Plot files (without extension) written next to the report, with captions.
    pub plots: Vec<(String, String)>,
}

/// The markdown report: setup, recommendations, the Pareto front, the builds and the variants.
pub fn markdown(data: &SweepData, rows: &[VariantRow], cx: &ReportContext) -> String {
    let mut md = String::new();
    let p = &data.plan;
    let _ = writeln!(md, "# Accuracy vs cost sweep\n");
    let _ = writeln!(
        md,
        "Scene `{}`, path `{}`, {} frames of {}×{}, {} builds, {} variants. Adapter: {}; sampler \
         anisotropy {}×.\n",
        cx.scene,
        cx.path,
        p.frames,
        p.width,
        p.height,
        data.builds.len(),
        rows.len(),
        data.adapter,
        data.anisotropy
    );
    match data.reference {
        Reference::Original => {
            let _ = writeln!(
                md,
                "Reference: every frame drawn with the original textures (stored at full class resolution, \
                 mip-mapped) by the naive renderer (`--mode original`) on the base build. Covered PSNR is over \
                 the pixels the reference or the base build's tree draws on (alpha-tested). Means are over frames; frame time is the median.\n"
            );
        }
        Reference::Supersampled(k) => {
            let _ = writeln!(
                md,
                "Reference: ground truth, every frame drawn with the original textures at {k} × {k} the \
                 pixels on the base build and box-filtered in linear light to {}×{} (`--reference \
                 supersampled:{k}`). Both the tree and the original textures (drawn naively at the frame's \
                 resolution, each build's own) are measured against it: where the original columns fall \
                 short too, the loss is not the tree's. Covered PSNR is over the pixels the base build's \
                 original textures or its tree draw on (alpha-tested). Means are over frames; frame time is the median.\n",
                p.width, p.height
            );
        }
    }
    if data.anisotropy > 1 && data.software {
        let _ = writeln!(
            md,
            "**Note:** a software rasteriser filters the tree's original-texture draws (explicit \
             gradients) and the reference (implicit) differently under anisotropic filtering (lavapipe, \
             data/city drawn on originals only: 28–44 dB apart at 16×, 75 dB at 1×). Views that use original textures then \
             measure the driver, not the tree; `--anisotropy 1` isolates the atlas tree's own error.\n"
        );
    }
    let nothing = data.measures_nothing();
    if nothing {
        let _ = writeln!(md, "**Warning:** {MEASURED_NOTHING}.\n");
    }
    if let Some(note) = empty_frames_note(data) {
        let _ = writeln!(md, "**Note:** {note}.\n");
    }
    let _ = writeln!(md, "## Recommended defaults\n");
    match recommendation(data, rows) {
        Some(rec) => {
            // One line per distinct variant, naming every role it fills.
            let tol = rec.tolerance_db;
            let roles = [
                (rec.best, "Most accurate".to_string()),
                (
                    rec.fastest_frames,
                    format!(
                        "**fastest frames within {tol} dB of it** (the recommended runtime default; \
                         times within {:.0} % of the least count as equal, and variants of one build \
                         that draw identical frames share their mean time)",
                        TIME_TIE_SHARE * 100.0
                    ),
                ),
                (rec.smallest_file, format!("smallest file within {tol} dB")),
                (rec.fastest_build, format!("fastest build within {tol} dB")),
            ];
            let mut seen: Vec<usize> = Vec::new();
            for &(i, _) in &roles {
                if seen.contains(&i) {
                    continue;
                }
                seen.push(i);
                let names: Vec<&str> = roles
                    .iter()
                    .filter(|(j, _)| *j == i)
                    .map(|(_, n)| n.as_str())
                    .collect();
                // The first letter upper-cased, past any markdown emphasis (`**fastest …`).
                let mut label = names.join(", ");
                if let Some((at, c)) = label.char_indices().find(|(_, c)| c.is_alphabetic()) {
                    let rest = &label[at + c.len_utf8()..];
                    label = format!("{}{}{rest}", &label[..at], c.to_uppercase());
                }
                let _ = writeln!(md, "- {label}: {}", describe(&rows[i]));
            }
            let _ = writeln!(md);
        }
        None if nothing => {
            let _ = writeln!(md, "None: nothing was measured.\n");
        }
        None => {
            let _ = writeln!(md, "No variant has a finite PSNR.\n");
        }
    }
    let _ = writeln!(md, "## Pareto front (median frame ms ↓, covered PSNR ↑)\n");
    for i in frame_time_front(rows) {
        let _ = writeln!(md, "- {}", describe(&rows[i]));
    }
    let _ = writeln!(md);
    for (file, caption) in &cx.plots {
        let _ = writeln!(
            md,
            "![{caption}]({file}.png)  \n*{caption}* ([SVG]({file}.svg))\n"
        );
    }
    match (data.plan.builds.first()).and_then(|b| base_row(rows, &b.knobs, &data.plan.base_runtime))
    {
        Some(base) => effects_table(&mut md, rows, base),
        None if !rows.is_empty() => {
            let _ = writeln!(
                md,
                "## What each knob costs\n\nNot measured: the grid's base variant was not rendered \
                 (see Builds not rendered), so no change can be measured against it.\n"
            );
        }
        None => {}
    }
    if !data.skipped.is_empty() {
        let _ = writeln!(
            md,
            "## Builds not rendered\n\nBuilt and measured (see Builds), but their variants could not be \
             drawn with every block resident on this device:\n"
        );
        for (id, why) in &data.skipped {
            let _ = writeln!(md, "- `{id}`: {why}");
        }
        let _ = writeln!(md);
    }
    builds_table(&mut md, &data.builds);
    variants_table(&mut md, rows, data.reference);
    md
}

/// What each knob costs and buys, one row per single-knob change from the base.
fn effects_table(md: &mut String, rows: &[VariantRow], base: usize) {
    let effects = knob_effects(rows, base);
    if effects.is_empty() {
        return;
    }
    let _ = writeln!(
        md,
        "## What each knob costs (one knob changed from the base `{}`)\n",
        rows[base].id
    );
    let _ = writeln!(
        md,
        "Base: covered PSNR {} dB, SSIM {}, median frame {} ms, file {}, build {} s. Ratios are variant / base.\n",
        f(rows[base].psnr_covered_db, 2),
        f(rows[base].ssim, 4),
        f(rows[base].frame_ms_median, 2),
        human_bytes(rows[base].file_bytes),
        f(rows[base].build_s, 1)
    );
    let _ = writeln!(
        md,
        "| knob | value | Δ covered PSNR dB | Δ SSIM | frame time × | file × | build time × |"
    );
    let _ = writeln!(md, "|---|---|---:|---:|---:|---:|---:|");
    for e in &effects {
        let _ = writeln!(
            md,
            "| {} | {} | {} | {} | {} | {} | {} |",
            e.knob,
            e.value,
            signed(e.psnr_delta_db, 2),
            signed(e.ssim_delta, 4),
            f(e.frame_ratio, 2),
            f(e.file_ratio, 2),
            f(e.build_ratio, 2)
        );
    }
    let _ = writeln!(md);
}

fn builds_table(md: &mut String, builds: &[BuildRow]) {
    let _ = writeln!(md, "## Builds\n");
    let _ = writeln!(
        md,
        "| build | file | nodes | leaves | depth | blocks | build s | stages (s) | peak RSS |"
    );
    let _ = writeln!(md, "|---|---:|---:|---:|---:|---:|---:|---|---:|");
    for b in builds {
        let stages: Vec<String> = b
            .stage_s
            .iter()
            .map(|(n, s)| format!("{n} {s:.2}"))
            .collect();
        let _ = writeln!(
            md,
            "| `{}` | {} | {} | {} | {} | {} | {:.2} | {} | {} |",
            b.knobs.id(),
            human_bytes(b.file_bytes),
            b.nodes,
            b.leaves,
            b.depth,
            b.blocks,
            b.build_s,
            stages.join(", "),
            b.peak_rss_bytes.map_or("?".into(), human_bytes),
        );
    }
    let _ = writeln!(md);
}

fn variants_table(md: &mut String, rows: &[VariantRow], reference: Reference) {
    let _ = writeln!(
        md,
        "## Variants (over all frames: PSNR of the mean squared error, paged bytes summed, other columns \
         means)\n"
    );
    // Against a supersampled reference, the original textures' own scores beside the tree's.
    let originals = matches!(reference, Reference::Supersampled(_));
    let _ = writeln!(
        md,
        "| variant | PSNR dB | covered PSNR dB | SSIM |{} magnified | below target | coarser | select µs | encode µs | GPU ms | frame ms (median) | paged |",
        if originals {
            " original PSNR dB | original covered PSNR dB | original SSIM |"
        } else {
            ""
        }
    );
    let _ = writeln!(
        md,
        "|---|---:|---:|---:|{}---:|---:|---:|---:|---:|---:|---:|---:|",
        if originals { "---:|---:|---:|" } else { "" }
    );
    for r in rows {
        let original = if originals {
            format!(
                " {} | {} | {} |",
                f(r.original_psnr_db, 2),
                f(r.original_psnr_covered_db, 2),
                f(r.original_ssim, 4)
            )
        } else {
            String::new()
        };
        let _ = writeln!(
            md,
            "| `{}` | {} | {} | {} |{original} {} | {} | {} | {} | {} | {} | {} | {} |",
            r.id,
            f(r.psnr_db, 2),
            f(r.psnr_covered_db, 2),
            f(r.ssim, 4),
            f(r.magnified_share, 3),
            f(r.below_target_share, 3),
            f(r.coarser_share, 3),
            f(r.select_us, 1),
            f(r.encode_us, 1),
            f(r.gpu_ms, 2),
            f(r.frame_ms_median, 2),
            human_bytes(r.bytes_loaded)
        );
    }
    let _ = writeln!(md);
}
