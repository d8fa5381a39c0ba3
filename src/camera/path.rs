//! Keyframed camera paths: [`Keyframe`], [`CameraPath`] (JSON load / save / validate, sampling with a
//! monotone cubic) and [`PathKind`], the CLI's choice between a generated path and a JSON file.
//!
//! Units: seconds (keyframe times), world units (metres: eye and target), degrees (field of view). The
//! generated paths live in `generated` and fly over a [`Ground`].

use super::Camera;
use super::ground::{Ground, GroundError};
use glam::DVec3;
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// Everything that can go wrong loading, validating or generating a camera path.
#[derive(Debug, thiserror::Error)]
pub enum CameraError {
    #[error("{path}: cannot read camera path: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error("{path}: not a camera path (line {line}, column {column}): {source}")]
    Json {
        path: PathBuf,
        line: usize,
        column: usize,
        #[source]
        source: serde_json::Error,
    },
    #[error("{path}: a camera path needs at least 1 keyframe, found 0")]
    NoKeyframes { path: PathBuf },
    /// The file is a JSON array, not the object `{"keyframes": [...]}` (serde read an array as the
    /// struct's fields in order, and said "expected a sequence" of a sequence; fault hunt, session 38).
    #[error(
        "{path}: a camera path is a JSON object, {{\"keyframes\": [...]}}, not an array (a bare list of \
         keyframes goes under \"keyframes\")"
    )]
    NotAnObject { path: PathBuf },
    #[error("{path}: keyframe {keyframe}: {field} is not finite ({value})")]
    NonFinite {
        path: PathBuf,
        keyframe: usize,
        field: &'static str,
        value: f64,
    },
    #[error(
        "{path}: keyframe {keyframe}: time {time} s is not after keyframe {previous}'s time {previous_time} s (times must increase strictly)"
    )]
    Unsorted {
        path: PathBuf,
        keyframe: usize,
        time: f64,
        previous: usize,
        previous_time: f64,
    },
    #[error("{path}: keyframe {keyframe}: {field} is {value:e}, beyond ±{limit:e} ({unit})")]
    OutOfRange {
        path: PathBuf,
        keyframe: usize,
        field: &'static str,
        value: f64,
        limit: f64,
        unit: &'static str,
    },
    #[error(
        "{path}: keyframe {keyframe}: time {time} s is only {gap:e} s after keyframe {previous}'s (keyframes must be at least {MIN_KEYFRAME_GAP:e} s apart)"
    )]
    TooClose {
        path: PathBuf,
        keyframe: usize,
        time: f64,
        previous: usize,
        gap: f64,
    },
    #[error(
        "{path}: keyframe {keyframe}: field of view {fov}° is outside [{MIN_FOV_DEG}°, 180°) (narrower, f32 clip \
         coordinates cannot place the scene: the frame drew blank)"
    )]
    BadFov {
        path: PathBuf,
        keyframe: usize,
        fov: f64,
    },
    #[error(
        "{path}: keyframe {keyframe}: eye and target coincide (or lie so close that their difference has no \
         length in f64), the view direction is undefined"
    )]
    DegenerateView { path: PathBuf, keyframe: usize },
    #[error(
        "{path}: near is {near:e} (far {far}): the projection's depth term near·far/(far − near) is {term:e}, \
         below the smallest normal f32 ({min:e}), so every depth rounds alike and nothing is drawn; use a \
         larger near"
    )]
    NearUnderflows {
        path: PathBuf,
        near: f64,
        far: f64,
        term: f64,
        min: f64,
    },
    #[error("{path}: {field} is {value}, it must be finite and > 0 (and near < far)")]
    BadLens {
        path: PathBuf,
        field: &'static str,
        value: f64,
    },
    #[error("{path}: near is {near} and far is {far}: near must be less than far")]
    NearNotBelowFar { path: PathBuf, near: f64, far: f64 },
    #[error(
        "{path}: up vector {up:?} must be finite and non-zero, and long enough that its length is a number \
         (not below ~1e-154)"
    )]
    BadUp { path: PathBuf, up: [f64; 3] },
    #[error(
        "scene bounds {lo:?}..{hi:?} are not finite or not ordered; cannot generate a {kind} path"
    )]
    BadBounds {
        kind: &'static str,
        lo: [f64; 3],
        hi: [f64; 3],
    },
    #[error("{path}: cannot write camera path: {source}")]
    Write {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    #[error(
        "unknown camera path '{given}': expected overview-dive, street, orbit or a file ending in .json"
    )]
    UnknownKind { given: String },
    #[error("cannot derive the ground for the {kind} path: {source}")]
    Ground {
        kind: PathKind,
        #[source]
        source: GroundError,
    },
}

