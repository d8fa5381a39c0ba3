//! The 3D Tiles 1.1 side: frames, bounding boxes and geometric errors (`../shared/3dtiles/NOTES.md`).
//!
//! - **Frames.** glTF contents are y-up, and 3D Tiles clients turn them +90° about x into the z-up tile
//!   frame: a y-up point `(x, y, z)` is the tile-frame point `(x, −z, y)`. A scene whose up axis is
//!   another (`--up z`, or found so by `--up auto`) is first turned so that its up axis is y
//!   ([`to_gltf_frame`]; the contents' leaf nodes carry the same rotation), so its ground lies in the
//!   tile frame's xy plane (a z-up scene was exported on its side: fault hunt, session 33). Each tree's
//!   top tile carries a translation `transform` to the tree's origin (f64 in JSON), and everything under it
//!   (boxes, contents) is relative to that origin: UTM-size coordinates keep full precision.
//! - **geometricError.** CesiumJS and 3DTilesRendererJS refine a tile when
//!   `g · H / (d · 2 tan(fov_y/2)) > S` (S = maximumScreenSpaceError / errorTarget, 16 by default), d the
//!   distance to its box. With `g = min_distance · 2 tan(fov_x/2) · S / W` (W and fov_x of the build) a tile
//!   refines exactly where atlastree's selection (§4) descends below it, at the build's screen width. For a
//!   texel ratio `r` other than the build's `r0`, set the client's S to `16 · r0 / r`.

use crate::scene::UpAxis;
use glam::DVec3;
use serde_json::{Value, json};

/// The clients' default screen-space error, pixels, the geometric errors are computed for.
pub const SCREEN_SPACE_ERROR: f64 = 16.0;

/// The geometric error of a tile whose node's atlas suffices from `min_distance` on (world units), for a
/// build at `screen_width` pixels and a horizontal field of view of `fov_x_deg` degrees.
pub fn geometric_error(min_distance: f64, screen_width: u32, fov_x_deg: f64) -> f64 {
    let t = (fov_x_deg.to_radians() * 0.5).tan();
    min_distance * 2.0 * t * SCREEN_SPACE_ERROR / f64::from(screen_width.max(1))
}

/// The inverse of [`geometric_error`]: the distance at which a client refines a tile of error `g`.
pub fn refine_distance(g: f64, screen_width: u32, fov_x_deg: f64) -> f64 {
    let t = (fov_x_deg.to_radians() * 0.5).tan();
    g * f64::from(screen_width.max(1)) / (2.0 * t * SCREEN_SPACE_ERROR)
}

/// Relative slack of a content box: 8 f32 steps (two roundings of each coordinate, with room).
pub(super) const F32_SLACK: f64 = 8.0 * f32::EPSILON as f64;

/// A scene-frame vector in glTF's frame: the scene turned so that its `up` axis is +y (a rotation, the
/// identity for y-up: z-up `(x, y, z)` → `(x, z, −y)`, x-up → `(−y, x, z)`).
pub(super) fn to_gltf_frame(p: DVec3, up: UpAxis) -> DVec3 {
    match up {
        UpAxis::Y => p,
        UpAxis::Z => DVec3::new(p.x, p.z, -p.y),
        UpAxis::X => DVec3::new(-p.y, p.x, p.z),
    }
}

/// [`to_gltf_frame`] as a glTF node rotation (unit quaternion `[x, y, z, w]`), `None` for y-up.
pub(super) fn gltf_rotation(up: UpAxis) -> Option<[f64; 4]> {
    let h = std::f64::consts::FRAC_1_SQRT_2;
    match up {
        UpAxis::Y => None,
        // −90° about x.
        UpAxis::Z => Some([-h, 0.0, 0.0, h]),
        // +90° about z.
        UpAxis::X => Some([0.0, 0.0, h, h]),
    }
}

/// A scene-frame vector (up axis `up`) in the tile frame (z-up).
pub(super) fn to_tile_frame(p: DVec3, up: UpAxis) -> DVec3 {
    let g = to_gltf_frame(p, up);
    DVec3::new(g.x, -g.z, g.y)
}

