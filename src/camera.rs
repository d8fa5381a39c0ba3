//! Cameras, view frusta and camera paths for the per-frame traversal (paper §4) and the fly-through
//! experiments.
//!
//! All world maths is f64. Everything that compares a camera with the scene is done **relative to the
//! eye** (`p - eye`, computed in f64 before anything else): a scene at UTM-size coordinates (1e6–1e7 m)
//! is culled and measured as exactly as one at the origin, and the matrices handed to the GPU
//! ([`Camera::view_proj_relative`]) contain no large translation at all.
//!
//! - [`Camera`]: eye, target, up, horizontal field of view (the paper's `c`), aspect, near/far.
//! - [`Frustum`]: six planes, hierarchical AABB classification ([`Frustum::classify_aabb_masked`]).
//! - [`distance_to_aabb`]: the paper's "distance between camera and `N.bounds`".
//! - [`CameraPath`]: keyframed paths (JSON), sampled with a monotone cubic; generated paths
//!   ([`CameraPath::overview_dive`], [`CameraPath::street`], [`CameraPath::orbit`]); [`PathKind`] for the CLI.

use crate::scene::UpAxis;
use glam::{DMat4, DVec2, DVec3, DVec4};
use serde::{Deserialize, Serialize};
use std::path::{Path, PathBuf};

/// A perspective camera. Units: world units (metres) and degrees.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Camera {
    pub eye: DVec3,
    pub target: DVec3,
    /// Approximate up direction; need not be unit length or orthogonal to the view direction. When it is
    /// (nearly) parallel to the view direction (looking straight down), another axis is used, see
    /// [`Camera::basis`].
    pub up: DVec3,
    /// Horizontal field of view, degrees (the paper's `c`, §5.2.1), in (0, 180).
    pub fov_x_deg: f64,
    /// Width / height of the viewport.
    pub aspect: f64,
    /// Near and far plane distances along the view direction, world units, `0 < near < far`.
    pub near: f64,
    pub far: f64,
}

/// An orthonormal right-handed camera frame: `right × up = -forward`.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Basis {
    pub forward: DVec3,
    pub right: DVec3,
    pub up: DVec3,
}

impl Camera {
    /// The camera frame. Degenerate inputs never panic: a zero or non-finite view direction becomes
    /// `-Z`, and an `up` (nearly) parallel to the view direction is replaced by the world axis least
    /// aligned with it (so looking straight down works with `up = +Y`).
    pub fn basis(&self) -> Basis {
        let forward = (self.target - self.eye)
            .try_normalize()
            .unwrap_or(DVec3::NEG_Z);
        let up_hint = self.up.try_normalize().unwrap_or(DVec3::Y);
        let right = forward
            .cross(up_hint)
            .try_normalize()
            .filter(|_| forward.dot(up_hint).abs() < 1.0 - 1e-9)
            .unwrap_or_else(|| forward.cross(least_aligned_axis(forward)).normalize());
        let up = right.cross(forward);
        Basis { forward, right, up }
    }

    /// `tan(fov_x / 2)`.
    pub fn tan_half_fov_x(&self) -> f64 {
        (self.fov_x_deg.to_radians() * 0.5).tan()
    }

    /// `tan(fov_y / 2) = tan(fov_x / 2) / aspect`.
    pub fn tan_half_fov_y(&self) -> f64 {
        self.tan_half_fov_x() / self.aspect
    }

    /// View matrix of the camera **at the origin** (rotation only; right-handed, looking down `-Z` in
    /// view space). Apply it to `p - eye`.
    pub fn view_relative(&self) -> DMat4 {
        let Basis {
            forward: f,
            right: r,
            up: u,
        } = self.basis();
        DMat4::from_cols(
            DVec4::new(r.x, u.x, -f.x, 0.0),
            DVec4::new(r.y, u.y, -f.y, 0.0),
            DVec4::new(r.z, u.z, -f.z, 0.0),
            DVec4::W,
        )
    }