/// Largest |coordinate| of a keyframe's eye or target, world units (10⁶ km: beyond any scene, and far
/// enough from f64's range that the spline's differences and slopes stay finite).
pub(super) const MAX_COORDINATE: f64 = 1e9;
/// Largest |time| of a keyframe, seconds (about 30 years).
pub(super) const MAX_TIME: f64 = 1e9;
/// Narrowest field of view a keyframe takes, degrees: at 10⁻⁸° (a 10⁸× zoom) the frame drew blank in
/// both modes with no warning, at 10⁻⁶° partly; 10⁻³° draws right.
pub const MIN_FOV_DEG: f64 = 1e-3;
/// Smallest time between two keyframes, seconds (the spline divides by it).
pub(super) const MIN_KEYFRAME_GAP: f64 = 1e-6;

/// One keyframe: time, eye, target and horizontal field of view. An unknown field is refused (a
/// misspelled `"fvo"` was ignored without a word).
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Keyframe {
    /// Seconds from the start of the path.
    pub time: f64,
    pub eye: [f64; 3],
    pub target: [f64; 3],
    /// Horizontal field of view, degrees.
    pub fov: f64,
}

fn default_up() -> [f64; 3] {
    [0.0, 1.0, 0.0]
}
pub(super) fn default_aspect() -> f64 {
    16.0 / 9.0
}
pub(super) fn default_near() -> f64 {
    0.25
}
fn default_far() -> f64 {
    1.0e5
}

/// A keyframed camera path. JSON:
///
/// ```json
/// { "keyframes": [ { "time": 0.0, "eye": [x, y, z], "target": [x, y, z], "fov": 60.0 }, … ],
///   "up": [0, 1, 0], "aspect": 1.7778, "near": 0.25, "far": 100000.0 }
/// ```
///
/// `up` defaults to `[0, 1, 0]`, `aspect` to 16/9, `near` to 0.25 m and `far` to 100 km.
///
/// Sampling ([`CameraPath::sample`]) interpolates eye and target per coordinate with a monotone cubic
/// Hermite spline (Fritsch–Carlson tangents, PCHIP): C¹, through every keyframe exactly, and **never
/// outside the range of the two keyframes around `t` in any coordinate** (no overshoot: a path whose
/// keyframes are above the ground stays above it). The field of view is interpolated linearly. Times
/// outside the keyframes clamp to the first or last keyframe. An unknown field is refused, with its name
/// and the fields there are (a misspelled `"upp"` was ignored without a word).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CameraPath {
    pub keyframes: Vec<Keyframe>,
    #[serde(default = "default_up")]
    pub up: [f64; 3],
    #[serde(default = "default_aspect")]
    pub aspect: f64,
    #[serde(default = "default_near")]
    pub near: f64,
    #[serde(default = "default_far")]
    pub far: f64,
}

impl CameraPath {
    /// Reads and validates a path file.
    pub fn load(path: &Path) -> Result<CameraPath, CameraError> {
        let text = crate::util::read_text_file(path).map_err(|source| CameraError::Io {
            path: path.to_owned(),
            source,
        })?;
        CameraPath::from_json(&text, path)
    }

    /// Parses and validates JSON text; `origin` names the source in errors.
    pub fn from_json(text: &str, origin: &Path) -> Result<CameraPath, CameraError> {
        let body = text.trim_start_matches('\u{feff}').trim_start();
        if body.starts_with('[') {
            return Err(CameraError::NotAnObject {
                path: origin.to_owned(),
            });
        }
        let parsed: CameraPath =
            serde_json::from_str(text).map_err(|source| CameraError::Json {
                path: origin.to_owned(),
                line: source.line(),
                column: source.column(),
                source,
            })?;
        parsed.validate(origin)?;
        Ok(parsed)
    }

