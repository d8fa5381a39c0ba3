//! Sharded builds (issue 22): `build --shard I/N` + `merge` give the one-process file byte for byte, shard
//! reruns give the same shard file, and the merge refuses missing, corrupt and foreign shards, naming the
//! shard and the command that rebuilds it, without writing anything.

use atlastree::preprocess::shard::{ShardSpec, choose_cut, shard_path};
use atlastree::preprocess::{
    BuildOptions, MergeError, NoProgress, ShardedOptions, build, build_shard, merge,
};
use atlastree::scene::{ImportOptions, Scene, import};
use atlastree::store::TreeFile;
use std::path::{Path, PathBuf};

fn city() -> &'static Scene {
    crate::built::city_scene()
}

/// The deeper fixture: data/city at 256² atlases, every node that does not fit split (depth 6, 330 + 24
/// nodes in two trees).
fn deep_opts() -> BuildOptions {
    BuildOptions {
        atlas_size: 256,
        leaf_originals_atlases: 0.0,
        ..BuildOptions::default()
    }
}

fn argv(spec: ShardSpec) -> Vec<String> {
    vec![
        "atlastree".into(),
        "build".into(),
        "city.gltf".into(),
        "--shard".into(),
        spec.to_string(),
    ]
}

/// Builds every shard of `count` into `out`'s directory.
fn build_shards(opts: &BuildOptions, out: &Path, count: u32) {
    for index in 0..count {
        let spec = ShardSpec { index, count };
        let sharded = ShardedOptions {
            spec,
            argv: argv(spec),
            import: None,
        };
        let r = build_shard(city(), opts, out, &sharded, &NoProgress).unwrap();
        assert_eq!((r.shard, r.count), (index, count));
        assert!(shard_path(out, spec).exists());
    }
}

fn one_process(opts: &BuildOptions, dir: &Path) -> Vec<u8> {
    let path = dir.join("one.atlastree");
    build(city(), opts, &path, &NoProgress).unwrap();
    std::fs::read(path).unwrap()
}

fn identical_for_every_count(opts: &BuildOptions, counts: &[u32]) {
    let dir = tempfile::tempdir().unwrap();
    let reference = one_process(opts, dir.path());
    for &n in counts {
        let out = dir.path().join(format!("n{n}.atlastree"));
        build_shards(opts, &out, n);
        let report = merge(&out, None, &NoProgress).unwrap();
        assert_eq!(report.count, n);
        assert_eq!(report.shards.len(), n as usize);
        let merged = std::fs::read(&out).unwrap();
        assert_eq!(merged.len(), reference.len(), "N = {n}: file length");
        assert!(
            merged == reference,
            "N = {n}: merged file differs from the one-process build"
        );
    }
}

#[test]
fn merged_file_is_the_one_process_file_on_data_city() {
    identical_for_every_count(&BuildOptions::default(), &[1, 2, 3, 4, 16]);
}

/// Coverage-preserving alpha mips rescale the level 1 handed to the parent, so the merge must make the
/// atlases above the cut with the same option (carried in the shard header's pixel options).
#[test]
fn merged_file_is_the_one_process_file_with_coverage_alpha_mips() {
    let opts = BuildOptions {
        alpha_mips: atlastree::preprocess::image_ops::AlphaMips::Coverage,
        ..deep_opts()
    };
    let dir = tempfile::tempdir().unwrap();
    let plain = one_process(&deep_opts(), dir.path());
    let kept = one_process(&opts, dir.path());
    assert_eq!(plain.len(), kept.len(), "same tables and block sizes");
    assert!(plain != kept, "data/city's MASK textures must change");
    identical_for_every_count(&opts, &[3, 16]);
}

#[test]
fn merged_file_is_the_one_process_file_on_a_deep_tree() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("deep.atlastree");
    build(city(), &deep_opts(), &path, &NoProgress).unwrap();
    let file = TreeFile::open(&path).unwrap();
    let forest = file.to_forest();
    let depth = forest.trees[0]
        .nodes
        .iter()
        .map(|n| n.level.0)
        .max()
        .unwrap();
    assert!(depth >= 3, "the deep fixture has depth {depth}");
    // The cut of 4 and 16 shards lies inside the tree: the merge makes atlases above it.
    for n in [4, 16] {
        let cut = choose_cut(&forest, n);
        assert!(
            cut.shards.iter().flatten().any(|u| u.node != 0),
            "N = {n}: cut at the roots"
        );
    }
    identical_for_every_count(&deep_opts(), &[1, 2, 3, 4, 16]);
}

