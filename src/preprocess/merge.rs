//! The merge of a sharded build ([`merge`], docs/DESIGN.md "Sharded builds", step 4): checks every
//! shard file against the others and the cut, copies their blocks into the paging file, makes the atlases
//! above the cut from the shards' handoffs and finishes the file atomically.

use super::shard::{
    self, Cut, ShardSpec, Unit, choose_cut, handoff_side, shard_blocks, shard_path,
};
use super::shard_files::{complete_sets_text, only_count};
use super::shard_run::ShardReport;
use super::{BuildError, Progress, raster};
use crate::ids::BlockId;
use crate::preprocess::image_ops::LinearImage;
use crate::store::shard::{ShardFile, ShardFileError};
use crate::store::{FileWriter, StoreError, TreeFile};
use serde::Serialize;
use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// Why a merge failed. Every variant names the shard and, where one can, the command that rebuilds it.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error(
        "no shard files for {out} (expected {out}.shard-I-of-N beside it, written by `atlastree build … --shard I/N`)"
    )]
    NoShards { out: PathBuf },
    #[error(
        "shard files of several builds beside {out}: N = {}; remove the stale ones or say which with --shards N",
        counts.iter().map(u32::to_string).collect::<Vec<_>>().join(" and ")
    )]
    AmbiguousCount { out: PathBuf, counts: Vec<u32> },
    #[error("--shards {count}: expected a shard count from 1 to {max}", max = shard::MAX_SHARDS)]
    BadCount { count: u32 },
    #[error("shard {shard} of {count} is missing: {path} does not exist{rebuild}{complete}")]
    Missing {
        shard: u32,
        count: u32,
        path: PathBuf,
        rebuild: String,
        /// Where every shard of another count lies beside OUT: what `--shards` may have meant.
        complete: String,
    },
    /// The process ran out of file descriptors opening the shards (every shard is held open): a limit of
    /// this machine, not a fault of the shard.
    #[error(
        "opening shard {shard} of {count} ({path}): {source}: the merge holds all {count} shards open; raise \
         the open-files limit (ulimit -n, at least {count} plus a few) and merge again"
    )]
    TooManyOpen {
        shard: u32,
        count: u32,
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("shard {shard} of {count} ({path}) is unreadable or corrupt: {source}{rebuild}")]
    Corrupt {
        shard: u32,
        count: u32,
        path: PathBuf,
        rebuild: String,
        #[source]
        source: ShardFileError,
    },
    #[error("shard {shard} of {count} ({path}) belongs to another build: {why}{rebuild}")]
    Foreign {
        shard: u32,
        count: u32,
        path: PathBuf,
        why: String,
        rebuild: String,
    },
    /// Two shards decoded one image to different pixels: its file changed between their builds, and the
    /// fingerprint (name, size, byte length) did not show it.
    #[error(
        "shards {first} ({p1}) and {second} ({p2}) of {count} decoded {image} to different pixels: the \
         file changed between their builds (same name, size and byte length), so their atlases would mix \
         two versions of it; rebuild the shards built before the change (if unsure, all {count}) from the scene as it \
         is now, then merge again",
        p1 = .first_path.display(),
        p2 = .second_path.display()
    )]
    ImagesDiffer {
        image: String,
        first: u32,
        first_path: PathBuf,
        second: u32,
        second_path: PathBuf,
        count: u32,
    },
    #[error(
        "shard 0 holds no table prefix (its shards were built from the plan {plan}), and the plan cannot give it: \
         {why}; plan again with the shards' flags ({command}) and merge again: the plan of the same scene and \
         flags is the one the shards read (if the scene changed since they were built, rebuild them from the new plan)"
    )]
    Plan {
        plan: PathBuf,
        why: String,
        /// The plan step's command: the shards' own with `--shard plan`.
        command: String,
    },
    #[error("merging into {out}: {source}")]
    Store {
        out: PathBuf,
        #[source]
        source: StoreError,
    },
    #[error("merging into {out}: {source}")]
    Build {
        out: PathBuf,
        #[source]
        source: BuildError,
    },
}