    /// Pretty JSON text of the path.
    pub fn to_json(&self) -> String {
        // Serialising plain numbers and vectors cannot fail; non-finite numbers become `null`, which
        // `validate` rejects on reading.
        serde_json::to_string_pretty(self).unwrap_or_default()
    }

    /// Writes the path as JSON, atomically (the old file or the new one, never a partial one).
    pub fn save(&self, path: &Path) -> Result<(), CameraError> {
        crate::util::write_atomic(path, (self.to_json() + "\n").as_bytes()).map_err(|source| {
            CameraError::Write {
                path: path.to_owned(),
                source,
            }
        })
    }

    /// Checks everything [`CameraPath::sample`] relies on (finite values, |eye|, |target| ≤
    /// [`MAX_COORDINATE`], |time| ≤ [`MAX_TIME`], times increasing by at least [`MIN_KEYFRAME_GAP`], a
    /// field of view in (0°, 180°), a usable lens and up vector), so every sample is finite; `origin`
    /// names the source in errors.
    pub fn validate(&self, origin: &Path) -> Result<(), CameraError> {
        let path = || origin.to_owned();
        if self.keyframes.is_empty() {
            return Err(CameraError::NoKeyframes { path: path() });
        }
        let up = DVec3::from_array(self.up);
        // `try_normalize` fails where the length underflows too (`[0, 1e-300, 0]`), not only at zero.
        if up.try_normalize().is_none() {
            return Err(CameraError::BadUp {
                path: path(),
                up: self.up,
            });
        }
        // Not `aspect`: frames take their viewport's, and the commands' help says a file's is not used
        // (a file was refused for it: fault hunt, session 35); [`CameraPath::sample`] keeps one usable.
        for (field, value) in [("near", self.near), ("far", self.far)] {
            if !(value.is_finite() && value > 0.0) {
                return Err(CameraError::BadLens {
                    path: path(),
                    field,
                    value,
                });
            }
        }
        if self.near >= self.far {
            // Both named: the old message blamed near alone (fault hunt, session 33).
            return Err(CameraError::NearNotBelowFar {
                path: path(),
                near: self.near,
                far: self.far,
            });
        }
        // The depth term of `Camera::projection` reaches the GPU as an f32; subnormal or zero, every
        // fragment's depth rounds alike (1e-40 drew blank frames without a word).
        let term = self.near * self.far / (self.far - self.near);
        let min = f64::from(f32::MIN_POSITIVE);
        if term < min {
            return Err(CameraError::NearUnderflows {
                path: path(),
                near: self.near,
                far: self.far,
                term,
                min,
            });
        }
        for (i, k) in self.keyframes.iter().enumerate() {
            let fields = [
                ("time", k.time),
                ("eye.x", k.eye[0]),
                ("eye.y", k.eye[1]),
                ("eye.z", k.eye[2]),
                ("target.x", k.target[0]),
                ("target.y", k.target[1]),
                ("target.z", k.target[2]),
                ("fov", k.fov),
            ];
            if let Some(&(field, value)) = fields.iter().find(|(_, v)| !v.is_finite()) {
                return Err(CameraError::NonFinite {
                    path: path(),
                    keyframe: i,
                    field,
                    value,
                });
            }
            let limits = [(MAX_TIME, "seconds")]
                .into_iter()
                .chain(std::iter::repeat_n((MAX_COORDINATE, "world units"), 6));
            if let Some((&(field, value), (limit, unit))) = fields
                .iter()
                .zip(limits)
                .find(|((_, v), (limit, _))| v.abs() > *limit)
            {
                return Err(CameraError::OutOfRange {
                    path: path(),
                    keyframe: i,
                    field,
                    value,
                    limit,
                    unit,
                });
            }
            if !(MIN_FOV_DEG..180.0).contains(&k.fov) {
                return Err(CameraError::BadFov {
                    path: path(),
                    keyframe: i,
                    fov: k.fov,
                });
            }
            let (eye, target) = (DVec3::from_array(k.eye), DVec3::from_array(k.target));
            if (target - eye).try_normalize().is_none() {
                return Err(CameraError::DegenerateView {
                    path: path(),
                    keyframe: i,
                });
            }
            if let Some(prev) = i.checked_sub(1).and_then(|p| self.keyframes.get(p)) {
                if k.time <= prev.time {
                    return Err(CameraError::Unsorted {
                        path: path(),
                        keyframe: i,
                        time: k.time,
                        previous: i - 1,
                        previous_time: prev.time,
                    });
                }
                if k.time - prev.time < MIN_KEYFRAME_GAP {
                    return Err(CameraError::TooClose {
                        path: path(),
                        keyframe: i,
                        time: k.time,
                        previous: i - 1,
                        gap: k.time - prev.time,
                    });
                }
            }
        }
        Ok(())
    }

