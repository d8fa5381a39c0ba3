//! `atlastree merge OUT`: the shard files of a sharded build into the paging file (issue 22).

use super::progress::Bars;
use anyhow::Context;
use atlastree::preprocess::merge;
use atlastree::util::human_bytes;
use clap::Args;
use std::path::PathBuf;
use std::process::ExitCode;

// Its --help text is the doc comment of `cli::Command::Merge` (clap shows the variant's, not this struct's).
#[derive(Args, Debug)]
pub(crate) struct MergeArgs {
    /// The paging file to write (the `-o` of the shards' build).
    pub out: PathBuf,
    /// The number of shards N, when shard files of several builds lie beside OUT.
    #[arg(long)]
    pub shards: Option<u32>,
    /// Print the report as JSON.
    #[arg(long)]
    pub json: bool,
    /// No progress bars.
    #[arg(short, long)]
    pub quiet: bool,
}

pub(super) fn run(a: MergeArgs) -> anyhow::Result<ExitCode> {
    super::reject_output_url(&a.out, "OUT")?;
    let bars = Bars::new(a.quiet || a.json);
    let r = merge(&a.out, a.shards, &bars)
        .with_context(|| format!("merging the shards of {}", a.out.display()))?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&r)?);
        return Ok(ExitCode::SUCCESS);
    }
    println!(
        "merged {} shards into {} ({}) in {:.2} s; {} atlases made above the cut; peak memory {}",
        r.count,
        r.out.display(),
        human_bytes(r.file_bytes),
        r.seconds,
        r.above_cut,
        r.peak_rss_bytes.map_or("?".into(), human_bytes)
    );
    println!(
        "  {:>5}  {:>10}  {:>7}  {:>8}  {:>9}  {:>11}",
        "shard", "bytes", "blocks", "subtrees", "time", "peak memory"
    );
    for s in &r.shards {
        println!(
            "  {:>5}  {:>10}  {:>7}  {:>8}  {:>9}  {:>11}",
            s.shard,
            human_bytes(s.file_bytes),
            s.blocks,
            s.units,
            s.seconds.map_or("?".into(), |t| format!("{t:.2} s")),
            s.peak_rss_bytes.map_or("?".into(), human_bytes)
        );
    }
    if let Some(p) = &r.plan {
        println!(
            "  {:>5}  {:>10}  {:>7}  {:>8}  {:>9}  {:>11}   ({})",
            "plan",
            "",
            "",
            "",
            p.seconds.map_or("?".into(), |t| format!("{t:.2} s")),
            p.peak_rss_bytes.map_or("?".into(), human_bytes),
            p.path.display()
        );
    }
    // What the shards warned about (an image drawn as the magenta fallback is in the merged file): each
    // warning once, with the shards that gave it.
    let mut warned: Vec<(&str, Vec<u32>)> = Vec::new();
    for s in &r.shards {
        for w in &s.warnings {
            match warned.iter_mut().find(|(x, _)| x == w) {
                Some((_, shards)) => shards.push(s.shard),
                None => warned.push((w, vec![s.shard])),
            }
        }
    }
    let fallbacks: u64 = r.shards.iter().filter_map(|s| s.image_fallbacks).sum();
    if fallbacks > 0 {
        // "Below" only where something is (a report missing or written by an older build has none).
        let plan_warned = r.plan.as_ref().is_some_and(|p| !p.warnings.is_empty());
        let below = if warned.is_empty() && !plan_warned {
            "the shards' reports name no image"
        } else {
            "the warnings below name them"
        };
        println!(
            "  images drawn as the magenta fallback: {fallbacks}, counted per shard (they are in the merged file; \
             {below})"
        );
    }
    for w in r.plan.iter().flat_map(|p| &p.warnings) {
        println!("  warning (plan): {w}");
    }
    for (w, shards) in &warned {
        let list: Vec<String> = shards.iter().map(u32::to_string).collect();
        println!("  warning (shard {}): {w}", list.join(", "));
    }
    let times: Vec<f64> = r.shards.iter().filter_map(|s| s.seconds).collect();
    if times.len() == r.shards.len() && !times.is_empty() {
        let max = times.iter().cloned().fold(0.0, f64::max);
        let mean = times.iter().sum::<f64>() / times.len() as f64;
        let plan = match r.plan.as_ref().map(|p| p.seconds) {
            Some(Some(s)) => format!("plan {s:.2} s + "),
            Some(None) => "plan (time unknown) + ".into(),
            None => String::new(),
        };
        println!(
            "  slowest shard {max:.2} s, mean {mean:.2} s (max/mean {:.2}); critical path on {} machines ≈ {plan}{:.2} s + merge {:.2} s",
            max / mean.max(1e-9),
            r.count,
            max,
            r.seconds
        );
    }
    Ok(ExitCode::SUCCESS)
}