/// One shard's line of the merge report.
#[derive(Clone, Debug, Serialize)]
pub struct MergedShard {
    pub shard: u32,
    #[serde(serialize_with = "crate::util::path_lossy")]
    pub path: PathBuf,
    pub file_bytes: u64,
    pub blocks: u64,
    pub units: u64,
    /// From the shard's JSON report, if present.
    pub seconds: Option<f64>,
    pub peak_rss_bytes: Option<u64>,
    pub work: Option<u64>,
    /// From the shard's JSON report: images drawn as the magenta fallback, and its warnings (its
    /// import's first, where it imported the scene).
    pub image_fallbacks: Option<u64>,
    pub warnings: Vec<String>,
}

/// What a merge did.
#[derive(Clone, Debug, Serialize)]
pub struct MergeReport {
    #[serde(serialize_with = "crate::util::path_lossy")]
    pub out: PathBuf,
    pub count: u32,
    pub shards: Vec<MergedShard>,
    /// Atlases made above the cut.
    pub above_cut: u64,
    pub file_bytes: u64,
    pub seconds: f64,
    pub peak_rss_bytes: Option<u64>,
    /// The plan step, when the shards read a plan file: its time and peak memory from its report
    /// (`OUT.plan.json`), if present.
    pub plan: Option<MergedPlan>,
}

/// The plan step of a planned build, as the merge reports it.
#[derive(Clone, Debug, Serialize)]
pub struct MergedPlan {
    #[serde(serialize_with = "crate::util::path_lossy")]
    pub path: PathBuf,
    pub seconds: Option<f64>,
    pub peak_rss_bytes: Option<u64>,
    /// What the scene's import and planning the trees warned about (from the plan's report; the shards
    /// that read the plan do not repeat it).
    pub warnings: Vec<String>,
}

/// `argv` with the value of its `-o`/`--out` (in any of clap's spellings) replaced by `out`, made
/// absolute (the merge may run elsewhere than the shard did).
fn with_out(argv: &[String], out: &Path) -> Vec<String> {
    let out = crate::util::shell_words::path_to_recorded(
        &std::path::absolute(out).unwrap_or_else(|_| out.to_path_buf()),
    );
    let mut args = Vec::with_capacity(argv.len());
    let mut it = argv.iter();
    while let Some(a) = it.next() {
        if a == "-o" || a == "--out" {
            args.push(a.clone());
            if it.next().is_some() {
                args.push(out.clone());
            }
        } else if let Some(flag) = ["--out=", "-o="].into_iter().find(|f| a.starts_with(f)) {
            args.push(format!("{flag}{out}"));
        } else if a.starts_with("-o") && !a.starts_with("--") && a.len() > 2 {
            args.push(format!("-o{out}"));
        } else {
            args.push(a.clone());
        }
    }
    args
}

/// `; rebuild it with: …` from a shard's stored command line, with its `--shard` value replaced.
fn rebuild_hint(argv: Option<&[String]>, spec: ShardSpec) -> String {
    match with_shard(argv, &spec.to_string()) {
        Some(command) => format!("; rebuild it with: {command}"),
        None => format!("; rebuild it with `atlastree build … --shard {spec}`"),
    }
}

/// A shard's stored command line with its `--shard` value replaced by `value`, quoted for a shell; `None`
/// without one.
fn with_shard(argv: Option<&[String]>, value: &str) -> Option<String> {
    let argv = argv.filter(|a| !a.is_empty())?;
    let mut args: Vec<String> = Vec::with_capacity(argv.len());
    let mut it = argv.iter();
    while let Some(a) = it.next() {
        if a == "--shard" {
            it.next();
            args.push("--shard".into());
            args.push(value.to_string());
        } else if a.starts_with("--shard=") {
            args.push(format!("--shard={value}"));
        } else {
            args.push(a.clone());
        }
    }
    let quoted: Vec<String> = args
        .iter()
        .map(|a| crate::util::shell_words::shell_word(a))
        .collect();
    Some(quoted.join(" "))
}

