//! Planned sharded builds (issue 22): `build --shard plan` writes `OUT.plan` once; shards read it and
//! import nothing of the scene but its images; their merge is the one-process file byte for byte. A plan
//! of other flags, another scene or changed images is refused by the shard; a missing or corrupt plan by
//! the merge, without writing anything.

use atlastree::preprocess::shard::{ShardSpec, shard_path};
use atlastree::preprocess::{
    BuildOptions, MergeError, NoProgress, ShardPlanError, ShardedOptions, build, build_shard,
    build_shard_planned, merge, plan_shards, shard_plan_key,
};
use atlastree::scene::{ImportOptions, import};
use atlastree::store::TreeFile;
use atlastree::store::shard::ShardFile;
use atlastree::store::shard_plan::{PlanFile, plan_path};
use std::path::{Path, PathBuf};

fn city_path() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf")
}

/// data/city at 256² atlases, every node that does not fit split: a tree of depth ≥ 3.
fn deep_opts() -> BuildOptions {
    BuildOptions {
        atlas_size: 256,
        leaf_originals_atlases: 0.0,
        ..BuildOptions::default()
    }
}

/// Plans `scene` (a copy of data/city or data/city itself) into `OUT.plan`.
fn plan(scene: &Path, opts: &BuildOptions, out: &Path) -> [u64; 2] {
    let imported = import(scene, &ImportOptions::default()).unwrap();
    let key = shard_plan_key(opts, scene, "").unwrap();
    // The flags it shapes, as the CLI records them (the shards' own lines have none: they differ).
    let size = format!("--atlas-size={}", opts.atlas_size);
    let argv = ["atlastree", "build", size.as_str(), "--shard", "plan"]
        .map(String::from)
        .to_vec();
    let report = plan_shards(&imported, opts, out, key, argv, &NoProgress).unwrap();
    assert_eq!(report.path, plan_path(out));
    assert_eq!(report.triangles, imported.triangles.len() as u64);
    key
}

fn planned_shard(
    scene: &Path,
    opts: &BuildOptions,
    out: &Path,
    spec: ShardSpec,
) -> Result<atlastree::preprocess::ShardReport, atlastree::preprocess::BuildError> {
    let plan = PlanFile::open(&plan_path(out)).unwrap();
    let key = shard_plan_key(opts, scene, "").unwrap();
    let sharded = ShardedOptions {
        spec,
        // As the CLI records it: the flags that shape the tables, which the plan's key checked.
        argv: vec![
            "atlastree".into(),
            "build".into(),
            format!("--atlas-size={}", opts.atlas_size),
            "--shard".into(),
            spec.to_string(),
        ],
        import: None,
    };
    build_shard_planned(&plan, key, scene, opts, out, &sharded, &NoProgress)
}

#[test]
fn planned_shards_merge_into_the_one_process_file() {
    let scene = city_path();
    let imported = import(&scene, &ImportOptions::default()).unwrap();
    for opts in [BuildOptions::default(), deep_opts()] {
        let dir = tempfile::tempdir().unwrap();
        let one = dir.path().join("one.atlastree");
        build(&imported, &opts, &one, &NoProgress).unwrap();
        let reference = std::fs::read(&one).unwrap();
        for n in [1u32, 2, 3, 4, 16] {
            let out = dir.path().join(format!("n{n}.atlastree"));
            plan(&scene, &opts, &out);
            for index in 0..n {
                let spec = ShardSpec { index, count: n };
                let r = planned_shard(&scene, &opts, &out, spec).unwrap();
                assert_eq!((r.shard, r.count), (index, n));
                // No shard carries the table prefix: the merge reads it from the plan.
                let f = ShardFile::open(&shard_path(&out, spec)).unwrap();
                assert_eq!(f.header.prefix_len, 0, "N = {n}, shard {index}");
                assert!(r.stages.seconds("read plan").is_some());
            }
            let report = merge(&out, None, &NoProgress).unwrap();
            let p = report.plan.expect("the merge names the plan");
            assert_eq!(p.path, plan_path(&out));
            assert!(
                std::fs::read(&out).unwrap() == reference,
                "N = {n}: planned merge differs from the one-process build"
            );
        }
    }
}

