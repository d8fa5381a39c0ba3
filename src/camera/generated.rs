//! The generated camera paths of the fly-through experiments, over a [`Ground`]: `overview-dive`,
//! `street` and `orbit`.
//!
//! Units: metres (world units) and seconds. Plane coordinates and heights are those of the scene's
//! [`UpAxis`]; *footprint* is the plane extent of the ground's bounds `[lo, hi]`, *diagonal* its length
//! (at least 1 m), *top* `height(hi)`. The *ground under the eye* is [`Ground::height_at`] at the eye's
//! plane point.
//!
//! **How the ground is kept under the eye.** Between two keyframes a sampled eye stays inside the
//! per-coordinate range of the two (monotone cubic, see [`CameraPath`]): its plane point lies in the
//! box the two keyframes' plane points span, its height between theirs. So every keyframe that is
//! placed *above the ground* is placed above the **highest ground of the boxes of its two segments**
//! (to the keyframes before and after it, [`Ground::max_in_box`]); the `street` path, whose plane motion
//! is a straight line, uses the highest ground along its segments ([`Ground::max_along`]). Then no
//! sample comes closer to the ground under it than the smallest offset of its two keyframes. On a flat
//! ground ([`Ground::flat`]) every such maximum is the ground itself and the paths are exactly those of
//! the bounds alone.
//!
//! [`CameraPath::overview_dive`], [`CameraPath::street`] and [`CameraPath::orbit`] are the paths over
//! [`Ground::flat`] (the bounds' lowest point as the ground); the `_on` forms take a derived ground.

use super::ground::Ground;
use super::path::{CameraError, CameraPath, Keyframe, default_aspect, default_near};
use crate::scene::UpAxis;
use glam::{DVec2, DVec3};

/// Eye height above the ground at the street keyframes, metres.
const EYE_HEIGHT: f64 = 1.7;
/// The least share of its diagonal the street path travels over content; below it the path follows the
/// footprint's diagonal or the content's own ([`CameraPath::street_on`]).
const STREET_MIN_TRAVEL: f64 = 0.25;

/// The directions tried from the dive's building to its street point, in order (the first, towards
/// the footprint's low corner, is the only one a flat ground ever uses).
const APPROACHES: [DVec2; 8] = [
    DVec2::new(-1.0, -1.0),
    DVec2::new(1.0, -1.0),
    DVec2::new(-1.0, 1.0),
    DVec2::new(1.0, 1.0),
    DVec2::new(-1.0, 0.0),
    DVec2::new(1.0, 0.0),
    DVec2::new(0.0, -1.0),
    DVec2::new(0.0, 1.0),
];

impl CameraPath {
    /// The generated path `kind` over `ground` (its bounds, up axis and heights).
    fn generated(
        kind: &'static str,
        ground: &Ground,
        make: impl FnOnce(&Frame) -> (Vec<Keyframe>, f64),
    ) -> Result<CameraPath, CameraError> {
        let (lo, hi) = ground.bounds();
        if !(lo.is_finite() && hi.is_finite() && lo.cmple(hi).all()) {
            return Err(CameraError::BadBounds {
                kind,
                lo: lo.to_array(),
                hi: hi.to_array(),
            });
        }
        let frame = Frame::new(ground);
        let (keyframes, far) = make(&frame);
        Ok(CameraPath {
            keyframes,
            up: ground.up().vector().to_array(),
            aspect: default_aspect(),
            near: default_near(),
            far,
        })
    }

    /// [`CameraPath::overview_dive_on`] over [`Ground::flat`]`(lo, hi, up)`.
    pub fn overview_dive(lo: DVec3, hi: DVec3, up: UpAxis) -> Result<CameraPath, CameraError> {
        CameraPath::overview_dive_on(&Ground::flat(lo, hi, up))
    }

    /// [`CameraPath::street_on`] over [`Ground::flat`]`(lo, hi, up)`.
    pub fn street(lo: DVec3, hi: DVec3, up: UpAxis) -> Result<CameraPath, CameraError> {
        CameraPath::street_on(&Ground::flat(lo, hi, up))
    }

    /// [`CameraPath::orbit_on`] over [`Ground::flat`]`(lo, hi, up)`.
    pub fn orbit(lo: DVec3, hi: DVec3, up: UpAxis) -> Result<CameraPath, CameraError> {
        CameraPath::orbit_on(&Ground::flat(lo, hi, up))
    }

