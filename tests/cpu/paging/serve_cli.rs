//! The `serve` command from the command line: its help, serving until Ctrl-C, refusing a file that is not
//! a paging file.

use super::http::{fetch, fixture, quick};
use atlastree::ids::BlockId;
use atlastree::paging::{HttpSource, SourceError};
use std::time::{Duration, Instant};

fn bin() -> std::process::Command {
    std::process::Command::new(env!("CARGO_BIN_EXE_atlastree"))
}

#[test]
fn cli_serve_help_teaches() {
    let out = bin().args(["serve", "--help"]).output().unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    for word in ["--port", "--bind", "Range", "Ctrl-C"] {
        assert!(text.contains(word), "{word} missing from:\n{text}");
    }
}

#[test]
fn cli_serve_serves_until_ctrl_c() {
    use std::io::BufRead;
    let fx = fixture();
    let mut child = bin()
        .args(["serve", "--port", "0", "--json"])
        .arg(&fx.path)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    let mut line = String::new();
    let stdout = child.stdout.take().unwrap();
    std::io::BufReader::new(stdout)
        .read_line(&mut line)
        .unwrap();
    let v: serde_json::Value = serde_json::from_str(&line).expect("a JSON line");
    assert_eq!(v["blocks"], fx.file.blocks().len());
    assert_eq!(v["file_bytes"], fx.bytes.len());
    let url = v["url"].as_str().unwrap();
    let (remote, src) = HttpSource::open(url, quick()).unwrap();
    assert_eq!(
        fetch(&src, &remote, 1).unwrap(),
        fx.file.block(BlockId(1)).unwrap().into_owned()
    );
    let killed = std::process::Command::new("kill")
        .args(["-INT", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(killed.success());
    let t = Instant::now();
    let out = child.wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{:?}: {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(t.elapsed() < Duration::from_secs(5));
    let e = fetch(&src, &remote, 1).unwrap_err();
    assert!(matches!(e, SourceError::Transport { .. }), "{e}");

    // A file that is not a paging file is refused before serving.
    let bad = fx.path.with_extension("bad");
    std::fs::write(&bad, b"not a tree").unwrap();
    let out = bin()
        .args(["serve", "--port", "0"])
        .arg(&bad)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("city.bad"));
}
