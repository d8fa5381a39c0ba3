//! The binary on the embedded default scene: scene-info, build, inspect --verify, demo, and clear errors on
//! bad input (a missing file, a corrupt paging file) with a non-zero exit and no panic.

use std::path::PathBuf;
use std::process::{Command, Output};

mod refusals;

/// The binary, without the log filters a developer's shell may set (they add lines to stderr).
fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_atlastree"));
    c.env_remove("RUST_LOG").env_remove("ATLASTREE_LOG");
    c
}

fn scene() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf")
}

fn run(cmd: &mut Command) -> Output {
    let out = cmd.output().expect("spawn atlastree");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "panic: {stderr}");
    out
}

fn json(out: &Output) -> serde_json::Value {
    assert!(
        out.status.success(),
        "exit {:?}: {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

/// `atlastree build --d-min-ratio 10 --json ARGS -o OUT data/city`, its JSON report.
fn build_json(out: &std::path::Path, args: &[&str]) -> serde_json::Value {
    json(&run(bin()
        .args(["build", "--d-min-ratio", "10", "--json"])
        .args(args)
        .arg("-o")
        .arg(out)
        .arg(scene())))
}

/// An absurd `RAYON_NUM_THREADS` is refused before any work, with the limit (99,999 aborted in the
/// thread pool's start).
#[test]
fn an_absurd_thread_count_is_refused() {
    let out = run(bin()
        .env("RAYON_NUM_THREADS", "99999")
        .arg("scene-info")
        .arg(scene()));
    assert_eq!(out.status.code(), Some(2));
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("at most 1024"), "{stderr}");
}

#[test]
fn scene_info_reports_the_default_scene() {
    let v = json(&run(bin().arg("scene-info").arg(scene()).arg("--json")));
    // The committed fixture (data/README.md: citygen mixed --seed 1 --buildings 24) counted by the gltf
    // crate, not by atlastree's importer: 1322.
    let triangles = crate::fixtures::gltf_count::triangles(&scene());
    assert_eq!(triangles, 1322, "the fixture changed");
    assert_eq!(v["triangles"], triangles, "{v}");
    assert_eq!(v["up"], "Y");
    let text = run(bin().arg("scene-info").arg(scene()));
    let s = String::from_utf8_lossy(&text.stdout);
    assert!(
        s.contains(&format!("triangles {triangles}")) && s.contains("planarity"),
        "{s}"
    );
}

#[test]
fn the_avx2_kernels_and_the_scalar_rules_write_the_same_file() {
    // `ATLASTREE_SCALAR` turns the AVX2 twins off (sRGB decode and encode, the BC1 error measure): the
    // default scene with its alpha materials, BC1 (opaque) and BC3 (alpha) blocks, byte for byte.
    #[cfg(target_arch = "x86_64")]
    let avx2 = std::arch::is_x86_feature_detected!("avx2");
    #[cfg(not(target_arch = "x86_64"))]
    let avx2 = false;
    if !avx2 {
        eprintln!(
            "NOTE: this CPU has no AVX2, so both builds take the scalar rules: the comparison checks only \
             that a build is deterministic"
        );
    }
    let dir = tempfile::tempdir().unwrap();
    let build = |name: &str, scalar: bool| {
        let out = dir.path().join(name);
        let mut cmd = bin();
        cmd.args(["build", "--d-min-ratio", "10", "--compress", "bc1", "-o"])
            .arg(&out)
            .arg(scene());
        if scalar {
            cmd.env("ATLASTREE_SCALAR", "1");
        } else {
            cmd.env_remove("ATLASTREE_SCALAR");
        }
        let o = run(&mut cmd);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read(out).unwrap()
    };
    let (simd, scalar) = (
        build("simd.atlastree", false),
        build("scalar.atlastree", true),
    );
    assert!(simd.len() > 1 << 20, "{} bytes", simd.len());
    assert!(simd == scalar, "the two paths wrote different files");
}

#[test]
fn build_then_inspect_verify() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    // The defaults keep the 2-Mtexel district in one leaf scaled to fit (its originals are within the
    // 16-atlas budget): one node per tree, the opaque leaf scaled below 1.
    let d = build_json(&out, &["--atlas-size", "512"]);
    let t0 = &d["trees"][0];
    assert_eq!(
        (t0["nodes"].as_u64(), t0["depth"].as_u64()),
        (Some(1), Some(0)),
        "{d}"
    );
    assert_eq!(t0["leaf_reasons"]["scaled"], 1, "{d}");
    assert!(
        t0["leaf_reasons"]["scale_min"].as_f64().unwrap() < 1.0,
        "{d}"
    );
    // A 2-atlas budget splits it into a multi-level tree.
    let b = build_json(&out, &["--atlas-size", "512", "--leaf-originals", "2"]);
    let trees = b["trees"].as_array().unwrap();
    assert_eq!(
        trees.len(),
        2,
        "opaque + alpha tree (the scene has MASK and BLEND materials)"
    );
    let scene_tris: u64 = trees.iter().map(|t| t["triangles"].as_u64().unwrap()).sum();
    assert_eq!(scene_tris, crate::fixtures::gltf_count::triangles(&scene()));
    // The paging file gets the permissions of a plain `File::create` (0o644 less the umask), not the
    // temp file's private 0o600.
    #[cfg(unix)]
    {
        use std::os::unix::fs::PermissionsExt;
        let plain = dir.path().join("plain");
        std::fs::File::create(&plain).unwrap();
        let mode = |p: &std::path::Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
        assert_eq!(mode(&out), mode(&plain));
    }
    assert!(trees[0]["depth"].as_u64().unwrap() >= 2, "{b}");
    let v = json(&run(bin()
        .args(["inspect", "--verify", "--json"])
        .arg(&out)));
    assert_eq!(v["verify"]["violation_count"], 0, "{v}");
    assert_eq!(v["verify"]["ok"], true, "{v}");
    // The multi-level tree's inner atlases are checked against their children.
    assert!(
        v["verify"]["inner_quadrants_checked"].as_u64() > Some(0),
        "{v}"
    );
    // The build's total counts its import (it left it out: the stages summed to more).
    let stages: f64 = b["timings"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|t| t[0] != "total")
        .map(|t| t[1].as_f64().unwrap())
        .sum();
    let total = b["timings"]
        .as_array()
        .unwrap()
        .iter()
        .find(|t| t[0] == "total")
        .and_then(|t| t[1].as_f64())
        .unwrap();
    assert!(stages <= total + 1e-3, "stages {stages} s, total {total} s");
    // simulate --json: stdout is the JSON alone (the header and the files written go to stderr).
    let sim = json(&run(bin()
        .args(["simulate", "--json", "--out"])
        .arg(dir.path().join("sim"))
        .arg(&out)));
    let runs = sim.as_array().expect("an array of runs");
    assert!(
        !runs.is_empty() && runs.iter().all(|r| r["run"].is_string()),
        "{sim}"
    );
    // `--out` a link to a folder not made yet: made where the link points, as `export -o` does
    // (`create_dir_all` of the link failed with "File exists"; fault hunt, session 38).
    #[cfg(unix)]
    {
        let link = dir.path().join("sim_link");
        std::os::unix::fs::symlink("sim_target", &link).unwrap();
        let o = run(bin()
            .args(["simulate", "--frames", "5", "--out"])
            .arg(&link)
            .arg(&out));
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        assert!(dir.path().join("sim_target/summary.csv").is_file());
    }
    assert_eq!(v["inspect"]["blocks"], b["blocks"]);
    let enabled = v["inspect"]["enabled"].to_string();
    assert!(enabled.contains("alpha tree: on"), "{enabled}");

    // A corrupt block: verify names it and exits 1.
    let mut bytes = std::fs::read(&out).unwrap();
    let n = bytes.len();
    bytes[n - 100] ^= 0x5a;
    std::fs::write(&out, &bytes).unwrap();
    let o = run(bin().args(["inspect", "--verify"]).arg(&out));
    assert_eq!(o.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&o.stdout).contains("checksum mismatch"));
    // A truncated file: under --verify --json the schema of a file that opens (`ok`, `violations`),
    // exit 1; without --verify a clear error naming the file, exit 2.
    std::fs::write(&out, &bytes[..1000]).unwrap();
    let o = run(bin().args(["inspect", "--verify", "--json"]).arg(&out));
    assert_eq!(o.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).expect("JSON on stdout");
    assert_eq!(
        (&v["verify"]["ok"], &v["inspect"]),
        (&serde_json::json!(false), &serde_json::Value::Null),
        "{v}"
    );
    assert!(
        v["verify"]["violations"][0]
            .as_str()
            .unwrap()
            .contains("bytes"),
        "{v}"
    );
    let o = run(bin().arg("inspect").arg(&out));
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("city.atlastree") && e.contains("bytes"), "{e}");
}

