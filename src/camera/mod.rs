//! Cameras, view frusta and camera paths for the per-frame traversal (paper §4) and the fly-through
//! experiments.
//!
//! All world maths is f64. Everything that compares a camera with the scene is done **relative to the
//! eye** (`p - eye`, computed in f64 before anything else): a scene at UTM-size coordinates (1e6–1e7 m)
//! is culled and measured as exactly as one at the origin, and the matrices handed to the GPU
//! ([`Camera::view_proj_relative`]) contain no large translation at all. Units: world units (metres),
//! seconds and degrees.
//!
//! This module holds the per-frame geometry:
//!
//! - [`Camera`]: eye, target, up, horizontal field of view (the paper's `c`), aspect, near/far.
//! - [`Frustum`]: six planes, hierarchical AABB classification ([`Frustum::classify_aabb_masked`]).
//! - [`distance_to_aabb`]: the paper's "distance between camera and `N.bounds`".
//!
//! Its submodules hold the paths:
//!
//! - `path`: [`Keyframe`], [`CameraPath`] (JSON load / save / validate, monotone cubic sampling) and
//!   [`PathKind`] for the CLI.
//! - `generated`: the generated paths ([`CameraPath::overview_dive_on`], [`CameraPath::street_on`],
//!   [`CameraPath::orbit_on`]) over a [`Ground`].
//! - `ground`: [`Ground`], the height field of the scene's ground that the generated paths fly over.

mod generated;
mod ground;
mod path;
#[cfg(test)]
mod test_scenes;

pub use ground::{Ground, GroundError};
pub use path::{CameraError, CameraPath, Keyframe, MIN_FOV_DEG, PathKind};

use glam::{DMat4, DVec3, DVec4};
use serde::{Deserialize, Serialize};

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
}