#[test]
fn cut_is_deterministic_covers_every_leaf_once_and_balances_work() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("deep.atlastree");
    build(city(), &deep_opts(), &path, &NoProgress).unwrap();
    let forest = TreeFile::open(&path).unwrap().to_forest();
    for n in [1u32, 2, 3, 4, 16] {
        let cut = choose_cut(&forest, n);
        assert_eq!(cut, choose_cut(&forest, n));
        assert_eq!(cut.shards.len(), n as usize);
        // Every leaf lies below exactly one unit.
        for (t, tree) in forest.trees.iter().enumerate() {
            let mut under = vec![0u32; tree.nodes.len()];
            for u in cut.shards.iter().flatten().filter(|u| u.tree as usize == t) {
                let mut stack = vec![u.node as usize];
                while let Some(i) = stack.pop() {
                    under[i] += 1;
                    stack.extend(
                        tree.nodes[i]
                            .children
                            .iter()
                            .flatten()
                            .map(|c| c.0 as usize),
                    );
                }
            }
            for (i, n) in tree.nodes.iter().enumerate() {
                if n.leaf.is_some() {
                    assert_eq!(under[i], 1, "tree {t} leaf node {i}");
                }
            }
        }
        let mean = cut.work.iter().sum::<u64>() as f64 / f64::from(n);
        let max = *cut.work.iter().max().unwrap() as f64;
        if n <= 4 {
            assert!(
                max / mean <= 1.1,
                "N = {n}: max/mean work {:.3}",
                max / mean
            );
        }
    }
}

#[test]
fn shard_rerun_writes_the_same_bytes_and_merge_is_idempotent() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    let opts = deep_opts();
    build_shards(&opts, &out, 3);
    let spec = ShardSpec { index: 1, count: 3 };
    let first = std::fs::read(shard_path(&out, spec)).unwrap();
    let sharded = ShardedOptions {
        spec,
        argv: argv(spec),
        import: None,
    };
    build_shard(city(), &opts, &out, &sharded, &NoProgress).unwrap();
    assert!(std::fs::read(shard_path(&out, spec)).unwrap() == first);
    merge(&out, None, &NoProgress).unwrap();
    let once = std::fs::read(&out).unwrap();
    merge(&out, Some(3), &NoProgress).unwrap();
    assert!(std::fs::read(&out).unwrap() == once);
}

/// A shard whose report (`.json`) cannot be written is still a finished shard, said with a warning (it
/// was a failed step with its shard file published; fault hunt, session 29).
#[test]
fn a_shard_whose_report_cannot_be_written_is_finished_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    let spec = ShardSpec { index: 0, count: 2 };
    let report_path = {
        let mut p = shard_path(&out, spec).into_os_string();
        p.push(".json");
        std::path::PathBuf::from(p)
    };
    // A folder where the report goes: its write fails.
    std::fs::create_dir(&report_path).unwrap();
    let sharded = ShardedOptions {
        spec,
        argv: argv(spec),
        import: None,
    };
    let r = build_shard(city(), &deep_opts(), &out, &sharded, &NoProgress).unwrap();
    assert!(shard_path(&out, spec).is_file());
    let said = (r.warnings.iter())
        .filter(|w| w.contains("the shard file is complete, but its report could not be written"))
        .count();
    assert_eq!(said, 1, "{:#?}", r.warnings);
}

/// A directory with the 4 shards of the deep build and an existing output the failed merges must leave.
fn four_shards() -> (tempfile::TempDir, PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    build_shards(&deep_opts(), &out, 4);
    // A previous paging file (its magic: a file without it is never replaced).
    std::fs::write(&out, previous_output()).unwrap();
    (dir, out)
}