    /// From a whole-scene overview high above, down to one building at street level and back up (the
    /// paper's "rapidly changing visibility"), 20 s.
    ///
    /// The building is the preferred spot at fractions `(0.62, 0.37)` of the footprint (away from the
    /// quadtree's first split lines) moved to the nearest content ([`Ground::content_near`]). The street
    /// point lies 2 % of the footprint (1–25 m per axis) from it, towards the footprint's low corner
    /// unless another of eight directions is better: less lift over the ground between it and the
    /// approach, and ground nearer the building's level.
    ///
    /// Documented bounds (checked by tests): the eye stays inside the footprint; at every time it is at
    /// least 1.7 m above the ground under it and at most the *overview height*
    /// `max(top + 0.9 · diagonal, highest ground + 20 m)` (the whole footprint fits a 60° view); it
    /// reaches the overview height, and at the two street keyframes it is 1.7 m above the highest
    /// ground around the street (exactly 1.7 m above the ground under it where that is level, as on a
    /// flat ground). Targets stay inside the footprint at heights in `[lowest ground, top]`.
    pub fn overview_dive_on(ground: &Ground) -> Result<CameraPath, CameraError> {
        CameraPath::generated("overview-dive", ground, |f| {
            let centre = f.at(0.5, 0.5);
            let building = f.clamp_plane(ground.content_near(f.at(0.62, 0.37)));
            let off = (f.size * 0.02)
                .max(DVec2::splat(1.0))
                .min(DVec2::splat(25.0));
            let a = f.best_approach(building, off);
            let lifts = Lifts {
                overview: (f.top + 0.9 * f.diag).max(ground.highest() + 20.0),
                low: (0.02 * f.diag).clamp(1.7, 80.0),
                mid: 0.25 * f.diag,
            };
            let gc = ground.height_at(centre);
            let gb = ground.height_at(building);
            let look = gb + (f.top - gb).min(10.0);
            let swing = f.lerp_plane(centre, building, 0.6);
            let stop = |time, eye, lift, target, target_h, fov| Stop {
                time,
                eye: f.clamp_plane(eye),
                lift,
                target,
                target_h,
                fov,
            };
            use Lift::{Low, Mid, Overview, Street};
            let stops = [
                stop(0.0, centre - f.size * 0.01, Overview, centre, gc, 60.0),
                stop(4.0, swing, Mid, building, gb, 60.0),
                stop(7.0, a.near, Low, building, gb, 60.0),
                stop(9.0, a.street, Street, building, look, 75.0),
                stop(11.0, a.walk, Street, building, look, 75.0),
                stop(13.0, a.near, Low, building, gb, 60.0),
                stop(16.0, swing, Mid, building, gb, 60.0),
                stop(20.0, centre + f.size * 0.01, Overview, centre, gc, 60.0),
            ];
            let eyes: Vec<DVec2> = stops.iter().map(|s| s.eye).collect();
            let grounds = segment_grounds(&eyes, |p, q| ground.max_in_box(p, q));
            let ks = stops
                .iter()
                .zip(grounds)
                .map(|(s, g)| {
                    let h = lifts.height(s.lift, g);
                    f.key(s.time, s.eye, h, s.target, s.target_h, s.fov)
                })
                .collect();
            (ks, f.far(lifts.overview))
        })
    }