/// The 3D Tiles `box` of the scene-frame AABB `[lo, hi]` relative to `origin`: centre, then the three
/// half-axis vectors, in the tile frame. Half sizes are kept at least `1e-6` of the largest (and at least
/// 1e-9) so a flat node still has a volume. A box of content is first grown ([`with_f32_slack`]).
pub(super) fn tile_box(lo: DVec3, hi: DVec3, origin: DVec3, up: UpAxis) -> Value {
    let c = to_tile_frame((lo + hi) * 0.5 - origin, up);
    let h = (hi - lo) * 0.5;
    let floor = (h.max_element() * 1e-6).max(1e-9);
    let h = to_tile_frame(h, up).abs().max(DVec3::splat(floor));
    json!([c.x, c.y, c.z, h.x, 0.0, 0.0, 0.0, h.y, 0.0, 0.0, 0.0, h.z])
}

/// `[lo, hi]` grown on every side by [`F32_SLACK`] of its farthest corner's distance from `origin`: a
/// tile's f32 positions (relative to `origin`, from the file's f32 positions relative to their leaf) lie
/// up to a few f32 steps outside the f64 bounds (13 µm at 100 m, outside the box without it).
pub(super) fn with_f32_slack(lo: DVec3, hi: DVec3, origin: DVec3) -> (DVec3, DVec3) {
    let reach = (lo - origin).abs().max((hi - origin).abs()).max_element();
    let slack = DVec3::splat(reach * F32_SLACK);
    (lo - slack, hi + slack)
}

/// The column-major 4 × 4 translation to the scene-frame point `origin`, in the tile frame.
pub(super) fn translation(origin: DVec3, up: UpAxis) -> Value {
    let o = to_tile_frame(origin, up);
    json!([
        1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, o.x, o.y, o.z, 1.0
    ])
}

/// The box of the union of boxes given as scene-frame AABBs.
pub(super) fn union(boxes: impl IntoIterator<Item = (DVec3, DVec3)>) -> Option<(DVec3, DVec3)> {
    boxes
        .into_iter()
        .reduce(|a, b| (a.0.min(b.0), a.1.max(b.1)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn geometric_error_and_refine_distance_are_inverse() {
        let g = geometric_error(250.0, 800, 60.0);
        // 250 · 2 tan 30° · 16 / 800 = 5.7735…
        assert!((g - 5.773_502_691_896_258).abs() < 1e-12);
        assert!((refine_distance(g, 800, 60.0) - 250.0).abs() < 1e-9);
    }

    /// The rotation given to the contents' leaf nodes is [`to_gltf_frame`], and every up axis ends up
    /// as the tile frame's z.
    #[test]
    fn every_up_axis_becomes_the_tile_frames_z() {
        let p = DVec3::new(1.0, 2.0, 3.0);
        for up in [UpAxis::X, UpAxis::Y, UpAxis::Z] {
            let up_vector = up.vector();
            assert_eq!(to_tile_frame(up_vector, up), DVec3::Z, "{up:?}");
            assert_eq!(to_gltf_frame(up_vector, up), DVec3::Y, "{up:?}");
            let q = gltf_rotation(up).map_or(glam::DQuat::IDENTITY, glam::DQuat::from_array);
            assert!((q * p - to_gltf_frame(p, up)).length() < 1e-12, "{up:?}");
        }
        // A z-up scene's frame is the tile frame itself.
        assert_eq!(to_tile_frame(p, UpAxis::Z), p);
    }

    #[test]
    fn boxes_are_z_up_and_relative_to_the_origin() {
        let b = tile_box(
            DVec3::new(1000.0, 10.0, -20.0),
            DVec3::new(1010.0, 14.0, -10.0),
            DVec3::new(1000.0, 0.0, 0.0),
            UpAxis::Y,
        );
        let v: Vec<f64> = b
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert_eq!(&v[..3], &[5.0, 15.0, 12.0]);
        assert_eq!((v[3], v[7], v[11]), (5.0, 5.0, 2.0));
        // Grown by the slack of the farthest corner's coordinate (20, of (10, 14, -20)).
        let (lo, hi) = with_f32_slack(
            DVec3::new(1000.0, 10.0, -20.0),
            DVec3::new(1010.0, 14.0, -10.0),
            DVec3::new(1000.0, 0.0, 0.0),
        );
        let slack = 20.0 * F32_SLACK;
        assert_eq!(lo, DVec3::new(1000.0, 10.0, -20.0) - slack);
        assert_eq!(hi, DVec3::new(1010.0, 14.0, -10.0) + slack);
    }
}