    /// Right-handed perspective projection with the `[0, 1]` depth range of wgpu, built from the
    /// tangents directly (no round trip through a vertical angle).
    pub fn projection(&self) -> DMat4 {
        let r = self.far / (self.near - self.far);
        DMat4::from_cols(
            DVec4::new(1.0 / self.tan_half_fov_x(), 0.0, 0.0, 0.0),
            DVec4::new(0.0, 1.0 / self.tan_half_fov_y(), 0.0, 0.0),
            DVec4::new(0.0, 0.0, r, -1.0),
            DVec4::new(0.0, 0.0, r * self.near, 0.0),
        )
    }

    /// `projection · view` with the view translation removed: it maps **camera-relative** positions
    /// `p - eye` to clip space. The translation is applied in f64 before the matrix (per leaf origin on
    /// the CPU: `leaf.origin - eye`), so the matrix holds only rotation and projection, every entry is of
    /// order 1, and nothing of the size of the world coordinates ever reaches f32. Two cameras that differ
    /// only by a translation have the identical matrix.
    pub fn view_proj_relative(&self) -> DMat4 {
        self.projection() * self.view_relative()
    }

    /// The six planes of the view volume; see [`Frustum`].
    pub fn frustum(&self) -> Frustum {
        let Basis {
            forward: f,
            right: r,
            up: u,
        } = self.basis();
        let tx = self.tan_half_fov_x();
        let ty = self.tan_half_fov_y();
        // A relative point p has x = p·r, y = p·u, depth z = p·f; inside iff |x| ≤ tx z, |y| ≤ ty z,
        // near ≤ z ≤ far. Each inequality is one plane n·p + d ≥ 0.
        let side = |n: DVec3| n.try_normalize().unwrap_or(n).extend(0.0);
        let planes = [
            side(r + tx * f),
            side(-r + tx * f),
            side(u + ty * f),
            side(-u + ty * f),
            f.extend(-self.near),
            (-f).extend(self.far),
        ];
        Frustum {
            origin: self.eye,
            planes,
        }
    }
}

/// The world axis with the smallest absolute component of `v` (ties: X before Y before Z).
fn least_aligned_axis(v: DVec3) -> DVec3 {
    let a = v.abs();
    if a.x <= a.y && a.x <= a.z {
        DVec3::X
    } else if a.y <= a.z {
        DVec3::Y
    } else {
        DVec3::Z
    }
}

/// Where an axis-aligned box lies relative to a frustum.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash, Serialize)]
pub enum Visibility {
    /// Entirely outside at least one plane: nothing of it can be seen.
    Outside,
    /// Neither provably outside nor inside all planes (conservative: a box near a corner of the view
    /// volume can be reported `Intersects` although it is outside).
    Intersects,
    /// Entirely inside all six planes.
    Inside,
}

/// A set of frustum planes still to be tested, bit `i` = plane `i`. Children of a node that is inside
/// plane `i` are inside it too (their bounds are contained in the parent's), so the hierarchical test
/// (paper §4) drops such planes; a node inside all planes passes `PlaneMask::NONE` to its subtree.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub struct PlaneMask(pub u8);

impl PlaneMask {
    /// All six planes.
    pub const ALL: PlaneMask = PlaneMask(0b11_1111);
    /// No plane: the box is known to be inside.
    pub const NONE: PlaneMask = PlaneMask(0);
}

/// A view frustum: six inward-facing planes `(n, d)` with `n·q + d ≥ 0` inside, where `q = p - origin`
/// is **relative to the eye** (`origin`). Order: left, right, bottom, top, near, far. Side planes have
/// unit normals, so `n·q + d` is a signed distance in world units.
///
/// The planes are built and evaluated camera-relative (boxes are shifted by `-origin` in f64 first);
/// [`Frustum::world_planes`] gives the same planes offset by the eye for callers that want world-space
/// planes.
#[derive(Copy, Clone, Debug, PartialEq)]
pub struct Frustum {
    pub origin: DVec3,
    pub planes: [DVec4; 6],
}

