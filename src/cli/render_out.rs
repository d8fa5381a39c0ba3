//! A render's output folder before the run: what an earlier run into it left (its modes' folders and
//! files, cleared where this run draws again) and the earlier summary, marked incomplete as this run
//! starts and with why where it fails, as not this run's.

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

/// Removes an earlier run's frames, contact sheet and stats from `dir`, where this run draws `mode`
/// (`dir` is the output folder itself when `alone`, else `mode`'s folder in it), only where the earlier
/// run (which drew `earlier`, from its summary) wrote into that folder: a single-mode run into the output
/// folder, a multi-mode run into its modes' folders (review of session 34). Returns how many went.
pub(super) fn remove_earlier_frames(
    dir: &std::path::Path,
    earlier: &[Mode],
    mode: Mode,
    alone: bool,
) -> anyhow::Result<usize> {
    let wrote_here = if alone {
        earlier.len() == 1
    } else {
        earlier.len() > 1 && earlier.contains(&mode)
    };
    if !wrote_here {
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

/// A run that failed marks the `summary.json` in `out`, if any, `"complete": false` with its error
/// (`"failed"`): before its own summary was begun ([`mode_runs`]), the earlier run's (a finished earlier
/// run's summary beside a failed run read as this run's result: fault hunt, session 29); after, its own
/// placeholder. Frames stay. Returns `error`.
pub(super) fn mark_earlier_summary_stale(
    out: &std::path::Path,
    error: anyhow::Error,
) -> anyhow::Error {
    mark_earlier_summary(out, Some(&error));
    error
}

/// Marks an earlier run's `summary.json` in `out` incomplete as this run starts, so a run interrupted
/// before it writes its own (a Ctrl-C while the tables of a stalled server load) leaves no summary that
/// says `"complete": true` beside it (fault hunt, session 34); with `error`, says why this run failed.
pub(super) fn mark_earlier_summary(out: &std::path::Path, error: Option<&anyhow::Error>) {
    let path = out.join("summary.json");
    let earlier = atlastree::util::read_regular(&path, Some(1 << 20))
        .ok()
        .and_then(|b| serde_json::from_slice::<serde_json::Value>(&b).ok());
    if let Some(serde_json::Value::Object(mut summary)) = earlier {
        summary.insert("complete".into(), false.into());
        // An older run's failure is not this run's.
        match error {
            Some(error) => summary.insert("failed".into(), format!("{error:#}").into()),
            None => summary.remove("failed"),
        };
        let text = serde_json::Value::Object(summary).to_string() + "\n";
        if let Err(e) = atlastree::util::write_atomic(&path, text.as_bytes()) {
            eprintln!(
                "warning: could not mark {} as not this run's: {e}",
                path.display()
            );
        }
    }
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

#[cfg(test)]
mod tests {
    /// A run that starts marks the earlier summary incomplete (an interrupt before its own left
    /// `"complete": true`; fault hunt, session 34); one that fails adds why; the rest is kept.
    #[test]
    fn an_earlier_summary_is_marked_when_a_run_starts_and_fails() {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let path = out.join("summary.json");
        std::fs::write(&path, r#"{"complete": true, "modes": {"tree": {}}}"#).unwrap();
        let read = || -> serde_json::Value {
            serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap()
        };
        super::mark_earlier_summary(out, None);
        let v = read();
        assert_eq!(v["complete"], false);
        assert!(v.get("failed").is_none() && v["modes"]["tree"].is_object());
        let e = super::mark_earlier_summary_stale(out, anyhow::anyhow!("no such host"));
        assert_eq!(e.to_string(), "no such host");
        assert_eq!(read()["failed"], "no such host");
    }

    /// An earlier run's outputs that this run does not overwrite go, and only those: mode folders an
    /// earlier multi-mode run's summary names, top-level outputs of a single-mode run when this run
    /// draws into folders; a user's file, or a folder the summary does not name, stays.
    #[test]
    fn an_earlier_runs_outputs_are_removed_and_nothing_else() {
        use super::{Mode, clear_earlier_run, earlier_modes, remove_earlier_frames};
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path();
        let touch = |p: &str| {
            let p = out.join(p);
            std::fs::create_dir_all(p.parent().unwrap()).unwrap();
            std::fs::write(p, b"x").unwrap();
        };
        for f in [
            "tree/frame_0000.png",
            "tree/stats.csv",
            "dummy/stats.csv",
            "dummy/notes.txt",
        ] {
            touch(f);
        }
        touch("original/stats.csv");
        touch("selection.json");
        // No summary: no render wrote here, nothing is removed (a user's `frame_holiday.png` went;
        // fault hunt, session 34).
        touch("frame_holiday.png");
        clear_earlier_run(out, &earlier_modes(out), &[Mode::Tree, Mode::Dummy], false).unwrap();
        let earlier = earlier_modes(out);
        assert_eq!(
            remove_earlier_frames(out, &earlier, Mode::Tree, true).unwrap(),
            0
        );
        assert!(out.join("selection.json").exists() && out.join("frame_holiday.png").exists());
        std::fs::remove_file(out.join("frame_holiday.png")).unwrap();
        let summary = r#"{"modes": {"tree": {}, "dummy": {}}}"#;
        std::fs::write(out.join("summary.json"), summary).unwrap();
        // In the JSON object's order (by name).
        assert_eq!(earlier_modes(out), [Mode::Dummy, Mode::Tree]);
        clear_earlier_run(out, &earlier_modes(out), &[Mode::Tree], false).unwrap();
        assert!(!out.join("tree").exists() && !out.join("selection.json").exists());
        assert!(!out.join("dummy/stats.csv").exists() && out.join("dummy/notes.txt").exists());
        // Not named by the summary: not render's to remove.
        assert!(out.join("original/stats.csv").exists());
        // A single-mode run's top-level outputs, then a multi-mode run.
        touch("frame_0003.png");
        touch("stats.csv");
        touch("mine.png");
        std::fs::write(out.join("summary.json"), r#"{"modes": {"tree": {}}}"#).unwrap();
        clear_earlier_run(out, &earlier_modes(out), &[Mode::Tree, Mode::Dummy], true).unwrap();
        assert!(!out.join("frame_0003.png").exists() && !out.join("stats.csv").exists());
        assert!(out.join("mine.png").exists());
        // Frames go only from the folder the earlier run drew into: a multi-mode run's are in its mode
        // folders, so a single-mode run into the output folder keeps the frames there (review of
        // session 34), and removes the mode's own folder's only where that run drew the mode.
        touch("frame_0001.png");
        touch("tree/frame_0001.png");
        std::fs::write(
            out.join("summary.json"),
            r#"{"modes": {"tree": {}, "dummy": {}}}"#,
        )
        .unwrap();
        let earlier = earlier_modes(out);
        assert_eq!(
            remove_earlier_frames(out, &earlier, Mode::Tree, true).unwrap(),
            0
        );
        assert!(out.join("frame_0001.png").exists());
        let tree = out.join("tree");
        assert_eq!(
            remove_earlier_frames(&tree, &earlier, Mode::Original, false).unwrap(),
            0
        );
        assert_eq!(
            remove_earlier_frames(&tree, &earlier, Mode::Tree, false).unwrap(),
            1
        );
    }
}