/// `--materials` keeps the triangles of matching materials only (the paper's facades-only Berlin test):
/// scene-info counts them, `--decode` decodes exactly the images they use, `build` builds an opaque tree
/// over them alone (data/city's facades are opaque, so no alpha tree), and a pattern matching nothing is a
/// clear error naming the pattern, with no output file.
#[test]
fn materials_filter_and_decode_baseline() {
    let all = json(&run(bin().arg("scene-info").arg(scene()).arg("--json")));
    let mats = all["materials"].as_array().unwrap();
    let facade_tris: u64 = mats
        .iter()
        .filter(|m| m["name"].as_str().unwrap().starts_with("facade_"))
        .map(|m| m["triangles"].as_u64().unwrap())
        .sum();
    let facade_mats = mats
        .iter()
        .filter(|m| {
            m["name"].as_str().unwrap().starts_with("facade_")
                && m["triangles"].as_u64().unwrap() > 0
        })
        .count() as u64;
    assert!(facade_tris > 0 && facade_tris < 1322, "{facade_tris}");
    let v = json(&run(bin()
        .args([
            "scene-info",
            "--json",
            "--decode",
            "--materials",
            "facade_*",
        ])
        .arg(scene())));
    assert_eq!(v["triangles"].as_u64(), Some(facade_tris), "{v}");
    assert_eq!(
        v["materials"].as_array().map(|m| m.len() as u64),
        Some(facade_mats),
        "only the kept materials remain"
    );
    let d = &v["decode"];
    assert_eq!(
        d["images"].as_u64(),
        Some(facade_mats),
        "one facade image per facade material: {d}"
    );
    assert_eq!((&d["failures"], &d["fallbacks"]), (&0.into(), &0.into()));
    assert!(
        d["texels"].as_u64().unwrap() >= facade_mats * 64 * 64,
        "{d}"
    );
    assert!(d["seconds"].as_f64().unwrap() > 0.0);

    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("facades.atlastree");
    let b = build_json(&out, &["--atlas-size", "256", "--materials", "facade_*"]);
    let trees = b["trees"].as_array().unwrap();
    assert_eq!(trees.len(), 1, "facades are opaque: no alpha tree: {b}");
    assert_eq!(trees[0]["triangles"].as_u64(), Some(facade_tris));
    let i = json(&run(bin()
        .args(["inspect", "--verify", "--json"])
        .arg(&out)));
    assert_eq!(i["verify"]["violation_count"], 0, "{i}");
    let enabled = i["inspect"]["enabled"].to_string();
    assert!(
        enabled.contains("alpha tree and alpha pipelines: off"),
        "the dropped MASK/BLEND materials are not in the file: {enabled}"
    );

    let none = dir.path().join("none.atlastree");
    let o = run(bin()
        .args(["build", "--materials", "nothing_*", "-o"])
        .arg(&none)
        .arg(scene()));
    assert_eq!(o.status.code(), Some(2), "{o:?}");
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("nothing_*") && e.contains("scene.gltf"), "{e}");
    assert!(
        !e.contains("materials include: )") && e.contains("facade_"),
        "the error names some of the scene's materials: {e}"
    );
    assert!(!none.exists());
}