impl Frustum {
    /// The planes in world space: `n·p + d_world ≥ 0` inside, `d_world = d - n·origin`. Less exact than
    /// the relative form for points far from the origin of the world; prefer [`Frustum::classify_aabb`].
    pub fn world_planes(&self) -> [DVec4; 6] {
        self.planes
            .map(|p| p.truncate().extend(p.w - p.truncate().dot(self.origin)))
    }

    /// Classifies the world-space box `[lo, hi]` against all six planes.
    pub fn classify_aabb(&self, lo: DVec3, hi: DVec3) -> Visibility {
        self.classify_aabb_masked(lo, hi, PlaneMask::ALL).0
    }

    /// Classifies `[lo, hi]` against the planes in `mask` only (the others are known to hold for the
    /// box), returning the class and the planes the box still straddles (for its children). Per plane the
    /// box corner furthest along the normal decides "outside", the nearest one "inside".
    pub fn classify_aabb_masked(
        &self,
        lo: DVec3,
        hi: DVec3,
        mask: PlaneMask,
    ) -> (Visibility, PlaneMask) {
        if mask.0 == 0 {
            return (Visibility::Inside, PlaneMask::NONE);
        }
        let lo = lo - self.origin;
        let hi = hi - self.origin;
        let mut straddled = 0u8;
        for (i, plane) in self.planes.iter().enumerate() {
            let bit = 1u8 << i;
            if mask.0 & bit == 0 {
                continue;
            }
            let n = plane.truncate();
            let far_corner = DVec3::select(n.cmpge(DVec3::ZERO), hi, lo);
            let near_corner = DVec3::select(n.cmpge(DVec3::ZERO), lo, hi);
            let furthest = n.dot(far_corner) + plane.w;
            // A NaN box counts as outside rather than visible.
            if furthest < 0.0 || furthest.is_nan() {
                return (Visibility::Outside, PlaneMask::NONE);
            }
            if n.dot(near_corner) + plane.w < 0.0 {
                straddled |= bit;
            }
        }
        if straddled == 0 {
            (Visibility::Inside, PlaneMask::NONE)
        } else {
            (Visibility::Intersects, PlaneMask(straddled))
        }
    }

    /// True if the world point `p` is inside or on all planes.
    pub fn contains_point(&self, p: DVec3) -> bool {
        let q = p - self.origin;
        self.planes
            .iter()
            .all(|pl| pl.truncate().dot(q) + pl.w >= 0.0)
    }
}

/// Euclidean distance from `eye` to the box `[lo, hi]`, world units; 0 when `eye` is inside or on the
/// box (paper §4: "the distance d between the camera and N.bounds"). Computed per axis from the signed
/// gaps `lo - eye` and `eye - hi`, so it is as exact as the coordinates' differences.
#[inline]
pub fn distance_to_aabb(eye: DVec3, lo: DVec3, hi: DVec3) -> f64 {
    let gap = (lo - eye).max(eye - hi).max(DVec3::ZERO);
    gap.length()
}

// ------------------------------------------------------------------------------------------------
// Camera paths
// ------------------------------------------------------------------------------------------------

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
    #[error("{path}: keyframe {keyframe}: field of view {fov}° is outside (0°, 180°)")]
    BadFov {
        path: PathBuf,
        keyframe: usize,
        fov: f64,
    },
    #[error(
        "{path}: keyframe {keyframe}: eye and target coincide, the view direction is undefined"
    )]
    DegenerateView { path: PathBuf, keyframe: usize },
    #[error("{path}: {field} is {value}, it must be finite and > 0 (and near < far)")]
    BadLens {
        path: PathBuf,
        field: &'static str,
        value: f64,
    },
    #[error("{path}: up vector {up:?} must be finite and non-zero")]
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
}