/// The bytes standing in for a previous paging file: its magic, then a marker.
fn previous_output() -> Vec<u8> {
    [&atlastree::store::format::MAGIC[..], b"previous output"].concat()
}

/// The merge fails, leaves the previous output and no temp file, and the message names `shard` and a
/// rebuild command with `--shard shard/4`.
fn refused(out: &Path, shard: u32) -> MergeError {
    let e = merge(out, None, &NoProgress).unwrap_err();
    let msg = e.to_string();
    assert!(msg.contains(&format!("shard {shard} of 4")), "{msg}");
    assert!(msg.contains(&format!("--shard {shard}/4")), "{msg}");
    assert_eq!(std::fs::read(out).unwrap(), previous_output());
    let stray: Vec<_> = std::fs::read_dir(out.parent().unwrap())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| !n.starts_with("city.atlastree"))
        .collect();
    assert!(stray.is_empty(), "left behind: {stray:?}");
    e
}

#[test]
fn merge_refuses_a_missing_shard() {
    let (_dir, out) = four_shards();
    // A count with no shard beside a complete set of 4: the message points at that set (it named only
    // shard 0 of 3 as missing; fault hunt, session 34).
    let e = merge(&out, Some(3), &NoProgress).unwrap_err().to_string();
    assert!(e.contains("shard 0 of 3 is missing"), "{e}");
    assert!(e.contains("all 4 shards of a 4-shard build"), "{e}");
    assert!(e.contains("--shards 4"), "{e}");
    std::fs::remove_file(shard_path(&out, ShardSpec { index: 2, count: 4 })).unwrap();
    // While a build writes it (its temp file locked), the merge says so instead of asking for a rebuild.
    let shard2 = shard_path(&out, ShardSpec { index: 2, count: 4 });
    let writing = atlastree::util::AtomicFile::create(&shard2, 0o666).unwrap();
    let e = merge(&out, None, &NoProgress).unwrap_err().to_string();
    let pid = std::process::id();
    assert!(
        e.contains(&format!("process {pid} is writing it now")),
        "{e}"
    );
    assert!(!e.contains("--shard 2/4"), "{e}");
    drop(writing);
    let e = refused(&out, 2);
    assert!(matches!(e, MergeError::Missing { shard: 2, .. }));
    // No complete set beside it: nothing more is said.
    assert!(!e.to_string().contains("beside it lie"), "{e}");
}

#[test]
fn merge_refuses_corrupt_and_truncated_shards() {
    let (_dir, out) = four_shards();
    let path = shard_path(&out, ShardSpec { index: 3, count: 4 });
    let good = std::fs::read(&path).unwrap();
    // A flipped byte in the header, in the tables, in a block payload and in the last (handoff) byte.
    for at in [40, 200, good.len() / 2, good.len() - 1] {
        let mut bad = good.clone();
        bad[at] ^= 0x10;
        std::fs::write(&path, &bad).unwrap();
        assert!(
            matches!(refused(&out, 3), MergeError::Corrupt { shard: 3, .. }),
            "flip at {at}"
        );
    }
    std::fs::write(&path, &good[..good.len() - 7]).unwrap();
    assert!(matches!(
        refused(&out, 3),
        MergeError::Corrupt { shard: 3, .. }
    ));
    std::fs::write(&path, b"").unwrap();
    assert!(matches!(
        refused(&out, 3),
        MergeError::Corrupt { shard: 3, .. }
    ));
}