/// `scene-info --decode` counts the images the import could not find (drawn as the fallback checker)
/// apart: "decoded 55 images" with 0 failures read as 55 good images where 53 were missing (fault hunt,
/// session 32).
#[test]
fn decode_counts_missing_images_as_fallbacks() {
    let dir = tempfile::tempdir().unwrap();
    let gltf = crate::built::city_copy(dir.path());
    let mut missing = 0;
    let textures: Vec<_> = (std::fs::read_dir(dir.path().join("city/textures")).unwrap())
        .map(|e| e.unwrap().path())
        .collect();
    for texture in textures.iter().skip(1).step_by(2) {
        std::fs::remove_file(texture).unwrap();
        missing += 1;
    }
    let v = json(&run(bin()
        .args(["scene-info", "--json", "--decode"])
        .arg(&gltf)));
    let fallbacks = v["decode"]["fallbacks"].as_u64().unwrap();
    assert!(
        fallbacks > 0 && fallbacks <= missing,
        "{fallbacks} of {missing}: {v}"
    );
    let text = run(bin().args(["scene-info", "--decode"]).arg(&gltf));
    let text = String::from_utf8_lossy(&text.stdout);
    assert!(
        text.contains(&format!(
            "{fallbacks} of them missing or unreadable at import"
        )),
        "{text}"
    );
}

