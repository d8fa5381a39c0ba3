//! Cameras and selection scales the CPU suite's paging tests share.

use atlastree::camera::Camera;
use atlastree::model::BuildParams;
use atlastree::select::{SelectOptions, min_distance_scale};
use glam::DVec3;

/// A 60°, 4:3, Y-up camera at `eye` looking at `target`, near 0.5 m, far plane `far` (m).
pub fn look(eye: DVec3, target: DVec3, far: f64) -> Camera {
    Camera {
        eye,
        target,
        up: DVec3::Y,
        fov_x_deg: 60.0,
        aspect: 4.0 / 3.0,
        near: 0.5,
        far,
    }
}

/// The selection scale of an 800 px wide view with horizontal fov `fov_x_deg` at texel ratio 1.
pub fn scale_800(params: &BuildParams, fov_x_deg: f64) -> f64 {
    min_distance_scale(
        params,
        &SelectOptions {
            screen_width: 800,
            texel_ratio: 1.0,
            fov_x_deg,
        },
    )
    .expect("valid build parameters")
}