    /// A low flight across the scene along its footprint's diagonal from 5 % to 95 %, the eye
    /// alternating between 1.7 m and 10 m above the ground, looking ahead towards the next keyframe, at
    /// about 15 m/s (at least 10 s). Nine keyframes, each over the content nearest its point of the
    /// diagonal ([`Ground::content_near`]; on a ground without content the diagonal itself, a straight
    /// line).
    ///
    /// Documented bounds: eye inside the footprint; at every time at least 1.7 m above the ground under
    /// it; at each keyframe its listed height (1.7–10 m) above the highest ground along its two segments
    /// ([`Ground::max_along`]), so on a flat ground the height above the ground stays in `[1.7 m, 10 m]`,
    /// and never more than 10 m above the highest ground.
    pub fn street_on(ground: &Ground) -> Result<CameraPath, CameraError> {
        CameraPath::generated("street", ground, |f| {
            let heights = [
                EYE_HEIGHT, 10.0, 4.0, EYE_HEIGHT, 7.0, 2.5, 10.0, EYE_HEIGHT, 5.0,
            ];
            let n = heights.len() - 1;
            let fraction = |i: usize| i as f64 / n as f64;
            let along = |a: DVec2, b: DVec2| -> Vec<DVec2> {
                (0..=n).map(|i| a.lerp(b, fraction(i))).collect()
            };
            let (a, b) = (f.at(0.05, 0.05), f.at(0.95, 0.95));
            let length = (b - a).length();
            // Each keyframe over the content nearest its point of the diagonal: a track's diagonal crosses
            // empty corners, where a low eye looking ahead saw only sky (zengarden: 9 of 30 frames).
            let snapped: Vec<DVec2> = (along(a, b).into_iter())
                .map(|p| {
                    let near = ground.content_near(p);
                    if near == p { p } else { f.clamp_plane(near) }
                })
                .collect();
            // Where the content is a cell or two, the keyframes all snapped there and the eye stood still
            // or crept (fault hunt, session 38): a 1 km road of one quad (content is counted by triangle
            // centroids) moved 0 m in 60 s, and zengarden's track, far inside its skybox's bounds, was
            // crossed at ~0.2 m/s. Then the flight goes along the footprint's diagonal where the scene's
            // ground covers the whole footprint, else along the diagonal of the content's own extent.
            let travelled: f64 = snapped.windows(2).map(|w| (w[1] - w[0]).length()).sum();
            let [nx, ny] = ground.cells();
            let covered = ground.measured_cells() == nx * ny;
            let (a, b, eyes) = if travelled >= STREET_MIN_TRAVEL * length {
                (a, b, snapped)
            } else if covered {
                (a, b, along(a, b))
            } else if let Some((lo, hi)) = ground.content_bounds() {
                let (a, b) = (lo.lerp(hi, 0.05), lo.lerp(hi, 0.95));
                (a, b, along(a, b))
            } else {
                (a, b, snapped)
            };
            let diagonal = |i: usize| a.lerp(b, fraction(i));
            let duration = ((b - a).length() / 15.0).max(10.0);
            let dir = (b - a).try_normalize().unwrap_or(DVec2::X);
            let grounds = segment_grounds(&eyes, |p, q| ground.max_along(p, q));
            // Looking ahead along the flight: towards the next keyframe (the last along the one before;
            // the diagonal where two keyframes share a spot).
            let ahead = |i: usize| {
                let j = if i < n { i } else { i - 1 };
                if eyes[j] == diagonal(j) && eyes[j + 1] == diagonal(j + 1) {
                    return dir;
                }
                (eyes[j + 1] - eyes[j]).try_normalize().unwrap_or(dir)
            };
            let ks = heights
                .iter()
                .zip(grounds)
                .enumerate()
                .map(|(i, (&h, g))| {
                    let eye = eyes[i];
                    let target = eye + ahead(i) * 50.0;
                    f.key(
                        duration * fraction(i),
                        eye,
                        g + h,
                        target,
                        g + h * 0.5,
                        70.0,
                    )
                })
                .collect();
            (ks, f.far(ground.highest() + 10.0))
        })
    }

    /// One turn around the centre at a medium height, 30 s: eye on a circle of radius `0.5 · diagonal`
    /// of the footprint (so partly outside the footprint), at `height(lo) + 0.3 · diagonal`, looking at
    /// the centre at `height(lo)`. Bounds-based: the ground's heights are not used.
    ///
    /// Documented bounds: eye height exactly `height(lo) + 0.3 · diagonal` (constant), planar distance
    /// from the centre in `[0.495, 0.5025] · diagonal` (the per-coordinate spline deviates slightly
    /// from the circle).
    pub fn orbit_on(ground: &Ground) -> Result<CameraPath, CameraError> {
        CameraPath::generated("orbit", ground, |f| {
            let centre = f.at(0.5, 0.5);
            let radius = 0.5 * f.diag;
            let height = f.bottom + 0.3 * f.diag;
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
                        f.bottom,
                        60.0,
                    )
                })
                .collect();
            (ks, f.far(height))
        })
    }
}

/// Per keyframe (plane eye points `eyes`, in time order), the highest ground over its segments to the
/// keyframes before and after it, as `max(a, b)` gives it for a segment `a → b`.
fn segment_grounds(eyes: &[DVec2], max: impl Fn(DVec2, DVec2) -> f64) -> Vec<f64> {
    let segments: Vec<f64> = eyes.windows(2).map(|w| max(w[0], w[1])).collect();
    (0..eyes.len())
        .map(|i| {
            let before = i.checked_sub(1).and_then(|j| segments.get(j));
            let after = segments.get(i);
            match (before, after) {
                (Some(&b), Some(&a)) => b.max(a),
                (Some(&g), None) | (None, Some(&g)) => g,
                (None, None) => eyes.get(i).map_or(f64::NEG_INFINITY, |&p| max(p, p)),
            }
        })
        .collect()
}