/// `build --compress bc1` next to an uncompressed build of the same scene: the compressed file is smaller by
/// the format's ratio, `inspect` names the formats (BC1 opaque, BC3 alpha) and bytes per block, and
/// `inspect --verify --reference` re-measures every atlas's PSNR against the uncompressed file and finds
/// it equal to the recorded one.
#[test]
fn build_compress_bc1_then_inspect_verify_reference() {
    let dir = tempfile::tempdir().unwrap();
    let build = |name: &str, compress: &str, more: &[&str]| {
        let out = dir.path().join(name);
        let b = json(&run(bin()
            .args(["build", "--d-min-ratio", "10", "--atlas-size", "256"])
            .args(more)
            .args(["--compress", compress, "--json", "-o"])
            .arg(&out)
            .arg(scene())));
        (out, b)
    };
    let (plain, pb) = build("none.atlastree", "none", &[]);
    let (bc1, cb) = build("bc1.atlastree", "bc1", &[]);
    assert_eq!(pb["blocks"], cb["blocks"], "same tree, same blocks");
    let (pt, ct) = (&pb["trees"], &cb["trees"]);
    assert_eq!(
        (ct[0]["format"].as_str(), ct[1]["format"].as_str()),
        (Some("Bc1"), Some("Bc3"))
    );
    assert_eq!(
        pt[0]["atlas_psnr_db"].as_f64(),
        Some(atlastree::texfmt::PSNR_CAP_DB),
        "lossless is the PSNR cap"
    );
    let psnr0 = ct[0]["atlas_psnr_db"].as_f64().unwrap();
    assert!((30.0..60.0).contains(&psnr0), "{psnr0}");
    let (ps, cs) = (
        pb["file_bytes"].as_u64().unwrap(),
        cb["file_bytes"].as_u64().unwrap(),
    );
    // BC1 is 1/8 and BC3 1/4 of RGBA8 per texel (small mips round up to a block, blocks to 4 KiB).
    assert!(cs * 4 < ps && cs * 9 > ps, "{cs} vs {ps}");

    let v = json(&run(bin()
        .args(["inspect", "--verify", "--json", "--reference"])
        .arg(&plain)
        .arg(&bc1)));
    assert_eq!(v["verify"]["violation_count"], 0, "{v}");
    let trees = v["inspect"]["trees"].as_array().unwrap();
    assert_eq!(trees[0]["bytes_per_block"], 8);
    assert_eq!(trees[1]["bytes_per_block"], 16);
    assert_eq!(trees[0]["atlas_psnr_db"].as_f64().unwrap(), psnr0);
    let atlases = v["verify"]["atlas_psnr"].as_array().unwrap();
    let nodes: u64 = trees.iter().map(|t| t["nodes"].as_u64().unwrap()).sum();
    assert_eq!(atlases.len() as u64, nodes, "one PSNR per stored atlas");
    for a in atlases {
        let (r, m) = (a["recorded_db"].as_f64(), a["measured_db"].as_f64());
        assert!(r.is_some() && r == m, "{a}");
    }
    // Text output names the format and the per-atlas PSNR.
    let o = run(bin().args(["inspect", "--verify"]).arg(&bc1));
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(
        s.contains("format bc1 (8 bytes per 4×4 texels)") && s.contains("atlas PSNR ("),
        "{s}"
    );
    // The reference must be uncompressed and of the same tree: the compressed file itself is refused as a
    // usage error, exit 2 (it was a violation of the intact file, exit 1).
    let o = run(bin()
        .args(["inspect", "--verify", "--reference"])
        .arg(&bc1)
        .arg(&bc1));
    assert_eq!(o.status.code(), Some(2));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("(not rgba8)"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    // A reference with a corrupt block: the violation says why (it said only "not comparable"); one that
    // cannot be opened is named as the reference, not as FILE.
    let corrupt = dir.path().join("corrupt.atlastree");
    let mut bytes = std::fs::read(&plain).unwrap();
    let block0 = atlastree::store::TreeFile::open(&plain).unwrap().blocks()[0].offset as usize;
    bytes[block0 + 64] ^= 0x5a;
    std::fs::write(&corrupt, &bytes).unwrap();
    let o = run(bin()
        .args(["inspect", "--verify", "--reference"])
        .arg(&corrupt)
        .arg(&bc1));
    let out = String::from_utf8_lossy(&o.stdout);
    assert_eq!(o.status.code(), Some(1));
    assert!(
        out.contains(
            "not comparable with the reference: the reference's block 0: checksum mismatch"
        ),
        "{out}"
    );
    // A reference built with another mip filter (not recorded in the file): every atlas differs, and the
    // first violation says the reference is likely another build's (it read as a corrupt file).
    let (kaiser, _) = build("kaiser.atlastree", "none", &["--filter", "kaiser"]);
    let o = bin()
        .args(["inspect", "--verify", "--json", "--reference"])
        .arg(&kaiser)
        .arg(&bc1)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(1));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    let first = v["verify"]["violations"][0].as_str().unwrap_or_default();
    assert!(
        first.starts_with(&format!(
            "all {nodes} compressed atlases differ from the reference"
        )) && first.contains("--filter"),
        "{v}"
    );
    // A reference built with another screen width: a usage error (exit 2) naming that parameter.
    let (other, _) = build("other.atlastree", "none", &["--screen-width", "801"]);
    let o = run(bin()
        .args(["inspect", "--verify", "--reference"])
        .arg(&other)
        .arg(&bc1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(2), "{err}");
    assert!(
        err.contains("its screen width 801 (this file: 800)") && !err.contains("d_min"),
        "{err}"
    );
    std::fs::write(&corrupt, &bytes[..4096]).unwrap();
    let o = run(bin()
        .args(["inspect", "--verify", "--reference"])
        .arg(&corrupt)
        .arg(&bc1));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(
        err.contains(&format!("opening the reference {}", corrupt.display())),
        "{err}"
    );
}

#[test]
fn bad_input_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.gltf");
    let o = run(bin().arg("scene-info").arg(&missing));
    assert_eq!(o.status.code(), Some(2));
    // One line naming the file once, its cause once.
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(
        stderr.trim_end(),
        format!(
            "error: {}: cannot read: No such file or directory (os error 2)",
            missing.display()
        ),
    );
    let missing_tree = dir.path().join("nope.atlastree");
    let o = run(bin().arg("inspect").arg(&missing_tree));
    assert_eq!(
        String::from_utf8_lossy(&o.stderr).trim_end(),
        format!(
            "error: opening {}: No such file or directory (os error 2)",
            missing_tree.display()
        ),
    );
    let broken = dir.path().join("broken.gltf");
    std::fs::write(
        &broken,
        b"{ \"asset\": { \"version\": \"2.0\" }, \"meshes\": [ {",
    )
    .unwrap();
    let out = dir.path().join("x.atlastree");
    let o = run(bin().arg("build").arg(&broken).arg("-o").arg(&out));
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("broken.gltf"));
    assert!(!out.exists());
    let o = run(bin()
        .args(["build", "--atlas-size", "1000", "-o"])
        .arg(&out)
        .arg(scene()));
    assert!(String::from_utf8_lossy(&o.stderr).contains("--atlas-size 1000"));
    // Commands that read a local paging file say so when given a URL (only render pages over HTTP).
    let url = "http://127.0.0.1:9/city.atlastree";
    for (command, args) in [
        ("inspect", vec!["inspect", url]),
        ("simulate", vec!["simulate", url]),
        ("export", vec!["export", "3dtiles", url, "-o", "tiles"]),
        ("serve", vec!["serve", url]),
    ] {
        let o = run(bin().current_dir(dir.path()).args(&args));
        assert_eq!(o.status.code(), Some(2), "{command}");
        assert_eq!(
            String::from_utf8_lossy(&o.stderr).trim_end(),
            format!(
                "error: {url}: `atlastree {command}` reads a local paging file, not a URL (`atlastree render URL` \
                 pages over HTTP; download the file for {command})"
            ),
        );
    }
    // The scheme in any case; another scheme is named, not "No such file or directory".
    let upper = "HTTP://127.0.0.1:9/city.atlastree";
    let o = run(bin().current_dir(dir.path()).args(["inspect", upper]));
    assert!(
        String::from_utf8_lossy(&o.stderr).contains("reads a local paging file, not a URL"),
        "{}",
        String::from_utf8_lossy(&o.stderr)
    );
    for args in [
        vec!["inspect", "ftp://127.0.0.1/city.atlastree"],
        vec!["render", "ftp://127.0.0.1/city.atlastree", "--out", "r"],
    ] {
        let o = run(bin().current_dir(dir.path()).args(&args));
        assert_eq!(o.status.code(), Some(2), "{args:?}");
        let e = String::from_utf8_lossy(&o.stderr);
        assert!(e.contains("unsupported URL scheme 'ftp'"), "{args:?}: {e}");
    }
}