/// Merges the shard files of `out`'s build (`count` shards, or the only count found beside `out`) into
/// `out`, atomically: checks every shard (present, intact, same fingerprint, the blocks and subtree roots
/// the cut gives it), copies every block, makes the atlases above the cut from the shards' handoffs, and
/// finishes the paging file. Byte-identical to the one-process build with the same scene and flags.
pub fn merge(
    out: &Path,
    count: Option<u32>,
    progress: &dyn Progress,
) -> Result<MergeReport, MergeError> {
    let t_all = Instant::now();
    // Before any work: an OUT that may not be replaced (the scene, `OUT/`, a device) is refused now, not
    // after every block is copied.
    crate::store::check_replaceable(out).map_err(|source| MergeError::Store {
        out: out.to_path_buf(),
        source,
    })?;
    let mut set = ShardSet::open(out, count)?;
    set.check_headers()?;
    set.check_images()?;
    let opened_plan = set.plan.take();
    let first = &set.shards[0];
    let (tables, plan) = if first.header.prefix_len > 0 {
        let tables = (first.skeleton())
            .map_err(|e| set.foreign(0, format!("its table prefix does not open: {e}")))?;
        (Tables::Shard0(tables), None)
    } else {
        let (file, tables) = planned_tables(
            out,
            first.header.prefix_hash,
            opened_plan,
            set.shard_argv.as_deref(),
        )?;
        let path = file.path().to_path_buf();
        // Only the report of this very plan: two plan runs for one OUT at once could leave one's file
        // and the other's report (fault hunt, session 39), as a shard's report is checked against it.
        let report = read_sidecar::<super::ShardPlanReport>(&path)
            .filter(|r| r.key == Some(file.header.key));
        let plan = MergedPlan {
            seconds: report.as_ref().and_then(super::ShardPlanReport::seconds),
            peak_rss_bytes: report.as_ref().and_then(|r| r.stages.peak_rss_bytes),
            warnings: report
                .map(|r| [r.import_warnings, r.warnings].concat())
                .unwrap_or_default(),
            path,
        };
        (Tables::Plan(file, tables), Some(plan))
    };
    let forest = tables.file().to_skeleton();
    let cut = choose_cut(&forest, set.count);
    set.check_cut(&forest, &cut)?;
    let pixels = raster::PixelOptions::from_code(first.header.pixel_options).ok_or_else(|| {
        set.foreign(
            0,
            format!(
                "unknown pixel options code {} (mip filter, alpha mips)",
                first.header.pixel_options
            ),
        )
    })?;

    let store_err = |source| MergeError::Store {
        out: out.to_path_buf(),
        source,
    };
    let writer = tables.writer(out, &set.shards[0]).map_err(store_err)?;
    drop(tables);
    let handoffs = set.copy_blocks(&writer, progress)?;
    let below: u64 = (cut.shards.iter().flatten())
        .map(|u| shard::subtree_nodes(&forest.trees[u.tree as usize], crate::ids::NodeId(u.node)))
        .sum();
    let above = forest
        .trees
        .iter()
        .map(|t| t.nodes.len() as u64)
        .sum::<u64>()
        - below;
    progress.stage("merge: atlases above the cut", Some(above));
    let done = |n: u64| progress.set(n);
    let atlas_out = raster::AtlasOut::new(&forest, pixels, &writer, &done);
    let fetch = |u| handoffs.get(&u).map(|&(slot, i)| set.handoff(slot, i));
    shard::raster_forest_above(&atlas_out, &forest, &fetch).map_err(|source| {
        MergeError::Build {
            out: out.to_path_buf(),
            source,
        }
    })?;
    progress.finish_stage();
    progress.stage("merge: write", None);
    let summary = writer.finish().map_err(store_err)?;
    progress.finish_stage();
    Ok(MergeReport {
        out: out.to_path_buf(),
        count: set.count,
        shards: set.report_lines(),
        above_cut: above,
        file_bytes: summary.total,
        seconds: t_all.elapsed().as_secs_f64(),
        peak_rss_bytes: crate::util::peak_rss_bytes(),
        plan,
    })
}

