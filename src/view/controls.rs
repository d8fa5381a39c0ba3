//! The viewer's camera controller, recorder and path follower: plain data and maths, no window, so every
//! rule is unit-tested.
//!
//! - **Fly** (default): `W`/`S` move along the view direction, `A`/`D` strafe, `Q`/`E` move down/up along
//!   the scene's up axis, `Shift` ×[`FAST_FACTOR`]; dragging the mouse turns (yaw about the up axis, pitch
//!   clamped to ±[`MAX_PITCH_DEG`]); the scroll wheel scales the speed by [`SCROLL_STEP`] per notch.
//! - **Orbit**: dragging turns the eye around a target point, the wheel moves it closer or further, the
//!   movement keys pan the target (horizontally along the view, `Q`/`E` vertically).
//! - **Frame** (`F`): looks at the whole scene bounds from the current heading, from above.
//!
//! Units: world units (metres), seconds, radians inside (degrees for the field of view, as in
//! [`Camera`]). Mouse deltas are in physical pixels.

use crate::camera::{Camera, CameraPath, Keyframe};
use glam::DVec3;

/// Speed multiplier while `Shift` is held.
pub const FAST_FACTOR: f64 = 4.0;
/// Fly speed factor (or orbit distance divisor) per scroll notch.
pub const SCROLL_STEP: f64 = 1.2;
/// Pitch limit, degrees: the view never reaches the up axis, so the camera basis stays defined.
pub const MAX_PITCH_DEG: f64 = 89.0;
/// Turn per pixel of mouse movement, radians (0.2° per pixel).
pub const LOOK_RADIANS_PER_PIXEL: f64 = 0.2 * std::f64::consts::PI / 180.0;
/// Fly speed limits, world units per second.
pub const MIN_SPEED: f64 = 0.01;
pub const MAX_SPEED: f64 = 1.0e6;
/// Closest orbit distance, world units.
pub const MIN_ORBIT_DISTANCE: f64 = 0.1;
/// Pitch used by [`Controller::frame`] when the current view is flatter, degrees (looking down).
pub const FRAME_PITCH_DEG: f64 = -35.0;
/// Smallest time step between two recorded keyframes, seconds.
pub const RECORD_INTERVAL_S: f64 = 0.1;

/// A key the controller reacts to (the window maps physical keys to these).
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum Key {
    Forward,
    Back,
    Left,
    Right,
    Down,
    Up,
    Fast,
}

impl Key {
    const ALL: [Key; 7] = [
        Key::Forward,
        Key::Back,
        Key::Left,
        Key::Right,
        Key::Down,
        Key::Up,
        Key::Fast,
    ];

    fn bit(self) -> u8 {
        1 << Key::ALL.iter().position(|&k| k == self).unwrap_or(0)
    }
}

/// How mouse drags and movement keys move the camera.
#[derive(Copy, Clone, Debug, PartialEq, Eq, Hash)]
pub enum ControlMode {
    /// Free flight from the eye.
    Fly,
    /// Turning around a target point.
    Orbit,
}

/// The interactive camera: eye, heading (yaw about the up axis, pitch above the horizontal), lens, and
/// the orbit target. Produces a [`Camera`] per frame.
#[derive(Clone, Debug, PartialEq)]
pub struct Controller {
    pub mode: ControlMode,
    /// Unit up axis of the scene.
    up: DVec3,
    /// Horizontal reference direction (yaw 0) and its right-hand neighbour (yaw +90°), unit, ⟂ `up`.
    ref_forward: DVec3,
    ref_right: DVec3,
    pub eye: DVec3,
    /// Heading, radians: yaw turns right (clockwise seen from above), pitch up.
    yaw: f64,
    pitch: f64,
    /// Orbit mode: the point turned around and the eye's distance to it.
    pub orbit_target: DVec3,
    pub orbit_distance: f64,
    /// Fly speed, world units per second (also the orbit pan speed).
    pub speed: f64,
    /// Horizontal field of view, degrees; near and far planes, world units.
    pub fov_x_deg: f64,
    pub near: f64,
    pub far: f64,
    /// Bit set of held [`Key`]s.
    held: u8,
    /// The camera this controller started from and the heading it was turned into: drawn as given
    /// while the eye and heading are still those. A heading clamps its pitch to ±[`MAX_PITCH_DEG`] and
    /// has no yaw of its own straight down, so `view --camera` looking down steeply showed another
    /// picture than `render` of the same camera (rotated 90° straight down; fault hunt, session 37).
    start: Option<(Camera, (f64, f64))>,
}