/// The plan step's warnings (its report, `OUT.plan.json`) reach the merge's report: the shards that read
/// the plan do not repeat them, so the merge is where a planned build's warnings are seen together.
#[test]
fn the_merge_reports_the_plans_warnings() {
    let scene = city_path();
    let opts = BuildOptions::default();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("w.atlastree");
    let imported = import(&scene, &ImportOptions::default()).unwrap();
    let key = shard_plan_key(&opts, &scene, "").unwrap();
    let mut report = plan_shards(&imported, &opts, &out, key, Vec::new(), &NoProgress).unwrap();
    assert!(report.warnings.is_empty(), "{:?}", report.warnings);
    report
        .warnings
        .push("Opaque tree: a warning of the plan".into());
    report.save();
    assert_eq!(report.warnings.len(), 1, "{:?}", report.warnings);
    for index in 0..2 {
        let r = planned_shard(&scene, &opts, &out, ShardSpec { index, count: 2 }).unwrap();
        assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    }
    let merged = merge(&out, None, &NoProgress).unwrap();
    let p = merged.plan.expect("the merge names the plan");
    assert_eq!(p.warnings, ["Opaque tree: a warning of the plan"]);
    // The report of another plan (two plan runs for one OUT at once left one's file and the other's
    // report; fault hunt, session 39) is not this plan's: its time and warnings are left out.
    report.key = report.key.map(|[a, b]| [a ^ 1, b]);
    report.save();
    let merged = merge(&out, None, &NoProgress).unwrap();
    let p = merged.plan.expect("the merge names the plan");
    assert!(
        p.warnings.is_empty() && p.seconds.is_none(),
        "{:?}",
        p.warnings
    );
}

#[test]
fn the_plans_skeleton_is_the_tables_without_their_geometry() {
    // Read without its geometry sections, the plan gives the very skeleton the whole prefix gives.
    let scene = city_path();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    plan(&scene, &deep_opts(), &out);
    let file = PlanFile::open(&plan_path(&out)).unwrap();
    let bytes = std::fs::read(plan_path(&out)).unwrap();
    let prefix_at = bytes.len() - file.header.prefix_len as usize;
    let whole = TreeFile::from_table_prefix(&bytes[prefix_at..], "whole").unwrap();
    let skeleton = file.skeleton().unwrap();
    let json = |f: &TreeFile| serde_json::to_string(&f.to_skeleton()).unwrap();
    assert_eq!(json(&skeleton), json(&whole));
    assert!(!whole.tree(0).unwrap().vertices.is_empty());
    let t = skeleton.tree(0).unwrap();
    assert!(t.vertices.is_empty() && t.indices.is_empty() && t.source_triangles.is_empty());
    // A flipped byte inside the vertices (never read by the skeleton) is caught by the prefix hash.
    let vertices = whole
        .header()
        .section(atlastree::store::format::Section::Vertices);
    let mut bytes = bytes;
    bytes[prefix_at + (vertices.offset + vertices.length / 2) as usize] ^= 1;
    std::fs::write(plan_path(&out), &bytes).unwrap();
    let Err(e) = PlanFile::open(&plan_path(&out)).unwrap().skeleton() else {
        panic!("a flipped vertex byte passed the plan's prefix hash");
    };
    assert!(e.to_string().contains("table prefix checksum"), "{e}");
}

#[test]
fn planned_and_self_planning_shards_write_the_same_blocks() {
    // A shard that plans for itself and one that reads the plan differ only in the prefix shard 0 carries.
    let scene = city_path();
    let imported = import(&scene, &ImportOptions::default()).unwrap();
    let opts = deep_opts();
    let dir = tempfile::tempdir().unwrap();
    let (a, b) = (
        dir.path().join("a.atlastree"),
        dir.path().join("b.atlastree"),
    );
    plan(&scene, &opts, &b);
    for index in 0..3 {
        let spec = ShardSpec { index, count: 3 };
        let sharded = ShardedOptions {
            spec,
            argv: vec!["x".into()],
            import: None,
        };
        build_shard(&imported, &opts, &a, &sharded, &NoProgress).unwrap();
        planned_shard(&scene, &opts, &b, spec).unwrap();
        let (fa, fb) = (
            ShardFile::open(&shard_path(&a, spec)).unwrap(),
            ShardFile::open(&shard_path(&b, spec)).unwrap(),
        );
        assert_eq!(fa.header.fingerprint, fb.header.fingerprint);
        assert_eq!(fa.header.prefix_hash, fb.header.prefix_hash);
        // Payload offsets differ by shard 0's prefix; blocks and handoffs are the same bytes.
        let blocks = |f: &ShardFile| -> Vec<(u32, u64, u64, u64)> {
            (f.blocks.iter())
                .map(|e| (e.block, e.length, e.checksum, e.sse))
                .collect()
        };
        let handoffs = |f: &ShardFile| -> Vec<(u32, u32, u64)> {
            (f.handoffs.iter())
                .map(|h| (h.tree, h.node, h.checksum))
                .collect()
        };
        assert!(blocks(&fa) == blocks(&fb), "shard {index}: blocks differ");
        assert!(
            handoffs(&fa) == handoffs(&fb),
            "shard {index}: handoffs differ"
        );
        assert_eq!(fa.header.prefix_len > 0, index == 0);
    }
}

