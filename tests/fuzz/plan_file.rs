//! Target `plan_file`: mutants of the plan file of a two-shard planned build of data/city (small atlases)
//! read by both shards, then merged (issue 22: a corrupt, truncated or foreign plan is refused, naming the
//! file, never planned into a wrong file).
//!
//! Mutations: byte flips (one to eight, most in the header and manifest), truncation, appended bytes, and
//! resealed edits (a header word, or a byte of the manifest, changed and the checksums recomputed). A
//! build whose shards and merge all succeed must write exactly the one-process file; anything else it
//! writes is an accepted corruption.

use super::harness::{self, Verdict};
use arbitrary::Unstructured;
use atlastree::preprocess::shard::ShardSpec;
use atlastree::preprocess::{
    BuildOptions, DMin, NoProgress, ShardedOptions, build, build_shard_planned, merge, plan_shards,
    shard_plan_key,
};
use atlastree::scene::{ImportOptions, import};
use atlastree::store::shard_plan::{PlanFile, PlanHeader, plan_path};
use std::path::PathBuf;
use std::sync::OnceLock;

/// CI cases (each: two planned shards of a small build and their merge, when the plan opens).
const DEFAULT_CASES: u64 = 300;

struct Base {
    scene: PathBuf,
    opts: BuildOptions,
    key: [u64; 2],
    /// The plan file's bytes.
    plan: Vec<u8>,
    /// The one-process paging file.
    reference: Vec<u8>,
}

fn base() -> &'static Base {
    static BASE: OnceLock<Base> = OnceLock::new();
    BASE.get_or_init(|| {
        let scene_path = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf");
        let scene = import(&scene_path, &ImportOptions::default()).expect("data/city imports");
        let opts = BuildOptions {
            d_min: DMin::Ratio(40.0),
            atlas_size: 64,
            border: 4,
            leaf_originals_atlases: 0.0,
            ..Default::default()
        };
        let dir = tempfile::tempdir().expect("temp dir");
        let one = dir.path().join("one.atlastree");
        build(&scene, &opts, &one, &NoProgress).expect("data/city builds");
        let out = dir.path().join("city.atlastree");
        let key = shard_plan_key(&opts, &scene_path, "").expect("key");
        plan_shards(&scene, &opts, &out, key, vec![], &NoProgress).expect("plans");
        Base {
            scene: scene_path,
            opts,
            key,
            plan: std::fs::read(plan_path(&out)).expect("read plan"),
            reference: std::fs::read(&one).expect("read the build"),
        }
    })
}

const HEADER: usize = size_of::<PlanHeader>();

fn header_of(b: &[u8]) -> PlanHeader {
    bytemuck::pod_read_unaligned(&b[..HEADER])
}

/// Recomputes the manifest's and the header's checksums.
fn reseal(b: &mut [u8]) {
    let mut h = header_of(b);
    let end = (HEADER as u64)
        .saturating_add(h.manifest_len)
        .min(b.len() as u64) as usize;
    h.manifest_checksum = xxhash_rust::xxh3::xxh3_64(&b[HEADER..end]);
    let bytes = bytemuck::bytes_of(&h);
    h.checksum = xxhash_rust::xxh3::xxh3_64(&bytes[..HEADER - 8]);
    b[..HEADER].copy_from_slice(bytemuck::bytes_of(&h));
}

/// One mutation of `m`, described.
fn mutate_bytes(u: &mut Unstructured<'_>, m: &mut Vec<u8>) -> arbitrary::Result<String> {
    let len = m.len();
    let manifest_end = HEADER + header_of(m).manifest_len as usize;
    Ok(match u.int_in_range(0u8..=9)? {
        0..=3 => {
            let p = if u.ratio(2u8, 3u8)? {
                u.choose_index(manifest_end.min(len))?
            } else {
                u.choose_index(len)?
            };
            let mask = u.int_in_range(1u8..=255)?;
            m[p] ^= mask;
            format!("flip {mask:#04x} at {p}")
        }
        4 => {
            let n = u.int_in_range(2usize..=8)?;
            for _ in 0..n {
                let p = u.choose_index(len)?;
                m[p] ^= u.int_in_range(1u8..=255)?;
            }
            format!("{n} flips")
        }
        5 => {
            let cut = u.choose_index(len)?;
            m.truncate(cut);
            format!("truncated to {cut}")
        }
        6 => {
            let n = *u.choose(&[1usize, 15, 16, 4096])?;
            m.resize(len + n, 0);
            format!("{n} zero bytes appended")
        }
        7 => {
            // A resealed manifest byte (JSON: mostly a syntax error, sometimes another image or argv).
            let p = HEADER + u.choose_index(manifest_end - HEADER)?;
            let v = u.arbitrary::<u8>()?;
            m[p] = v;
            reseal(m);
            format!("manifest byte {p} := {v:#04x}, resealed")
        }
        _ => {
            // A resealed header word (before the checksum).
            let at = 8 * u.choose_index((HEADER - 8) / 8)?;
            let old = u64::from_le_bytes(m[at..at + 8].try_into().unwrap_or_default());
            let v = match u.int_in_range(0u8..=5)? {
                0 => 0,
                1 => u64::MAX,
                2 => old.wrapping_add(1),
                3 => old.wrapping_sub(1),
                4 => old ^ (1 << u.int_in_range(0..=63)?),
                _ => u.arbitrary::<u64>()?,
            };
            m[at..at + 8].copy_from_slice(&v.to_le_bytes());
            reseal(m);
            format!("header word at {at}: {old} → {v}, resealed")
        }
    })
}

fn mutate(data: &[u8]) -> Verdict {
    let base = base();
    let mut u = Unstructured::new(data);
    let mut m = base.plan.clone();
    let Ok(what) = mutate_bytes(&mut u, &mut m) else {
        return Verdict::Skipped;
    };
    let dir = tempfile::tempdir().expect("temp dir");
    let out: PathBuf = dir.path().join("city.atlastree");
    std::fs::write(plan_path(&out), &m).expect("write plan");
    for index in 0..2 {
        let spec = ShardSpec { index, count: 2 };
        let sharded = ShardedOptions {
            spec,
            argv: vec!["atlastree".into()],
            import: None,
        };
        let built = PlanFile::open(&plan_path(&out))
            .map_err(|e| e.to_string())
            .and_then(|plan| {
                build_shard_planned(
                    &plan,
                    base.key,
                    &base.scene,
                    &base.opts,
                    &out,
                    &sharded,
                    &NoProgress,
                )
                .map_err(|e| e.to_string())
            });
        if let Err(e) = built {
            // Without the temp folder, so the sample groups refusals by kind.
            let dir = dir.path().display().to_string();
            return Verdict::Refused(e.replace(&dir, ""));
        }
    }
    match merge(&out, None, &NoProgress) {
        Err(e) => {
            if out.exists() {
                return Verdict::AcceptedCorruption(format!(
                    "{what}: failed ({e}) but wrote the output"
                ));
            }
            Verdict::Refused(e.to_string().replace(&dir.path().display().to_string(), ""))
        }
        Ok(_) => {
            if std::fs::read(&out).expect("read merged") == base.reference {
                Verdict::Accepted
            } else {
                Verdict::AcceptedCorruption(format!(
                    "{what}: planned into a file that differs from the one-process build"
                ))
            }
        }
    }
}

#[test]
fn plan_file() {
    let counts = harness::run("plan_file", DEFAULT_CASES, mutate);
    assert!(counts.refused > 0, "{counts:?}");
}
