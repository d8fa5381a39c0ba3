//! The frame planner on the CPU (no GPU): select → page → resolve as plain data.
//!
//! - a residency change the executor cannot apply is taken back: the block is not resident, the failure
//!   is counted (`apply_errors`, the pager's failures, `last_error`), the items that needed it are drawn
//!   with an ancestor atlas, and the block is requested again after the back-off;
//! - a still plan (warm-up, preview) steps no pager and moves no clock;
//! - the clock may not run backwards;
//! - the capacity may be lowered and raised again up to the capacity at creation, never above it;
//! - a planner of a paging file selects from copies of its node tables, not through the memory map.

use crate::fixtures::corners::{corners, options};
use atlastree::camera::{Camera, CameraPath};
use atlastree::ids::BlockId;
use atlastree::paging::{BlockTable, Event, PagerOptions, ResidencyError};
use atlastree::plan::{FramePlanner, NoResidency, PlanError, Residency};
use atlastree::preprocess::{NoProgress, build};
use atlastree::sim::InstantLoader;
use atlastree::store::TreeFile;
use glam::DVec3;

fn build_corners(dir: &std::path::Path) -> TreeFile {
    let out = dir.join("corners.atlastree");
    build(&corners(), &options(), &out, &NoProgress).unwrap();
    TreeFile::open(&out).unwrap()
}

fn street(file: &TreeFile, n: usize) -> (Vec<Camera>, f64) {
    let params = file.to_params();
    let path = CameraPath::street(
        DVec3::new(0.0, 0.0, 0.0),
        DVec3::new(400.0, 1.0, 400.0),
        params.up,
    )
    .unwrap();
    let cams: Vec<Camera> = path.frames(30.0, n).collect();
    let scale = crate::views::scale_800(&params, cams[0].fov_x_deg);
    (cams, scale)
}

fn planner(file: &TreeFile, capacity: u32) -> FramePlanner<'_> {
    let table = BlockTable::from_file(file).unwrap();
    let trees = atlastree::plan::file_trees(file);
    let opts = PagerOptions {
        capacity,
        ..PagerOptions::default()
    };
    let mut p = FramePlanner::paged(
        trees,
        table,
        opts,
        Box::new(InstantLoader::default()),
        |_| Ok(None),
    )
    .unwrap();
    p.take_bootstrap();
    p
}

/// Fails every load of one block; counts the changes it saw.
struct FailOne {
    block: BlockId,
    loads_seen: u32,
}

impl Residency for FailOne {
    fn apply(&mut self, event: &Event) -> Result<u64, ResidencyError> {
        match event {
            Event::Loaded { block, .. } if *block == self.block => {
                self.loads_seen += 1;
                Err(ResidencyError::Upload {
                    message: format!("{block}: upload refused (test)"),
                })
            }
            _ => Ok(0),
        }
    }
}

#[test]
fn a_load_the_executor_cannot_apply_is_taken_back_counted_and_retried() {
    let dir = tempfile::tempdir().unwrap();
    let file = build_corners(dir.path());
    let (cams, scale) = street(&file, 120);
    // Which block does the flight load first (a clean run)?
    let mut clean = planner(&file, u32::MAX);
    let mut first_load = None;
    let mut record = atlastree::plan::RecordResidency(|e: &Event| {
        if let Event::Loaded { block, .. } = e {
            first_load.get_or_insert(*block);
        }
    });
    for (i, c) in cams.iter().enumerate() {
        clean.plan(c, i as f64 / 30.0, scale, &mut record).unwrap();
    }
    let victim = first_load.expect("the flight loads some block");
    let mut p = planner(&file, u32::MAX);
    let mut exec = FailOne {
        block: victim,
        loads_seen: 0,
    };
    let mut errors = 0u32;
    let mut coarser_frames = 0u32;
    let mut offered_at = Vec::new();
    for (i, c) in cams.iter().enumerate() {
        let seen = exec.loads_seen;
        let plan = p.plan(c, i as f64 / 30.0, scale, &mut exec).unwrap();
        if exec.loads_seen > seen {
            offered_at.push(i);
        }
        let s = plan.stats.paging.unwrap();
        errors += s.apply_errors;
        coarser_frames += u32::from(s.coarse.coarser_items > 0);
        let pager = p.pager().unwrap();
        assert!(
            !pager.is_resident(victim),
            "frame {i}: the block the executor refused is resident"
        );
        pager.check_invariants().unwrap();
    }
    assert!(
        exec.loads_seen >= 2,
        "the refused block is requested again after the back-off ({} loads)",
        exec.loads_seen
    );
    assert_eq!(errors, exec.loads_seen, "every refusal is counted");
    assert_eq!(
        p.pager().unwrap().totals().failures,
        u64::from(exec.loads_seen)
    );
    assert!(p.last_error().unwrap().contains("upload refused"));
    // A transient upload failure backs off ever longer (the failure count is not reset by the fetch that
    // succeeded before the upload failed): the waits between offers never shrink and do grow.
    assert!(offered_at.len() >= 3, "offers at frames {offered_at:?}");
    let gaps: Vec<usize> = offered_at.windows(2).map(|w| w[1] - w[0]).collect();
    assert!(
        gaps.windows(2).all(|g| g[1] >= g[0]),
        "offers at frames {offered_at:?}"
    );
    assert!(
        gaps[gaps.len() - 1] > gaps[0],
        "offers at frames {offered_at:?}"
    );
    assert!(
        coarser_frames > 0,
        "the items that needed the refused block are drawn coarser"
    );
}