#[test]
fn merge_refuses_a_shard_of_another_build() {
    let (_dir, out) = four_shards();
    // Shard 1 rebuilt with other flags (a sharper mip filter): same tables, other pixels.
    let spec = ShardSpec { index: 1, count: 4 };
    let other = BuildOptions {
        mip_filter: atlastree::preprocess::image_ops::MipFilter::Kaiser,
        ..deep_opts()
    };
    let sharded = ShardedOptions {
        spec,
        argv: argv(spec),
        import: None,
    };
    build_shard(city(), &other, &out, &sharded, &NoProgress).unwrap();
    assert!(matches!(
        refused(&out, 1),
        MergeError::Foreign { shard: 1, .. }
    ));
    // Shard 0 the odd one out (shard 1 rebuilt as the others, shard 0 with the other flags): shard 0 is
    // named, not the first shard that differs from it.
    let good = ShardedOptions {
        spec,
        argv: argv(spec),
        import: None,
    };
    build_shard(city(), &deep_opts(), &out, &good, &NoProgress).unwrap();
    let spec0 = ShardSpec { index: 0, count: 4 };
    let stale0 = ShardedOptions {
        spec: spec0,
        argv: argv(spec0),
        import: None,
    };
    build_shard(city(), &other, &out, &stale0, &NoProgress).unwrap();
    let e = refused(&out, 0);
    assert!(matches!(e, MergeError::Foreign { shard: 0, .. }), "{e}");
    assert!(e.to_string().contains("the other 3 of 4 shards'"), "{e}");
    build_shard(city(), &deep_opts(), &out, &stale0, &NoProgress).unwrap();
    // A shard of a 3-shard build renamed into slot 1.
    let (_dir3, out3) = {
        let dir = tempfile::tempdir().unwrap();
        let o = dir.path().join("city.atlastree");
        build_shards(&deep_opts(), &o, 3);
        (dir, o)
    };
    std::fs::copy(
        shard_path(&out3, ShardSpec { index: 1, count: 3 }),
        shard_path(&out, spec),
    )
    .unwrap();
    assert!(matches!(
        refused(&out, 1),
        MergeError::Foreign { shard: 1, .. }
    ));
}

#[test]
fn merge_without_shards_or_with_two_counts_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    assert!(matches!(
        merge(&out, None, &NoProgress),
        Err(MergeError::NoShards { .. })
    ));
    // Stray names no build writes (a count of 0 once panicked the merge, one of 2³²−1 aborted it
    // allocating a shard list, an index past its count) are no shards.
    for stray in [
        "0-of-0",
        "0-of-4294967295",
        "5-of-4",
        "0-of-4097",
        "x-of-2",
        "0-of-04",
        "+1-of-2",
    ] {
        std::fs::write(
            dir.path().join(format!("city.atlastree.shard-{stray}")),
            b"",
        )
        .unwrap();
    }
    assert!(matches!(
        merge(&out, None, &NoProgress),
        Err(MergeError::NoShards { .. })
    ));
    build_shards(&BuildOptions::default(), &out, 2);
    build_shards(&BuildOptions::default(), &out, 3);
    match merge(&out, None, &NoProgress) {
        Err(MergeError::AmbiguousCount { counts, .. }) => assert_eq!(counts, vec![2, 3]),
        other => panic!("expected AmbiguousCount, got {other:?}"),
    }
    merge(&out, Some(3), &NoProgress).unwrap();
    assert!(TreeFile::open(&out).is_ok());
    assert!(matches!(
        merge(&out, Some(0), &NoProgress),
        Err(MergeError::BadCount { count: 0 })
    ));
}

