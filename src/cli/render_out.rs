//! A render's output folder before the run: what an earlier run into it left (its modes' folders and
//! files, cleared where this run draws again) and, where this run fails before its own summary begins,
//! the earlier summary marked as not this run's.

use anyhow::Context;
use atlastree::render::Mode;

/// Render's own outputs in a folder: frame PNGs, the contact sheet and `stats.csv`.
pub(super) fn is_render_output(n: &str) -> bool {
    (n.starts_with("frame_") && n.ends_with(".png"))
        || matches!(n, "contact_sheet.png" | "stats.csv")
}

/// The modes an earlier run into `out` drew, from its `summary.json` (none where it has none).
pub(super) fn earlier_modes(out: &std::path::Path) -> Vec<Mode> {
    let Ok(bytes) = atlastree::util::read_regular(&out.join("summary.json"), Some(1 << 20)) else {
        return Vec::new();
    };
    let json: serde_json::Value = serde_json::from_slice(&bytes).unwrap_or_default();
    let Some(modes) = json.get("modes").and_then(|m| m.as_object()) else {
        return Vec::new();
    };
    modes.keys().filter_map(|k| k.parse().ok()).collect()
}

/// Removes an earlier run's frames, contact sheet and stats from mode folder `dir`, only where a render
/// wrote into its output (`earlier`, from its summary, names modes); returns how many went.
pub(super) fn remove_earlier_frames(
    dir: &std::path::Path,
    earlier: &[Mode],
) -> anyhow::Result<usize> {
    if earlier.is_empty() {
        return Ok(0);
    }
    atlastree::util::remove_stale_outputs(dir, is_render_output)
        .with_context(|| format!("removing an earlier run's frames from {}", dir.display()))
}

/// Removes what an earlier run (which drew `earlier`) left in `out` that a run drawing `now` will not
/// overwrite, so `out` holds one run's outputs: `selection.json` where this run writes none; the mode
/// folders of an earlier multi-mode run that this run does not draw into (the folder too once empty);
/// the top-level outputs of an earlier single-mode run where this run draws into mode folders. Only
/// render's own file names, and only where `summary.json` says a render wrote them; a note says what.
pub(super) fn clear_earlier_run(
    out: &std::path::Path,
    earlier: &[Mode],
    now: &[Mode],
    selection: bool,
) -> anyhow::Result<()> {
    if earlier.is_empty() {
        // No render's summary: nothing here is known to be render's.
        return Ok(());
    }
    let mut notes = Vec::new();
    let mut remove = |dir: &std::path::Path, pick: &dyn Fn(&str) -> bool| -> anyhow::Result<()> {
        let n = atlastree::util::remove_stale_outputs(dir, pick)
            .with_context(|| format!("removing an earlier run's outputs from {}", dir.display()))?;
        if n > 0 {
            notes.push(format!("{n} from {}", dir.display()));
        }
        Ok(())
    };
    if !selection {
        remove(out, &|n| n == "selection.json")?;
    }
    let folders_now = now.len() > 1;
    if earlier.len() > 1 {
        for &m in earlier.iter().filter(|m| !(folders_now && now.contains(m))) {
            let dir = out.join(m.name());
            remove(&dir, &is_render_output)?;
            let _ = std::fs::remove_dir(&dir);
        }
    } else if !earlier.is_empty() && folders_now {
        remove(out, &is_render_output)?;
    }
    if !notes.is_empty() {
        eprintln!(
            "note: removed an earlier run's outputs: {}",
            notes.join(", ")
        );
    }
    Ok(())
}

/// A run that failed before its own summary was begun ([`mode_runs`]) marks the earlier run's
/// `summary.json` in `out`, if any, `"complete": false` with this run's error (`"failed"`): a finished
/// earlier run's summary beside a failed run read as this run's result (fault hunt, session 29). Its
/// frames stay. Returns `error`.
pub(super) fn mark_earlier_summary_stale(
    out: &std::path::Path,
    error: anyhow::Error,
) -> anyhow::Error {
    let path = out.join("summary.json");
    let earlier = atlastree::util::read_regular(&path, Some(1 << 20))
        .ok()
        .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok());
    if let Some(serde_json::Value::Object(mut summary)) = earlier {
        summary.insert("complete".into(), false.into());
        summary.insert("failed".into(), format!("{error:#}").into());
        let text = serde_json::Value::Object(summary).to_string() + "\n";
        if let Err(e) = atlastree::util::write_atomic(&path, text.as_bytes()) {
            eprintln!(
                "warning: could not mark {} as not this run's: {e}",
                path.display()
            );
        }
    }
    error
}

/// The error of setting up an all-resident renderer (`what`: for which file). Original mode and a
/// reference need every block resident, so "page the blocks" is no way out for them (`needs_all`): it
/// was the advice, and paging then refused them (fault hunt, session 32).
pub(super) fn setup_error(
    e: atlastree::render::RenderError,
    needs_all: bool,
    what: String,
) -> anyhow::Error {
    if needs_all && matches!(e, atlastree::render::RenderError::TooManyLayers { .. }) {
        anyhow::Error::new(e).context(format!(
            "{what}: --mode original and --reference draw with every block resident, which this file's \
             blocks exceed on this device; render --mode tree (or dummy) with --capacity K"
        ))
    } else {
        anyhow::Error::new(e).context(what)
    }
}