#[test]
fn shard_refuses_a_plan_of_other_flags_another_scene_or_changed_images() {
    let dir = tempfile::tempdir().unwrap();
    let scene = crate::built::city_copy(dir.path());
    let out = dir.path().join("city.atlastree");
    let opts = deep_opts();
    plan(&scene, &opts, &out);
    let spec = ShardSpec { index: 1, count: 2 };
    let other_input = |e: atlastree::preprocess::BuildError| {
        let msg = e.to_string();
        assert!(msg.contains("city.atlastree.plan"), "{msg}");
        assert!(msg.contains("--shard plan"), "{msg}");
        matches!(&e, atlastree::preprocess::BuildError::Plan(p) if matches!(**p, ShardPlanError::OtherInput { .. }))
    };
    // Other flags.
    let border = BuildOptions {
        border: 8,
        ..deep_opts()
    };
    assert!(other_input(
        planned_shard(&scene, &border, &out, spec).unwrap_err()
    ));
    // Flags that do not shape the plan are not refused: the pixel options travel in the shard headers.
    let kaiser = BuildOptions {
        mip_filter: atlastree::preprocess::image_ops::MipFilter::Kaiser,
        max_memory_bytes: Some(8 << 30),
        ..deep_opts()
    };
    assert_eq!(
        shard_plan_key(&kaiser, &scene, "").unwrap(),
        shard_plan_key(&opts, &scene, "").unwrap()
    );
    // Another scene: one byte of the buffer changed.
    let bin = scene.with_file_name("scene.bin");
    let mut bytes = std::fs::read(&bin).unwrap();
    bytes[100] ^= 1;
    std::fs::write(&bin, &bytes).unwrap();
    assert!(other_input(
        planned_shard(&scene, &opts, &out, spec).unwrap_err()
    ));
    bytes[100] ^= 1;
    std::fs::write(&bin, &bytes).unwrap();
    planned_shard(&scene, &opts, &out, spec).unwrap();
    // `--max-file-gib` is a limit, not in the key: a shard checks it against the plan's file (it wrote
    // its part of a file over the limit: fault hunt, session 35).
    let file_len = PlanFile::open(&plan_path(&out))
        .unwrap()
        .skeleton()
        .unwrap()
        .header()
        .file_len;
    let small = BuildOptions {
        max_file_bytes: file_len - 1,
        ..deep_opts()
    };
    let e = planned_shard(&scene, &small, &out, spec).unwrap_err();
    assert!(
        matches!(&e, atlastree::preprocess::BuildError::TooLarge { predicted, .. } if *predicted == file_len),
        "{e}"
    );
    // Its advice is the limit alone: the flags that shape the file are the plan's.
    let msg = e.to_string();
    assert!(
        msg.contains("the plan fixes the file's size") && !msg.contains("--d-min"),
        "{msg}"
    );
    let exact = BuildOptions {
        max_file_bytes: file_len,
        ..deep_opts()
    };
    planned_shard(&scene, &exact, &out, spec).unwrap();
    // An image that grew (same name, another byte length).
    let texture = std::fs::read_dir(dir.path().join("city/textures"))
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .min()
        .unwrap();
    let mut png = std::fs::read(&texture).unwrap();
    png.extend_from_slice(&[0; 7]);
    std::fs::write(&texture, &png).unwrap();
    let e = planned_shard(&scene, &opts, &out, spec).unwrap_err();
    assert!(
        matches!(&e, atlastree::preprocess::BuildError::Plan(p) if matches!(**p, ShardPlanError::ImagesChanged { .. })),
        "{e}"
    );
}