#[test]
fn memory_budget_sizes_the_cache_or_refuses_up_front_with_the_number_needed() {
    let dir = tempfile::tempdir().unwrap();
    let reference = one_process(&BuildOptions::default(), dir.path());
    let out = dir.path().join("budget.atlastree");
    // What this machine's rasteriser threads need for this scene: the refusal and the fit are set around it.
    let sides = (city().images.iter()).map(|i| (i.width, i.height));
    let largest = sides
        .clone()
        .map(|(w, h)| u64::from(w) * u64::from(h))
        .max()
        .unwrap();
    let threads = rayon::current_num_threads() as u64;
    let images = atlastree::preprocess::memory::ImageLoad::of(sides, threads);
    let needed = atlastree::preprocess::memory::plan_memory(
        u64::MAX,
        atlastree::preprocess::memory::PlanLoad::triangles(city().triangles.len() as u64),
        1024,
        threads,
        images,
        2 << 30,
    )
    .unwrap()
    .needed_bytes;
    let tight = BuildOptions {
        max_memory_bytes: Some(needed - (1 << 20)),
        ..BuildOptions::default()
    };
    match build(city(), &tight, &out, &NoProgress) {
        Err(atlastree::preprocess::BuildError::Memory(e)) => {
            assert_eq!(e.budget_mib, (needed - (1 << 20)) >> 20);
            assert_eq!(e.needed_mib, needed.div_ceil(1 << 20), "{e}");
            assert_eq!(e.triangles, city().triangles.len() as u64);
            // The largest image is named (the first of the largest, in scene order).
            let name = &(city().images.iter())
                .find(|i| u64::from(i.width) * u64::from(i.height) == largest)
                .unwrap()
                .name;
            assert_eq!(&e.largest_image, name);
            assert_eq!(*e.images, images);
            // The cause of the cache's need (every image once, the threads' largest images, or the
            // cache's minimum: `memory`'s unit tests tell which when), naming the largest image.
            let text = e.to_string();
            let causes = [
                format!(
                    "every image once ({} texels; the largest, {name}",
                    images.all_texels
                ),
                format!("the {threads} largest images"),
                format!("the largest image, {name}"),
                "the cache's minimum of 64 MiB".to_string(),
            ];
            assert!(causes.iter().any(|c| text.contains(c.as_str())), "{e}");
            assert!(text.contains("MiB for the originals the"), "{e}");
        }
        other => panic!("expected a memory error, got {other:?}"),
    }
    assert!(!out.exists(), "a refused build wrote {}", out.display());
    let budget = needed + (32 << 20);
    let fits = BuildOptions {
        max_memory_bytes: Some(budget),
        ..BuildOptions::default()
    };
    let report = build(city(), &fits, &out, &NoProgress).unwrap();
    let plan = report.memory.expect("a budget gives a memory plan");
    assert_eq!(plan.budget, budget);
    assert!(
        plan.image_cache_bytes < 2 << 30,
        "the cache was lowered to fit"
    );
    assert!(plan.plan_bytes + plan.raster_bytes + plan.image_cache_bytes * 5 / 4 <= budget);
    // The budget changes what is held at once, not what is written.
    assert!(std::fs::read(&out).unwrap() == reference);
    // Peak memory per stage: each stage of the build reported once, in order (Linux).
    if cfg!(target_os = "linux") {
        let stages: Vec<&str> = report
            .stages
            .stage_peak_rss
            .iter()
            .map(|s| s.0.as_str())
            .collect();
        assert_eq!(stages.first(), Some(&"sizing Opaque"));
        assert_eq!(
            &stages[stages.len() - 3..],
            &["rasterise", "write", "total"]
        );
    }
}

/// `atlastree merge OUT -q` as a child process.
fn merge_cmd(out: &Path) -> std::process::Command {
    let mut c = std::process::Command::new(env!("CARGO_BIN_EXE_atlastree"));
    c.arg("merge").arg(out).arg("-q");
    c
}

#[test]
fn killed_merge_leaves_nothing_or_the_whole_file_and_a_rerun_succeeds() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    build_shards(&deep_opts(), &out, 4);
    let start = std::time::Instant::now();
    assert!(merge_cmd(&out).status().unwrap().success());
    let took = start.elapsed();
    let reference = std::fs::read(&out).unwrap();
    let (mut absent, mut complete) = (0, 0);
    let points = 16u32;
    for k in 0..points {
        std::fs::remove_file(&out).unwrap();
        let delay = took.mul_f64(1.2 * f64::from(k) / f64::from(points));
        let mut child = merge_cmd(&out)
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap();
        std::thread::sleep(delay);
        let _ = child.kill();
        child.wait().unwrap();
        match std::fs::read(&out) {
            Ok(bytes) => {
                assert!(
                    bytes == reference,
                    "kill at {delay:?}: a partial or different file"
                );
                complete += 1;
            }
            Err(_) => absent += 1,
        }
        // The rerun writes the same bytes and leaves no temp file.
        assert!(merge_cmd(&out).status().unwrap().success());
        assert!(std::fs::read(&out).unwrap() == reference);
        let temps: Vec<String> = std::fs::read_dir(dir.path())
            .unwrap()
            .flatten()
            .map(|e| e.file_name().to_string_lossy().into_owned())
            .filter(|n| !n.starts_with("city.atlastree"))
            .collect();
        assert!(temps.is_empty(), "kill at {delay:?}: left {temps:?}");
    }
    println!(
        "merge kill test: {points} kill points over 1.2 × {took:?}: {absent} no file, {complete} complete"
    );
    assert!(absent > 0, "no kill landed before the rename");
}

