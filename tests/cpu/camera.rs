//! Camera paths: JSON round trip, exact keyframes, clear errors for bad files, generated paths inside
//! their documented bounds.

use atlastree::camera::{CameraError, CameraPath, Ground, GroundError, Keyframe, PathKind};
use atlastree::scene::UpAxis;
use glam::{DVec2, DVec3};
use std::path::Path;

fn key(time: f64, eye: [f64; 3], target: [f64; 3], fov: f64) -> Keyframe {
    Keyframe {
        time,
        eye,
        target,
        fov,
    }
}

fn sample_path() -> CameraPath {
    CameraPath {
        keyframes: vec![
            key(0.0, [0.0, 100.0, 0.0], [10.0, 0.0, 10.0], 60.0),
            key(1.5, [20.0, 50.0, 5.0], [30.0, 0.0, 10.0], 70.0),
            key(4.0, [40.0, 1.7, -3.0], [60.0, 1.7, 0.0], 90.0),
            key(4.25, [41.0, 2.0, -3.5], [60.0, 2.0, 0.0], 90.0),
        ],
        up: [0.0, 0.0, 1.0],
        aspect: 1.25,
        near: 0.5,
        far: 2000.0,
    }
}

#[test]
fn json_round_trip_through_a_file() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let file = dir.path().join("path.json");
    let path = sample_path();
    path.save(&file).unwrap_or_else(|e| panic!("{e}"));
    let loaded = CameraPath::load(&file).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(loaded, path);
    // Generated paths round-trip bit-exactly too (serde_json prints shortest round-trip floats).
    let generated = CameraPath::overview_dive(
        DVec3::new(4.5e6, 31.3, 5.5e6),
        DVec3::new(4.51e6, 187.1, 5.513e6),
        UpAxis::Y,
    )
    .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        CameraPath::from_json(&generated.to_json(), Path::new("mem")).ok(),
        Some(generated)
    );
}

#[test]
fn optional_fields_take_documented_defaults() {
    let text =
        r#"{ "keyframes": [ { "time": 0, "eye": [1, 2, 3], "target": [1, 2, 0], "fov": 50 } ] }"#;
    let p = CameraPath::from_json(text, Path::new("mem")).unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(
        (p.up, p.aspect, p.near, p.far),
        ([0.0, 1.0, 0.0], 16.0 / 9.0, 0.25, 1.0e5)
    );
    // A single keyframe: every time gives it.
    for t in [-1.0, 0.0, 3.0, f64::NAN] {
        let c = p.sample(t);
        assert_eq!(
            (c.eye, c.target, c.fov_x_deg),
            (DVec3::new(1.0, 2.0, 3.0), DVec3::new(1.0, 2.0, 0.0), 50.0)
        );
    }
    assert_eq!(p.frames(30.0, 5).count(), 5);
}

#[test]
fn sampling_at_keyframe_times_returns_the_keyframes() {
    let p = sample_path();
    for k in &p.keyframes {
        let c = p.sample(k.time);
        assert_eq!(c.eye.to_array(), k.eye);
        assert_eq!(c.target.to_array(), k.target);
        assert_eq!(c.fov_x_deg, k.fov);
        assert_eq!(
            (c.up, c.aspect, c.near, c.far),
            (DVec3::Z, 1.25, 0.5, 2000.0)
        );
    }
    // Clamped outside, continuous inside (no jump larger than the motion allows over 1 ms).
    assert_eq!(p.sample(-5.0).eye.to_array(), p.keyframes[0].eye);
    assert_eq!(p.sample(99.0).eye.to_array(), p.keyframes[3].eye);
    let mut prev = p.sample(0.0).eye;
    for i in 1..=4250 {
        let e = p.sample(i as f64 * 1e-3).eye;
        assert!((e - prev).length() < 0.2, "jump at t = {} ms", i);
        prev = e;
    }
    // fov is linear: halfway between keyframes 0 and 1.
    assert!((p.sample(0.75).fov_x_deg - 65.0).abs() < 1e-12);
    // frames(): start + i / fps.
    let frames: Vec<_> = p.frames(2.0, 4).collect();
    assert_eq!(frames[3].eye.to_array(), p.keyframes[1].eye, "t = 1.5 s");
}

fn err_of(text: &str) -> CameraError {
    match CameraPath::from_json(text, Path::new("bad.json")) {
        Ok(p) => panic!("accepted {p:?}"),
        Err(e) => e,
    }
}