/// Where the merge's tables come from: shard 0's prefix or the plan's, read as a skeleton (no geometry)
/// and copied into the paging file in pieces.
enum Tables {
    Shard0(TreeFile),
    Plan(crate::store::shard_plan::PlanFile, TreeFile),
}

impl Tables {
    fn file(&self) -> &TreeFile {
        match self {
            Tables::Shard0(t) | Tables::Plan(_, t) => t,
        }
    }

    /// The writer of the paging file, its tables written; shard 0 is `first`.
    fn writer(&self, out: &Path, first: &ShardFile) -> Result<FileWriter, StoreError> {
        match self {
            Tables::Shard0(t) => first.writer(out, t),
            Tables::Plan(plan, t) => plan.writer(out, t),
        }
    }
}

/// The tables of a planned build, from `OUT.plan` (checked: intact, and the plan the shards say they were
/// built from), without their geometry; `opened` is the plan where the shard set already opened it.
fn planned_tables(
    out: &Path,
    prefix_hash: [u64; 2],
    opened: Option<crate::store::shard_plan::PlanFile>,
    argv: Option<&[String]>,
) -> Result<(crate::store::shard_plan::PlanFile, TreeFile), MergeError> {
    let path = crate::store::shard_plan::plan_path(out);
    let command = with_shard(argv, "plan")
        .unwrap_or_else(|| "`atlastree build SCENE -o OUT FLAGS --shard plan`".into());
    let refuse = |why: String| MergeError::Plan {
        plan: path.clone(),
        why,
        command: command.clone(),
    };
    let plan = match opened {
        Some(plan) => plan,
        None if !path.exists() => return Err(refuse("it does not exist".into())),
        None => {
            crate::store::shard_plan::PlanFile::open(&path).map_err(|e| refuse(e.to_string()))?
        }
    };
    if plan.header.prefix_hash != prefix_hash {
        return Err(refuse(
            "its tables are not the ones the shards were built from (another plan was written since, or the scene \
             changed)"
                .into(),
        ));
    }
    let tables = plan.skeleton().map_err(|e| refuse(e.to_string()))?;
    Ok((plan, tables))
}

/// The N shard files of one build, opened, in slot order (slot i is the file named shard i), with the
/// command line the rebuild hints copy.
struct ShardSet {
    count: u32,
    shards: Vec<ShardFile>,
    /// The stored command line of a shard of the build most shards belong to (a foreign shard's flags
    /// would rebuild the wrong thing), or the plan's ([`ShardSet::prefer_plan`]).
    argv: Option<Vec<String>>,
    /// The majority shards' own command line, whatever the plan says: the flags a plan made again for
    /// these shards must have (a replaced plan's own command would write the same wrong plan again).
    shard_argv: Option<Vec<String>>,
    /// `OUT.plan` where planned shards are merged and it opens: the shards built from it are the
    /// reference, however many are stale; the merge then reads its tables from this one open.
    plan: Option<crate::store::shard_plan::PlanFile>,
}