/// data/city copied under `dir` (its images are external files the test may rewrite) and imported.
fn city_copy(dir: &Path) -> Scene {
    import(&crate::built::city_copy(dir), &ImportOptions::default()).unwrap()
}

/// Rewrites the image file at `path` with other pixels (one flat colour, `w × h` as before) and its byte
/// length kept (a PNG padded after its end), so the shard fingerprint (name, size, byte length) cannot
/// tell the versions apart. False when the flat PNG does not fit the old length.
pub(crate) fn rewrite_keeping_length(path: &Path, w: u32, h: u32) -> bool {
    let len = std::fs::metadata(path).unwrap().len() as usize;
    let flat = image::RgbaImage::from_pixel(w, h, image::Rgba([255, 0, 255, 255]));
    let mut bytes = Vec::new();
    flat.write_to(
        &mut std::io::Cursor::new(&mut bytes),
        image::ImageFormat::Png,
    )
    .unwrap();
    if bytes.len() > len {
        return false;
    }
    bytes.resize(len, 0);
    std::fs::write(path, bytes).unwrap();
    true
}

/// Issue 22, robustness: an image rewritten between two shards' builds with its name, size and byte length
/// kept passes the fingerprint; the pixel hashes the shards carry make the merge refuse the mix, naming the
/// image and both shards. Rebuilding the shards that decoded it gives the one-process file of the scene as
/// it is now.
#[test]
fn merge_refuses_shards_that_decoded_two_versions_of_an_image() {
    use atlastree::scene::ImageData;
    use atlastree::store::shard::ShardFile;
    let dir = tempfile::tempdir().unwrap();
    let scene = city_copy(dir.path());
    let out = dir.path().join("city.atlastree");
    let opts = deep_opts();
    let count = 4;
    let shard = |index: u32| {
        let spec = ShardSpec { index, count };
        let sharded = ShardedOptions {
            spec,
            argv: argv(spec),
            import: None,
        };
        build_shard(&scene, &opts, &out, &sharded, &NoProgress).unwrap();
    };
    (0..count).for_each(shard);
    let files: Vec<ShardFile> = (0..count)
        .map(|index| ShardFile::open(&shard_path(&out, ShardSpec { index, count })).unwrap())
        .collect();
    // An external image at least two shards decoded, whose flat version fits its byte length.
    let decoders = |i: usize| -> Vec<u32> {
        (0..count)
            .filter(|&s| files[s as usize].images[i].decoded == 1)
            .collect()
    };
    let (image, users) = (0..scene.images.len())
        .filter(|&i| decoders(i).len() >= 2)
        .find(|&i| {
            let img = &scene.images[i];
            matches!(&img.data, ImageData::File(p) if rewrite_keeping_length(p, img.width, img.height))
        })
        .map(|i| (i, decoders(i)))
        .expect("data/city at 256² atlases in 4 shards: an image two shards decode");
    drop(files);
    // The last of its users rebuilt after the change.
    let last = *users.last().unwrap();
    shard(last);
    let e = merge(&out, None, &NoProgress).unwrap_err();
    match &e {
        MergeError::ImagesDiffer {
            image: what,
            first,
            second,
            count: 4,
            ..
        } => {
            assert_eq!((*first, *second), (users[0], last), "{e}");
            let path = shard_path(&out, ShardSpec { index: last, count });
            assert!(
                e.to_string().contains(&format!("({})", path.display())),
                "{e}"
            );
            assert!(what.starts_with(&format!("image {image} ")), "{e}");
        }
        other => panic!("expected ImagesDiffer, got {other}"),
    }
    assert!(!out.exists(), "a refused merge writes nothing");
    // Every user rebuilt: the file of the scene as it is now.
    users.iter().for_each(|&s| shard(s));
    merge(&out, None, &NoProgress).unwrap();
    let one = dir.path().join("one.atlastree");
    build(&scene, &opts, &one, &NoProgress).unwrap();
    assert!(std::fs::read(&out).unwrap() == std::fs::read(&one).unwrap());
}