    /// Time of the first keyframe, seconds (0 for an empty path).
    pub fn start(&self) -> f64 {
        self.keyframes.first().map_or(0.0, |k| k.time)
    }

    /// Time from the first to the last keyframe, seconds.
    pub fn duration(&self) -> f64 {
        self.keyframes.last().map_or(0.0, |k| k.time) - self.start()
    }

    /// The camera at time `t` (seconds, clamped to the keyframes; NaN means the start). At a keyframe's
    /// time the keyframe is returned exactly. An empty path (which `validate` rejects) gives a camera at
    /// the origin looking down `-Z`.
    pub fn sample(&self, t: f64) -> Camera {
        let lens = |eye: DVec3, target: DVec3, fov: f64| Camera {
            eye,
            target,
            up: DVec3::from_array(self.up),
            fov_x_deg: fov,
            aspect: if self.aspect.is_finite() && self.aspect > 0.0 {
                self.aspect
            } else {
                default_aspect()
            },
            near: self.near,
            far: self.far,
        };
        let ks = &self.keyframes;
        let (Some(first), Some(last)) = (ks.first(), ks.last()) else {
            return lens(DVec3::ZERO, DVec3::NEG_Z, 60.0);
        };
        let at = |k: &Keyframe| lens(k.eye.into(), k.target.into(), k.fov);
        if t.is_nan() || t <= first.time {
            return at(first);
        }
        if t >= last.time {
            return at(last);
        }
        // The segment [i, i+1] with times[i] <= t < times[i+1].
        let i = ks.partition_point(|k| k.time <= t).saturating_sub(1);
        let (Some(k0), Some(k1)) = (ks.get(i), ks.get(i + 1)) else {
            return at(last);
        };
        if t == k0.time {
            return at(k0);
        }
        let s = (t - k0.time) / (k1.time - k0.time);
        let eye = self.interpolate(i, s, |k| k.eye);
        let mut target = self.interpolate(i, s, |k| k.target);
        // Eye and target passing through one point between two valid keyframes (they swap places): no
        // view direction there, which `Camera::basis` took as -Z, one the path never asked for (fault
        // hunt, session 38). The keyframes' directions blended instead, else the segment's first.
        if (target - eye).length() <= 1e-9 * eye.length().max(1.0) {
            let dir =
                |k: &Keyframe| (DVec3::from(k.target) - DVec3::from(k.eye)).normalize_or_zero();
            let blended = dir(k0).lerp(dir(k1), s).try_normalize().unwrap_or(dir(k0));
            target = eye + blended;
        }
        let fov = k0.fov + (k1.fov - k0.fov) * s;
        lens(eye, target, fov)
    }

