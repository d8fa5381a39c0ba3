//! Builds survive faults (issue 23): the real binary building `data/city` is killed at seeded moments,
//! runs out of file size, races another build of the same output, and replaces a file a reader maps. Each
//! time the output is absent or the complete file (byte-identical to a reference build), no temp file is
//! left for the next build to trip on, and the next build succeeds byte for byte.

use atlastree::inspect;
use atlastree::store::{LoadMode, TreeFile};
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::sync::OnceLock;
use std::time::{Duration, Instant};

fn scene() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("data/city/scene.gltf")
}

/// `atlastree build` of `data/city` at 256² atlases into `out` (a few seconds in release).
fn build_args(out: &Path, atlas: u32) -> Vec<String> {
    let mut args: Vec<String> = ["build", "--d-min-ratio", "10", "--atlas-size"]
        .map(String::from)
        .into();
    args.push(atlas.to_string());
    args.push("-o".into());
    args.push(out.display().to_string());
    args.push(scene().display().to_string());
    args
}

fn build_cmd(out: &Path) -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_atlastree"));
    c.args(build_args(out, 256))
        .stdout(Stdio::null())
        .stderr(Stdio::piped());
    c
}

fn run_ok(cmd: &mut Command) -> Output {
    let out = cmd.output().expect("spawn atlastree");
    assert!(
        out.status.success(),
        "exit {:?}: {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

/// The reference build's bytes and how long it took.
fn reference() -> &'static (Vec<u8>, Duration) {
    static REF: OnceLock<(Vec<u8>, Duration)> = OnceLock::new();
    REF.get_or_init(|| {
        let dir = tempfile::tempdir().unwrap();
        let out = dir.path().join("city.atlastree");
        let t = Instant::now();
        run_ok(&mut build_cmd(&out));
        let took = t.elapsed();
        let bytes = std::fs::read(&out).unwrap();
        let file = TreeFile::from_bytes(&bytes).unwrap();
        assert!(inspect::verify(&file).ok());
        (bytes, took)
    })
}

/// The temp files of `out` in its directory (`.<name>.tmp.*`).
fn temps(out: &Path) -> Vec<String> {
    let prefix = format!(".{}.tmp.", out.file_name().unwrap().to_string_lossy());
    let mut v: Vec<String> = std::fs::read_dir(out.parent().unwrap())
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.starts_with(&prefix))
        .collect();
    v.sort();
    v
}

/// The output is absent, or complete and equal to the reference.
fn absent_or_complete(out: &Path, reference: &[u8], what: &str) -> bool {
    match std::fs::read(out) {
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => false,
        Err(e) => panic!("{what}: {e}"),
        Ok(bytes) => {
            assert!(
                bytes == reference,
                "{what}: output differs from the reference ({} bytes)",
                bytes.len()
            );
            true
        }
    }
}