#[test]
fn merge_refuses_a_missing_corrupt_or_replaced_plan_and_writes_nothing() {
    let scene = city_path();
    let opts = deep_opts();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    plan(&scene, &opts, &out);
    for index in 0..2 {
        planned_shard(&scene, &opts, &out, ShardSpec { index, count: 2 }).unwrap();
    }
    let plan_file = plan_path(&out);
    let good = std::fs::read(&plan_file).unwrap();
    let refused = |why: &str| {
        let e = merge(&out, None, &NoProgress).unwrap_err();
        assert!(matches!(e, MergeError::Plan { .. }), "{why}: {e}");
        let msg = e.to_string();
        assert!(
            msg.contains("city.atlastree.plan") && msg.contains("--shard plan"),
            "{msg}"
        );
        assert!(!out.exists(), "{why}: the merge wrote {}", out.display());
        msg
    };
    std::fs::remove_file(&plan_file).unwrap();
    assert!(refused("missing").contains("does not exist"));
    let mut flipped = good.clone();
    let at = flipped.len() - 100;
    flipped[at] ^= 0x10;
    std::fs::write(&plan_file, &flipped).unwrap();
    assert!(refused("corrupt").contains("checksum"));
    std::fs::write(&plan_file, &good[..good.len() - 1]).unwrap();
    refused("truncated");
    // Another build's plan (other flags): intact, but not the tables the shards were cut from.
    plan(&scene, &BuildOptions::default(), &out);
    let msg = refused("replaced");
    assert!(
        msg.contains("not the ones the shards were built from"),
        "{msg}"
    );
    // The command to plan again is the shards' own, not the replacing plan's (which would write it again).
    assert!(
        msg.contains("(atlastree build --atlas-size=256 --shard plan)")
            && !msg.contains("--atlas-size=1024"),
        "{msg}"
    );
    std::fs::write(&plan_file, &good).unwrap();
    merge(&out, None, &NoProgress).unwrap();
    // As the refusal says: a plan made again with the shards' flags is theirs, so the same shards merge
    // (its hint said to rebuild them, a cluster's whole pixel pass; fault hunt, session 35).
    std::fs::remove_file(&plan_file).unwrap();
    let merged = std::fs::read(&out).unwrap();
    std::fs::remove_file(&out).unwrap();
    assert!(refused("missing again").contains("merge again"));
    plan(&scene, &opts, &out);
    merge(&out, None, &NoProgress).unwrap();
    assert!(std::fs::read(&out).unwrap() == merged);
}

/// A plan made again with other flags and one shard rebuilt from it: the merge names a shard that was
/// not built from the plan, with the plan's flags in its rebuild hint (it named the rebuilt shard, and
/// its hint's old flags were refused by the new plan: a circle; fault hunt, session 31). Rebuilt from
/// the plan, the shards merge into the one-process file of the new flags.
#[test]
fn a_merge_after_a_new_plan_names_the_shards_not_built_from_it() {
    let scene = city_path();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    plan(&scene, &deep_opts(), &out);
    for index in 0..3 {
        planned_shard(&scene, &deep_opts(), &out, ShardSpec { index, count: 3 }).unwrap();
    }
    let new = BuildOptions {
        border: 8,
        ..deep_opts()
    };
    plan(&scene, &new, &out);
    planned_shard(&scene, &new, &out, ShardSpec { index: 1, count: 3 }).unwrap();
    let e = merge(&out, None, &NoProgress).unwrap_err();
    let msg = e.to_string();
    assert!(
        matches!(e, MergeError::Foreign { shard: 0, .. })
            && msg.contains(
                "it was not built from the plan beside OUT, which 1 of 3 shards were (shard 1)"
            )
            && msg.contains("plan"),
        "{msg}"
    );
    assert!(!out.exists());
    for index in [0, 2] {
        planned_shard(&scene, &new, &out, ShardSpec { index, count: 3 }).unwrap();
    }
    merge(&out, None, &NoProgress).unwrap();
    let whole = dir.path().join("whole.atlastree");
    let imported = import(&scene, &ImportOptions::default()).unwrap();
    build(&imported, &new, &whole, &NoProgress).unwrap();
    assert!(std::fs::read(&out).unwrap() == std::fs::read(&whole).unwrap());
}