    /// Monotone cubic Hermite interpolation of `get` on segment `i` at parameter `s ∈ [0, 1)`, computed
    /// as keyframe `i` plus an offset built from coordinate differences only (translation-stable).
    fn interpolate(&self, i: usize, s: f64, get: impl Fn(&Keyframe) -> [f64; 3]) -> DVec3 {
        let ks = &self.keyframes;
        let pos = |j: usize| ks.get(j).map(|k| DVec3::from_array(get(k)));
        let time = |j: usize| ks.get(j).map_or(0.0, |k| k.time);
        let (Some(p0), Some(p1)) = (pos(i), pos(i + 1)) else {
            return pos(i).unwrap_or(DVec3::ZERO);
        };
        let h = time(i + 1) - time(i);
        let delta = (p1 - p0) / h;
        // Secant slopes of the neighbouring segments (None at the ends).
        let before = i
            .checked_sub(1)
            .and_then(|j| Some(((p0 - pos(j)?) / (time(i) - time(j)), time(i) - time(j))));
        let after = pos(i + 2).map(|p2| {
            (
                (p2 - p1) / (time(i + 2) - time(i + 1)),
                time(i + 2) - time(i + 1),
            )
        });
        let m0 = before.map_or(delta, |(d_prev, h_prev)| {
            pchip_slope(d_prev, h_prev, delta, h)
        });
        let m1 = after.map_or(delta, |(d_next, h_next)| {
            pchip_slope(delta, h, d_next, h_next)
        });
        let s2 = s * s;
        let s3 = s2 * s;
        let h10 = s3 - 2.0 * s2 + s;
        let h01 = -2.0 * s3 + 3.0 * s2;
        let h11 = s3 - s2;
        p0 + (p1 - p0) * h01 + m0 * (h * h10) + m1 * (h * h11)
    }

    /// `count` cameras at `start + i / fps`, i = 0..count (clamped to the last keyframe).
    pub fn frames(&self, fps: f64, count: usize) -> impl Iterator<Item = Camera> + '_ {
        let start = self.start();
        (0..count).map(move |i| self.sample(start + i as f64 / fps))
    }
}

/// Fritsch–Carlson / PCHIP slope at a knot between secants `d0` (segment length `h0`) and `d1` (`h1`):
/// 0 where the data turn (or are flat), else the weighted harmonic mean, which is at most 3× either
/// secant, the sufficient condition for a monotone segment. Per coordinate.
fn pchip_slope(d0: DVec3, h0: f64, d1: DVec3, h1: f64) -> DVec3 {
    let w1 = 2.0 * h1 + h0;
    let w2 = h1 + 2.0 * h0;
    let one = |a: f64, b: f64| {
        if a * b <= 0.0 {
            0.0
        } else {
            (w1 + w2) / (w1 / a + w2 / b)
        }
    };
    DVec3::new(one(d0.x, d1.x), one(d0.y, d1.y), one(d0.z, d1.z))
}

/// Which camera path a command uses: `overview-dive`, `street`, `orbit`, or a JSON file.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum PathKind {
    OverviewDive,
    Street,
    Orbit,
    File(PathBuf),
}

impl std::str::FromStr for PathKind {
    type Err = CameraError;

    fn from_str(s: &str) -> Result<PathKind, CameraError> {
        match s {
            "overview-dive" => Ok(PathKind::OverviewDive),
            "street" => Ok(PathKind::Street),
            "orbit" => Ok(PathKind::Orbit),
            _ if s.to_ascii_lowercase().ends_with(".json") => Ok(PathKind::File(PathBuf::from(s))),
            _ => Err(CameraError::UnknownKind {
                given: s.to_owned(),
            }),
        }
    }
}

impl std::fmt::Display for PathKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            PathKind::OverviewDive => f.write_str("overview-dive"),
            PathKind::Street => f.write_str("street"),
            PathKind::Orbit => f.write_str("orbit"),
            PathKind::File(p) => write!(f, "{}", p.display()),
        }
    }
}

impl PathKind {
    /// The path: generated over `ground` (its bounds, up axis and heights), or loaded from the file
    /// (the ground is then unused).
    pub fn resolve(&self, ground: &Ground) -> Result<CameraPath, CameraError> {
        match self {
            PathKind::OverviewDive => CameraPath::overview_dive_on(ground),
            PathKind::Street => CameraPath::street_on(ground),
            PathKind::Orbit => CameraPath::orbit_on(ground),
            PathKind::File(p) => CameraPath::load(p),
        }
    }