fn splitmix64(state: &mut u64) -> u64 {
    *state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *state;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

#[test]
fn killed_build_leaves_nothing_or_the_whole_file_and_the_next_build_succeeds() {
    let (reference, took) = reference();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    // 40 kill points: stratified over 0..1.25 × the reference build's time (one per stratum, seeded), so
    // the early stages, the block writes, the rename and just after it are all hit.
    let mut state = 23u64;
    let points = 40u64;
    let (mut complete, mut absent, mut stale_seen) = (0, 0, 0);
    let mut window = *took;
    for k in 0..points {
        let u = (k as f64 + (splitmix64(&mut state) >> 11) as f64 / (1u64 << 53) as f64)
            / points as f64;
        // The window follows the load: the other tests of this binary run beside it, so each following
        // build's own time (measured below) stretches it when builds got slower than the reference.
        let delay = window.mul_f64(1.25 * u);
        let _ = std::fs::remove_file(&out);
        let mut child = build_cmd(&out).stderr(Stdio::null()).spawn().unwrap();
        std::thread::sleep(delay);
        let _ = child.kill(); // SIGKILL; an error means it had already exited
        let status = child.wait().unwrap();
        let what = format!("kill point {k} at {delay:?} ({status})");
        if absent_or_complete(&out, reference, &what) {
            complete += 1;
        } else {
            absent += 1;
        }
        stale_seen += temps(&out).len();
        // The next build cleans up after the killed one and writes the same bytes.
        let started = std::time::Instant::now();
        run_ok(&mut build_cmd(&out));
        window = window.max(started.elapsed());
        assert!(
            std::fs::read(&out).unwrap() == *reference,
            "{what}: next build differs"
        );
        assert_eq!(
            temps(&out),
            Vec::<String>::new(),
            "{what}: temps after the next build"
        );
    }
    println!(
        "kill test: {points} kill points over 1.25 × {took:?} (window grown to {window:?} by load): {absent} left no file, {complete} the complete \
         file; {stale_seen} stale temps left by killed builds, all removed by the next build"
    );
    // The kills landed both before the rename (no file) and after it (the complete file).
    assert!(
        absent > 0 && complete > 0,
        "{absent} absent, {complete} complete"
    );
}

/// Spawns `build` (stderr piped), sends `signal` (`kill`'s spelling, e.g. "-INT") once its temp file
/// beside `out` exists, and waits for it.
fn signal_while_writing(build: &mut Command, out: &Path, signal: &str) -> Output {
    let child = build.stderr(Stdio::piped()).spawn().unwrap();
    let started = std::time::Instant::now();
    while temps(out).is_empty() {
        assert!(
            started.elapsed() < std::time::Duration::from_secs(60),
            "no temp file within 60 s"
        );
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    let sent = Command::new("kill")
        .args([signal, &child.id().to_string()])
        .status()
        .unwrap();
    assert!(sent.success(), "kill {signal}");
    child.wait_with_output().unwrap()
}

/// Ctrl-C or SIGTERM (a scheduler cancelling a job) while the paging file is being written: the process
/// ends by that signal (so a shell loop stops; `$?` 130, 143), removes its temp file itself (a SIGKILLed
/// one leaves it to the next build, above) and says so, and no output appears. The build is BC7 so it is
/// still writing when the signal comes.
#[test]
fn interrupted_build_removes_its_temp_file_and_ends_by_the_signal() {
    use std::os::unix::process::ExitStatusExt;
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    for (signal, number) in [("-INT", 2), ("-TERM", 15)] {
        let mut build = build_cmd(&out);
        build.args(["--compress", "bc7"]);
        let output = signal_while_writing(&mut build, &out, signal);
        let status = output.status;
        assert_eq!(status.signal(), Some(number), "{signal}: {status}");
        // Said, not silent: the removed temp file counted.
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert!(
            stderr
                .contains("interrupted: stopped before finishing; 1 unfinished output(s) removed"),
            "{signal}: {stderr}"
        );
        assert_eq!(temps(&out), Vec::<String>::new(), "{signal}: temp left");
        assert!(!out.exists(), "{signal}: an output appeared");
    }
}

/// A signal the build was started with ignored stays ignored: `nohup` ignores SIGHUP, and a logout ended
/// a nohup'd build (review, session 36). The build goes on and writes its file.
#[test]
fn a_signal_ignored_at_start_stays_ignored() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    let mut args = vec![
        "-c".to_string(),
        "trap '' HUP; exec \"$0\" \"$@\"".to_string(),
    ];
    args.push(env!("CARGO_BIN_EXE_atlastree").into());
    args.extend(build_args(&out, 256));
    args.extend(["--compress".into(), "bc7".into()]);
    let mut build = Command::new("bash");
    build.args(&args).stdout(Stdio::null());
    let output = signal_while_writing(&mut build, &out, "-HUP");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{}: {stderr}", output.status);
    assert!(!stderr.contains("interrupted"), "{stderr}");
    assert!(out.is_file(), "the build finished");
}

/// Runs the build under `ulimit -f 1024` (1 MiB or 512 KiB, by the shell's unit). SIGXFSZ keeps the
/// shell's default disposition (kill): the tool ignores it itself (`cli::os_limits`), so the write fails
/// with EFBIG instead of the process being killed without a word.
fn build_limited(out: &Path) -> Output {
    let mut script = String::from("ulimit -f 1024; exec \"$0\"");
    for i in 0..build_args(out, 256).len() {
        script.push_str(&format!(" \"${}\"", i + 1));
    }
    Command::new("sh")
        .arg("-c")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_atlastree"))
        .args(build_args(out, 256))
        .stdout(Stdio::null())
        .output()
        .unwrap()
}

#[test]
fn file_size_limit_fails_clearly_and_leaves_no_partial_file() {
    let (reference, _) = reference();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    let failed = build_limited(&out);
    let stderr = String::from_utf8_lossy(&failed.stderr);
    assert_eq!(failed.status.code(), Some(2), "{}: {stderr}", failed.status);
    assert!(!stderr.contains("panicked"), "{stderr}");
    let want = format!("writing {} failed", out.display());
    assert!(stderr.contains(&want), "{stderr}");
    assert!(stderr.contains("File too large"), "{stderr}");
    assert!(!out.exists(), "no output file");
    assert_eq!(temps(&out), Vec::<String>::new(), "temp removed");
    // An existing output is kept as it was.
    std::fs::write(&out, reference).unwrap();
    let failed = build_limited(&out);
    assert_eq!(failed.status.code(), Some(2));
    assert!(
        std::fs::read(&out).unwrap() == *reference,
        "old file intact"
    );
    assert_eq!(temps(&out), Vec::<String>::new());
    println!(
        "disk-full test: exit 2, {}",
        stderr.lines().last().unwrap_or("")
    );
}

#[test]
fn concurrent_builds_of_one_output_leave_one_complete_file() {
    let (reference, _) = reference();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    let children: Vec<_> = (0..3).map(|_| build_cmd(&out).spawn().unwrap()).collect();
    for c in children {
        let o = c.wait_with_output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    }
    assert!(
        std::fs::read(&out).unwrap() == *reference,
        "the survivor is complete"
    );
    assert_eq!(temps(&out), Vec::<String>::new());
}

#[test]
fn mapped_reader_keeps_its_file_while_a_build_replaces_it() {
    let (reference, _) = reference();
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    std::fs::write(&out, reference).unwrap();
    let old = TreeFile::open_with(&out, LoadMode::Mmap).unwrap();
    assert!(old.is_mapped());
    // A different build (128² atlases) replaces the file while `old` maps it.
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_atlastree"));
    cmd.args(build_args(&out, 128)).stdout(Stdio::null());
    let child = cmd.spawn().unwrap();
    // Read and verify the old file while the build runs, and after.
    let mut passes = 0;
    let mut child = child;
    loop {
        old.verify_blocks().unwrap();
        passes += 1;
        if child.try_wait().unwrap().is_some() {
            break;
        }
    }
    assert!(child.wait().unwrap().success());
    assert!(inspect::verify(&old).ok(), "the old map still verifies");
    assert_eq!(old.params().atlas_size, 256);
    assert_eq!(old.file_len(), reference.len() as u64);
    let new = TreeFile::open(&out).unwrap();
    assert_eq!(
        new.params().atlas_size,
        128,
        "the path now holds the new build"
    );
    assert!(passes >= 1);
}

/// `-o` naming an input (the scene itself, a copy of it, a directory) is refused before any work and
/// leaves the file as it was; an existing paging file and an empty file are replaced as before.
#[test]
fn an_output_that_is_not_a_paging_file_is_never_replaced() {
    let (reference, _) = reference();
    let dir = tempfile::tempdir().unwrap();
    let gltf = dir.path().join("copy.gltf");
    std::fs::copy(scene(), &gltf).unwrap();
    let before = std::fs::read(&gltf).unwrap();
    for target in [gltf.clone(), dir.path().to_path_buf()] {
        let failed = build_cmd(&target).output().unwrap();
        let stderr = String::from_utf8_lossy(&failed.stderr);
        assert_eq!(failed.status.code(), Some(2), "{stderr}");
        let want = format!(
            "{} exists and is not an atlastree paging file",
            target.display()
        );
        assert!(stderr.contains(&want), "{stderr}");
        assert_eq!(temps(&target), Vec::<String>::new());
    }
    // A shard or the plan step refuses it too, before any work (the merge would write there).
    for step in ["plan", "0/2"] {
        let failed = build_cmd(&gltf).args(["--shard", step]).output().unwrap();
        let stderr = String::from_utf8_lossy(&failed.stderr);
        assert_eq!(failed.status.code(), Some(2), "--shard {step}: {stderr}");
        assert!(
            stderr.contains("is not an atlastree paging file"),
            "{stderr}"
        );
    }
    let beside: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(beside, ["copy.gltf"], "no plan or shard file written");
    assert!(
        std::fs::read(&gltf).unwrap() == before,
        "the glTF is intact"
    );
    // The store's check directly: what it says of each kind of file.
    let err = atlastree::store::check_replaceable(&gltf).unwrap_err();
    assert!(err.to_string().contains("JSON text: a glTF scene"), "{err}");
    let empty = dir.path().join("empty.atlastree");
    std::fs::write(&empty, b"").unwrap();
    run_ok(&mut build_cmd(&empty));
    assert!(
        std::fs::read(&empty).unwrap() == *reference,
        "empty file replaced"
    );
    run_ok(&mut build_cmd(&empty));
    assert!(
        std::fs::read(&empty).unwrap() == *reference,
        "paging file replaced"
    );
    // A folder that does not exist, or a file where the folder should be: refused before any work, whole
    // build, plan step and shard alike.
    let missing = dir.path().join("no/such/out.atlastree");
    let under_file = gltf.join("out.atlastree");
    for (target, what) in [
        (&missing, "does not exist"),
        (&under_file, "is not a folder"),
    ] {
        for shard in [None, Some("plan"), Some("1/2")] {
            let mut cmd = build_cmd(target);
            if let Some(step) = shard {
                cmd.args(["--shard", step]);
            }
            let failed = cmd.output().unwrap();
            let stderr = String::from_utf8_lossy(&failed.stderr);
            assert_eq!(failed.status.code(), Some(2), "{shard:?}: {stderr}");
            let want = format!(
                "{}: its folder {} {what}: create it first",
                target.display(),
                target.parent().unwrap().display()
            );
            assert!(stderr.contains(&want), "{shard:?}: {stderr}");
            assert!(
                !stderr.contains("rasterise"),
                "refused before any work: {stderr}"
            );
        }
    }
    assert!(!dir.path().join("no").exists());
}

/// A plan file whose tables fail their hash (found by the shard's streamed pass, after the header checks
/// a truncated plan fails) says what to do with it, as a truncated one does; removing it lets the shard plan
/// itself.
#[test]
fn a_corrupt_plan_says_to_make_it_again_or_remove_it() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("city.atlastree");
    run_ok(build_cmd(&out).args(["--shard", "plan"]));
    let plan = dir.path().join("city.atlastree.plan");
    let mut bytes = std::fs::read(&plan).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 0x10;
    std::fs::write(&plan, &bytes).unwrap();
    let failed = build_cmd(&out).args(["--shard", "0/2"]).output().unwrap();
    let stderr = String::from_utf8_lossy(&failed.stderr);
    assert_eq!(failed.status.code(), Some(2), "{stderr}");
    assert!(
        stderr.contains(&format!(
            "the plan {} is corrupt: make it again with `--shard plan`, or remove it",
            plan.display()
        )) && stderr.contains("checksum mismatch"),
        "{stderr}"
    );
    std::fs::remove_file(&plan).unwrap();
    run_ok(build_cmd(&out).args(["--shard", "0/2"]));
}