#[test]
fn bad_files_give_clear_errors() {
    let missing = CameraPath::load(Path::new("/nonexistent/dir/path.json"));
    assert!(
        matches!(missing, Err(CameraError::Io { .. })),
        "{missing:?}"
    );
    let msg = missing.err().map(|e| e.to_string()).unwrap_or_default();
    assert!(msg.contains("/nonexistent/dir/path.json"), "{msg}");

    let e = err_of("{ \"keyframes\": [ { \"time\": 0, \"eye\": [1, 2] ");
    assert!(matches!(e, CameraError::Json { line: 1, .. }), "{e}");
    let e = err_of(
        r#"{ "keyframes": [ { "time": 0, "eye": [0,0,0], "target": [1,0,0], "fov": null } ] }"#,
    );
    assert!(matches!(e, CameraError::Json { .. }), "{e}");
    assert!(e.to_string().starts_with("bad.json: "), "{e}");

    let e = err_of(r#"{ "keyframes": [] }"#);
    assert!(matches!(e, CameraError::NoKeyframes { .. }), "{e}");

    let kf = |t: f64, fov: f64| {
        format!(r#"{{ "time": {t}, "eye": [0, 10, 0], "target": [5, 0, 5], "fov": {fov} }}"#)
    };
    let e = err_of(&format!(
        r#"{{ "keyframes": [ {}, {}, {} ] }}"#,
        kf(0.0, 60.0),
        kf(2.0, 60.0),
        kf(1.0, 60.0)
    ));
    assert!(
        matches!(
            e,
            CameraError::Unsorted {
                keyframe: 2,
                previous: 1,
                time: 1.0,
                previous_time: 2.0,
                ..
            }
        ),
        "{e}"
    );
    assert!(e.to_string().contains("keyframe 2"), "{e}");
    let e = err_of(&format!(
        r#"{{ "keyframes": [ {}, {} ] }}"#,
        kf(1.0, 60.0),
        kf(1.0, 60.0)
    ));
    assert!(
        matches!(e, CameraError::Unsorted { keyframe: 1, .. }),
        "equal times: {e}"
    );
    let e = err_of(&format!(
        r#"{{ "keyframes": [ {}, {} ] }}"#,
        kf(0.0, 60.0),
        kf(1.0, 180.0)
    ));
    assert!(matches!(e, CameraError::BadFov { keyframe: 1, .. }), "{e}");
    // Narrower than 10⁻³° (the frame drew blank at 10⁻⁸°, with no warning): refused too.
    let e = err_of(&format!(
        r#"{{ "keyframes": [ {}, {} ] }}"#,
        kf(0.0, 60.0),
        kf(1.0, 1e-8)
    ));
    assert!(matches!(e, CameraError::BadFov { keyframe: 1, .. }), "{e}");
    // Eye and target equal, or 1e-300 apart (the difference's length underflows): no direction.
    for target in ["[0,1,0]", "[1e-300,1,1e-300]"] {
        let e = err_of(&format!(
            r#"{{ "keyframes": [ {{ "time": 0, "eye": [0,1,0], "target": {target}, "fov": 60 }} ] }}"#
        ));
        assert!(
            matches!(e, CameraError::DegenerateView { keyframe: 0, .. }),
            "{target}: {e}"
        );
    }
    let e = err_of(&format!(
        r#"{{ "keyframes": [ {} ], "near": 10, "far": 5 }}"#,
        kf(0.0, 60.0)
    ));
    // Both planes named (it blamed near alone: fault hunt, session 33).
    assert!(
        matches!(
            e,
            CameraError::NearNotBelowFar {
                near: 10.0,
                far: 5.0,
                ..
            }
        ) && e.to_string().contains("near is 10 and far is 5"),
        "{e}"
    );
    // A near so small that the projection's depth term is no normal f32 drew blank frames; 1e-30 draws.
    let e = err_of(&format!(
        r#"{{ "keyframes": [ {} ], "near": 1e-40, "far": 1000 }}"#,
        kf(0.0, 60.0)
    ));
    assert!(
        matches!(e, CameraError::NearUnderflows { .. }) && e.to_string().contains("larger near"),
        "{e}"
    );
    let tiny = format!(
        r#"{{ "keyframes": [ {} ], "near": 1e-30, "far": 1000 }}"#,
        kf(0.0, 60.0)
    );
    let p: atlastree::camera::CameraPath = serde_json::from_str(&tiny).unwrap();
    p.validate(Path::new("code")).unwrap();
    // A misspelled field was ignored (the path drawn with the default up, a keyframe's fov field lost).
    for (text, name) in [
        (format!(r#"{{ "keyframes": [ {} ], "upp": [0, 0, 1] }}"#, kf(0.0, 60.0)), "upp"),
        (
            r#"{ "keyframes": [ { "time": 0, "eye": [0,5,0], "target": [1,5,0], "fov": 60, "fvo": 90 } ] }"#.to_string(),
            "fvo",
        ),
    ] {
        let e = err_of(&text);
        assert!(
            matches!(e, CameraError::Json { .. }) && e.to_string().contains(&format!("unknown field `{name}`")),
            "{e}"
        );
    }
    // An up of length 0, or of a length that underflows.
    for up in ["[0, 0, 0]", "[0, 1e-300, 0]"] {
        let e = err_of(&format!(
            r#"{{ "keyframes": [ {} ], "up": {up} }}"#,
            kf(0.0, 60.0)
        ));
        assert!(matches!(e, CameraError::BadUp { .. }), "{up}: {e}");
    }
    // A short but representable direction is a view.
    let ok = r#"{ "keyframes": [ { "time": 0, "eye": [0,5,0], "target": [1e-100,5,0], "fov": 60 } ], "up": [0, 1e-100, 0] }"#;
    let p: atlastree::camera::CameraPath = serde_json::from_str(ok).unwrap();
    p.validate(Path::new("code")).unwrap();

    // NaN cannot be written in JSON; a path built in code is validated the same way.
    let mut p = sample_path();
    p.keyframes[2].eye[1] = f64::NAN;
    let e = p.validate(Path::new("code"));
    assert!(
        matches!(
            e,
            Err(CameraError::NonFinite {
                keyframe: 2,
                field: "eye.y",
                ..
            })
        ),
        "{e:?}"
    );
}

#[test]
fn path_kinds_parse() {
    assert_eq!(
        "overview-dive".parse::<PathKind>().ok(),
        Some(PathKind::OverviewDive)
    );
    assert_eq!("street".parse::<PathKind>().ok(), Some(PathKind::Street));
    assert_eq!("orbit".parse::<PathKind>().ok(), Some(PathKind::Orbit));
    assert_eq!(
        "a/b.JSON".parse::<PathKind>().ok(),
        Some(PathKind::File("a/b.JSON".into()))
    );
    let e = "spiral".parse::<PathKind>();
    assert!(
        matches!(&e, Err(CameraError::UnknownKind { given }) if given == "spiral"),
        "{e:?}"
    );
    for k in [PathKind::OverviewDive, PathKind::Street, PathKind::Orbit] {
        assert_eq!(k.to_string().parse::<PathKind>().ok(), Some(k));
    }
}

/// Scene bounds used for the generated-path checks: ordinary, huge coordinates, flat, tiny, each up axis.
fn scenes() -> Vec<(DVec3, DVec3, UpAxis)> {
    let mut v = Vec::new();
    for up in [UpAxis::X, UpAxis::Y, UpAxis::Z] {
        let swap = |p: DVec3| match up {
            UpAxis::X => DVec3::new(p.y, p.x, p.z),
            UpAxis::Y => p,
            UpAxis::Z => DVec3::new(p.x, p.z, p.y),
        };
        for (lo, hi) in [
            (
                DVec3::new(0.0, 34.0, 0.0),
                DVec3::new(10_000.0, 200.0, 10_000.0),
            ),
            (
                DVec3::new(4.5e6, 120.0, 5.5e6),
                DVec3::new(4.5e6 + 3000.0, 260.0, 5.5e6 + 1800.0),
            ),
            (DVec3::new(-50.0, 0.0, -20.0), DVec3::new(50.0, 0.0, 20.0)),
            (DVec3::new(0.0, 0.0, 0.0), DVec3::new(0.0, 0.0, 0.0)),
        ] {
            v.push((swap(lo), swap(hi), up));
        }
    }
    v
}

#[test]
fn generated_paths_stay_finite_and_inside_their_documented_bounds() {
    for (lo, hi, up) in scenes() {
        let (plo, phi) = (up.plane(lo), up.plane(hi));
        let (ground, top) = (up.height(lo), up.height(hi));
        let diag = (phi - plo).length().max(1.0);
        let centre = (plo + phi) * 0.5;
        let inside = |p: DVec2| p.cmpge(plo - 1e-6).all() && p.cmple(phi + 1e-6).all();
        let tol = 1e-6 * (1.0 + ground.abs());
        let ctx = format!("{lo} {hi} {up:?}");

        let dive = CameraPath::overview_dive(lo, hi, up).unwrap_or_else(|e| panic!("{ctx}: {e}"));
        let street = CameraPath::street(lo, hi, up).unwrap_or_else(|e| panic!("{ctx}: {e}"));
        let orbit = CameraPath::orbit(lo, hi, up).unwrap_or_else(|e| panic!("{ctx}: {e}"));
        for p in [&dive, &street, &orbit] {
            p.validate(Path::new("generated"))
                .unwrap_or_else(|e| panic!("{ctx}: {e}"));
            assert_eq!(p.up, up.vector().to_array());
        }
        let samples = |p: &CameraPath| {
            let (s, d) = (p.start(), p.duration());
            (0..=2000)
                .map(move |i| p.sample(s + d * i as f64 / 2000.0))
                .collect::<Vec<_>>()
        };
        let overview = (top - ground + 0.9 * diag).max(20.0);
        let mut dive_min = f64::INFINITY;
        let mut dive_max: f64 = 0.0;
        for c in samples(&dive) {
            assert!(c.eye.is_finite() && c.target.is_finite(), "{ctx}");
            let h = up.height(c.eye) - ground;
            assert!(
                h >= 1.7 - tol && h <= overview + tol,
                "{ctx}: dive height {h}"
            );
            assert!(
                inside(up.plane(c.eye)) && inside(up.plane(c.target)),
                "{ctx}: dive leaves the footprint"
            );
            let th = up.height(c.target);
            assert!(
                th >= ground - tol && th <= top + tol,
                "{ctx}: dive target height {th}"
            );
            assert!(
                c.far > (c.eye - c.target).length(),
                "{ctx}: target beyond the far plane"
            );
            dive_min = dive_min.min(h);
            dive_max = dive_max.max(h);
        }
        // It really dives: from the overview height down to street level.
        assert!((dive_min - 1.7).abs() <= tol, "{ctx}: lowest {dive_min}");
        assert!(
            (dive_max - overview).abs() <= tol,
            "{ctx}: highest {dive_max}"
        );
        for c in samples(&street) {
            assert!(c.eye.is_finite() && c.target.is_finite(), "{ctx}");
            let h = up.height(c.eye) - ground;
            assert!(
                (1.7 - tol..=10.0 + tol).contains(&h),
                "{ctx}: street height {h}"
            );
            assert!(
                inside(up.plane(c.eye)),
                "{ctx}: street leaves the footprint"
            );
        }
        assert!(street.duration() >= 10.0);
        for c in samples(&orbit) {
            assert!(c.eye.is_finite() && c.target.is_finite(), "{ctx}");
            let h = up.height(c.eye) - ground;
            assert!((h - 0.3 * diag).abs() <= tol, "{ctx}: orbit height {h}");
            let r = (up.plane(c.eye) - centre).length() / diag;
            assert!(
                (0.495..=0.5025).contains(&r),
                "{ctx}: orbit radius {r} diagonals"
            );
        }
    }
}

#[test]
fn generated_paths_reject_bad_bounds() {
    let e = CameraPath::orbit(DVec3::ONE, DVec3::ZERO, UpAxis::Y);
    assert!(
        matches!(e, Err(CameraError::BadBounds { kind: "orbit", .. })),
        "{e:?}"
    );
    let e = CameraPath::street(DVec3::ZERO, DVec3::new(1.0, f64::NAN, 1.0), UpAxis::Y);
    assert!(
        matches!(e, Err(CameraError::BadBounds { kind: "street", .. })),
        "{e:?}"
    );
    let e = PathKind::OverviewDive.resolve(&Ground::flat(
        DVec3::splat(f64::INFINITY),
        DVec3::splat(f64::INFINITY),
        UpAxis::Z,
    ));
    assert!(
        matches!(
            e,
            Err(CameraError::BadBounds {
                kind: "overview-dive",
                ..
            })
        ),
        "{e:?}"
    );
}

#[test]
fn resolve_with_derives_the_ground_only_for_generated_paths() {
    let dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let file = dir.path().join("path.json");
    sample_path().save(&file).unwrap_or_else(|e| panic!("{e}"));
    let failing = || Err(GroundError::NoGeometry);
    // A JSON path never asks for the ground.
    let loaded = PathKind::File(file.clone())
        .resolve_with(|| panic!("the ground was derived for a JSON path"))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(loaded, sample_path());
    // A generated one does, and says which path could not get it.
    for kind in [PathKind::OverviewDive, PathKind::Street, PathKind::Orbit] {
        let e = kind.resolve_with(failing);
        assert!(
            matches!(&e, Err(CameraError::Ground { kind: k, source: GroundError::NoGeometry }) if *k == kind),
            "{e:?}"
        );
        let msg = e.err().map(|e| e.to_string()).unwrap_or_default();
        assert!(msg.contains(&kind.to_string()), "{msg}");
    }
    // Over a flat ground resolve gives the bounds-only paths.
    let (lo, hi) = (DVec3::new(0.0, 34.0, 0.0), DVec3::new(800.0, 90.0, 300.0));
    let flat = Ground::flat(lo, hi, UpAxis::Y);
    let pairs = [
        (
            PathKind::OverviewDive,
            CameraPath::overview_dive(lo, hi, UpAxis::Y),
        ),
        (PathKind::Street, CameraPath::street(lo, hi, UpAxis::Y)),
        (PathKind::Orbit, CameraPath::orbit(lo, hi, UpAxis::Y)),
    ];
    for (kind, expect) in pairs {
        let got = kind.resolve_with(|| Ok(flat.clone()));
        assert_eq!(got.ok(), expect.ok(), "{kind}");
    }
}