impl ShardSet {
    /// Finds and opens every shard of `out` (`count`, or the only count found beside it); fails on the
    /// first missing or unreadable one.
    fn open(out: &Path, count: Option<u32>) -> Result<ShardSet, MergeError> {
        let count = match count {
            Some(n) if n == 0 || n > shard::MAX_SHARDS => {
                return Err(MergeError::BadCount { count: n });
            }
            Some(n) => n,
            None => only_count(out)?,
        };
        let mut opened: Vec<Option<ShardFile>> = Vec::with_capacity(count as usize);
        let mut failures: Vec<(u32, PathBuf, Option<ShardFileError>)> = Vec::new();
        for index in 0..count {
            let path = shard_path(out, ShardSpec { index, count });
            let file = if path.exists() {
                ShardFile::open(&path).map_err(Some)
            } else {
                Err(None)
            };
            match file {
                Ok(f) => opened.push(Some(f)),
                Err(e) => {
                    failures.push((index, path, e));
                    opened.push(None);
                }
            }
        }
        let prints: Vec<[u64; 2]> = (opened.iter().flatten())
            .map(|f| f.header.fingerprint)
            .collect();
        let majority = prints.iter().max_by_key(|p| {
            (
                prints.iter().filter(|q| q == p).count(),
                std::cmp::Reverse(prints.iter().position(|q| q == *p)),
            )
        });
        // With `-o` naming this merge's OUT: shards built elsewhere and gathered here are rebuilt here.
        let argv = (opened.iter().flatten())
            .find(|f| Some(&f.header.fingerprint) == majority)
            .map(|f| with_out(&f.argv, out));
        let mut set = ShardSet {
            count,
            shards: Vec::new(),
            shard_argv: argv.clone(),
            argv,
            plan: None,
        };
        // Before any hint is made (a missing shard's too).
        let mut read = opened.iter().flatten().peekable();
        if read.peek().is_none() || read.any(|f| f.header.prefix_len == 0) {
            set.prefer_plan(out, opened.iter().flatten());
        }
        if let Some((shard, path, err)) = failures.into_iter().next() {
            let err = match err {
                Some(ShardFileError::Io { source, .. })
                    if crate::util::is_out_of_descriptors(&source) =>
                {
                    return Err(MergeError::TooManyOpen {
                        shard,
                        count,
                        path,
                        source,
                    });
                }
                other => other,
            };
            let rebuild = set.hint(shard);
            return Err(match err {
                None => MergeError::Missing {
                    shard,
                    count,
                    // A shard still being written is waited for, not built twice (fault hunt,
                    // session 34: the merge sent the user off to rebuild it).
                    rebuild: match crate::util::writer_of(&path) {
                        Some(pid) => format!(
                            "; process {pid} is writing it now: merge again once it has finished"
                        ),
                        None => rebuild,
                    },
                    path,
                    complete: complete_sets_text(out, count),
                },
                Some(source) => MergeError::Corrupt {
                    shard,
                    count,
                    path,
                    rebuild,
                    source,
                },
            });
        }
        set.shards = opened.into_iter().flatten().collect();
        Ok(set)
    }

