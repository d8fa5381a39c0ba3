//! The binary on the embedded default scene: scene-info, build, inspect --verify, demo, and clear errors on
//! bad input (a missing file, a corrupt paging file) with a non-zero exit and no panic.

use std::path::PathBuf;
use std::process::{Command, Output};

fn bin() -> Command {
    Command::new(env!("CARGO_BIN_EXE_atlastree"))
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

#[test]
fn scene_info_reports_the_default_scene() {
    let v = json(&run(bin().arg("scene-info").arg(scene()).arg("--json")));
    // Counts of the committed fixture (data/README.md: citygen mixed --seed 1 --buildings 24).
    assert_eq!(v["triangles"], 1322, "{v}");
    assert_eq!(v["up"], "Y");
    let text = run(bin().arg("scene-info").arg(scene()));
    let s = String::from_utf8_lossy(&text.stdout);
    assert!(
        s.contains("triangles 1322") && s.contains("planarity"),
        "{s}"
    );
}

#[test]
fn build_then_inspect_verify() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    let b = json(&run(bin()
        .args([
            "build",
            "--d-min-ratio",
            "10",
            "--atlas-size",
            "512",
            "--json",
            "-o",
        ])
        .arg(&out)
        .arg(scene())));
    let trees = b["trees"].as_array().unwrap();
    assert_eq!(
        trees.len(),
        2,
        "opaque + alpha tree (the scene has MASK and BLEND materials)"
    );
    let scene_tris: u64 = trees.iter().map(|t| t["triangles"].as_u64().unwrap()).sum();
    assert_eq!(scene_tris, 1322);
    assert!(trees[0]["depth"].as_u64().unwrap() >= 2, "{b}");
    let v = json(&run(bin()
        .args(["inspect", "--verify", "--json"])
        .arg(&out)));
    assert_eq!(v["verify"]["violation_count"], 0, "{v}");
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
    // A truncated file: a clear error naming the file, exit 2.
    std::fs::write(&out, &bytes[..1000]).unwrap();
    let o = run(bin().arg("inspect").arg(&out));
    assert_eq!(o.status.code(), Some(2));
    let e = String::from_utf8_lossy(&o.stderr);
    assert!(e.contains("city.atlastree") && e.contains("bytes"), "{e}");
}

#[test]
fn bad_input_is_a_clear_error() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("nope.gltf");
    let o = run(bin().arg("scene-info").arg(&missing));
    assert_eq!(o.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&o.stderr).contains("nope.gltf"));
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