/// Images the import replaced with the fallback checker are reported by the build (text and JSON), not
/// only by `scene-info`.
#[test]
fn build_reports_what_the_import_replaced() {
    let dir = tempfile::tempdir().unwrap();
    let city = scene().parent().unwrap().to_path_buf();
    let text = std::fs::read(scene()).unwrap();
    let mut doc: serde_json::Value = serde_json::from_slice(&text).unwrap();
    for img in doc["images"].as_array_mut().unwrap() {
        let abs = city.join(img["uri"].as_str().unwrap());
        img["uri"] = serde_json::json!(abs.display().to_string());
    }
    doc["images"][0]["uri"] = serde_json::json!("missing.png");
    // A JPEG cut to a third (a broken download): drawn as it decodes, and reported.
    let jpeg = (doc["images"].as_array().unwrap().iter())
        .position(|i| i["uri"].as_str().unwrap().ends_with(".jpg"))
        .unwrap();
    let whole = std::fs::read(doc["images"][jpeg]["uri"].as_str().unwrap()).unwrap();
    let cut = dir.path().join("cut.jpg");
    std::fs::write(&cut, &whole[..whole.len() / 3]).unwrap();
    doc["images"][jpeg]["uri"] = serde_json::json!(cut.display().to_string());
    std::fs::copy(city.join("scene.bin"), dir.path().join("scene.bin")).unwrap();
    let path = dir.path().join("scene.gltf");
    std::fs::write(&path, serde_json::to_vec(&doc).unwrap()).unwrap();
    let out = dir.path().join("x.atlastree");
    let o = run(bin()
        .args(["build", "--d-min-ratio", "10", "--atlas-size", "256", "-o"])
        .arg(&out)
        .arg(&path));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        stdout.contains(
            "  import: 2 warnings: 1 missing images (drawn with the magenta/black checker), 1 truncated images, 0 \
             primitives and 0 triangles skipped"
        ),
        "{stdout}"
    );
    assert!(stdout.contains("missing.png"), "{stdout}");
    assert!(
        stdout.contains(&format!(
            "({}): the data ends without its end marker (a JPEG's end-of-image, a PNG's IEND) or \
             holds fewer bytes than its JPEG frame header's size needs: a truncated or patched file?",
            cut.display()
        )),
        "{stdout}"
    );
    let report = build_json(&out, &[]);
    assert_eq!(
        report["import"]["missing_images"], 0,
        "the embedded city itself imports clean"
    );
    let o = run(bin()
        .args([
            "build",
            "--d-min-ratio",
            "10",
            "--atlas-size",
            "256",
            "--json",
            "-o",
        ])
        .arg(&out)
        .arg(&path));
    let report = json(&o);
    assert_eq!(report["import"]["missing_images"], 1);
    assert_eq!(report["import"]["truncated_images"], 1);
    assert_eq!(report["import"]["warnings_total"], 2);
}