/// One keyframe: time, eye, target and horizontal field of view.
#[derive(Copy, Clone, Debug, PartialEq, Serialize, Deserialize)]
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
fn default_aspect() -> f64 {
    16.0 / 9.0
}
fn default_near() -> f64 {
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
/// outside the keyframes clamp to the first or last keyframe.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
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
        let text = std::fs::read_to_string(path).map_err(|source| CameraError::Io {
            path: path.to_owned(),
            source,
        })?;
        CameraPath::from_json(&text, path)
    }

    /// Parses and validates JSON text; `origin` names the source in errors.
    pub fn from_json(text: &str, origin: &Path) -> Result<CameraPath, CameraError> {
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

    /// Writes the path as JSON.
    pub fn save(&self, path: &Path) -> Result<(), CameraError> {
        std::fs::write(path, self.to_json() + "\n").map_err(|source| CameraError::Write {
            path: path.to_owned(),
            source,
        })
    }

    /// Checks everything [`CameraPath::sample`] relies on; `origin` names the source in errors.
    pub fn validate(&self, origin: &Path) -> Result<(), CameraError> {
        let path = || origin.to_owned();
        if self.keyframes.is_empty() {
            return Err(CameraError::NoKeyframes { path: path() });
        }
        let up = DVec3::from_array(self.up);
        if !up.is_finite() || up.length_squared() == 0.0 {
            return Err(CameraError::BadUp {
                path: path(),
                up: self.up,
            });
        }
        for (field, value) in [
            ("aspect", self.aspect),
            ("near", self.near),
            ("far", self.far),
        ] {
            if !(value.is_finite() && value > 0.0) {
                return Err(CameraError::BadLens {
                    path: path(),
                    field,
                    value,
                });
            }
        }
        if self.near >= self.far {
            return Err(CameraError::BadLens {
                path: path(),
                field: "near",
                value: self.near,
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
            if !(k.fov > 0.0 && k.fov < 180.0) {
                return Err(CameraError::BadFov {
                    path: path(),
                    keyframe: i,
                    fov: k.fov,
                });
            }
            if k.eye == k.target {
                return Err(CameraError::DegenerateView {
                    path: path(),
                    keyframe: i,
                });
            }
            if let Some(prev) = i.checked_sub(1).and_then(|p| self.keyframes.get(p))
                && k.time <= prev.time
            {
                return Err(CameraError::Unsorted {
                    path: path(),
                    keyframe: i,
                    time: k.time,
                    previous: i - 1,
                    previous_time: prev.time,
                });
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
            aspect: self.aspect,
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
        let target = self.interpolate(i, s, |k| k.target);
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

    /// The generated path `kind` over a scene with bounds `[lo, hi]` and the given up axis.
    fn generated(
        kind: &'static str,
        lo: DVec3,
        hi: DVec3,
        up: UpAxis,
        make: impl FnOnce(&Frame) -> (Vec<Keyframe>, f64),
    ) -> Result<CameraPath, CameraError> {
        if !(lo.is_finite() && hi.is_finite() && lo.cmple(hi).all()) {
            return Err(CameraError::BadBounds {
                kind,
                lo: lo.to_array(),
                hi: hi.to_array(),
            });
        }
        let frame = Frame::new(lo, hi, up);
        let (keyframes, far) = make(&frame);
        Ok(CameraPath {
            keyframes,
            up: up.vector().to_array(),
            aspect: default_aspect(),
            near: default_near(),
            far,
        })
    }

    /// From a whole-scene overview high above, down to one building at street level and back up (the
    /// paper's "rapidly changing visibility"), 20 s.
    ///
    /// Documented bounds (checked by tests): the eye stays inside the scene's footprint (plane bounds)
    /// and its height above the ground (`height(lo)`) stays in `[1.7 m, overview height]`, where the
    /// overview height is `max(top + 0.9 · diagonal, ground + 20 m)` (the whole footprint fits a 60°
    /// view); targets stay
    /// inside the footprint at heights in `[ground, top]`.
    pub fn overview_dive(lo: DVec3, hi: DVec3, up: UpAxis) -> Result<CameraPath, CameraError> {
        CameraPath::generated("overview-dive", lo, hi, up, |f| {
            let centre = f.at(0.5, 0.5);
            // A building away from the quadtree's first split lines.
            let building = f.at(0.62, 0.37);
            let street_off = (f.size * 0.02)
                .max(DVec2::splat(1.0))
                .min(DVec2::splat(25.0));
            let street = f.clamp_plane(building - street_off);
            let overview = (f.top + 0.9 * f.diag).max(f.ground + 20.0);
            let low = f.ground + (0.02 * f.diag).clamp(1.7, 80.0);
            let mid = (f.ground + 0.25 * f.diag).max(low);
            let near_eye = f.clamp_plane(building - street_off * 4.0);
            let look = f.ground + (f.top - f.ground).min(10.0);
            let ks = vec![
                f.key(
                    0.0,
                    centre - f.size * 0.01,
                    overview,
                    centre,
                    f.ground,
                    60.0,
                ),
                f.key(
                    4.0,
                    f.lerp_plane(centre, building, 0.6),
                    mid,
                    building,
                    f.ground,
                    60.0,
                ),
                f.key(7.0, near_eye, low, building, f.ground, 60.0),
                f.key(9.0, street, f.ground + 1.7, building, look, 75.0),
                f.key(
                    11.0,
                    f.lerp_plane(street, building, 0.5),
                    f.ground + 1.7,
                    building,
                    look,
                    75.0,
                ),
                f.key(13.0, near_eye, low, building, f.ground, 60.0),
                f.key(
                    16.0,
                    f.lerp_plane(centre, building, 0.6),
                    mid,
                    building,
                    f.ground,
                    60.0,
                ),
                f.key(
                    20.0,
                    centre + f.size * 0.01,
                    overview,
                    centre,
                    f.ground,
                    60.0,
                ),
            ];
            (ks, f.far(overview))
        })
    }

    /// A low flight across the scene along its footprint's diagonal from 5 % to 95 %, eye height
    /// alternating between 1.7 m and 10 m above the ground, looking ahead along the line, at about
    /// 15 m/s (at least 10 s).
    ///
    /// Documented bounds: eye inside the footprint, eye height above ground in `[1.7 m, 10 m]`.
    pub fn street(lo: DVec3, hi: DVec3, up: UpAxis) -> Result<CameraPath, CameraError> {
        CameraPath::generated("street", lo, hi, up, |f| {
            let a = f.at(0.05, 0.05);
            let b = f.at(0.95, 0.95);
            let length = (b - a).length();
            let duration = (length / 15.0).max(10.0);
            let heights = [1.7, 10.0, 4.0, 1.7, 7.0, 2.5, 10.0, 1.7, 5.0];
            let n = heights.len() - 1;
            let dir = (b - a).try_normalize().unwrap_or(DVec2::X);
            let ks = heights
                .iter()
                .enumerate()
                .map(|(i, &h)| {
                    let s = i as f64 / n as f64;
                    let eye = a.lerp(b, s);
                    let target = eye + dir * 50.0;
                    f.key(
                        duration * s,
                        eye,
                        f.ground + h,
                        target,
                        f.ground + h * 0.5,
                        70.0,
                    )
                })
                .collect();
            (ks, f.far(f.ground + 10.0))
        })
    }

    /// One turn around the centre at a medium height, 30 s: eye on a circle of radius `0.5 · diagonal`
    /// of the footprint (so partly outside the footprint), at `ground + 0.3 · diagonal`, looking at the
    /// centre on the ground.
    ///
    /// Documented bounds: eye height exactly `ground + 0.3 · diagonal` (constant), planar distance
    /// from the centre in `[0.495, 0.5025] · diagonal` (the per-coordinate spline deviates slightly from the circle).
    pub fn orbit(lo: DVec3, hi: DVec3, up: UpAxis) -> Result<CameraPath, CameraError> {
        CameraPath::generated("orbit", lo, hi, up, |f| {
            let centre = f.at(0.5, 0.5);
            let radius = 0.5 * f.diag;
            let height = f.ground + 0.3 * f.diag;
            let steps = 32;
            let ks = (0..=steps)
                .map(|i| {
                    let a = std::f64::consts::TAU * i as f64 / steps as f64;
                    let eye = centre + DVec2::new(a.cos(), a.sin()) * radius;
                    f.key_unclamped(
                        30.0 * i as f64 / steps as f64,
                        eye,
                        height,
                        centre,
                        f.ground,
                        60.0,
                    )
                })
                .collect();
            (ks, f.far(height))
        })
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

/// Scene footprint helpers for the generated paths: plane coordinates, heights and keyframes.
struct Frame {
    up: UpAxis,
    lo: DVec2,
    size: DVec2,
    /// Footprint diagonal, at least 1 m.
    diag: f64,
    ground: f64,
    top: f64,
}

impl Frame {
    fn new(lo: DVec3, hi: DVec3, up: UpAxis) -> Frame {
        let lo2 = up.plane(lo);
        let size = up.plane(hi) - lo2;
        Frame {
            up,
            lo: lo2,
            size,
            diag: size.length().max(1.0),
            ground: up.height(lo),
            top: up.height(hi),
        }
    }

    /// The plane point at fractions `(u, v)` of the footprint.
    fn at(&self, u: f64, v: f64) -> DVec2 {
        self.lo + self.size * DVec2::new(u, v)
    }

    fn clamp_plane(&self, p: DVec2) -> DVec2 {
        p.clamp(self.lo, self.lo + self.size)
    }

    fn lerp_plane(&self, a: DVec2, b: DVec2, s: f64) -> DVec2 {
        self.clamp_plane(a.lerp(b, s))
    }

    /// The 3D point with plane coordinates `p` and height `h`.
    fn point(&self, p: DVec2, h: f64) -> DVec3 {
        match self.up {
            UpAxis::X => DVec3::new(h, p.x, p.y),
            UpAxis::Y => DVec3::new(p.x, h, p.y),
            UpAxis::Z => DVec3::new(p.x, p.y, h),
        }
    }

    /// A keyframe with eye and target clamped to the footprint.
    fn key(
        &self,
        time: f64,
        eye: DVec2,
        eye_h: f64,
        target: DVec2,
        target_h: f64,
        fov: f64,
    ) -> Keyframe {
        self.key_unclamped(
            time,
            self.clamp_plane(eye),
            eye_h,
            self.clamp_plane(target),
            target_h,
            fov,
        )
    }

    fn key_unclamped(
        &self,
        time: f64,
        eye: DVec2,
        eye_h: f64,
        target: DVec2,
        target_h: f64,
        fov: f64,
    ) -> Keyframe {
        Keyframe {
            time,
            eye: self.point(eye, eye_h).to_array(),
            target: self.point(target, target_h).to_array(),
            fov,
        }
    }

    /// A far plane that sees the whole scene from height `h`.
    fn far(&self, h: f64) -> f64 {
        (2.0 * (self.diag + (h - self.ground).abs() + (self.top - self.ground))).max(1000.0)
    }
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
    /// The path: generated from the scene bounds `[lo, hi]` and `up`, or loaded from the file.
    pub fn resolve(&self, lo: DVec3, hi: DVec3, up: UpAxis) -> Result<CameraPath, CameraError> {
        match self {
            PathKind::OverviewDive => CameraPath::overview_dive(lo, hi, up),
            PathKind::Street => CameraPath::street(lo, hi, up),
            PathKind::Orbit => CameraPath::orbit(lo, hi, up),
            PathKind::File(p) => CameraPath::load(p),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cam(eye: DVec3, target: DVec3) -> Camera {
        Camera {
            eye,
            target,
            up: DVec3::Y,
            fov_x_deg: 90.0,
            aspect: 2.0,
            near: 1.0,
            far: 100.0,
        }
    }

    #[test]
    fn basis_is_orthonormal_and_right_handed_even_looking_straight_down() {
        for target in [
            DVec3::new(0.0, 0.0, -5.0),
            DVec3::new(0.0, -5.0, 0.0),
            DVec3::new(0.0, 5.0, 0.0),
        ] {
            let b = cam(DVec3::ZERO, target).basis();
            assert!((b.forward.length() - 1.0).abs() < 1e-12);
            assert!((b.right.length() - 1.0).abs() < 1e-12);
            assert!((b.up.length() - 1.0).abs() < 1e-12);
            assert!(b.forward.dot(b.right).abs() < 1e-12 && b.forward.dot(b.up).abs() < 1e-12);
            assert!(
                (b.right.cross(b.up) + b.forward).length() < 1e-12,
                "right × up = -forward"
            );
        }
        // Looking down -Z with up +Y: right is +X.
        let b = cam(DVec3::ZERO, DVec3::NEG_Z).basis();
        assert!((b.right - DVec3::X).length() < 1e-15);
    }

    #[test]
    fn projection_agrees_with_frustum_planes() {
        let c = Camera {
            eye: DVec3::new(4.5e6, 120.0, 5.5e6),
            ..cam(DVec3::ZERO, DVec3::ZERO)
        };
        let c = Camera {
            target: c.eye + DVec3::new(1.0, -0.3, -2.0),
            ..c
        };
        let vp = c.view_proj_relative();
        let f = c.frustum();
        let b = c.basis();
        // Points at the frustum corners (slightly inside / outside) land inside / outside clip space.
        for depth in [1.0 + 1e-6, 50.0, 100.0 - 1e-6] {
            for (sx, sy) in [
                (-1.0, -1.0),
                (1.0, -1.0),
                (-1.0, 1.0),
                (1.0, 1.0),
                (0.3, -0.2),
            ] {
                for (k, inside) in [(0.999, true), (1.001, false)] {
                    let x = sx * k * c.tan_half_fov_x() * depth;
                    let y = sy * k * c.tan_half_fov_y() * depth;
                    let rel = b.forward * depth + b.right * x + b.up * y;
                    let clip = vp * rel.extend(1.0);
                    let ndc = clip.truncate() / clip.w;
                    let in_clip =
                        ndc.x.abs() <= 1.0 && ndc.y.abs() <= 1.0 && (0.0..=1.0).contains(&ndc.z);
                    let in_frustum = f.contains_point(c.eye + rel);
                    let expect = inside || (sx.abs() < 1.0 && sy.abs() < 1.0);
                    assert_eq!(in_clip, expect, "clip depth {depth} ({sx},{sy}) k {k}");
                    assert_eq!(
                        in_frustum, expect,
                        "frustum depth {depth} ({sx},{sy}) k {k}"
                    );
                }
            }
        }
        // Near maps to depth 0, far to 1.
        let near = vp * (b.forward * 1.0).extend(1.0);
        let far = vp * (b.forward * 100.0).extend(1.0);
        assert!((near.z / near.w).abs() < 1e-12);
        assert!((far.z / far.w - 1.0).abs() < 1e-12);
    }

    #[test]
    fn view_proj_relative_is_translation_invariant() {
        let a = cam(DVec3::new(1.0, 2.0, 3.0), DVec3::new(4.0, 0.0, -7.0));
        let t = DVec3::new(4.5e6, 120.0, 5.5e6);
        let b = Camera {
            eye: a.eye + t,
            target: a.target + t,
            ..a
        };
        let (ma, mb) = (a.view_proj_relative(), b.view_proj_relative());
        assert!(ma.abs_diff_eq(mb, 1e-9), "{ma:?} vs {mb:?}");
    }

    #[test]
    fn classify_boxes() {
        let c = cam(DVec3::ZERO, DVec3::NEG_Z);
        let f = c.frustum();
        let v = |lo: [f64; 3], hi: [f64; 3]| f.classify_aabb(lo.into(), hi.into());
        assert_eq!(
            v([-1.0, -1.0, -20.0], [1.0, 1.0, -10.0]),
            Visibility::Inside
        );
        assert_eq!(
            v([-1.0, -1.0, 5.0], [1.0, 1.0, 10.0]),
            Visibility::Outside,
            "behind"
        );
        assert_eq!(
            v([-1.0, -1.0, -0.5], [1.0, 1.0, 0.5]),
            Visibility::Outside,
            "before near"
        );
        assert_eq!(
            v([-1.0, -1.0, -2.0], [1.0, 1.0, 0.5]),
            Visibility::Intersects,
            "through near"
        );
        assert_eq!(
            v([-1.0, -1.0, -150.0], [1.0, 1.0, -120.0]),
            Visibility::Outside,
            "beyond far"
        );
        assert_eq!(
            v([-1.0, -1.0, -150.0], [1.0, 1.0, -90.0]),
            Visibility::Intersects,
            "through far"
        );
        // fov 90°: at depth 10 the half width is 10; aspect 2 → half height 5.
        assert_eq!(
            v([10.5, -1.0, -10.0], [12.0, 1.0, -10.0]),
            Visibility::Outside,
            "right"
        );
        assert_eq!(
            v([-1.0, 5.5, -10.0], [1.0, 6.0, -10.0]),
            Visibility::Outside,
            "top"
        );
        assert_eq!(
            v([-1.0, 4.5, -10.0], [1.0, 6.0, -10.0]),
            Visibility::Intersects,
            "top edge"
        );
        // Masked: a box known inside all planes is not tested at all.
        assert_eq!(
            f.classify_aabb_masked(DVec3::splat(1e9), DVec3::splat(1e9), PlaneMask::NONE),
            (Visibility::Inside, PlaneMask::NONE)
        );
        let (cls, mask) = f.classify_aabb_masked(
            DVec3::new(-1.0, -1.0, -150.0),
            DVec3::new(1.0, 1.0, -90.0),
            PlaneMask::ALL,
        );
        assert_eq!(
            (cls, mask),
            (Visibility::Intersects, PlaneMask(1 << 5)),
            "straddles far only"
        );
        let nan = DVec3::splat(f64::NAN);
        assert_eq!(f.classify_aabb(nan, nan), Visibility::Outside);
    }

    #[test]
    fn world_planes_match_relative_planes() {
        let c = cam(
            DVec3::new(100.0, 20.0, -30.0),
            DVec3::new(120.0, 10.0, -60.0),
        );
        let f = c.frustum();
        let p = DVec3::new(110.0, 15.0, -50.0);
        for (w, r) in f.world_planes().iter().zip(f.planes.iter()) {
            let dw = w.truncate().dot(p) + w.w;
            let dr = r.truncate().dot(p - f.origin) + r.w;
            assert!((dw - dr).abs() < 1e-9);
        }
    }

    #[test]
    fn distance_to_boxes() {
        let (lo, hi) = (DVec3::new(0.0, 0.0, 0.0), DVec3::new(10.0, 5.0, 10.0));
        assert_eq!(distance_to_aabb(DVec3::new(5.0, 2.0, 5.0), lo, hi), 0.0);
        assert_eq!(
            distance_to_aabb(DVec3::new(10.0, 5.0, 10.0), lo, hi),
            0.0,
            "on a corner"
        );
        assert_eq!(distance_to_aabb(DVec3::new(13.0, 2.0, 14.0), lo, hi), 5.0);
        assert_eq!(distance_to_aabb(DVec3::new(5.0, -7.0, 5.0), lo, hi), 7.0);
        let t = DVec3::new(4.5e6, 120.0, 5.5e6);
        assert_eq!(
            distance_to_aabb(DVec3::new(13.0, 2.0, 14.0) + t, lo + t, hi + t),
            5.0
        );
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