    /// As [`PathKind::resolve`], deriving the ground with `ground` only for a generated kind, so a JSON
    /// path never pays for it nor fails on it (e.g. `kind.resolve_with(|| Ground::from_tree(&file))`).
    pub fn resolve_with(
        &self,
        ground: impl FnOnce() -> Result<Ground, GroundError>,
    ) -> Result<CameraPath, CameraError> {
        match self {
            PathKind::File(p) => CameraPath::load(p),
            kind => {
                let g = ground().map_err(|source| CameraError::Ground {
                    kind: kind.clone(),
                    source,
                })?;
                kind.resolve(&g)
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Keyframes whose eye and target swap places pass through eye == target between them: the sampled
    /// camera there looks along the keyframes' blended direction, not -Z.
    #[test]
    fn eye_and_target_crossing_keep_a_view_direction() {
        let key = |time: f64, eye: [f64; 3], target: [f64; 3]| {
            format!(r#"{{"time": {time}, "eye": {eye:?}, "target": {target:?}, "fov": 60}}"#)
        };
        let text = format!(
            r#"{{"keyframes": [{}, {}]}}"#,
            key(0.0, [0.0, 5.0, 0.0], [10.0, 5.0, 0.0]),
            key(2.0, [10.0, 5.0, 0.0], [0.0, 5.0, 0.0])
        );
        let path = CameraPath::from_json(&text, Path::new("p.json")).unwrap();
        let mid = path.sample(1.0);
        let forward = mid.basis().forward;
        assert!(
            forward.is_finite() && forward.dot(DVec3::NEG_Z) < 0.99,
            "{forward}"
        );
        assert!(forward.y.abs() < 1e-9, "{forward}");
    }

    /// A bare array of keyframes is refused saying the file must be an object, not serde's "expected a
    /// sequence" of a sequence; an object still reads (a BOM before it too).
    #[test]
    fn an_array_is_not_a_camera_path() {
        let origin = Path::new("p.json");
        let key = r#"{"time": 0, "eye": [0, 5, 0], "target": [1, 0, 0], "fov": 60}"#;
        for text in [format!("[{key}]"), format!("\u{feff} [{key}]")] {
            let e = CameraPath::from_json(&text, origin).unwrap_err();
            assert!(matches!(e, CameraError::NotAnObject { .. }), "{e}");
            assert!(e.to_string().contains("not an array"), "{e}");
        }
        let object = format!(r#"{{"keyframes": [{key}]}}"#);
        assert!(CameraPath::from_json(&object, origin).is_ok());
    }

    /// A file's `aspect` is not used (frames take their viewport's), so it is not refused; the sampled
    /// camera keeps a usable one.
    #[test]
    fn an_unused_aspect_is_not_refused() {
        let json =
            br#"{"keyframes": [{"time": 0, "eye": [0, 10, 0], "target": [0, 0, 0], "fov": 60}],
            "aspect": 0}"#;
        let path: CameraPath = serde_json::from_slice(json).unwrap();
        path.validate(Path::new("p.json")).unwrap();
        assert_eq!(path.sample(0.0).aspect, default_aspect());
    }

    #[test]
    fn pchip_never_overshoots_keyframes() {
        let path = CameraPath {
            keyframes: [
                (0.0, 100.0),
                (1.0, 10.0),
                (1.5, 1.7),
                (4.0, 1.7),
                (5.0, 300.0),
            ]
            .iter()
            .map(|&(t, h)| Keyframe {
                time: t,
                eye: [t * 3.0, h, 0.0],
                target: [0.0, 0.0, -1.0],
                fov: 60.0,
            })
            .collect(),
            up: [0.0, 1.0, 0.0],
            aspect: 1.0,
            near: 0.1,
            far: 10.0,
        };
        let mut prev = f64::INFINITY;
        for i in 0..=1000 {
            let t = i as f64 * 0.005;
            let y = path.sample(t).eye.y;
            assert!((1.7 - 1e-12..=300.0).contains(&y), "t {t}: {y}");
            if t <= 1.5 {
                assert!(y <= prev + 1e-12, "monotone decreasing at t {t}");
            }
            prev = y;
        }
    }
}