#[test]
fn a_still_plan_steps_no_pager_and_moves_no_clock() {
    let dir = tempfile::tempdir().unwrap();
    let file = build_corners(dir.path());
    let (cams, scale) = street(&file, 60);
    let mut p = planner(&file, 8);
    let last = cams.last().unwrap();
    for c in &cams[..30] {
        let before = *p.pager().unwrap().totals();
        let plan = p.plan_still(c, scale, &mut NoResidency).unwrap();
        assert_eq!(plan.time, None);
        assert!(plan.resolved.is_some());
        assert_eq!(*p.pager().unwrap().totals(), before);
    }
    // A still plan at a late camera does not let a later timed plan start pre-warmed: the first timed
    // plan loads what a fresh planner's first plan loads.
    p.plan_still(last, scale, &mut NoResidency).unwrap();
    let a = p.plan(&cams[0], 0.0, scale, &mut NoResidency).unwrap();
    let a = a.stats.paging.unwrap().resident_hash;
    let mut fresh = planner(&file, 8);
    let b = fresh.plan(&cams[0], 0.0, scale, &mut NoResidency).unwrap();
    assert_eq!(a, b.stats.paging.unwrap().resident_hash);
}

#[test]
fn the_clock_may_not_run_backwards() {
    let dir = tempfile::tempdir().unwrap();
    let file = build_corners(dir.path());
    let (cams, scale) = street(&file, 2);
    let mut p = planner(&file, 8);
    p.plan(&cams[0], 1.0, scale, &mut NoResidency).unwrap();
    p.plan(&cams[1], 1.0, scale, &mut NoResidency).unwrap();
    match p.plan(&cams[1], 0.5, scale, &mut NoResidency) {
        Err(PlanError::TimeBackwards { time, last }) => assert_eq!((time, last), (0.5, 1.0)),
        Err(e) => panic!("wrong error: {e}"),
        Ok(_) => panic!("a plan at 0.5 s after one at 1 s was accepted"),
    }
}

#[test]
fn capacity_goes_down_and_back_up_to_the_capacity_at_creation() {
    let dir = tempfile::tempdir().unwrap();
    let file = build_corners(dir.path());
    let blocks = file.blocks().len() as u32;
    let mut p = planner(&file, u32::MAX);
    assert_eq!(p.max_capacity(), Some(blocks));
    p.set_capacity(2);
    assert_eq!(p.pager().unwrap().options().capacity, 2);
    p.set_capacity(blocks);
    assert_eq!(p.pager().unwrap().options().capacity, blocks);
    p.set_capacity(blocks + 10);
    assert_eq!(
        p.pager().unwrap().options().capacity,
        blocks,
        "never above what the executor was sized for"
    );
    // An all-resident planner has no capacity and plans without paging.
    let mut all = FramePlanner::from_file(&file);
    assert_eq!(all.max_capacity(), None);
    let (cams, scale) = street(&file, 1);
    let plan = all.plan(&cams[0], 0.0, scale, &mut NoResidency).unwrap();
    assert!(plan.resolved.is_none() && plan.stats.paging.is_none());
    assert!(plan.stats.nodes_drawn > 0);
}

/// A paging file rewritten in place while it is drawn (same path, not truncated: `dd conv=notrunc`, a
/// copy over it) must not change the nodes the planner selects: it read the node tables through the
/// memory map every frame, so the fault hunt's render drew 60 of 150 frames with no geometry, no load
/// failure and no warning. The planner now selects from copies taken at the start; here the whole file
/// is zeroed under the map and the next plan selects what the first did.
#[test]
fn a_file_rewritten_in_place_does_not_change_the_selection() {
    use std::io::Write;
    let dir = tempfile::tempdir().unwrap();
    let file = build_corners(dir.path());
    assert!(
        file.is_mapped(),
        "the test needs the memory map (ATLASTREE_NO_MMAP unset)"
    );
    let mut planner = FramePlanner::from_file(&file);
    let (cams, scale) = street(&file, 1);
    let before = planner
        .plan_still(&cams[0], scale, &mut NoResidency)
        .unwrap();
    let (drawn, cuts) = (before.stats.nodes_drawn, format!("{:?}", before.cuts));
    assert!(drawn > 0);
    let len = std::fs::metadata(file.path()).unwrap().len() as usize;
    let mut f = std::fs::OpenOptions::new()
        .write(true)
        .open(file.path())
        .unwrap();
    f.write_all(&vec![0u8; len]).unwrap();
    f.sync_all().unwrap();
    let after = planner
        .plan_still(&cams[0], scale, &mut NoResidency)
        .unwrap();
    assert_eq!(after.stats.nodes_drawn, drawn);
    assert_eq!(format!("{:?}", after.cuts), cuts);
}