impl Controller {
    /// A controller looking like `camera` (eye, direction, lens) in a scene whose up axis is `up`.
    pub fn from_camera(camera: &Camera, up: DVec3) -> Controller {
        let up = up.try_normalize().unwrap_or(DVec3::Y);
        let ref_forward = horizontal_reference(up);
        let ref_right = ref_forward.cross(up);
        let mut c = Controller {
            mode: ControlMode::Fly,
            up,
            ref_forward,
            ref_right,
            eye: camera.eye,
            yaw: 0.0,
            pitch: 0.0,
            orbit_target: camera.target,
            orbit_distance: camera.eye.distance(camera.target).max(MIN_ORBIT_DISTANCE),
            speed: 10.0,
            fov_x_deg: camera.fov_x_deg,
            near: camera.near,
            far: camera.far,
            held: 0,
            start: None,
        };
        c.look_along(camera.target - camera.eye);
        c.start = Some((*camera, c.heading()));
        c
    }

    /// Unit view direction of the heading.
    pub fn direction(&self) -> DVec3 {
        let (sy, cy) = self.yaw.sin_cos();
        let (sp, cp) = self.pitch.sin_cos();
        (self.ref_forward * cy + self.ref_right * sy) * cp + self.up * sp
    }

    /// Heading `(yaw, pitch)`, radians.
    pub fn heading(&self) -> (f64, f64) {
        (self.yaw, self.pitch)
    }

    /// Points the heading along `dir` (ignored when zero or not finite); pitch is clamped.
    pub fn look_along(&mut self, dir: DVec3) {
        let Some(d) = dir.try_normalize() else {
            return;
        };
        let max = MAX_PITCH_DEG.to_radians();
        self.pitch = d.dot(self.up).clamp(-1.0, 1.0).asin().clamp(-max, max);
        self.yaw = d.dot(self.ref_right).atan2(d.dot(self.ref_forward));
    }

    /// Presses (`true`) or releases a movement key.
    pub fn set_key(&mut self, key: Key, pressed: bool) {
        if pressed {
            self.held |= key.bit();
        } else {
            self.held &= !key.bit();
        }
    }

    /// Releases every key (the window lost focus).
    pub fn release_all(&mut self) {
        self.held = 0;
    }

    fn is_held(&self, key: Key) -> bool {
        self.held & key.bit() != 0
    }

    /// A mouse drag of `(dx, dy)` pixels (right, down): turns the heading; in orbit mode the eye moves
    /// around the target with it.
    pub fn drag(&mut self, dx: f64, dy: f64) {
        if !(dx.is_finite() && dy.is_finite()) {
            return;
        }
        let max = MAX_PITCH_DEG.to_radians();
        self.yaw = wrap_angle(self.yaw + dx * LOOK_RADIANS_PER_PIXEL);
        self.pitch = (self.pitch - dy * LOOK_RADIANS_PER_PIXEL).clamp(-max, max);
        if self.mode == ControlMode::Orbit {
            self.eye = self.orbit_target - self.direction() * self.orbit_distance;
        }
    }

    /// `notches` of the scroll wheel (positive: away from the user / up): fly mode scales the speed by
    /// [`SCROLL_STEP`] per notch; orbit mode divides the distance by it (moves closer).
    pub fn scroll(&mut self, notches: f64) {
        if !notches.is_finite() {
            return;
        }
        let f = SCROLL_STEP.powf(notches);
        match self.mode {
            ControlMode::Fly => self.speed = (self.speed * f).clamp(MIN_SPEED, MAX_SPEED),
            ControlMode::Orbit => {
                self.orbit_distance = (self.orbit_distance / f).max(MIN_ORBIT_DISTANCE);
                self.eye = self.orbit_target - self.direction() * self.orbit_distance;
            }
        }
    }

    /// Switches between fly and orbit. Entering orbit keeps the eye and heading and turns around the point
    /// `orbit_distance` ahead.
    pub fn set_mode(&mut self, mode: ControlMode) {
        if mode == ControlMode::Orbit && self.mode == ControlMode::Fly {
            self.orbit_target = self.eye + self.direction() * self.orbit_distance;
        }
        self.mode = mode;
    }