#[test]
fn demo_runs_and_writes_pictures() {
    let dir = tempfile::tempdir().unwrap();
    let o = run(bin().args(["demo", "-q", "--out"]).arg(dir.path()));
    let s = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{s}\n{}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(s.contains("all invariants hold"), "{s}");
    for f in [
        "opaque-root-atlas.png",
        "opaque-leaves.png",
        "alpha-root-atlas.png",
    ] {
        let img = image::open(dir.path().join(f)).unwrap();
        assert!(img.width() >= 64, "{f}");
    }
}

/// A shard's output named by bytes that are not UTF-8 (a valid Unix file name) builds and merges (the
/// recorded command line panicked in `std::env::args`), and `simulate` with an `--out` under a regular
/// file is refused before its runs (it ran the whole grid, then failed).
#[cfg(unix)]
#[test]
fn a_non_utf8_shard_output_builds_and_simulate_refuses_its_out_early() {
    use std::os::unix::ffi::OsStrExt;
    let dir = tempfile::tempdir().unwrap();
    let out = dir
        .path()
        .join(std::ffi::OsStr::from_bytes(b"n\xffm.atlastree"));
    let o = run(bin()
        .args(["build", "--d-min-ratio", "10", "-q", "--shard", "0/1", "-o"])
        .arg(&out)
        .arg(scene()));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    // Its report, which the merge reads for its table, names the path lossily (serde refuses a
    // non-UTF-8 path: the report was an empty file, and `merge --json` failed after writing the merged
    // file; fault hunt, session 37).
    let mut report = out.clone().into_os_string();
    report.push(".shard-0-of-1.json");
    let text = std::fs::read(&report).unwrap();
    let v: serde_json::Value = serde_json::from_slice(&text).unwrap();
    assert!(v["path"].as_str().unwrap().contains("n\u{FFFD}m"), "{v}");
    let o = run(bin().args(["merge", "--json"]).arg(&out));
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let v: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
    assert_eq!(v["count"], 1, "{v}");
    assert!(atlastree::store::TreeFile::open(&out).is_ok());
    let taken = dir.path().join("taken");
    std::fs::write(&taken, b"x").unwrap();
    let o = run(bin()
        .args(["simulate", "--frames", "100000", "--out"])
        .arg(taken.join("x"))
        .arg(&out));
    let (stdout, stderr) = (
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr),
    );
    assert!(
        !o.status.success() && stderr.contains("taken exists and is not a folder"),
        "{stderr}"
    );
    // Refused before the grid's header (then its runs) is printed.
    assert!(
        !stdout.contains(" frames at "),
        "the grid started first: {stdout}"
    );
    // A missing shard's hint names the scene and the output byte for byte (`$'…\xff…'`; it printed
    // U+FFFD and named no file), and running it rebuilds the shard.
    let sub = dir.path().join(std::ffi::OsStr::from_bytes(b"s\xffd"));
    std::fs::create_dir(&sub).unwrap();
    let two = sub.join(std::ffi::OsStr::from_bytes(b"t\xffo.atlastree"));
    for i in 0..2 {
        let o = run(bin()
            .args([
                "build",
                "--d-min-ratio",
                "10",
                "-q",
                "--shard",
                &format!("{i}/2"),
                "-o",
            ])
            .arg(&two)
            .arg(scene()));
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    let missing = sub.join(std::ffi::OsStr::from_bytes(
        b"t\xffo.atlastree.shard-1-of-2",
    ));
    std::fs::remove_file(&missing).unwrap();
    let o = run(bin().args(["merge", "-q"]).arg(&two));
    let stderr = String::from_utf8_lossy(&o.stderr);
    let hint = stderr
        .split_once("rebuild it with: ")
        .map(|(_, h)| h.trim().to_string())
        .unwrap_or_default();
    assert!(
        !o.status.success() && hint.contains("\\xff") && !hint.contains('\u{FFFD}'),
        "{stderr}"
    );
    let o = run(Command::new("bash").args(["-c", &hint]));
    assert!(
        o.status.success(),
        "{hint}: {}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(missing.exists(), "{hint} did not rebuild the shard");
}