    /// Where some shard read a plan (or none could be read) and `OUT.plan` opens, the plan decides which
    /// shards are stale: a re-plan with other flags and one shard rebuilt from it made that shard the odd
    /// one out, and the hint sent the user to rebuild it with the old flags, which the new plan then
    /// refused (fault hunt, session 31). Hints then copy the plan's command line (its `--shard plan`
    /// becomes `--shard I/N`). A plan that does not open is reported later, where its tables are read.
    fn prefer_plan<'a>(&mut self, out: &Path, shards: impl Iterator<Item = &'a ShardFile>) {
        let path = crate::store::shard_plan::plan_path(out);
        let Ok(plan) = crate::store::shard_plan::PlanFile::open(&path) else {
            return;
        };
        // A shard built from this plan holds the flags the plan leaves out (`--filter`, `--alpha-mips`,
        // its own `--max-memory`): the plan's command dropped them, and the shard it rebuilt was refused
        // again (fault hunt, session 37). The plan's where no shard is from it.
        let from_plan =
            (shards.into_iter()).find(|f| f.header.prefix_hash == plan.header.prefix_hash);
        let argv = from_plan.map_or(&plan.manifest.argv, |f| &f.argv);
        self.argv = Some(with_out(argv, out));
        self.plan = Some(plan);
    }

    fn hint(&self, index: u32) -> String {
        rebuild_hint(
            self.argv.as_deref(),
            ShardSpec {
                index,
                count: self.count,
            },
        )
    }

    fn foreign(&self, slot: usize, why: String) -> MergeError {
        MergeError::Foreign {
            shard: slot as u32,
            count: self.count,
            path: self.shards[slot].path().to_path_buf(),
            why,
            rebuild: self.hint(slot as u32),
        }
    }

    fn corrupt(&self, slot: usize, source: ShardFileError) -> MergeError {
        MergeError::Corrupt {
            shard: slot as u32,
            count: self.count,
            path: self.shards[slot].path().to_path_buf(),
            rebuild: self.hint(slot as u32),
            source,
        }
    }

    /// Every shard says it is its slot of `count`, and all carry one fingerprint, prefix and pixel options.
    /// Where they differ, the shard named is one outside the largest group that agrees (shard 0 may be
    /// the stale one: naming whichever differs from shard 0 sent the user rebuilding a good shard); with
    /// no strict majority the message says so.
    fn check_headers(&self) -> Result<(), MergeError> {
        for (i, f) in self.shards.iter().enumerate() {
            let h = &f.header;
            if h.shard != i as u32 || h.count != self.count {
                let why = format!("it says it is shard {} of {}", h.shard, h.count);
                return Err(self.foreign(i, why));
            }
        }
        let same = |a: usize, b: usize| {
            let (x, y) = (&self.shards[a].header, &self.shards[b].header);
            x.fingerprint == y.fingerprint
                && x.prefix_hash == y.prefix_hash
                && x.pixel_options == y.pixel_options
        };
        let n = self.shards.len();
        // Per shard, how many shards agree with it; the first of the largest group (shard 0's on a tie),
        // among the shards built from the plan where there is one.
        let agreeing: Vec<usize> = (0..n)
            .map(|i| (0..n).filter(|&j| same(i, j)).count())
            .collect();
        // No shard from the plan: all are older than it, which reading the plan's tables reports.
        let plan = (self.plan.as_ref())
            .map(|p| p.header.prefix_hash)
            .filter(|&p| self.shards.iter().any(|f| f.header.prefix_hash == p));
        let from_plan = |i: usize| plan.is_none_or(|p| self.shards[i].header.prefix_hash == p);
        let Some(reference) = (0..n)
            .filter(|&i| from_plan(i))
            .fold(None, |best, i| match best {
                Some(b) if agreeing[b] >= agreeing[i] => Some(b),
                _ => Some(i),
            })
        else {
            // No shard at all (an open set has at least one; nothing to compare).
            return Ok(());
        };
        let Some(odd) = (0..n).find(|&i| !same(reference, i)) else {
            return Ok(());
        };
        let group = agreeing[reference];
        let why = if plan.is_some() && !from_plan(odd) {
            format!(
                "it was not built from the plan beside OUT, which {group} of {n} shards were (shard \
                 {reference})"
            )
        } else if 2 * group > n {
            format!(
                "its fingerprint (scene and flags) differs from the other {group} of {n} shards' (shard \
                 {reference}'s)"
            )
        } else {
            format!(
                "its fingerprint (scene and flags) differs from shard {reference}'s, and no fingerprint is \
                 held by most shards ({group} of {n} share shard {reference}'s): rebuild the shards built \
                 from another scene or other flags"
            )
        };
        Err(self.foreign(odd, why))
    }

    /// Every file two shards decoded has one pixel hash in both: a glTF image (whichever of its OPAQUE
    /// and alpha scene images each decoded), else a scene image (the fingerprint, equal by now, gives
    /// every shard the same image count).
    fn check_images(&self) -> Result<(), MergeError> {
        use crate::store::shard::ImageEntry;
        // One file's pixels: a glTF image (the scene images it becomes for OPAQUE and alpha materials
        // hash its pixels before the alpha is dropped), else the scene image itself. Two shards that
        // each decoded a different one of them read two versions undetected (fault hunt, session 37).
        let file_of = |i: usize, e: &ImageEntry| match e.gltf_image {
            u32::MAX => (0, i),
            g => (1, g as usize),
        };
        let mut first: std::collections::HashMap<(u8, usize), (usize, usize, &ImageEntry)> =
            std::collections::HashMap::new();
        for (slot, f) in self.shards.iter().enumerate() {
            for (i, e) in f.images.iter().enumerate().filter(|(_, e)| e.decoded == 1) {
                let (a, ia, ea) = *first.entry(file_of(i, e)).or_insert((slot, i, e));
                if ea.pixels != e.pixels {
                    let image = match (e.gltf_image, ia == i) {
                        (u32::MAX, _) => format!("image {i}"),
                        (g, true) => format!("image {i} (glTF image {g})"),
                        (g, false) => format!("images {ia} and {i} (glTF image {g})"),
                    };
                    return Err(MergeError::ImagesDiffer {
                        image,
                        first: a as u32,
                        first_path: self.shards[a].path().to_path_buf(),
                        second: slot as u32,
                        second_path: f.path().to_path_buf(),
                        count: self.count,
                    });
                }
            }
        }
        Ok(())
    }

    /// Each shard holds exactly the blocks and subtree roots the cut gives it.
    fn check_cut(&self, forest: &crate::model::AtlasForest, cut: &Cut) -> Result<(), MergeError> {
        let side = handoff_side(forest.params.atlas_size);
        for (i, (f, units)) in self.shards.iter().zip(&cut.shards).enumerate() {
            let expected = shard_blocks(forest, units);
            let got: Vec<(BlockId, u64)> = (f.blocks.iter())
                .map(|e| (BlockId(e.block), e.length))
                .collect();
            if got != expected {
                let why = format!(
                    "it holds {} blocks where the cut of shard 0's tables gives it {}",
                    got.len(),
                    expected.len()
                );
                return Err(self.foreign(i, why));
            }
            let roots: Vec<Unit> = (f.handoffs.iter())
                .map(|h| Unit {
                    tree: h.tree,
                    node: h.node,
                })
                .collect();
            if &roots != units
                || f.handoffs
                    .iter()
                    .any(|h| h.width != side || h.height != side)
            {
                let why = "its subtree roots differ from the cut of shard 0's tables".to_string();
                return Err(self.foreign(i, why));
            }
        }
        Ok(())
    }

    /// Copies every shard's blocks into `writer` (checksums verified on the way), checks every handoff's
    /// checksum, and returns where each unit's handoff is: (shard slot, entry), read again when its parent
    /// is combined ([`ShardSet::handoff`]).
    ///
    /// Shards are copied in order, the blocks of one shard on the rayon pool (positional reads and writes:
    /// a merge of gigabytes is page-cache copies, checksums and the leaf atlases' rect means, measured
    /// by the writer as a build measures them — work one core did alone); a shard's first
    /// bad block in entry order is the one reported, as a serial copy would.
    fn copy_blocks(
        &self,
        writer: &FileWriter,
        progress: &dyn Progress,
    ) -> Result<HashMap<Unit, (usize, usize)>, MergeError> {
        use rayon::prelude::*;
        use std::sync::atomic::{AtomicU64, Ordering};
        let total: u64 = self.shards.iter().map(|f| f.blocks.len() as u64).sum();
        progress.stage("merge: copy blocks", Some(total));
        let copied = AtomicU64::new(0);
        let mut handoffs = HashMap::new();
        for (slot, f) in self.shards.iter().enumerate() {
            let results: Vec<Result<(), MergeError>> = (f.blocks.par_iter().enumerate())
                .map(|(i, e)| {
                    let bytes = f.block(i).map_err(|err| self.corrupt(slot, err))?;
                    writer
                        .write_block_measured(BlockId(e.block), &bytes, e.sse)
                        .map_err(|source| MergeError::Store {
                            out: writer.target().to_path_buf(),
                            source,
                        })?;
                    progress.set(copied.fetch_add(1, Ordering::Relaxed) + 1);
                    Ok(())
                })
                .collect();
            results.into_iter().collect::<Result<(), MergeError>>()?;
            for (i, e) in f.handoffs.iter().enumerate() {
                drop(f.handoff(i).map_err(|err| self.corrupt(slot, err))?);
                let unit = Unit {
                    tree: e.tree,
                    node: e.node,
                };
                handoffs.insert(unit, (slot, i));
            }
        }
        progress.finish_stage();
        Ok(handoffs)
    }

    /// Handoff `i` of the shard in `slot`, read (and its checksum checked) again.
    fn handoff(&self, slot: usize, i: usize) -> Result<LinearImage, BuildError> {
        let f = &self.shards[slot];
        let e = &f.handoffs[i];
        let data = f.handoff(i).map_err(|e| BuildError::Shard(Box::new(e)))?;
        Ok(LinearImage {
            width: e.width,
            height: e.height,
            data,
        })
    }

    /// The merge report's line of every shard (time and peak memory from its JSON report, if present).
    fn report_lines(&self) -> Vec<MergedShard> {
        (self.shards.iter().enumerate())
            .map(|(slot, f)| {
                // Only a report of this very shard file: one copied in from another build kept the
                // old run's numbers (fault hunt, session 37).
                let side = read_sidecar::<ShardReport>(f.path()).filter(|r| {
                    (r.shard, r.count, r.file_bytes) == (slot as u32, self.count, f.header.file_len)
                });
                let total = |r: &ShardReport| {
                    (r.stages.timings.iter())
                        .find(|(n, _)| n == "total")
                        .map(|(_, s)| *s)
                };
                MergedShard {
                    shard: slot as u32,
                    path: f.path().to_path_buf(),
                    file_bytes: f.header.file_len,
                    blocks: f.blocks.len() as u64,
                    units: f.handoffs.len() as u64,
                    seconds: side.as_ref().and_then(total),
                    peak_rss_bytes: side.as_ref().and_then(|r| r.stages.peak_rss_bytes),
                    work: side.as_ref().map(|r| r.work),
                    image_fallbacks: side.as_ref().map(|r| r.image_fallbacks),
                    warnings: side
                        .map(|r| [r.import_warnings, r.warnings].concat())
                        .unwrap_or_default(),
                }
            })
            .collect()
    }
}