    /// Unit movement direction of the held keys in world space (zero when none or they cancel out).
    fn movement(&self) -> DVec3 {
        let dir = self.direction();
        let forward = match self.mode {
            ControlMode::Fly => dir,
            ControlMode::Orbit => (dir - self.up * dir.dot(self.up))
                .try_normalize()
                .unwrap_or(self.ref_forward),
        };
        let right = dir.cross(self.up).try_normalize().unwrap_or(self.ref_right);
        let axis = |plus: Key, minus: Key| {
            f64::from(u8::from(self.is_held(plus))) - f64::from(u8::from(self.is_held(minus)))
        };
        (forward * axis(Key::Forward, Key::Back)
            + right * axis(Key::Right, Key::Left)
            + self.up * axis(Key::Up, Key::Down))
        .normalize_or_zero()
    }

    /// Advances by `dt` seconds of held movement keys: the eye (fly) or the target with the eye (orbit)
    /// moves `speed · dt` (× [`FAST_FACTOR`] with `Shift`).
    pub fn update(&mut self, dt: f64) {
        if !(dt.is_finite() && dt > 0.0) {
            return;
        }
        let fast = if self.is_held(Key::Fast) {
            FAST_FACTOR
        } else {
            1.0
        };
        let step = self.movement() * self.speed * fast * dt;
        self.eye += step;
        if self.mode == ControlMode::Orbit {
            self.orbit_target += step;
        }
    }

    /// Frames the box `[lo, hi]`: keeps the yaw, looks down at least [`FRAME_PITCH_DEG`], and backs off
    /// until the bounding sphere fits the narrower field of view at `aspect`. Sets the orbit target to the
    /// centre, the speed to a quarter of the radius per second, and the far plane beyond the box.
    pub fn frame(&mut self, lo: DVec3, hi: DVec3, aspect: f64) {
        if !(lo.is_finite() && hi.is_finite()) {
            return;
        }
        let centre = (lo + hi) * 0.5;
        let radius = ((hi - lo).length() * 0.5).max(MIN_ORBIT_DISTANCE);
        self.pitch = self.pitch.min(FRAME_PITCH_DEG.to_radians());
        let tan_x = (self.fov_x_deg.to_radians() * 0.5).tan();
        let tan_y = if aspect.is_finite() && aspect > 0.0 {
            tan_x / aspect
        } else {
            tan_x
        };
        let half = tan_x.min(tan_y).atan();
        let distance = radius / half.sin().max(1e-6);
        self.orbit_target = centre;
        self.orbit_distance = distance;
        self.eye = centre - self.direction() * distance;
        self.speed = (radius * 0.25).clamp(MIN_SPEED, MAX_SPEED);
        self.far = self.far.max((distance + radius) * 2.0);
    }

    /// The camera of the current state at viewport `aspect` (width / height).
    pub fn camera(&self, aspect: f64) -> Camera {
        if let Some((start, heading)) = &self.start
            && self.mode == ControlMode::Fly
            && self.eye == start.eye
            && self.heading() == *heading
        {
            return Camera {
                aspect,
                up: self.up,
                fov_x_deg: self.fov_x_deg,
                near: self.near,
                far: self.far,
                ..*start
            };
        }
        let target = match self.mode {
            ControlMode::Fly => self.eye + self.direction(),
            ControlMode::Orbit => self.orbit_target,
        };
        Camera {
            eye: self.eye,
            target,
            up: self.up,
            fov_x_deg: self.fov_x_deg,
            aspect,
            near: self.near,
            far: self.far,
        }
    }
}

/// `a` wrapped into (−π, π].
fn wrap_angle(a: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    let w = (a + PI).rem_euclid(TAU) - PI;
    if w == -PI { PI } else { w }
}

/// A unit horizontal direction for yaw 0: the world axis least aligned with `up`, made ⟂ `up`.
fn horizontal_reference(up: DVec3) -> DVec3 {
    let a = up.abs();
    let axis = if a.x <= a.y && a.x <= a.z {
        DVec3::X
    } else if a.y <= a.z {
        DVec3::Y
    } else {
        DVec3::Z
    };
    // For up = +Y this is −Z: yaw 0 looks "north" as the default camera does.
    let h = (axis - up * axis.dot(up)).normalize();
    up.cross(h)
}