/// An image whose file changes while one build runs (decoded again after the cache evicted it): the cache
/// names it (`pixel_pass` returns that error, so the build fails instead of mixing the two versions).
#[test]
fn the_image_cache_names_an_image_whose_pixels_changed_between_two_decodes() {
    use atlastree::ids::ImageId;
    use atlastree::preprocess::image_cache::ImageCache;
    use atlastree::scene::ImageData;
    let dir = tempfile::tempdir().unwrap();
    let scene = city_copy(dir.path());
    let files: Vec<usize> = (0..scene.images.len())
        .filter(|&i| matches!(scene.images[i].data, ImageData::File(_)))
        .collect();
    let (a, b) = (files[0], files[1]);
    // A cache of 1 byte keeps one image per tier: reading b evicts a.
    let cache = ImageCache::new(&scene, 1);
    cache.get(ImageId(a as u32));
    cache.get(ImageId(b as u32));
    cache.get(ImageId(a as u32));
    assert_eq!(cache.decodes.load(std::sync::atomic::Ordering::Relaxed), 3);
    cache.check_decodes().unwrap();
    cache.get(ImageId(b as u32));
    let img = &scene.images[a];
    let ImageData::File(path) = &img.data else {
        unreachable!()
    };
    assert!(rewrite_keeping_length(path, img.width, img.height));
    cache.get(ImageId(a as u32));
    let e = cache.check_decodes().unwrap_err().to_string();
    assert!(
        e.contains(&format!("image {a} ({})", img.name)) && e.contains("changed during the build"),
        "{e}"
    );
}

/// An image that fails to decode is drawn as the magenta fallback in a sharded build as in a one-process
/// one; the shards' reports carry the fallback count and the warning naming the image, and the merge
/// report repeats them (the merge, all a sharded build's user may read, said nothing).
#[test]
fn a_fallback_image_is_reported_by_the_shards_and_the_merge() {
    let dir = tempfile::tempdir().unwrap();
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("data/city");
    let copy = dir.path().join("city");
    std::fs::create_dir_all(copy.join("textures")).unwrap();
    for name in ["scene.gltf", "scene.bin"] {
        std::fs::copy(src.join(name), copy.join(name)).unwrap();
    }
    let mut names: Vec<_> = std::fs::read_dir(src.join("textures"))
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    names.sort();
    for n in &names {
        std::fs::copy(src.join("textures").join(n), copy.join("textures").join(n)).unwrap();
    }
    // The first texture cut in half: its header and first chunks pass the import's checks, and its
    // decode fails (a cut right after the header is an import warning instead).
    let broken = copy.join("textures").join(&names[0]);
    let bytes = std::fs::read(&broken).unwrap();
    std::fs::write(&broken, &bytes[..bytes.len() / 2]).unwrap();
    let scene = import(&copy.join("scene.gltf"), &ImportOptions::default()).unwrap();
    let out = dir.path().join("x.atlastree");
    let opts = deep_opts();
    let mut shard_fallbacks = 0;
    for index in 0..2 {
        let spec = ShardSpec { index, count: 2 };
        let sharded = ShardedOptions {
            spec,
            argv: argv(spec),
            import: None,
        };
        let r = build_shard(&scene, &opts, &out, &sharded, &NoProgress).unwrap();
        shard_fallbacks += r.image_fallbacks;
        assert_eq!(
            r.warnings.len() as u64,
            r.image_fallbacks.min(1),
            "{:?}",
            r.warnings
        );
    }
    assert!(shard_fallbacks >= 1);
    let report = merge(&out, None, &NoProgress).unwrap();
    let fallbacks: u64 = report.shards.iter().filter_map(|s| s.image_fallbacks).sum();
    assert_eq!(fallbacks, shard_fallbacks);
    let name = names[0].to_string_lossy().into_owned();
    let warned = report.shards.iter().flat_map(|s| &s.warnings);
    assert!(
        warned
            .clone()
            .any(|w| w.contains(&name) && w.contains("magenta")),
        "{:?}",
        warned.collect::<Vec<_>>()
    );
}