fn read_sidecar<T: serde::de::DeserializeOwned>(path: &Path) -> Option<T> {
    let bytes = crate::util::read_regular(&super::shard_run::sidecar_path(path), None).ok()?;
    serde_json::from_slice(&bytes).ok()
}

#[cfg(test)]
mod tests {
    /// Every spelling of `-o` gets the merge's OUT (absolute); other arguments stay, `-q` among them.
    #[test]
    fn the_rebuild_command_writes_beside_this_merges_out() {
        let out = std::path::Path::new("/gathered/x.at");
        let args = |v: &[&str]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>();
        let argv = args(&[
            "atlastree",
            "build",
            "s.gltf",
            "-q",
            "-o",
            "/old/x.at",
            "--shard",
            "1/2",
        ]);
        assert_eq!(
            super::with_out(&argv, out),
            args(&[
                "atlastree",
                "build",
                "s.gltf",
                "-q",
                "-o",
                "/gathered/x.at",
                "--shard",
                "1/2"
            ])
        );
        for (given, want) in [
            ("-o/old/x.at", "-o/gathered/x.at"),
            ("-o=/old/x.at", "-o=/gathered/x.at"),
            ("--out=/old/x.at", "--out=/gathered/x.at"),
        ] {
            assert_eq!(
                super::with_out(&args(&["b", given]), out),
                args(&["b", want])
            );
        }
        assert_eq!(
            super::with_out(&args(&["b", "--out", "/old/x.at"]), out),
            args(&["b", "--out", "/gathered/x.at"])
        );
    }
}