/// Image files that cannot be opened for the open-files limit stop the build with an error that says
/// so, at import or in the pixel pass, and leave no file: they were drawn as the magenta fallback and
/// the build exited 0 (fault hunt, session 38). At the limit where the scene file itself cannot be
/// opened the build fails naming it; with room, it builds.
#[test]
fn an_open_files_limit_stops_the_build_not_the_image() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("o.atlastree");
    let build = |limit: u32| {
        let mut c = Command::new("sh");
        c.arg("-c")
            .arg(format!("ulimit -n {limit} && exec \"$@\""))
            .arg("sh")
            .arg(env!("CARGO_BIN_EXE_atlastree"))
            .args(build_args(&out, 256))
            .env("RAYON_NUM_THREADS", "2")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .stderr(Stdio::piped());
        c.output().expect("spawn sh")
    };
    let (mut stopped, mut limit_said) = (0, 0);
    for limit in 6..=8 {
        let o = build(limit);
        let e = String::from_utf8_lossy(&o.stderr);
        if o.status.success() {
            assert!(!e.contains("Too many open files"), "ulimit -n {limit}: {e}");
            std::fs::remove_file(&out).unwrap();
            continue;
        }
        assert!(
            e.contains("the open-files limit is too low for this build")
                || e.contains("cannot read"),
            "ulimit -n {limit}: {e}"
        );
        assert!(!e.contains("magenta"), "ulimit -n {limit}: {e}");
        assert!(!out.exists(), "ulimit -n {limit}: an output was left");
        stopped += 1;
        limit_said += usize::from(e.contains("the open-files limit is too low for this build"));
    }
    assert!(stopped > 0, "no limit from 6 to 8 stopped the build");
    assert!(
        limit_said > 0,
        "no limit from 6 to 8 stopped an image, only the scene file"
    );
    let o = build(1024);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
}
