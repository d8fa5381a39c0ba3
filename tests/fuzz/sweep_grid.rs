//! Target `sweep_grid`: structure-aware mutants of the `small` and `full` sweep grids as JSON, read by
//! [`atlastree::sweep::Grid::from_json`] and checked by [`atlastree::sweep::Grid::validate`] (what
//! `atlastree sweep --grid G.json` runs before any build). A mutant is one to three JSON edits
//! ([`crate::json_mut`]) or, one case in eight, the text cut short. A grid that validates must plan
//! builds the preprocessor accepts ([`atlastree::preprocess::resolve_params`] on a small scene) and
//! frames the renderer can allocate, else the case is an AcceptedCorruption.

use crate::harness::{self, Verdict};
use crate::json_mut::{self, Paths};
use arbitrary::Unstructured;
use atlastree::preprocess::resolve_params;
use atlastree::scene::Scene;
use atlastree::sweep::Grid;
use serde_json::Value;
use std::sync::OnceLock;

/// Cases per CI run.
const DEFAULT_CASES: u64 = 20_000;

/// First line of an edit-script corpus file (its edits apply to the `small` preset).
const MAGIC: &str = "#sweep-grid-edits";

/// The largest frame side a grid may ask for (wgpu's default `max_texture_dimension_2d`).
const MAX_SIDE: u32 = 8192;

struct Base {
    grids: [(Value, Paths); 2],
    scene: Scene,
}

fn base() -> &'static Base {
    static B: OnceLock<Base> = OnceLock::new();
    B.get_or_init(|| {
        let grid = |name: &str| {
            let g = Grid::preset(name).expect("preset");
            let v = serde_json::to_value(&g).expect("a grid serialises");
            let p = json_mut::paths(&v);
            (v, p)
        };
        Base {
            grids: [grid("small"), grid("full")],
            scene: atlastree::scene::synthetic::small_city(1, 32),
        }
    })
}

fn mutant(bytes: &[u8]) -> Option<(String, Option<String>)> {
    let b = base();
    if let Some(s) = json_mut::parse_script(bytes, MAGIC) {
        let mut doc = b.grids[0].0.clone();
        s.json.iter().for_each(|e| e.apply(&mut doc));
        return Some((doc.to_string(), s.expect));
    }
    let mut u = Unstructured::new(bytes);
    let (doc, paths) = &b.grids[u.choose_index(2).ok()?];
    let mut doc = doc.clone();
    if u.ratio(1, 8).ok()? {
        let text = serde_json::to_string_pretty(&doc).ok()?;
        let cut = u.int_in_range(0..=text.len()).ok()?;
        return Some((text.get(..cut).unwrap_or(&text).to_string(), None));
    }
    for _ in 0..u.int_in_range(1..=3).ok()? {
        json_mut::random_edit(&mut u, &doc, paths)
            .ok()?
            .apply(&mut doc);
    }
    Some((doc.to_string(), None))
}

/// What a validated grid promises; `Some(why)` when broken.
fn broken_promise(grid: &Grid, scene: &Scene) -> Option<String> {
    let plan = grid.plan();
    if plan.builds.first().is_none_or(|b| !b.is_base) {
        return Some("the plan does not start with the base build".into());
    }
    if plan.width > MAX_SIDE || plan.height > MAX_SIDE {
        return Some(format!("frames of {}×{} px", plan.width, plan.height));
    }
    // The preprocessor's own check (`border * 4 >= atlas_size` in u32) wraps for borders from 2^30 in
    // release builds: compare in u64 here.
    if let Some(b) = plan
        .builds
        .iter()
        .find(|b| u64::from(b.knobs.border) * 4 >= u64::from(b.knobs.atlas_size))
    {
        return Some(format!(
            "build {} has a border of a quarter atlas or more",
            b.knobs.id()
        ));
    }
    plan.builds.iter().find_map(|b| {
        resolve_params(scene, &b.knobs.options())
            .err()
            .map(|e| format!("build {} is refused by the preprocessor: {e}", b.knobs.id()))
    })
}

fn run_one(bytes: &[u8]) -> Verdict {
    let Some((text, expect)) = mutant(bytes) else {
        return Verdict::Skipped;
    };
    let verdict = match Grid::from_json(&text, "fuzz.json")
        .and_then(|g| g.validate("fuzz.json").map(|()| g))
    {
        Err(e) => Verdict::Refused(e.to_string()),
        Ok(grid) => match broken_promise(&grid, &base().scene) {
            Some(why) => Verdict::AcceptedCorruption(why),
            None => Verdict::Accepted,
        },
    };
    json_mut::expect_refusal(verdict, expect.as_deref())
}

#[test]
fn sweep_grid() {
    let counts = harness::run("sweep_grid", DEFAULT_CASES, run_one);
    // Both outcomes occur: a base input that stopped working would make every case a refusal.
    assert!(counts.accepted > 0 && counts.refused > 0, "{counts:?}");
}