/// Records the flown path as keyframes in the [`CameraPath`] format: at most one per
/// [`RECORD_INTERVAL_S`], times strictly increasing, from the first recorded frame at time 0.
#[derive(Clone, Debug, Default)]
pub struct Recorder {
    keyframes: Vec<Keyframe>,
    /// Time of the first frame pushed, seconds (the clock of [`Recorder::push`]).
    start: Option<f64>,
    lens: Option<Camera>,
}

impl Recorder {
    pub fn new() -> Recorder {
        Recorder::default()
    }

    /// Offers the camera at clock time `time` (seconds): kept when at least [`RECORD_INTERVAL_S`] after the
    /// last keyframe (the first one always). Cameras whose eye equals the target are skipped (a path cannot
    /// hold them). Returns whether it was kept.
    pub fn push(&mut self, time: f64, camera: &Camera) -> bool {
        if !time.is_finite() || camera.eye == camera.target {
            return false;
        }
        let start = *self.start.get_or_insert(time);
        let t = time - start;
        if let Some(last) = self.keyframes.last()
            && t - last.time < RECORD_INTERVAL_S
        {
            return false;
        }
        self.keyframes.push(Keyframe {
            time: t,
            eye: camera.eye.to_array(),
            target: camera.target.to_array(),
            fov: camera.fov_x_deg,
        });
        self.lens = Some(*camera);
        true
    }

    /// Keyframes so far.
    pub fn len(&self) -> usize {
        self.keyframes.len()
    }

    pub fn is_empty(&self) -> bool {
        self.keyframes.is_empty()
    }

    /// The recording as a path (up, aspect, near and far of the last camera), `None` when empty.
    pub fn path(&self) -> Option<CameraPath> {
        let lens = self.lens?;
        Some(CameraPath {
            keyframes: self.keyframes.clone(),
            up: lens.up.to_array(),
            aspect: lens.aspect,
            near: lens.near,
            far: lens.far,
        })
    }
}