/// How a dive keyframe's eye height follows from the ground `g` under its segments.
#[derive(Copy, Clone, Debug)]
enum Lift {
    /// The overview height (absolute).
    Overview,
    /// `max(g + mid, g + low)`.
    Mid,
    /// `g + low`.
    Low,
    /// `g + 1.7 m`.
    Street,
}

/// The dive's heights: the absolute overview height and the offsets above the ground.
struct Lifts {
    overview: f64,
    low: f64,
    mid: f64,
}

impl Lifts {
    fn height(&self, lift: Lift, g: f64) -> f64 {
        match lift {
            Lift::Overview => self.overview,
            Lift::Mid => (g + self.mid).max(g + self.low),
            Lift::Low => g + self.low,
            Lift::Street => g + EYE_HEIGHT,
        }
    }
}

/// One dive keyframe before its eye height is known.
struct Stop {
    time: f64,
    /// Plane point, inside the footprint.
    eye: DVec2,
    lift: Lift,
    target: DVec2,
    target_h: f64,
    fov: f64,
}

/// The dive's street part: the street point, the walk's end and the approach point above both.
struct Approach {
    street: DVec2,
    walk: DVec2,
    near: DVec2,
}

/// Scene footprint helpers for the generated paths: plane coordinates, heights and keyframes.
struct Frame<'a> {
    up: UpAxis,
    lo: DVec2,
    size: DVec2,
    /// Footprint diagonal, at least 1 m.
    diag: f64,
    /// `height(lo)`: the bounds' lowest point.
    bottom: f64,
    top: f64,
    ground: &'a Ground,
}

impl Frame<'_> {
    fn new(ground: &Ground) -> Frame<'_> {
        let (lo, hi) = ground.bounds();
        let up = ground.up();
        let lo2 = up.plane(lo);
        let size = up.plane(hi) - lo2;
        Frame {
            up,
            lo: lo2,
            size,
            diag: size.length().max(1.0),
            bottom: up.height(lo),
            top: up.height(hi),
            ground,
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

    /// The street part towards `dir` (per-axis signs) at offset `off` from `building`.
    fn approach(&self, building: DVec2, off: DVec2, dir: DVec2) -> Approach {
        let step = dir * off;
        let street = self.clamp_plane(building + step);
        Approach {
            street,
            walk: self.lerp_plane(street, building, 0.5),
            near: self.clamp_plane(building + step * 4.0),
        }
    }

    /// How far the street part `a` is from the ideal, metres: how far its two street keyframes must
    /// rise above the ground under them to clear the ground of their segments
    /// (`near → street → walk → near`), plus how far the ground under them lies from the building's
    /// (a street at the foot of a cliff below the building is not its street). Infinite when the street
    /// point or the walk's end coincides with the building (no view direction at eye height).
    fn cost(&self, a: &Approach, building: DVec2) -> f64 {
        if a.street == building || a.walk == building {
            return f64::INFINITY;
        }
        let g = self.ground;
        let (in_, walk, out) = (
            g.max_in_box(a.near, a.street),
            g.max_in_box(a.street, a.walk),
            g.max_in_box(a.walk, a.near),
        );
        let (gs, gw, gb) = (
            g.height_at(a.street),
            g.height_at(a.walk),
            g.height_at(building),
        );
        let rise = (in_.max(walk) - gs).max(walk.max(out) - gw);
        rise + (gs - gb).abs().max((gw - gb).abs())
    }

    /// The first approach of [`APPROACHES`] with the least cost (0 on a flat ground: the first).
    fn best_approach(&self, building: DVec2, off: DVec2) -> Approach {
        let mut best = self.approach(building, off, APPROACHES[0]);
        let mut best_cost = self.cost(&best, building);
        for &dir in &APPROACHES[1..] {
            if best_cost <= 0.0 {
                break;
            }
            let a = self.approach(building, off, dir);
            let cost = self.cost(&a, building);
            if cost < best_cost {
                (best, best_cost) = (a, cost);
            }
        }
        best
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
        (2.0 * (self.diag + (h - self.bottom).abs() + (self.top - self.bottom))).max(1000.0)
    }
}

#[cfg(test)]
mod tests;