/// A plan whose report cannot be written (its name is a folder here) keeps its plan and says so in its
/// warnings, instead of failing after the plan was committed (fault hunt, session 31).
#[test]
fn a_plan_whose_report_cannot_be_written_warns() {
    let scene = city_path();
    let opts = deep_opts();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    std::fs::create_dir(dir.path().join("city.atlastree.plan.json")).unwrap();
    let imported = import(&scene, &ImportOptions::default()).unwrap();
    let key = shard_plan_key(&opts, &scene, "").unwrap();
    let mut report = plan_shards(&imported, &opts, &out, key, Vec::new(), &NoProgress).unwrap();
    report.save();
    assert!(
        report
            .warnings
            .iter()
            .any(|w| w.contains("the plan file is complete, but its report could not be written")),
        "{:?}",
        report.warnings
    );
    assert!(plan_path(&out).exists());
}

/// The scene import's warnings (here a missing texture) are in the plan's report and a self-planning
/// shard's, as `import_warnings`, and the merge lists the plan's: `--json` of a sharded build dropped
/// them, and the merge promised "the shards' warnings below" and listed none (fault hunt, session 31).
#[test]
fn import_warnings_reach_the_plan_the_shards_and_the_merge() {
    let dir = tempfile::tempdir().unwrap();
    let src = city_path();
    let src = src.parent().unwrap();
    let copy = dir.path().join("city");
    std::fs::create_dir_all(copy.join("textures")).unwrap();
    for name in ["scene.gltf", "scene.bin"] {
        std::fs::copy(src.join(name), copy.join(name)).unwrap();
    }
    let mut names: Vec<_> = (std::fs::read_dir(src.join("textures")).unwrap())
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    // Every texture but the first: that one is missing.
    for n in &names[1..] {
        std::fs::copy(src.join("textures").join(n), copy.join("textures").join(n)).unwrap();
    }
    let scene = copy.join("scene.gltf");
    let missing = names[0].to_string_lossy().into_owned();
    let names_it = |w: &Vec<String>| w.iter().any(|x| x.contains(&missing));
    let opts = deep_opts();
    let out = dir.path().join("x.atlastree");
    let imported = import(&scene, &ImportOptions::default()).unwrap();
    let key = shard_plan_key(&opts, &scene, "").unwrap();
    let mut report = plan_shards(&imported, &opts, &out, key, Vec::new(), &NoProgress).unwrap();
    assert!(
        names_it(&report.import_warnings),
        "{:?}",
        report.import_warnings
    );
    assert!(!names_it(&report.warnings), "{:?}", report.warnings);
    report.save();
    for index in 0..2 {
        let r = planned_shard(&scene, &opts, &out, ShardSpec { index, count: 2 }).unwrap();
        // Said by the plan, not again by every shard.
        assert!(r.import_warnings.is_empty(), "{:?}", r.import_warnings);
    }
    let merged = merge(&out, None, &NoProgress).unwrap();
    let plan = merged.plan.unwrap();
    assert!(names_it(&plan.warnings), "{:?}", plan.warnings);
    // A shard that planned itself carries them too.
    let other = dir.path().join("y.atlastree");
    let spec = ShardSpec { index: 0, count: 1 };
    let sharded = ShardedOptions {
        spec,
        argv: vec!["atlastree".into()],
        import: None,
    };
    let r = build_shard(&imported, &opts, &other, &sharded, &NoProgress).unwrap();
    assert!(names_it(&r.import_warnings), "{:?}", r.import_warnings);
}

/// A planned merge's rebuild hint is the command of a shard built from the plan, which holds the flags
/// the plan leaves out (here `--filter kaiser`): the plan's own command dropped them, and the shard it
/// rebuilt was refused as another build's, again and again (fault hunt, session 37).
#[test]
fn a_planned_merge_hint_keeps_the_shards_own_flags() {
    let scene = city_path();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    let opts = deep_opts();
    plan(&scene, &opts, &out);
    let plan_file = PlanFile::open(&plan_path(&out)).unwrap();
    let key = shard_plan_key(&opts, &scene, "").unwrap();
    for index in [0, 2] {
        let spec = ShardSpec { index, count: 3 };
        let size = format!("--atlas-size={}", opts.atlas_size);
        let argv = ["atlastree", "build", &size, "--filter", "kaiser", "--shard"];
        let mut argv: Vec<String> = argv.map(String::from).to_vec();
        argv.push(spec.to_string());
        let sharded = ShardedOptions {
            spec,
            argv,
            import: None,
        };
        build_shard_planned(&plan_file, key, &scene, &opts, &out, &sharded, &NoProgress).unwrap();
    }
    let msg = merge(&out, None, &NoProgress).unwrap_err().to_string();
    assert!(
        msg.contains("shard 1 of 3 is missing") && msg.contains("--filter kaiser --shard 1/3"),
        "{msg}"
    );
}
