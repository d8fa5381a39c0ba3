//! Target `camera_path`: structure-aware mutants of a valid camera-path JSON read by
//! [`atlastree::camera::CameraPath::from_json`] (what `--path P.json` loads). A mutant is one to three
//! JSON edits ([`crate::json_mut`]) or, one case in eight, the text cut short. An accepted path must
//! sample to a usable camera at every time (finite eye and target, field of view in (0°, 180°)), else
//! the case is an AcceptedCorruption.

use crate::harness::{self, Verdict};
use crate::json_mut::{self, Paths};
use arbitrary::Unstructured;
use atlastree::camera::CameraPath;
use serde_json::Value;
use std::path::Path;
use std::sync::OnceLock;

/// Cases per CI run.
const DEFAULT_CASES: u64 = 20_000;

/// First line of an edit-script corpus file.
const MAGIC: &str = "#camera-path-edits";

/// A valid path: four keyframes over a city block, every optional field given.
const BASE: &str = r#"{
  "keyframes": [
    { "time": 0.0, "eye": [0.0, 120.0, -200.0], "target": [0.0, 0.0, 0.0], "fov": 60.0 },
    { "time": 2.5, "eye": [80.0, 60.0, -90.0], "target": [10.0, 5.0, 0.0], "fov": 55.0 },
    { "time": 4.0, "eye": [60.0, 1.7, -20.0], "target": [60.0, 1.7, 40.0], "fov": 70.0 },
    { "time": 9.0, "eye": [-40.0, 30.0, 50.0], "target": [0.0, 0.0, 0.0], "fov": 45.0 }
  ],
  "up": [0.0, 1.0, 0.0],
  "aspect": 1.7777,
  "near": 0.25,
  "far": 5000.0
}"#;

fn base() -> &'static (Value, Paths) {
    static B: OnceLock<(Value, Paths)> = OnceLock::new();
    B.get_or_init(|| {
        let v: Value = serde_json::from_str(BASE).expect("base path is JSON");
        let p = json_mut::paths(&v);
        (v, p)
    })
}

/// The mutant's text and expected refusal.
fn mutant(bytes: &[u8]) -> Option<(String, Option<String>)> {
    let (doc, paths) = base();
    let mut doc = doc.clone();
    if let Some(s) = json_mut::parse_script(bytes, MAGIC) {
        s.json.iter().for_each(|e| e.apply(&mut doc));
        return Some((doc.to_string(), s.expect));
    }
    let mut u = Unstructured::new(bytes);
    if u.ratio(1, 8).ok()? {
        let cut = u.int_in_range(0..=BASE.len()).ok()?;
        return Some((BASE.get(..cut).unwrap_or(BASE).to_string(), None));
    }
    for _ in 0..u.int_in_range(1..=3).ok()? {
        json_mut::random_edit(&mut u, &doc, paths)
            .ok()?
            .apply(&mut doc);
    }
    Some((doc.to_string(), None))
}

fn run_one(bytes: &[u8]) -> Verdict {
    let Some((text, expect)) = mutant(bytes) else {
        return Verdict::Skipped;
    };
    let verdict = match CameraPath::from_json(&text, Path::new("fuzz.json")) {
        Err(e) => Verdict::Refused(e.to_string()),
        Ok(path) => {
            let (start, end) = (path.start(), path.start() + path.duration());
            let mut times: Vec<f64> = path.keyframes.iter().map(|k| k.time).collect();
            times.extend(path.keyframes.windows(2).flat_map(|w| {
                let (a, b) = (w[0].time, w[1].time);
                [a + (b - a) * 0.25, a + (b - a) * 0.5, a + (b - a) * 0.999]
            }));
            times.extend([
                start - 1.0,
                end + 1.0,
                f64::NAN,
                f64::INFINITY,
                f64::NEG_INFINITY,
            ]);
            let bad = times.into_iter().find_map(|t| {
                let c = path.sample(t);
                let ok = c.eye.is_finite()
                    && c.target.is_finite()
                    && c.fov_x_deg > 0.0
                    && c.fov_x_deg < 180.0;
                (!ok).then(|| {
                    format!(
                        "sample({t}) = eye {} target {} fov {}",
                        c.eye, c.target, c.fov_x_deg
                    )
                })
            });
            match bad {
                Some(why) => Verdict::AcceptedCorruption(why),
                None => Verdict::Accepted,
            }
        }
    };
    json_mut::expect_refusal(verdict, expect.as_deref())
}

#[test]
fn camera_path() {
    let counts = harness::run("camera_path", DEFAULT_CASES, run_one);
    // Both outcomes occur: a base input that stopped working would make every case a refusal.
    assert!(counts.accepted > 0 && counts.refused > 0, "{counts:?}");
}