/// Path time of follow mode after `elapsed` seconds: the path plays from its first keyframe and loops.
pub fn follow_time(path: &CameraPath, elapsed: f64) -> f64 {
    let d = path.duration();
    if !(d > 0.0 && elapsed.is_finite()) {
        return path.start();
    }
    path.start() + elapsed.max(0.0).rem_euclid(d)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn cam(eye: DVec3, target: DVec3) -> Camera {
        Camera {
            eye,
            target,
            up: DVec3::Y,
            fov_x_deg: 60.0,
            aspect: 1.5,
            near: 0.25,
            far: 1000.0,
        }
    }

    fn close(a: DVec3, b: DVec3, tol: f64) -> bool {
        (a - b).abs().max_element() <= tol
    }

    #[test]
    fn from_camera_keeps_eye_and_direction() {
        for up in [DVec3::Y, DVec3::Z, DVec3::X] {
            let c = cam(DVec3::new(1.0, 2.0, 3.0), DVec3::new(4.0, -2.0, 0.5));
            let ctl = Controller::from_camera(&c, up);
            let dir = (c.target - c.eye).normalize();
            assert!(close(ctl.direction(), dir, 1e-12), "{up}");
            let out = ctl.camera(1.5);
            assert_eq!(out.eye, c.eye);
            assert!(close((out.target - out.eye).normalize(), dir, 1e-12));
            assert_eq!(out.up, up);
        }
    }

    /// A camera looking straight or steeply down is drawn as given until the user moves it: its
    /// heading clamps the pitch to 89° and has no yaw straight down (`view --camera` showed a tilted or
    /// 90°-rotated picture against `render`; fault hunt, session 37). The first move turns it into the
    /// heading.
    #[test]
    fn a_steep_start_camera_is_drawn_as_given_until_moved() {
        for target in [DVec3::new(0.0, -10.0, 0.0), DVec3::new(0.05, -10.0, 0.0)] {
            let c = cam(DVec3::ZERO, target);
            let mut ctl = Controller::from_camera(&c, DVec3::Y);
            let out = ctl.camera(1.5);
            assert_eq!((out.eye, out.target, out.up), (c.eye, c.target, c.up));
            ctl.set_key(Key::Forward, true);
            ctl.update(0.5);
            let moved = ctl.camera(1.5);
            assert_ne!(moved.eye, c.eye);
            let pitch = (moved.target - moved.eye).normalize().dot(DVec3::Y).asin();
            assert!(pitch >= -MAX_PITCH_DEG.to_radians() - 1e-12, "{pitch}");
        }
    }

    #[test]
    fn w_moves_along_the_view_for_speed_times_dt() {
        let c = cam(DVec3::ZERO, DVec3::new(0.0, 0.0, -1.0));
        let mut ctl = Controller::from_camera(&c, DVec3::Y);
        ctl.speed = 2.0;
        ctl.set_key(Key::Forward, true);
        ctl.update(0.5);
        assert!(
            close(ctl.eye, DVec3::new(0.0, 0.0, -1.0), 1e-12),
            "{}",
            ctl.eye
        );
        ctl.set_key(Key::Fast, true);
        ctl.update(0.5);
        assert!(
            close(ctl.eye, DVec3::new(0.0, 0.0, -5.0), 1e-12),
            "{}",
            ctl.eye
        );
        // W and S together cancel; D strafes right (+X when looking down −Z with +Y up); E goes up.
        ctl.set_key(Key::Fast, false);
        ctl.set_key(Key::Back, true);
        ctl.update(1.0);
        assert!(close(ctl.eye, DVec3::new(0.0, 0.0, -5.0), 1e-12));
        ctl.release_all();
        ctl.set_key(Key::Right, true);
        ctl.update(1.0);
        assert!(
            close(ctl.eye, DVec3::new(2.0, 0.0, -5.0), 1e-12),
            "{}",
            ctl.eye
        );
        ctl.set_key(Key::Right, false);
        ctl.set_key(Key::Up, true);
        ctl.update(1.0);
        assert!(
            close(ctl.eye, DVec3::new(2.0, 2.0, -5.0), 1e-12),
            "{}",
            ctl.eye
        );
        // Diagonal movement is not faster.
        ctl.set_key(Key::Up, false);
        ctl.set_key(Key::Forward, true);
        ctl.set_key(Key::Back, false);
        ctl.set_key(Key::Left, true);
        let before = ctl.eye;
        ctl.update(1.0);
        assert!((ctl.eye.distance(before) - 2.0).abs() < 1e-12);
    }

    #[test]
    fn drag_turns_right_and_down_and_clamps_pitch() {
        let c = cam(DVec3::ZERO, DVec3::new(0.0, 0.0, -1.0));
        let mut ctl = Controller::from_camera(&c, DVec3::Y);
        // 90° to the right: 450 px at 0.2°/px.
        ctl.drag(450.0, 0.0);
        assert!(
            close(ctl.direction(), DVec3::X, 1e-12),
            "{}",
            ctl.direction()
        );
        ctl.drag(0.0, 1.0e6);
        let (_, pitch) = ctl.heading();
        assert!((pitch + MAX_PITCH_DEG.to_radians()).abs() < 1e-12);
        // Still a valid camera (basis defined).
        let b = ctl.camera(1.0).basis();
        assert!(b.right.is_finite() && (b.right.length() - 1.0).abs() < 1e-9);
        ctl.drag(f64::NAN, 3.0);
        assert!(ctl.direction().is_finite());
    }

    #[test]
    fn scroll_scales_speed_within_limits() {
        let mut ctl = Controller::from_camera(&cam(DVec3::ZERO, DVec3::NEG_Z), DVec3::Y);
        ctl.speed = 10.0;
        ctl.scroll(2.0);
        assert!((ctl.speed - 14.4).abs() < 1e-9);
        ctl.scroll(-2.0);
        assert!((ctl.speed - 10.0).abs() < 1e-9);
        ctl.scroll(-1000.0);
        assert_eq!(ctl.speed, MIN_SPEED);
        ctl.scroll(1000.0);
        assert_eq!(ctl.speed, MAX_SPEED);
    }

    #[test]
    fn orbit_keeps_distance_to_target() {
        let c = cam(DVec3::new(0.0, 0.0, 10.0), DVec3::ZERO);
        let mut ctl = Controller::from_camera(&c, DVec3::Y);
        ctl.set_mode(ControlMode::Orbit);
        assert!(close(ctl.orbit_target, DVec3::ZERO, 1e-12));
        for (dx, dy) in [(100.0, 0.0), (37.0, -80.0), (-400.0, 250.0)] {
            ctl.drag(dx, dy);
            assert!((ctl.eye.distance(DVec3::ZERO) - 10.0).abs() < 1e-9);
            let cam = ctl.camera(1.0);
            assert_eq!(cam.target, DVec3::ZERO);
        }
        ctl.scroll(1.0);
        assert!((ctl.eye.distance(DVec3::ZERO) - 10.0 / 1.2).abs() < 1e-9);
        // Panning moves eye and target together, horizontally.
        ctl.set_key(Key::Forward, true);
        let (eye, target) = (ctl.eye, ctl.orbit_target);
        ctl.update(1.0);
        assert!(((ctl.eye - eye) - (ctl.orbit_target - target)).length() < 1e-12);
        assert!((ctl.orbit_target.y - target.y).abs() < 1e-12);
        assert!((ctl.orbit_target.distance(target) - ctl.speed).abs() < 1e-9);
    }

    #[test]
    fn frame_fits_the_bounding_sphere() {
        let mut ctl = Controller::from_camera(&cam(DVec3::ZERO, DVec3::NEG_Z), DVec3::Y);
        let (lo, hi) = (DVec3::new(-50.0, 0.0, -30.0), DVec3::new(50.0, 20.0, 30.0));
        for aspect in [0.5, 1.0, 2.0] {
            ctl.frame(lo, hi, aspect);
            let camera = ctl.camera(aspect);
            let centre = (lo + hi) * 0.5;
            let radius = (hi - lo).length() * 0.5;
            // Looking at the centre, from above.
            let dir = (camera.target - camera.eye).normalize();
            assert!(close(dir, (centre - camera.eye).normalize(), 1e-9));
            assert!(dir.y <= FRAME_PITCH_DEG.to_radians().sin() + 1e-12);
            // The sphere touches but does not cross the narrower half-angle.
            let half = camera.tan_half_fov_x().min(camera.tan_half_fov_y()).atan();
            let seen = (radius / camera.eye.distance(centre)).asin();
            assert!((seen - half).abs() < 1e-9, "{seen} vs {half}");
            // Every corner is inside the frustum.
            let f = camera.frustum();
            for i in 0..8 {
                let p = DVec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                );
                assert!(f.contains_point(p), "corner {p} aspect {aspect}");
            }
        }
    }

    #[test]
    fn recorder_writes_a_valid_path_through_the_cameras() {
        let mut rec = Recorder::new();
        assert!(rec.path().is_none());
        let mut kept = Vec::new();
        for i in 0..25 {
            let t = 100.0 + f64::from(i) * 0.04;
            let c = cam(
                DVec3::new(f64::from(i), 5.0, 0.0),
                DVec3::new(0.0, 0.0, -10.0),
            );
            if rec.push(t, &c) {
                kept.push((t - 100.0, c));
            }
        }
        // 0.96 s at 25 Hz offered, one keyframe per ≥ 0.1 s kept: t = 0, 0.12, 0.24, …, 0.96.
        assert_eq!(rec.len(), 9);
        assert!(!rec.push(200.0, &cam(DVec3::ONE, DVec3::ONE)));
        let path = rec.path().unwrap();
        let json = path.to_json();
        let back = CameraPath::from_json(&json, Path::new("recorded.json")).unwrap();
        for (t, c) in kept {
            let s = back.sample(t);
            assert!(close(s.eye, c.eye, 1e-9) && close(s.target, c.target, 1e-9));
        }
    }

    #[test]
    fn follow_time_loops() {
        let path = CameraPath {
            keyframes: vec![
                Keyframe {
                    time: 2.0,
                    eye: [0.0, 0.0, 0.0],
                    target: [0.0, 0.0, -1.0],
                    fov: 60.0,
                },
                Keyframe {
                    time: 6.0,
                    eye: [1.0, 0.0, 0.0],
                    target: [1.0, 0.0, -1.0],
                    fov: 60.0,
                },
            ],
            up: [0.0, 1.0, 0.0],
            aspect: 1.0,
            near: 0.25,
            far: 100.0,
        };
        assert_eq!(follow_time(&path, 0.0), 2.0);
        assert_eq!(follow_time(&path, 3.0), 5.0);
        assert_eq!(follow_time(&path, 5.0), 3.0);
        assert_eq!(follow_time(&path, f64::NAN), 2.0);
        let mut single = path.clone();
        single.keyframes.truncate(1);
        assert_eq!(follow_time(&single, 7.0), 2.0);
    }

    #[test]
    fn wrap_angle_range() {
        use std::f64::consts::PI;
        assert_eq!(wrap_angle(0.0), 0.0);
        assert!((wrap_angle(3.0 * PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(-PI) - PI).abs() < 1e-12);
        assert!((wrap_angle(2.5 * PI) - 0.5 * PI).abs() < 1e-12);
    }
}
